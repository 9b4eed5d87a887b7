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

"""The typed sections of a scenario: what they derive from their fields."""

from __future__ import annotations

from gyro_tdc.sim.specs import AccelSpec, RateTable
import numpy as np


def test_accel_spec_is_thermal_only_with_a_temperature_coefficient():
    assert not AccelSpec(gravity_mps2=9.8, noise_mps2_per_rt_hz=(0.0, 0.0, 0.0)).thermal
    assert AccelSpec(gravity_mps2=9.8, noise_mps2_per_rt_hz=(0.0, 0.0, 0.0),
                     dT2_mg_per_c2=(0.0, 0.1, 0.0)).thermal


def test_rate_table_moves_when_a_rate_is_not_zero_and_gives_arrays():
    still = RateTable(t_s=(0.0,), rate_rad_s=((0.0, 0.0, 0.0),))
    assert not still.moving
    table = RateTable(t_s=(0.0, 5.0), rate_rad_s=((0.0, 0.0, 0.0), (0.0, 0.1, 0.0)))
    assert table.moving
    t, rate = table.arrays()
    np.testing.assert_array_equal(t, [0.0, 5.0])
    assert rate.shape == (2, 3) and rate[1, 1] == 0.1
