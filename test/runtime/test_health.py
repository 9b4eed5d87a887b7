# Copyright 2026 The gyro_tdc Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""The compensator's health on /diagnostics (no rclpy): levels, messages and values."""

from __future__ import annotations

from dataclasses import replace
import math

from gyro_tdc.identify import fit_model
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.flags import describe_flags, NO_TEMPERATURE, NON_FINITE, OUT_OF_RANGE, STALE
from gyro_tdc.runtime.health import ERROR, health, InputStatus, OK, WARN
from gyro_tdc.runtime.policy import Policy
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def model():
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)
    return fit_model([run], features=('dT', 'dT2', 'dTdt', 'lag', 'warmup'), n_centers=10,
                     fit_params=False)


def test_health_no_model_is_an_error_until_one_is_loaded(model):
    core = CompensatorCore(Policy(reanchor_on_start=False))
    h = health(core, last_reload='failed: broken.yaml')
    assert (h.level, h.message) == (ERROR, 'no model loaded (failed: broken.yaml)')
    assert h.hardware_id == '' and h.values['model id'] == '' and h.values['model kind'] == ''
    assert h.values['compensation active'] == 'False' and h.values['reanchor'] == 'off'
    core.process(1.0, 0.0, 0.0, 0.0)
    h = health(core, h.mark)
    assert h.level == ERROR
    assert h.message == 'no model loaded (none); 1 samples passed through uncompensated'
    assert h.values['why not'] == 'no model loaded, raw rate passed through'
    core.set_model(replace(model, sensor_id='', frame_id='gyro_link'))
    h = health(core, h.mark, model_file='m.yaml', last_reload='loaded x', frame_id='gyro_link')
    assert (h.level, h.message, h.hardware_id) == (OK, 'compensating', 'gyro_link')  # the data's
    assert h.values['model file'] == 'm.yaml' and h.values['last reload'] == 'loaded x'
    assert h.values['model features'] == ','.join(model.features)


def test_health_waiting_then_compensating(model):
    core = CompensatorCore(Policy(), replace(model, sensor_id='L3GD20-42'))
    h = health(core, sensor_id='L3GD20-42', frame_id='imu_link')
    assert (h.level, h.message, h.hardware_id) == (OK, 'waiting for imu/data_raw', 'L3GD20-42')
    assert h.values['temperature degC'] == '' and h.values['temperature age s'] == ''
    core.add_temperature(10.0, 20.0)
    core.process(10.5, 0.0, 0.0, 0.0)
    h = health(core, h.mark)
    assert (h.level, h.message) == (OK, 'compensating')
    v = h.values
    assert v['compensation active'] == 'True' and v['why not'] == ''
    assert v['temperature degC'] == '20.000' and v['temperature age s'] == '0.500'
    assert v['messages in'] == v['messages out'] == v['compensated'] == '1'
    assert v['in range'] == 'True' and v['temperature stale'] == 'False'
    lo, hi = model.temp_range_c
    assert v['model range degC'] == f'{lo:.2f}..{hi:.2f}'


@pytest.mark.parametrize('bit,feed', [
    (NO_TEMPERATURE, lambda core: core.process(1.0, 0.0, 0.0, 0.0)),
    (NON_FINITE, lambda core: core.process(1.0, math.nan, 0.0, 0.0)),
    (STALE, lambda core: (core.add_temperature(0.0, 20.0), core.process(100.0, 0, 0, 0))),
    (OUT_OF_RANGE, lambda core: (core.add_temperature(0.0, 150.0), core.process(1.0, 0, 0, 0))),
])
def test_health_warns_of_what_is_new_since_the_last_report(model, bit, feed):
    core = CompensatorCore(Policy(), model)
    feed(core)
    feed(core)
    h = health(core)
    assert h.level == WARN and h.message.startswith(f'{describe_flags(bit)} (2 samples)')
    passed = bit in (NO_TEMPERATURE, NON_FINITE)
    assert h.message.endswith('; 2 samples passed through uncompensated') == passed
    assert h.values['compensation active'] == str(not passed)
    key = {NO_TEMPERATURE: 'no temperature yet', NON_FINITE: 'non-finite', STALE: 'stale',
           OUT_OF_RANGE: 'out of range'}[bit]
    assert h.values[key] == '2'
    assert h.values['temperature stale'] == str(bit == STALE)
    assert h.values['in range'] == str(bit != OUT_OF_RANGE)
    # Nothing new since: OK again, the cumulative counts stay.
    again = health(core, h.mark)
    assert again.level == OK and again.message == 'compensating'
    assert again.values[key] == '2'


def test_health_rejected_temperatures_errors_and_several_problems(model):
    core = CompensatorCore(Policy(passthrough_variance=0.5), model)
    core.add_temperature(0.0, math.nan)
    h = health(core)
    assert (h.level, h.message) == (WARN, 'non-finite temperature (1 samples rejected)')
    assert h.values['temperatures rejected'] == '1'
    assert core.fail(FloatingPointError('overflow')) == (0.5, 0.5, 0.5)
    core.process(1.0, 0.0, 0.0, 0.0)
    h = health(core, h.mark)
    assert h.level == ERROR
    assert h.message == ('no temperature yet (1 samples); compensation failed on 1 samples, '
                         'passed through: FloatingPointError: overflow; 1 samples passed '
                         'through uncompensated')
    assert h.values['errors'] == '1' and h.values['last error'] == 'FloatingPointError: overflow'
    assert core.counts == {'in': 1, 'out': 2, 'compensated': 0}
    assert health(core, h.mark).level == OK


def test_health_reports_the_reanchoring(model):
    core = CompensatorCore(Policy(reanchor_on_start=True, still_window=1.0), model)
    assert health(core).values['reanchor'] == 'waiting for stillness'
    core.add_temperature(0.0, 20.0)
    for k in range(300):
        core.process(0.01 * k, 0.0, 0.0, 0.0, (0.0, 0.0, 9.81))
    anchor = core.anchor
    assert anchor is not None
    v = health(core).values
    assert v['reanchor'] == f'done at t={anchor.t:.3f} s'
    assert v['reanchor shift dps'] == ','.join(f'{math.degrees(d):.5f}' for d in anchor.delta)


def test_health_names_the_stale_temperature_when_passing_through(model):
    core = CompensatorCore(Policy(stale_policy='passthrough', temperature_timeout=1.0), model)
    core.add_temperature(0.0, 20.0)
    core.process(5.0, 0.0, 0.0, 0.0)
    v = health(core).values
    assert v['why not'] == 'temperature stale, raw rate passed through'
    assert v['temperature stale'] == 'True' and v['stale'] == '1'


def test_health_warns_of_losses_marked_input_and_upstream_compensators(model):
    core = CompensatorCore(Policy(), model)
    inputs = InputStatus('reliable')
    h = health(core, inputs=inputs)
    assert h.level == OK and h.values['input reliability'] == 'reliable'
    inputs.lost, inputs.already_compensated = 7, 3
    h = health(core, h.mark, inputs=inputs)
    assert h.level == WARN
    assert h.message == ('input messages lost (7, reported by DDS; at least that many); input '
                         'already compensated by gyro_tdc (3 samples): the model is applied '
                         'twice')
    assert (h.values['input lost'], h.values['already compensated']) == ('7', '3')
    assert health(core, h.mark, inputs=inputs).level == OK  # nothing new
    inputs.upstream = ('/imu/compensator_node',)
    h = health(core, h.mark, inputs=inputs)
    assert h.level == WARN and 'published by gyro_tdc compensator /imu/compensator_node' in \
        h.message
    assert h.values['upstream compensators'] == '/imu/compensator_node'


def test_health_warns_while_a_refused_file_was_asked_for(model):
    core = CompensatorCore(Policy(), model)
    h = health(core, last_reload='rejected: m.yaml: nesting deeper than 32 levels')
    assert h.level == WARN
    assert h.message == (f'model file refused, keeping {model.model_id}: m.yaml: nesting '
                         'deeper than 32 levels')


def test_health_warns_of_a_frame_other_than_the_models(model):
    core = CompensatorCore(Policy(), replace(model, frame_id='imu_link'))
    core.add_temperature(10.0, 20.0)
    core.process(10.5, 0.0, 0.0, 0.0)
    h = health(core, frame_id='base_link')
    assert h.level == WARN and "frame 'base_link'" in h.message and "'imu_link'" in h.message
    assert (h.hardware_id, h.values['data frame'], h.values['model frame']) == (
        'base_link', 'base_link', 'imu_link')
    assert health(core, h.mark, frame_id='imu_link').level == OK
    assert health(core, h.mark).level == OK              # no frame on the data: no check
