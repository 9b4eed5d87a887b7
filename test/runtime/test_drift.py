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

"""The model in use: its variance table, the out-of-range widening and the drift cache."""

from __future__ import annotations

from gyro_tdc.learn.learner import learned_model
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.drift import CACHE_SIZE, growth, variance_table, widen
from gyro_tdc.runtime.flags import OUT_OF_RANGE, STALE
from gyro_tdc.runtime.policy import Policy
import numpy as np
import pytest

MODEL = learned_model(np.array([[0.01, -0.02, 0.005], [1e-3, 2e-4, -1e-4], [1e-6, 0, 0]]),
                      ('dT', 'dT2'), 20.0, (0.0, 60.0), np.full(3, 1e-6))


def test_the_variance_table_adds_the_stale_and_out_of_range_variances_per_flag():
    policy = Policy(stale_variance=2e-6, out_of_range_variance=3e-6)
    table = variance_table((1e-6, 2e-6, 4e-6), policy)
    assert table[0] == (1e-6, 2e-6, 4e-6)
    assert table[STALE] == pytest.approx((3e-6, 4e-6, 6e-6))
    assert table[OUT_OF_RANGE] == pytest.approx((4e-6, 5e-6, 7e-6))
    assert table[STALE | OUT_OF_RANGE] == pytest.approx((6e-6, 7e-6, 9e-6))


def test_the_out_of_range_variance_grows_with_the_distance_only_when_linear():
    linear = Policy(out_of_range='linear', out_of_range_variance=1e-6)
    assert growth(0.0, linear) == 0.0
    assert growth(5.0, linear) == pytest.approx(1e-6)
    assert growth(10.0, linear) == pytest.approx(4e-6)
    assert growth(10.0, Policy(out_of_range='clamp', out_of_range_variance=1e-6)) == 0.0
    var = (1.0, 2.0, 3.0)
    assert widen(var, 0.0) is var
    assert widen(var, 0.5) == (1.5, 2.5, 3.5)


def test_a_static_models_drift_is_cached_per_temperature_and_bounded():
    core = CompensatorCore(Policy(reanchor_on_start=False), MODEL)
    slot = core.slot
    assert slot.static and not slot.cache
    core.add_temperature(0.0, 25.0)
    entry = slot.cache[25.0]
    wx, wy, wz, *_ = core.process(0.01, 0.1, 0.2, 0.3)
    assert (wx, wy, wz) == ((0.1 - entry.bx) / entry.dx, (0.2 - entry.by) / entry.dy,
                            (0.3 - entry.bz) / entry.dz)
    assert entry.oor == 0 and entry.safe
    for k in range(2 * CACHE_SIZE):
        core.add_temperature(0.02 + k * 0.01, 25.0 + 0.01 * (k + 1))
    assert 0 < len(slot.cache) <= CACHE_SIZE
    core.add_temperature(10.0, 70.0)                 # outside 0..60 degC
    assert slot.cache[70.0].oor == OUT_OF_RANGE and slot.cache[70.0].distance_c > 0
