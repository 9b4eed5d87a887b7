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

:class:`SimSource` merges the simulator's IMU, thermometer and reference streams into
:class:`~gyro_tdc.sources.base.ImuSample` and paces itself by ``time_scale``, keeping every
time constant in simulated seconds. See ``doc/internals/sources.md``.
"""

from __future__ import annotations

from collections import deque
import os
import time
from typing import Any, Callable, Iterator

from gyro_tdc.base import TemperatureGate
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
    time_scale : float
        Simulated seconds per wall-clock second; 0 makes every sample due at once.
    max_batch : int
        Most samples :meth:`pending` yields per call.
    clock_ns : callable returning int, ns
        The clock stamps are shifted onto (the node clock).
    wall : callable returning float, s
        Monotonic clock that paces the run.

    Raises
    ------
    DeviceError
        The scenario cannot be loaded or simulated (the message says why).
    ValueError
        ``time_scale`` < 0 or ``max_batch`` < 1.

    """

    has_accel = True

    def __init__(self, scenario: str | os.PathLike | Any, *, seed: int = 0,
                 run_index: int = 0, rate_hz: float | None = None, chunk_s: float = 1.0,
                 time_scale: float = 1.0, max_batch: int = 2000,
                 clock_ns: Callable[[], int] = time.time_ns,
                 wall: Callable[[], float] = time.monotonic) -> None:
        if not time_scale >= 0.0:
            raise ValueError(f'Expected `time_scale` >= 0, got {time_scale!r}.')
        if int(max_batch) < 1:
            raise ValueError(f'Expected `max_batch` >= 1, got {max_batch!r}.')
        from gyro_tdc.sim import SimStream
        try:
            self._stream = SimStream(scenario, seed=seed, run_index=run_index,
                                     rate_hz=rate_hz or None)
        except (GyroTdcError, ValueError) as exc:
            raise DeviceError(f'Cannot simulate scenario '
                              f'{getattr(scenario, "name", scenario)!r}: {exc}') from None
        self.name = f'sim:{self._stream.run.name}'
        self._moving, self._scenario = bool(self._stream.run.moving), scenario
        self.time_scale, self.max_batch = float(time_scale), int(max_batch)
        self._chunk_s, self._clock_ns, self._wall = float(chunk_s), clock_ns, wall
        self._origin: tuple[int, float, float] | None = None  # (clock ns, sim s, wall s)
        self._imu: deque[tuple[float, tuple, tuple]] = deque()
        self._temps: deque[tuple[float, float]] = deque()
        self._refs: deque[tuple[float, tuple]] = deque()
        self._temp_gate = TemperatureGate()

    def _fill(self) -> None:
        """Pull the next chunk of the stream until an IMU sample is buffered or it is done."""
        stream = self._stream
        while not self._imu and not stream.done:
            imu, temp, ref = stream.next_until(stream.position + self._chunk_s)
            self._imu.extend(zip(imu.t.tolist(), map(tuple, imu.gyro.tolist()),
                                 map(tuple, imu.accel.tolist())))
            self._temps.extend(zip(temp.t.tolist(), temp.temp_c.tolist()))
            if self._moving:
                self._refs.extend(zip(ref.t.tolist(), map(tuple, ref.ref.tolist())))

    def _peek_t(self) -> float | None:
        """Return the time of the next IMU sample, s, or None when the run is over."""
        if not self._imu:
            self._fill()
        return self._imu[0][0] if self._imu else None

    def _start(self, now: float) -> tuple[int, float, float]:
        """Tie the first sample to the clocks (once, wall time ``now``); return the origin."""
        if self._origin is None:
            if (first := self._peek_t()) is None:
                raise SourceExhausted(f'scenario {self._scenario!r} has no samples')
            self._origin = (self._clock_ns(), first, now)
        return self._origin

    def pending(self) -> Iterator[ImuSample]:
        """
        Yield the samples due by now on the scaled clock, at most ``max_batch``.

        Yields
        ------
        ImuSample
            The next due sample (simulated seconds; :meth:`stamp_ns` maps them).

        Raises
        ------
        SourceExhausted
            The run is over (or has no samples at all).

        """
        now = self._wall()
        _, sim0, wall0 = self._start(now)
        limit = (float('inf') if self.time_scale == 0.0
                 else sim0 + (now - wall0) * self.time_scale)
        for _ in range(self.max_batch):
            if (t_next := self._peek_t()) is not None and t_next > limit:
                return
            yield self.read()  # raises SourceExhausted at the end of the run

    def stamp_ns(self, t: float) -> int:
        """Return the node-clock stamp, ns, of simulated time ``t``: shifted, not scaled."""
        origin_ns, sim0, _ = self._origin or self._start(self._wall())
        return origin_ns + int(round((t - sim0) * 1e9))

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
        if self._peek_t() is None:
            raise SourceExhausted(f'{self.name} finished')
        t, gyro, accel = self._imu.popleft()
        temp_c = temp_t = ref = None
        while self._temps and self._temps[0][0] <= t:
            reading = self._temps.popleft()
            if self._temp_gate.accept(*reading):  # implausible: never published (counted)
                temp_t, temp_c = reading
        while self._refs and self._refs[0][0] <= t:
            ref = self._refs.popleft()[1]
        return ImuSample(t, gyro, accel, temp_c, temp_t, ref)

    @property
    def temperatures_rejected(self) -> int:
        """Return the thermometer readings dropped as implausible (the plausibility gate)."""
        return self._temp_gate.rejected

    def close(self) -> None:
        """Drop the buffered samples."""
        for buffered in (self._imu, self._temps, self._refs):
            buffered.clear()
