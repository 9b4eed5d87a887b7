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

"""The typed sections of a scenario: what they derive from their fields; the presets."""

from __future__ import annotations

from gyro_tdc.sim import PRESETS, Scenario
from gyro_tdc.sim.specs import AccelSpec, preset, RateTable
import numpy as np
from scenarios import accel_thermal, table_moving


def test_accel_spec_is_thermal_only_with_a_temperature_coefficient():
    assert not accel_thermal(AccelSpec(gravity_mps2=9.8, noise_mps2_per_rt_hz=(0.0, 0.0, 0.0)))
    assert accel_thermal(AccelSpec(gravity_mps2=9.8, noise_mps2_per_rt_hz=(0.0, 0.0, 0.0),
                                   dT2_mg_per_c2=(0.0, 0.1, 0.0)))


def test_rate_table_moves_when_a_rate_is_not_zero_and_gives_arrays():
    still = RateTable(t_s=(0.0,), rate_rad_s=((0.0, 0.0, 0.0),))
    assert not table_moving(still)
    table = RateTable(t_s=(0.0, 5.0), rate_rad_s=((0.0, 0.0, 0.0), (0.0, 0.1, 0.0)))
    assert table_moving(table)
    t, rate = table.arrays()
    np.testing.assert_array_equal(t, [0.0, 5.0])
    assert rate.shape == (2, 3) and rate[1, 1] == 0.1


MINIMAL = {'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 10.0}]}}


def test_presets_hold_the_datasheet_figures_and_validate():
    assert set(PRESETS) == {'l3gd20', 'i3g4250d'}
    l3, i3 = PRESETS['l3gd20'], PRESETS['i3g4250d']
    assert l3['gyro']['range_dps'] == 250.0 and i3['gyro']['range_dps'] == 245.0
    assert l3['gyro']['bias_dps'] == [3.6, -4.3, 1.3]
    assert i3['gyro']['bias_dps'] == [2.6, -6.2, 1.3]
    assert l3['gyro']['warmup_tau_s'] == 240.0 and i3['gyro']['warmup_tau_s'] == 300.0
    assert l3['noise']['bias_instability_dps'] == [0.004, 0.005, 0.004]
    assert i3['noise']['bias_instability_dps'] == [0.004, 0.004, 0.005]
    for name, sections in PRESETS.items():
        assert set(sections) == {'gyro', 'noise', 'accel'}
        sc = Scenario.from_dict(dict(MINIMAL, sensor=name))
        assert sc.gyro.sensitivity_mdps_per_digit == 8.75 and sc.accel.gravity_mps2 == 9.80665


def test_preset_is_a_deep_copy():
    copy = preset('l3gd20')
    copy['gyro']['bias_dps'][0] = 99.0
    assert PRESETS['l3gd20']['gyro']['bias_dps'][0] == 3.6
    assert PRESETS['l3gd20']['noise'] is not PRESETS['i3g4250d']['noise']
