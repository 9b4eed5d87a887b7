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

"""The back-end Protocol and the sample it yields."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class ImuSample:
    """
    One reading of a gyro (and whatever came with it).

    Parameters
    ----------
    t : float, s
        Source time of the sample (simulated time, or a monotonic clock).
    omega : tuple of 3 float, rad/s
        Angular velocity x, y, z.
    accel : tuple of 3 float, m/s^2, or None
        Linear acceleration x, y, z when the device has an accelerometer.
    temp_c : float, degC, or None
        Temperature read with this sample; None when no new reading came with it.
    ref : tuple of 3 float, rad/s, or None
        Rate-table reference when it changed at this sample (simulator only).

    """

    t: float
    omega: Vec3
    accel: Vec3 | None = None
    temp_c: float | None = None
    ref: Vec3 | None = None


@runtime_checkable
class ImuSource(Protocol):
    """A gyro back-end: the driver node only ever talks to this."""

    name: str

    def read(self) -> ImuSample:
        """
        Return the next sample.

        Returns
        -------
        ImuSample
            The reading, converted to SI units.

        Raises
        ------
        gyro_tdc.errors.DeviceError
            The device vanished or returned something that is not a number.

        """
        ...

    def close(self) -> None:
        """Release the device."""
        ...
