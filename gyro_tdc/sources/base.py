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
The back-end Protocol and the sample it yields.

The driver node talks to a back-end only through :class:`ImuSource`: on every tick of its
timer it publishes what :meth:`~ImuSource.pending` yields, stamped by
:meth:`~ImuSource.stamp_ns`. A back-end paces itself: the simulator releases its samples as
its scaled clock reaches them; a device read once per tick mixes in :class:`PolledSource`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Iterator, Protocol, runtime_checkable

from gyro_tdc.errors import DeviceError

Vec3 = tuple[float, float, float]


class SourceExhausted(DeviceError):
    """A finite source (a simulated scenario) has no more samples."""


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One reading of a gyro (and whatever came with it), as every source yields it."""

    #: Source time of the sample, s (simulated time, or a monotonic clock).
    t: float
    #: Angular velocity x, y, z, rad/s.
    omega: Vec3
    #: Linear acceleration x, y, z, m/s^2, when the device has an accelerometer; else None.
    accel: Vec3 | None = None
    #: Temperature read with this sample, degC; None when no new reading came with it.
    temp_c: float | None = None
    #: Source time of the temperature reading when it differs from ``t``, s; else None.
    temp_t: float | None = None
    #: Rate-table reference x, y, z, rad/s, when it changed at this sample (simulator only);
    #: else None.
    ref: Vec3 | None = None


@runtime_checkable
class ImuSource(Protocol):
    """
    A gyro back-end: the driver node only ever talks to this.

    Attributes
    ----------
    name : str
        What the back-end reads (device name, ``sim:<scenario>``), for logs and diagnostics.
    has_accel : bool
        Whether samples carry acceleration (REP 145: else the covariance says "no data").

    """

    name: str
    has_accel: bool

    def pending(self) -> Iterator[ImuSample]:
        """
        Yield the samples due now, in time order (called once per tick of the driver).

        The driver publishes each sample before asking for the next.

        Raises
        ------
        SourceExhausted
            A finite source has no more samples.
        gyro_tdc.errors.DeviceError
            The device vanished or returned something that is not a number.

        """

    def stamp_ns(self, t: float) -> int:
        """Return the ROS stamp, ns on the node clock, of source time ``t`` (s)."""

    def read(self) -> ImuSample:
        """
        Return the next sample, whether due or not.

        Returns
        -------
        ImuSample
            The reading, converted to SI units.

        Raises
        ------
        gyro_tdc.errors.DeviceError
            The device vanished or returned something that is not a number.

        """

    def close(self) -> None:
        """Release the device."""


class PolledSource:
    """
    Pacing and stamps of a back-end read once per driver tick (mixed into a source class).

    Its ``read()`` returns a fresh reading whose ``t`` is in seconds on the node clock the
    source was given (the IIO back-end): every tick one sample is due, and its stamp is its
    time in nanoseconds.
    """

    def pending(self) -> Iterator[ImuSample]:
        """Yield one fresh reading (``self.read()``)."""
        yield self.read()

    def stamp_ns(self, t: float) -> int:
        """Return ``t`` (s on the node clock) in nanoseconds."""
        return int(round(t * 1e9))


def check_sample(sample: ImuSample) -> ImuSample:
    """
    Return ``sample`` when every number in it is finite.

    Raises
    ------
    DeviceError
        Some value is NaN or infinite (the driver never publishes garbage).

    """
    for name, size in (('t', 1), ('omega', 3), ('accel', 3), ('temp_c', 1)):
        if (value := getattr(sample, name)) is None and name in ('accel', 'temp_c'):
            continue                      # not read with this sample
        values = (value,) if size == 1 else value
        if len(values) != size or not all(
                isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise DeviceError(f'Sample field `{name}` holds {values!r}, expected finite numbers.')
    return sample


class Backoff:
    """
    Exponential retry delays: ``initial``, ``2 initial``, ... capped at ``maximum``.

    Parameters
    ----------
    initial : float, s
        First delay, > 0.
    maximum : float, s
        Largest delay, >= ``initial``.

    """

    def __init__(self, initial: float, maximum: float) -> None:
        if not (initial > 0.0 and maximum >= initial):
            raise ValueError(f'Expected 0 < `initial` <= `maximum`, got {initial!r} and '
                             f'{maximum!r}.')
        self.initial, self.maximum, self.failures = float(initial), float(maximum), 0

    def next_delay(self) -> float:
        """Record one more failure and return how long to wait before the next attempt."""
        delay = min(self.initial * 2.0 ** min(self.failures, 60), self.maximum)
        self.failures += 1
        return delay

    def reset(self) -> None:
        """Forget the failures (the device works again)."""
        self.failures = 0
