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
Stillness: decide from a window of gyro (and accelerometer) samples that the IMU is not moving.

Pure (numpy only). :class:`StillnessDetector` keeps running means and variances over
consecutive windows and returns an :class:`Anchor` -- the mean compensated rate over a still
window, i.e. the offset shift that zeroes it -- when a window passes every threshold. The
compensator's start-up re-anchoring (:class:`gyro_tdc.compensation_logic.CompensatorCore`)
uses it; it is the one home of the stillness test.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ['Anchor', 'StillnessDetector', 'Vec3']

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Anchor:
    """
    The result of a still window: the offset shift that zeroes the compensated rate.

    Parameters
    ----------
    t : float, s
        Stamp at the end of the window.
    delta : tuple of 3 float, rad/s
        Shift added to the model's drift.
    samples : int
        Samples in the window.
    gyro_std : tuple of 3 float, rad/s
        Standard deviation of the raw rate over the window.
    temp_c : float, degC
        Temperature at the end of the window.

    """

    t: float
    delta: Vec3
    samples: int
    gyro_std: Vec3
    temp_c: float


class StillnessDetector:
    """
    Decide from consecutive windows whether the gyro is still.

    A window is still when the raw rate's per-axis standard deviation is at most
    ``gyro_std``, the mean compensated rate is at most ``max_rate`` per axis, and the
    acceleration's standard deviation (when there is one) is at most ``accel_std``.

    Parameters
    ----------
    window : float, s
        Window length.
    gyro_std, max_rate : float, rad/s
        Thresholds on the raw rate's spread and the compensated rate's mean.
    accel_std : float, m/s^2
        Threshold on the acceleration's spread.

    """

    def __init__(self, window: float, gyro_std: float, max_rate: float,
                 accel_std: float) -> None:
        self.window = float(window)
        self.gyro_var = float(gyro_std) ** 2
        self.max_rate = float(max_rate)
        self.accel_var = float(accel_std) ** 2
        self.windows_rejected = 0
        self.reset()

    def reset(self) -> None:
        """Start a new window with the next sample."""
        self._t0: float | None = None
        self._n = 0
        self._g = np.zeros((2, 3))   # Welford mean, M2 of the raw rate
        self._o = np.zeros(3)        # running mean of the compensated rate
        self._a = np.zeros((2, 3))   # Welford mean, M2 of the acceleration
        self._accel = True

    def update(self, t: float, raw: Sequence[float], out: Sequence[float],
               accel: Sequence[float] | None, temp_c: float) -> Anchor | None:
        """
        Add one clean sample; return an :class:`Anchor` when a still window completes.

        Parameters
        ----------
        t : float, s
            Stamp.
        raw, out : sequence of 3 float, rad/s
            Raw and compensated rate.
        accel : sequence of 3 float, m/s^2, or None
            Acceleration when the IMU has an accelerometer.
        temp_c : float, degC
            Temperature used for the sample.

        Returns
        -------
        Anchor or None
            The anchor when a still window just ended, else None.

        """
        if self._t0 is None:
            self._t0 = t
        self._n += 1
        n = self._n
        g = np.asarray(raw, dtype=np.float64)
        d = g - self._g[0]
        self._g[0] += d / n
        self._g[1] += d * (g - self._g[0])
        self._o += (np.asarray(out, dtype=np.float64) - self._o) / n
        if accel is None:
            self._accel = False
        else:
            a = np.asarray(accel, dtype=np.float64)
            d = a - self._a[0]
            self._a[0] += d / n
            self._a[1] += d * (a - self._a[0])
        if t - self._t0 < self.window or n < 2:
            return None
        g_var = self._g[1] / (n - 1)
        still = bool(np.all(g_var <= self.gyro_var) and np.all(np.abs(self._o) <= self.max_rate))
        if still and self._accel:
            still = bool(np.all(self._a[1] / (n - 1) <= self.accel_var))
        if not still:
            self.windows_rejected += 1
            self.reset()
            return None
        anchor = Anchor(t, tuple(float(v) for v in self._o), n,
                        tuple(float(v) for v in np.sqrt(g_var)), float(temp_c))
        self.reset()
        return anchor
