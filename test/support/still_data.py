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

"""A still IMU at 20 Hz (L3GD20-like noise) and driving added to it: the still tests' data."""

from __future__ import annotations

import math

import numpy as np

RATE_HZ = 20.0
DEG = math.pi / 180.0
G = np.array([0.0, 0.0, 9.80665])


def rest(seconds: float, seed: int = 0, *, bias=(0.06, -0.07, 0.02)):
    """Return stamps, gyro and accel of a still IMU (L3GD20-like noise at 20 Hz)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    gyro = np.asarray(bias) + rng.normal(0.0, 0.03 * DEG * math.sqrt(RATE_HZ), (t.size, 3))
    accel = G + rng.normal(0.0, 0.0015 * math.sqrt(RATE_HZ), (t.size, 3))
    return t, gyro, accel


def drive(t, gyro, accel, a: float, b: float, seed: int = 1):
    """Add driving (manoeuvres plus vibration) between a and b seconds, in place."""
    rng = np.random.default_rng(seed)
    on = (t >= a) & (t < b)
    gyro[on] += rng.normal(0.0, 0.5 * DEG, (on.sum(), 3)) + [0, 0, 10 * DEG]
    accel[on] += rng.normal(0.0, 0.8, (on.sum(), 3))
    return on
