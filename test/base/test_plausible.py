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

"""The thermometer plausibility gate: range, slew from the last plausible reading, batch form."""

from __future__ import annotations

import math

from gyro_tdc.base import (MAX_TEMP_SLEW_C_S, plausible_temperatures, TEMP_PLAUSIBLE_C,
                           TEMP_SLEW_MARGIN_C, temperature_ok, TemperatureGate)
import numpy as np
import pytest


def test_range_and_slew():
    lo, hi = TEMP_PLAUSIBLE_C
    assert temperature_ok(None, None, 0.0, lo) and temperature_ok(None, None, 0.0, hi)
    for bad in (lo - 1e-9, hi + 1e-9, math.nan, math.inf, 1e30):
        assert not temperature_ok(None, None, 0.0, bad)
    assert not temperature_ok(None, None, math.nan, 25.0)
    step = TEMP_SLEW_MARGIN_C + MAX_TEMP_SLEW_C_S * 0.5
    assert temperature_ok(10.0, 25.0, 10.5, 25.0 + step)
    assert temperature_ok(10.0, 25.0, 9.5, 25.0 - step)          # late: by |dt|
    assert not temperature_ok(10.0, 25.0, 10.5, 25.0 + step * 1.001)


def test_a_glitch_costs_one_reading_and_a_real_jump_is_taken_later():
    gate = TemperatureGate()
    assert gate.accept(0.0, 25.0) and not gate.accept(0.1, 1e30) and gate.accept(0.2, 25.1)
    # 60 degC up for good: refused until 2 + 20 * dt covers it (dt = 2.9 s), then held.
    got = [gate.accept(0.2 + k * 0.5, 85.1) for k in range(1, 9)]
    assert got == [False] * 5 + [True] * 3 and gate.rejected == 6


@pytest.mark.parametrize('seed', range(20))
def test_batch_equals_the_streaming_gate(seed):
    rng = np.random.default_rng(seed)
    n = 300
    t = np.cumsum(rng.uniform(0.0, 0.5, n))
    c = 25.0 + np.cumsum(rng.normal(0.0, 2.0, n))
    bad = rng.random(n) < 0.1
    c[bad] = rng.choice([1e30, -500.0, 150.0, -90.0, 80.0], bad.sum())
    gate = TemperatureGate()
    expect = np.array([gate.accept(a, b) for a, b in zip(t, c)])
    np.testing.assert_array_equal(plausible_temperatures(t, c), expect)
    order = rng.permutation(n)             # any input order: judged in stamp order
    np.testing.assert_array_equal(plausible_temperatures(t[order], c[order]), expect[order])
