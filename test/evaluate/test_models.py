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

"""
Tests of gyro_tdc.evaluate.models: labels, model files, the ``px4`` baseline, on-board models.

Labels are file-name safe and unique; ``load_models`` reads model files and shipped names and
refuses ``px4`` without training bags. The ``px4`` cubic does not fit a constant training
axis: it passes it through, its other axes are those fitted with the axis at its reference;
training bags constant on every axis are refused in one line.
"""

from __future__ import annotations

import warnings

from bags import bag_from_run
from constant_axes import quanta, values, with_constant as _with
from gyro_tdc.data import load_runs
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import DatasetError, FitError, ModelFileError
from gyro_tdc.evaluate.models import (bag_labels, imu_mismatch, load_models, model_labels,
                                      NamedModel, onboard_model, PX4, safe_label)
from gyro_tdc.model import compensate
from gyro_tdc.model.compensation import CompensationModel
from gyro_tdc.model.fc_tempcal import ardupilot_correction, px4_correction
from hypothesis import example, given, settings
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def runs():
    """Return a training run and a held-out run with a known drift on every axis."""
    return (synth_run(seed=31, hours=0.5, rate_hz=2.0, noise_dps=0.02),
            synth_run(seed=32, hours=0.5, rate_hz=2.0, noise_dps=0.02, name='held'))


def test_labels_are_safe_and_unique():
    assert safe_label('models/My Model.yaml') == 'My_Model'
    assert safe_label('bags/run1/') == 'run1'
    assert safe_label('...') == 'unnamed'
    assert model_labels(['a/m.yaml', 'b/m.yaml', PX4, 'raw.yaml', 'b/m.yml']) == \
        ['m', 'm_2', 'px4', 'raw_model', 'm_3']
    assert bag_labels(['x/run1', 'y/run1', 'z/run2']) == ['x_run1', 'y_run1', 'run2']


def test_load_models(tmp_path):
    models = load_models(['l3gd20_modified'])
    assert [(m.name, m.label) for m in models] == [('l3gd20_modified', 'l3gd20_modified')]
    assert isinstance(models[0].model, CompensationModel)
    with pytest.raises(FitError, match='px4 baseline needs training bags'):
        load_models([PX4])
    with pytest.raises(ModelFileError):
        load_models([str(tmp_path / 'missing.yaml')])


@given(value=values, quantum=quanta)
@example(value=0.0, quantum=0.0078125)         # two values: which samples are read matters
@settings(max_examples=6)
def test_px4_passes_a_constant_training_axis_through(runs, tmp_path_factory, value, quantum):
    """Fit the cubic on the other axes only (as with the axis at its reference); log it."""
    train_run, held = runs
    stuck = _with(train_run, [2], value, quantum)
    folder = tmp_path_factory.mktemp('px4')
    bag = bag_from_run(stuck, folder / 'train')
    lines = []
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        px4 = load_models([PX4], train_bags=[bag], log=lines.append)[0].model
    assert px4.metrics['constant_axes'] == ['z']
    assert not np.any(px4.linear[:, 2]) and px4.intercept[2] == 0.0
    comp = compensate(px4, held.t, held.temp, held.omega)
    assert np.array_equal(comp[:, 2], held.omega[:, 2])
    # The other axes: the cubic fitted on the same bag read back with z at its reference.
    read = load_models([PX4], train_bags=[bag_from_run(_with(train_run, [2], 0.0, 0.0),
                                                       folder / 'ref')])[0].model
    np.testing.assert_array_equal(px4.linear[:, :2], read.linear[:, :2])
    np.testing.assert_array_equal(px4.intercept[:2], read.intercept[:2])
    np.testing.assert_array_equal(px4.residual_var[:2], read.residual_var[:2])
    assert any('gyro axis z constant: not fitted' in x for x in lines), lines
    # Training figures of the identity axis are its raw ones, over the bag as read (the IMU
    # samples after the last thermometer reading are not).
    read = load_runs([bag])[0]
    raw = np.degrees(np.sqrt(np.mean((read.omega[:, 2] - read.omega_ref[:, 2]) ** 2)))
    assert px4.metrics['train_rms_dps'][2] == pytest.approx(raw, rel=1e-6, abs=1e-12)


def test_px4_refuses_training_bags_constant_on_every_axis(runs, tmp_path):
    """Refuse, in one line, a px4 baseline with no gyro to fit."""
    bag = bag_from_run(_with(runs[0], [0, 1, 2], 0.0, 1e-4), tmp_path / 'dead')
    with pytest.raises(DatasetError) as err:
        load_models([PX4], train_bags=[bag])
    assert '\n' not in str(err.value) and 'every axis' in str(err.value)


# The flight controller's own correction as a model: its formula, or one line why not.

PX4_PARAMS = {'TC_G_ENABLE': 0, 'TC_G0_ID': 555, 'TC_G0_TREF': 30.0, 'TC_G0_TMIN': 10.0,
              'TC_G0_TMAX': 60.0, 'TC_G0_X0_1': 1e-4, 'TC_G0_X1_0': 2e-3, 'TC_G0_X2_0': 1e-5}
ARDU = {'INS_TCAL1_ENABLE': 0, 'INS_TCAL1_TMIN': 10.0, 'INS_TCAL1_TMAX': 60.0,
        'INS_TCAL1_GYR1_X': 2000.0, 'INS_TCAL1_GYR2_X': 10.0, 'INS_GYR1_CALTEMP': 25.0}


def _fc_log(firmware: str, params: dict, **info) -> Run:
    """Return a flat run from a log of ``firmware`` with ``params``, 0 to 70 degC."""
    t = np.arange(200.0)
    return Run(t, np.linspace(0.0, 70.0, 200), np.zeros((200, 3)), np.zeros((200, 3)),
               f'log.{firmware}', {'firmware': firmware, 'params': params, **info})


@pytest.mark.parametrize('spec, run, correction', [
    ('px4-onboard', _fc_log('px4', PX4_PARAMS, device_id=555), px4_correction),
    ('ardupilot-onboard', _fc_log('ardupilot', ARDU), ardupilot_correction),
])
def test_the_model_is_the_firmware_formula_clamped_to_its_range(spec, run, correction):
    model, line = onboard_model(spec, run)
    assert line.startswith(f"{spec}: the flight controller's correction from ")
    assert 'clamped to 10 .. 60 degC' in line and 'not applied' in line
    got = run.omega - compensate(model, run.t, run.temp, run.omega, out_of_range='clamp')
    np.testing.assert_allclose(got, correction(run.info['params'], run.temp), atol=1e-12)
    assert model.temp_range_c == (10.0, 60.0)


def test_a_firmware_without_temperature_calibration_is_said_and_corrects_nothing():
    run = _fc_log('ardupilot', {})                     # ArduCopter 3.x: no INS_TCAL* at all
    model, line = onboard_model('ardupilot-onboard', run)
    assert 'INS_TCAL1_*, which the log does not hold' in line and 'CALTEMP' not in line
    np.testing.assert_allclose(compensate(model, run.t, run.temp, run.omega), run.omega,
                               rtol=0, atol=1e-15)


def test_a_log_that_cannot_give_the_model_is_refused_in_one_line():
    with pytest.raises(DatasetError, match='needs a PX4 ULog'):
        onboard_model('px4-onboard', _fc_log('ardupilot', ARDU))
    with pytest.raises(DatasetError, match='no TC_Gn_ID .* is the device id 7'):
        onboard_model('px4-onboard', _fc_log('px4', PX4_PARAMS, device_id=7))
    with pytest.raises(DatasetError, match='already carries the on-board correction'):
        onboard_model('ardupilot-onboard', _fc_log('ardupilot', ARDU, onboard_compensated=True))


def test_a_log_of_another_imu_than_the_models_is_said_and_unknowns_are_not():
    """Warn only when both the model's IMUs and the log's are known and differ."""
    run = synth_run(hours=0.2, rate_hz=1.0, seed=1)
    model = CompensationModel.polynomial(('dT',), 20.0, np.zeros((2, 3)), temp_range_c=(0.0, 40.0),
                                         residual_var=np.full(3, 1e-6))
    named = NamedModel('m.yaml', 'm', model.replace(created={'imus': ['B 1 IMU 0']}))
    run.info.update(board='B 1', instance=1)
    said = imu_mismatch(named, run, 'log')
    assert said.startswith('warning: log is B 1 IMU 1; model m was trained on B 1 IMU 0')
    run.info['instance'] = 0
    assert imu_mismatch(named, run, 'log') is None                  # the same IMU
    run.info['board'] = ''
    assert imu_mismatch(named, run, 'log') is None                  # the log names no board
    run.info['board'] = 'B 2'
    for created in ({}, {'imus': 'B 1 IMU 0'}, {'imus': []}):        # none known, or malformed
        assert imu_mismatch(NamedModel('m', 'm', model.replace(created=created)), run,
                            'log') is None
    assert imu_mismatch(named, None, 'log') is None
