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

"""One thermal run as aligned numpy arrays: the unit every core function works on."""

from __future__ import annotations

from dataclasses import dataclass, field

from gyro_tdc.errors import DatasetError
import numpy as np
from numpy.typing import ArrayLike, NDArray


def float_array(name: str, a: ArrayLike, shape: tuple[int, ...] | None = None
                ) -> NDArray[np.float64]:
    """Return ``a`` as float64 of ``shape`` (None: any 1-D) or raise DatasetError naming it."""
    arr = np.asarray(a, dtype=np.float64)
    if (arr.ndim != 1) if shape is None else (arr.shape != shape):
        raise DatasetError(f'Expected `{name}` to have shape {shape or "(N,)"}, got {arr.shape}.')
    return arr


@dataclass(frozen=True)
class Run:
    """
    One continuous recording, aligned on the IMU stamps.

    Parameters
    ----------
    t : NDArray[np.float64], shape (N,), s
        IMU stamps, strictly increasing (seconds; any epoch).
    temp : NDArray[np.float64], shape (N,), degC
        Measured temperature at each IMU stamp.
    omega : NDArray[np.float64], shape (N, 3), rad/s
        Raw gyro output (x, y, z).
    omega_ref : NDArray[np.float64], shape (N, 3), rad/s
        Reference (true) rate at each stamp; zeros for a still sensor.
    name : str
        Where the run came from (bag path, scenario name...).
    info : dict
        Free-form extras (e.g. counts of rejected samples, simulator truth).
    accel : NDArray[np.float64], shape (N, 3), m/s^2, optional
        Linear acceleration at each stamp; None when not read or the IMU has no
        accelerometer (:mod:`gyro_tdc.identify` fits its thermal part).

    """

    t: NDArray[np.float64]
    temp: NDArray[np.float64]
    omega: NDArray[np.float64]
    omega_ref: NDArray[np.float64]
    name: str = 'run'
    info: dict = field(default_factory=dict, compare=False)
    accel: NDArray[np.float64] | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        """Check shapes and that stamps increase."""
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        if n < 0:
            raise ValueError(f'Expected `t` to have shape (N,), got {np.shape(self.t)}.')
        for key, shape in (('temp', (n,)), ('omega', (n, 3)), ('omega_ref', (n, 3)),
                           ('accel', (n, 3))):
            got = np.shape(getattr(self, key))
            if got != shape and not (key == 'accel' and self.accel is None):   # accel optional
                raise ValueError(f'Expected `{key}` to have shape {shape}, got {got}.')
        if n > 1 and not np.all(np.diff(self.t) > 0):
            raise ValueError('Expected `t` to be strictly increasing.')

    def __len__(self) -> int:
        """Return the number of samples."""
        return int(np.shape(self.t)[0])

    @property
    def duration_s(self) -> float:
        """Return the time span in seconds."""
        return float(self.t[-1] - self.t[0]) if len(self) > 1 else 0.0

    def slice(self, start: int, stop: int, name: str | None = None) -> 'Run':
        """Return samples ``start:stop`` as a new run."""
        return Run(self.t[start:stop], self.temp[start:stop], self.omega[start:stop],
                   self.omega_ref[start:stop], name or self.name, dict(self.info),
                   None if self.accel is None else self.accel[start:stop])
