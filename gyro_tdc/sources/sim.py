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
Simulated back-end: a scenario of :mod:`gyro_tdc.sim` handed out sample by sample.

:class:`SimSource` wraps :class:`gyro_tdc.sim.stream.SimStream` and merges its three
streams into :class:`~gyro_tdc.sources.base.ImuSample`: each IMU sample carries the
thermometer reading stamped since the previous IMU sample (with its own stamp in
``temp_t``) and, when the rate table moves, the reference rate that took effect since.
The driver node decides when to publish (``peek_t``) so it can pace the stream in real
time or faster.
"""

from __future__ import annotations

from collections import deque
import os
from typing import Any

from gyro_tdc.errors import DeviceError, GyroTdcError
from gyro_tdc.sources.base import ImuSample, SourceExhausted


class SimSource:
    """
    Hand out a simulated run as gyro samples in time order.

    Parameters
    ----------
    scenario : str, os.PathLike, Mapping or gyro_tdc.sim.Scenario
        Shipped scenario name (``config/scenarios``), YAML path or scenario.
    seed : int
        Seed of the run set.
    run_index : int
        Which run of a multi-run scenario.
    rate_hz : float, optional, Hz
        IMU rate overriding the scenario's (None or 0: the scenario's).
    chunk_s : float, s
        Simulated time pulled from the stream at once.

    Raises
    ------
    DeviceError
        The scenario cannot be loaded or simulated (the message says why).

    """

    has_accel = True

    def __init__(self, scenario: str | os.PathLike | Any, *, seed: int = 0,
                 run_index: int = 0, rate_hz: float | None = None,
                 chunk_s: float = 1.0) -> None:
        from gyro_tdc.sim.stream import SimStream
        try:
            self._stream = SimStream(scenario, seed=seed, run_index=run_index,
                                     rate_hz=rate_hz or None)
        except (GyroTdcError, ValueError) as exc:
            raise DeviceError(f'Cannot simulate scenario {scenario!r}: {exc}') from None
        run = self._stream.run
        self.name = f'sim:{run.name}'
        self.rate_hz = float(run.rate_hz)
        self.temp_var = float(run.temp_var)
        self.moving = bool(run.moving)
        self.truth = run.truth
        self._chunk_s = float(chunk_s)
        self._imu: deque[tuple[float, tuple, tuple]] = deque()
        self._temps: deque[tuple[float, float]] = deque()
        self._refs: deque[tuple[float, tuple]] = deque()
        self.skipped_temperatures = 0

    @property
    def run(self) -> Any:
        """Return the simulated run being streamed (a gyro_tdc.sim.SimRun)."""
        return self._stream.run

    def _fill(self) -> None:
        """Pull the next chunk of the stream until an IMU sample is buffered or it is done."""
        stream = self._stream
        while not self._imu and not stream.done:
            imu, temp, ref = stream.next_until(stream.position + self._chunk_s)
            self._imu.extend(zip(imu.t.tolist(), map(tuple, imu.gyro.tolist()),
                                 map(tuple, imu.accel.tolist())))
            self._temps.extend(zip(temp.t.tolist(), temp.temp_c.tolist()))
            if self.moving:
                self._refs.extend(zip(ref.t.tolist(), map(tuple, ref.ref.tolist())))

    def peek_t(self) -> float | None:
        """Return the stamp of the next IMU sample, s, or None when the run is over."""
        if not self._imu:
            self._fill()
        return self._imu[0][0] if self._imu else None

    def read(self) -> ImuSample:
        """
        Return the next IMU sample with the thermometer and table changes since the last.

        Returns
        -------
        ImuSample
            Simulated sample (stamps in simulated seconds from 0).

        Raises
        ------
        SourceExhausted
            The run is over.

        """
        if not self._imu:
            self._fill()
            if not self._imu:
                raise SourceExhausted(f'{self.name} finished')
        t, gyro, accel = self._imu.popleft()
        temp_c = temp_t = ref = None
        temps = self._temps
        while temps and temps[0][0] <= t:
            if temp_t is not None:
                self.skipped_temperatures += 1
            temp_t, temp_c = temps.popleft()
        refs = self._refs
        while refs and refs[0][0] <= t:
            ref = refs.popleft()[1]
        return ImuSample(t, gyro, accel, temp_c, temp_t, ref)

    def close(self) -> None:
        """Drop the buffered samples."""
        self._imu.clear()
        self._temps.clear()
        self._refs.clear()
