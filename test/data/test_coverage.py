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

"""Tests of gyro_tdc.data.coverage: temperature bins, sparse bins, heating and cooling minutes."""

from __future__ import annotations

from gyro_tdc.data.coverage import coverage, RATE_WINDOW_S, temperature_rate
from gyro_tdc.data.runs import Run
import numpy as np
import pytest


def _run(t, temp, name='run'):
    n = len(t)
    return Run(np.asarray(t, dtype=float), np.asarray(temp, dtype=float), np.zeros((n, 3)),
               np.zeros((n, 3)), name)


def test_rate_of_a_ramp_is_its_slope_everywhere():
    t = np.arange(0.0, 3600.0, 2.0)
    np.testing.assert_allclose(temperature_rate(t, 20.0 + t / 60.0 * 0.5), 0.5, rtol=1e-9)
    np.testing.assert_array_equal(temperature_rate(t, np.full(t.shape, 30.0)), 0.0)
    np.testing.assert_array_equal(temperature_rate(t[:1], [20.0]), [0.0])
    # A 0.1 degC quantisation step reads as a small rate over the window, not as heating.
    step = np.where(t < 1800.0, 20.0, 20.1)
    assert np.max(temperature_rate(t, step)) == pytest.approx(0.1 / RATE_WINDOW_S * 60.0)


def _soak_heat_cool(rate_c_per_min=0.5, minutes=60, dt=1.0):
    """Soak at 20 degC, heat to 50 degC, cool back: ``minutes`` each, 1 Hz."""
    n = int(minutes * 60 / dt)
    up = 20.0 + rate_c_per_min * np.arange(n) * dt / 60.0
    temp = np.concatenate([np.full(n, 20.0), up, up[-1] - (up - 20.0)])
    return _run(np.arange(3 * n) * dt, temp)


def test_heating_cooling_and_steady_minutes():
    c = coverage([_soak_heat_cool()])
    half = RATE_WINDOW_S / 2 / 60.0       # the rate window blurs each turn by this much
    assert c.heating_min == pytest.approx(60.0, abs=half)
    assert c.cooling_min == pytest.approx(60.0, abs=half)
    assert c.steady_min == pytest.approx(60.0, abs=2 * half)
    assert c.heating_min + c.cooling_min + c.steady_min == pytest.approx(180.0)
    assert c.temp_range_c == (20.0, pytest.approx(49.9917, abs=1e-3))
    assert c.threshold_c_per_min == 0.05


def test_samples_and_minutes_per_bin():
    run = _soak_heat_cool()
    c = coverage([run], bin_c=10.0)
    np.testing.assert_array_equal(c.edges, [20.0, 30.0, 40.0, 50.0])
    want = np.bincount(((run.temp - 20.0) // 10.0).astype(int), minlength=3)
    np.testing.assert_array_equal(c.samples, want)
    np.testing.assert_allclose(c.minutes, want / 60.0)
    assert c.sparse == []
    assert c.bin_c == 10.0


def test_bins_crossed_too_fast_are_sparse():
    t = np.arange(0.0, 3600.0 * 2 + 60.0, 1.0)
    # 60 min soak at 22 degC, 1 min jump to 38 degC, 60 min soak there.
    temp = np.interp(t, [0.0, 3600.0, 3660.0, t[-1]], [22.0, 22.0, 38.0, 38.0])
    c = coverage([_run(t, temp)])
    np.testing.assert_array_equal(c.edges, [20.0, 25.0, 30.0, 35.0, 40.0])
    assert c.sparse == [1, 2]


def test_several_runs_add_up_and_gaps_count_ten_periods():
    t = np.arange(0.0, 600.0, 1.0)
    gap = np.concatenate([t, 5000.0 + t])             # a 4401 s hole after 600 samples
    a, b = _run(t, np.full(600, 21.0)), _run(gap, np.full(1200, 26.0))
    c = coverage([a, b])
    np.testing.assert_array_equal(c.samples, [600, 1200])
    # run a: 600 periods of 1 s; run b: 1199 periods with the hole cut to 10 s, + 1.
    np.testing.assert_allclose(c.minutes, [600 / 60.0, (1198 + 10 + 1) / 60.0])


def test_long_runs_use_a_decimated_rate():
    t = np.arange(0.0, 250_000.0, 1.0)
    c = coverage([_run(t, 20.0 + t / 60.0 * 0.01)])    # 0.01 degC/min: below the threshold
    assert c.heating_min == 0.0 and c.cooling_min == 0.0
    c = coverage([_run(t, 20.0 + t / 60.0 * 0.1)])
    assert c.heating_min == pytest.approx(len(t) / 60.0)
