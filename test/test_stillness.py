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

"""The stillness test (no rclpy): still, moving, shaken and slowly turning windows."""

from __future__ import annotations

import math

from gyro_tdc.stillness import StillnessDetector
import numpy as np
import pytest


def test_stillness_detector():
    rng = np.random.default_rng(1)
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    found = None
    for k in range(200):
        raw = 0.003 + rng.normal(0, 0.002, 3)
        found = det.update(k * 0.01, raw, raw - 0.001, (0.0, 0.0, 9.81), 20.0) or found
    assert found is not None and found.samples == 101
    assert found.delta == pytest.approx((0.002,) * 3, abs=1e-3)
    # Moving (a rate swing) or shaken (accelerometer spread) is not still.
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    for k in range(300):
        raw = (0.1 * math.sin(k / 10.0), 0.0, 0.0)
        assert det.update(k * 0.01, raw, raw, None, 20.0) is None
    for k in range(300, 600):
        acc = (rng.normal(0, 0.5), 0.0, 9.81)
        assert det.update(k * 0.01, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), acc, 20.0) is None
    assert det.windows_rejected >= 4
    # A slow constant turn has no spread but a mean above max_rate.
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    for k in range(300):
        assert det.update(k * 0.01, (0.05, 0, 0), (0.05, 0, 0), None, 20.0) is None
