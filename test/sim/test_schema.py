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

"""The scenario schema: bad fields are named, defaults and effect lists apply."""

from __future__ import annotations

import copy
import re

from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import Scenario
from gyro_tdc.sim.schema import DEFAULTS
import pytest

MINIMAL = {'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 10.0}]}}


def _bad(**changes):
    data = copy.deepcopy(MINIMAL)
    for path, value in changes.items():
        node = data
        parts = path.split('__')
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return data


@pytest.mark.parametrize('data, field', [
    (_bad(gyro__dT2_dps_per_c2='abc'), 'gyro.dT2_dps_per_c2'),
    (_bad(gyro__dT_dps_per_c=[1.0, 2.0]), 'gyro.dT_dps_per_c'),
    (_bad(gyro__dt2_dps_per_c2=1e-3), 'gyro.dt2_dps_per_c2'),
    (_bad(gyro__effects=['bias', 'dT4']), 'gyro.effects'),
    (_bad(gyro__quantise='yes'), 'gyro.quantise'),
    (_bad(thermometer__location='probe'), 'thermometer.location'),
    (_bad(thermometer__rate_hz=0.0), 'thermometer.rate_hz'),
    (_bad(noise__arw_dps_per_rt_hz=-0.1), 'noise.arw_dps_per_rt_hz'),
    (_bad(noise__bias_instability_tau_s=[]), 'noise.bias_instability_tau_s'),
    (_bad(thermal__tau_die_s=float('nan')), 'thermal.tau_die_s'),
    (_bad(runs__count=0), 'runs.count'),
    (_bad(sensor='bmi088'), 'sensor'),
    (_bad(imu_rate_hz=-5), 'imu_rate_hz'),
    (_bad(format_version=2), 'format_version'),
    (_bad(colour='red'), 'colour'),
    (_bad(profile={'start_c': 0.0, 'segments': []}), 'profile.segments'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'hold', 'duration_s': 5.0},
                                                {'kind': 'ramp', 'to_c': 5.0,
                                                 'rate_c_per_h': -1.0}]}),
     'profile.segments[1].rate_c_per_h'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'wobble'}]}),
     'profile.segments[0].kind'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'staircase', 'to_c': 5.0,
                                                 'step_c': 0.1}]}),
     'profile.segments[0].hold_s'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'points', 't_s': [1.0, 2.0],
                                                 'temp_c': [0.0, 1.0]}]}),
     'profile.segments[0].t_s'),
    (_bad(rate_table=[{'t_s': 0.0, 'rate_dps': 1.0}, {'t_s': 0.0, 'rate_dps': 2.0}]),
     'rate_table[1].t_s'),
    (_bad(rate_table=[{'t_s': 0.0, 'rate_dps': 1.0, 'rate_rad_s': 1.0}]), 'rate_table[0]'),
    (_bad(duration_s=0.01), 'duration_s'),
])
def test_validation_error_names_the_field(data, field):
    with pytest.raises(ScenarioError, match=re.escape(f'`{field}`')) as info:
        Scenario.from_dict(data, source='bad.yaml')
    message = str(info.value)
    assert message.startswith('bad.yaml: ') and 'expected' in message and '\n' not in message


def test_scenario_must_be_a_mapping():
    with pytest.raises(ScenarioError, match='mapping'):
        Scenario.from_dict([1, 2, 3])


def test_effects_as_list_means_exactly_those():
    sc = Scenario.from_dict(dict(MINIMAL, sensor='l3gd20', gyro={'effects': ['dT3']}))
    assert sc.gyro.effects == ('dT3',)
    default = Scenario.from_dict(MINIMAL)
    assert default.gyro.effects == ('bias', 'dT', 'dT2')


def test_defaults_fill_every_section_and_the_preset_overrides_them():
    sc = Scenario.from_dict(MINIMAL)
    assert sc.thermal.internal_step_s == DEFAULTS['thermal']['internal_step_s'] == 0.1
    assert sc.thermometer.location == 'package' and sc.thermometer.rate_hz == 1.0
    assert sc.gyro.warmup_tau_s == DEFAULTS['gyro']['warmup_tau_s'] == 300.0
    assert sc.gyro.quantise and sc.gyro.bias_dps == (0.0, 0.0, 0.0)
    assert sc.noise.bias_instability_tau_s == (10.0, 100.0, 1000.0)
    assert sc.accel.gravity_mps2 == 9.80665 and sc.accel.tilt_deg == (0.0, 0.0)
    assert sc.runs.count == 1 and sc.runs.bias_offset_dps_std == (0.0, 0.0, 0.0)
    assert list(sc.data) == list(DEFAULTS)       # the normalised mapping keeps the order
    l3 = Scenario.from_dict(dict(MINIMAL, sensor='l3gd20'))
    assert l3.gyro.warmup_tau_s == 240.0 and l3.gyro.range_dps == 250.0
    assert l3.noise.bias_instability_dps == (0.004, 0.005, 0.004)
