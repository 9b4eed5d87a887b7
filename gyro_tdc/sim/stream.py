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
Stream a simulated run in time order, chunk by chunk, for a live driver.

:class:`SimStream` precomputes the run and hands it out in chunks up to a requested simulated
time, so a node can publish in real time or faster. See ``doc/internals/sim.md``.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim.simulator import ScenarioLike, SimRun, simulate_run
import numpy as np
from numpy.typing import NDArray

__all__ = ['ImuChunk', 'RefChunk', 'SimStream', 'TempChunk']


class ImuChunk(NamedTuple):
    """
    IMU samples of one chunk.

    Parameters
    ----------
    t : NDArray[np.float64], shape (K,), s
        Stamps.
    gyro : NDArray[np.float64], shape (K, 3), rad/s
        Angular velocity.
    accel : NDArray[np.float64], shape (K, 3), m/s^2
        Linear acceleration.

    """

    t: NDArray[np.float64]
    gyro: NDArray[np.float64]
    accel: NDArray[np.float64]


class TempChunk(NamedTuple):
    """
    Thermometer readings of one chunk.

    Parameters
    ----------
    t : NDArray[np.float64], shape (K,), s
        Stamps.
    temp_c : NDArray[np.float64], shape (K,), degC
        Readings.

    """

    t: NDArray[np.float64]
    temp_c: NDArray[np.float64]


class RefChunk(NamedTuple):
    """
    Rate-table change points of one chunk.

    Parameters
    ----------
    t : NDArray[np.float64], shape (K,), s
        Change times.
    ref : NDArray[np.float64], shape (K, 3), rad/s
        Reference rate from each change on.

    """

    t: NDArray[np.float64]
    ref: NDArray[np.float64]


class SimStream:
    """
    Hand out one simulated run in time order.

    Parameters
    ----------
    scenario : Scenario, str, os.PathLike or Mapping
        The scenario, or anything :func:`gyro_tdc.sim.load_scenario` accepts.
    seed : int
        Seed of the run set (the same run as ``simulate_scenario(scenario, seed)``).
    run_index : int
        Which run of a multi-run scenario.
    rate_hz : float, optional
        IMU rate overriding the scenario's.

    """

    def __init__(self, scenario: ScenarioLike, seed: int = 0, run_index: int = 0, *,
                 rate_hz: Optional[float] = None) -> None:
        self.run: SimRun = simulate_run(scenario, seed=seed, run_index=run_index, rate_hz=rate_hz)
        self._stamps = (self.run.imu_t, self.run.temp_t, self.run.ref_t)
        self._i = (0, 0, 0)      # the next IMU, thermometer and reference rows
        self._position = -math.inf

    @property
    def position(self) -> float:
        """Return the time up to which samples were handed out (start: the first stamp)."""
        return self.run.imu_t[0] if self._position == -math.inf else self._position

    @property
    def t_end(self) -> float:
        """Return the last stamp of any stream."""
        return float(max(t[-1] for t in self._stamps))

    @property
    def done(self) -> bool:
        """Return True once every sample was handed out."""
        return all(i >= t.size for i, t in zip(self._i, self._stamps))

    def next_until(self, t: float) -> tuple[ImuChunk, TempChunk, RefChunk]:
        """
        Return the chunks of samples stamped up to and including ``t`` not handed out yet.

        Each chunk in time order, possibly empty (a ``t`` before the last call's).

        Raises
        ------
        ScenarioError
            If ``t`` is not a number (NaN).

        """
        t = float(t)
        if math.isnan(t):
            raise ScenarioError('Expected `t` to be a time in seconds, got nan.')
        run = self.run
        (i0, i1, i2), self._i = self._i, tuple(
            max(i, int(np.searchsorted(ts, t, side='right')))
            for i, ts in zip(self._i, self._stamps))
        j0, j1, j2 = self._i
        imu = ImuChunk(run.imu_t[i0:j0], run.gyro[i0:j0], run.accel[i0:j0])
        temp = TempChunk(run.temp_t[i1:j1], run.temp_c[i1:j1])
        ref = RefChunk(run.ref_t[i2:j2], run.ref[i2:j2])
        self._position = max(self._position, t)
        return imu, temp, ref
