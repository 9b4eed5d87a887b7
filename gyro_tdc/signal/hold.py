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
The thermometer held by stamp: the newest reading at or before a stamp, within a timeout.

:class:`TemperatureHold` is the one zero-order hold: one stamp at a time
(:meth:`~TemperatureHold.at`, the compensator's core) or a batch of stamps
(:meth:`~TemperatureHold.held`, :func:`hold_readings`, the learner), behind the plausibility
gate (:mod:`gyro_tdc.base.plausible`) where the readings are raw.
"""

from __future__ import annotations

import bisect
import math
from typing import Sequence

from gyro_tdc.base import TemperatureGate
import numpy as np
from numpy.typing import NDArray

__all__ = ['hold_readings', 'TemperatureHold']


class TemperatureHold:
    """
    Zero-order hold of the thermometer by stamp, behind the plausibility gate.

    ``received`` counts the readings offered, ``rejected`` the non-finite ones and
    ``implausible`` those outside the plausible range, jumping faster than the slew bound from
    the last plausible one, or stamped too far ahead (:meth:`add`'s ``not_after``): none of
    them is held, so the held reading stays the last good one and ages by its stamp.

    Parameters
    ----------
    capacity : int or None
        Thermometer samples kept (enough to cover reordering between the two topics; None:
        all until :meth:`forget_before`).
    gate : bool
        Check each reading (finite, plausible); False holds every reading as it is (readings
        checked upstream; a NaN reading is held as NaN: no temperature).

    """

    def __init__(self, capacity: int | None = 256, gate: bool = True) -> None:
        self._t: list[float] = []      # stamps, increasing, and their readings
        self._c: list[float] = []
        self._capacity = capacity
        self.received = self.rejected = self.implausible = 0
        self._gate = TemperatureGate() if gate else None

    def __len__(self) -> int:
        """Return the number of samples held."""
        return len(self._t)

    def add(self, t: float, temp_c: float, not_after: float = math.inf) -> bool:
        """
        Add one thermometer sample ``temp_c`` (degC) at stamp ``t`` (s); return whether held.

        ``not_after`` (s) is the latest plausible stamp (the core: the last IMU stamp plus the
        stale timeout). A NaN/Inf sample counts as ``rejected``, an implausible one as
        ``implausible``; neither is held.
        """
        self.received += 1
        if self._gate is not None:
            if not (math.isfinite(t) and math.isfinite(temp_c)):
                self.rejected += 1
                return False
            if t > not_after or not self._gate.accept(t, temp_c):
                self.implausible += 1
                return False
        i = bisect.bisect_right(self._t, t)
        if i and self._t[i - 1] == t:
            self._c[i - 1] = temp_c
        else:
            self._t.insert(i, t)
            self._c.insert(i, temp_c)
        if self._capacity is not None and len(self._t) > self._capacity:
            del self._t[:len(self._t) - self._capacity], self._c[:len(self._c) - self._capacity]
        return True

    def at(self, t: float) -> tuple[float, float] | None:
        """
        Return ``(temp_c, stamp)`` of the latest sample stamped at or before ``t``.

        Returns
        -------
        tuple of float or None
            None when every sample held is later than ``t`` (or none was received).

        """
        i = bisect.bisect_right(self._t, t)
        return (self._c[i - 1], self._t[i - 1]) if i else None

    def drop_after(self, t: float) -> int:
        """
        Forget the samples stamped after ``t`` (a device clock restarted: the old session's).

        Returns
        -------
        int
            How many were dropped.

        """
        i = bisect.bisect_right(self._t, t)
        n = len(self._t) - i
        del self._t[i:], self._c[i:]
        return n

    @property
    def latest(self) -> tuple[float, float] | None:
        """Return ``(temp_c, stamp)`` of the newest sample, or None."""
        return (self._c[-1], self._t[-1]) if self._t else None

    def held(self, t: NDArray[np.float64], timeout: float) -> NDArray[np.float64]:
        """
        Return the reading held at each of the stamps ``t`` (s), degC.

        NaN before the first reading and where the held one is older than ``timeout`` (s).
        """
        t = np.asarray(t, dtype=np.float64)
        if not self._t:
            return np.full(t.size, math.nan)
        tt, tc = np.asarray(self._t), np.asarray(self._c)
        i = np.searchsorted(tt, t, side='right') - 1
        j = np.clip(i, 0, None)
        return np.where((i >= 0) & ~(t - tt[j] > timeout), tc[j], math.nan)    # NaN: not stale

    def forget_before(self, t: float) -> None:
        """Forget the readings no stamp from ``t`` (s) on needs: all before the one held at it."""
        keep = max(bisect.bisect_right(self._t, t) - 1, 0)
        del self._t[:keep], self._c[:keep]

    @property
    def readings(self) -> list[tuple[float, float]]:
        """Return the readings held, ``(stamp s, degC)`` in stamp order."""
        return list(zip(self._t, self._c))


def hold_readings(readings: Sequence[tuple[float, float]], t: NDArray[np.float64],
                  timeout: float) -> tuple[NDArray[np.float64], list[tuple[float, float]]]:
    """
    Hold readings ``(stamp s, degC)`` (any order, unchecked) at the stamps ``t`` (N >= 1).

    Returns the held reading per stamp (NaN before the first and after ``timeout`` s) and the
    readings still needed: the newest at or before ``t[-1]`` and all after it.
    """
    hold = TemperatureHold(None, gate=False)
    for stamp, temp_c in readings:
        hold.add(stamp, temp_c)
    held = hold.held(t, timeout)
    hold.forget_before(float(t[-1]))
    return held, hold.readings
