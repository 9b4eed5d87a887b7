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

"""The streaming noise floor: by the noise, not by the sample count or the stream's length."""

from __future__ import annotations

import math

from gyro_tdc.signal import NOISE_FACTOR, StillWindows
from gyro_tdc.signal.still_stream import NoiseFloor
import numpy as np

SIGMA = 5e-4


def _feed(still, t, gyro, accel=None, chunk=600):
    out = []
    for k in range(0, t.size, chunk):
        out += still.extend(t[k:k + chunk], gyro[k:k + chunk],
                            None if accel is None else accel[k:k + chunk])
    return out


def test_a_day_at_1hz_keeps_the_floor_near_the_noise_and_every_window_still():
    rng = np.random.default_rng(0)
    t = np.arange(86400.0)
    gyro = 0.01 + SIGMA * rng.standard_normal((t.size, 3))
    still = StillWindows(10.0, min_samples=3)
    wins = _feed(still, t, gyro)
    assert 0.5 * SIGMA < still.gyro_floor.min() and still.gyro_floor.max() < SIGMA
    assert np.mean([w.why == '' for w in wins]) > 0.999
    # The quietest single window of ten samples, the floor of old, sinks far below.
    lowest = np.min([min(w.gyro_std) for w in wins])
    assert lowest < 0.3 * SIGMA
    assert NOISE_FACTOR * lowest < SIGMA        # which refused most windows


def test_a_quantised_accelerometer_below_its_step_is_still():
    """Readings on few levels: the floor is the step's noise, not the mean's rounding."""
    rng = np.random.default_rng(1)
    t = np.arange(20000.0)
    gyro = SIGMA * rng.standard_normal((t.size, 3))
    accel = np.array([0.02, -0.03, 9.80665]) + 0.0015 * rng.standard_normal((t.size, 3))
    accel = np.round(accel / 0.0024) * 0.0024
    still = StillWindows(10.0, min_samples=3)
    wins = _feed(still, t, gyro, accel)
    assert np.all(still.accel_floor >= 0.0024 / math.sqrt(12.0) - 1e-12)
    assert np.mean([w.why == '' for w in wins]) > 0.99


def test_a_constant_axis_has_zero_scatter_and_no_floor():
    rng = np.random.default_rng(2)
    t = np.arange(2000.0) / 10.0
    gyro = SIGMA * rng.standard_normal((t.size, 3))
    gyro[:, 2] = 0.1 + 0.2                     # exactly one value (not exact in binary)
    still = StillWindows(10.0)
    wins = _feed(still, t, gyro)
    assert all(w.gyro_std[2] == 0.0 for w in wins)
    assert math.isinf(still.gyro_floor[2]) and np.isfinite(still.gyro_floor[:2]).all()


def test_noise_floor_pools_to_the_degrees_of_freedom():
    f = NoiseFloor()
    f.add(9, np.full(3, 1.0), np.full(3, math.inf))
    assert np.isinf(f.floor).all()            # 9 degrees of freedom: not yet
    for _ in range(4):
        f.add(9, np.full(3, 1.0), np.full(3, math.inf))
    np.testing.assert_allclose(f.floor, 1.0)
    f.add(9, np.zeros(3), np.array([0.5, math.inf, 0.5]))   # a constant window pooled
    assert f.floor[0] == f.floor[2] < 1.0 and f.floor[0] >= 0.5 / math.sqrt(12.0)
