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
The compensator's thermometer held by stamp (pure).

:class:`TemperatureHold` is a zero-order hold by stamp of the readings the plausibility gate
(:mod:`gyro_tdc.base.plausible`) lets through.
"""

from __future__ import annotations

import bisect
import math

from gyro_tdc.base import TemperatureGate

__all__ = ['TemperatureHold']


class TemperatureHold:
    """
    Zero-order hold of the thermometer by stamp, behind the plausibility gate.

    ``received`` counts the readings offered, ``rejected`` the non-finite ones and
    ``implausible`` those outside the plausible range, jumping faster than the slew bound from
    the last plausible one, or stamped too far ahead (:meth:`add`'s ``not_after``): none of
    them is held, so the held reading stays the last good one and ages by its stamp.

    Parameters
    ----------
    capacity : int
        Thermometer samples kept (enough to cover reordering between the two topics).

    """

    def __init__(self, capacity: int = 256) -> None:
        self._t: list[float] = []
        self._c: list[float] = []
        self._capacity = int(capacity)
        self.received = 0
        self.rejected = 0
        self.implausible = 0
        self._gate = TemperatureGate()

    def __len__(self) -> int:
        """Return the number of samples held."""
        return len(self._t)

    def add(self, t: float, temp_c: float, not_after: float = math.inf) -> bool:
        """
        Add one thermometer sample.

        Parameters
        ----------
        t : float, s
            Stamp.
        temp_c : float, degC
            Reading.
        not_after : float, s
            Latest plausible stamp (the core: the last IMU stamp plus the stale timeout).

        Returns
        -------
        bool
            False when the sample is NaN/Inf (``rejected``) or implausible (``implausible``)
            and was not held.

        """
        self.received += 1
        if not (math.isfinite(t) and math.isfinite(temp_c)):
            self.rejected += 1
            return False
        if t > not_after or not self._gate.accept(t, temp_c):
            self.implausible += 1
            return False
        if not self._t or t > self._t[-1]:
            self._t.append(t)
            self._c.append(temp_c)
        else:
            i = bisect.bisect_right(self._t, t)
            if i and self._t[i - 1] == t:
                self._c[i - 1] = temp_c
            else:
                self._t.insert(i, t)
                self._c.insert(i, temp_c)
        if len(self._t) > self._capacity:
            del self._t[:len(self._t) - self._capacity]
            del self._c[:len(self._c) - self._capacity]
        return True

    def at(self, t: float) -> tuple[float, float] | None:
        """
        Return ``(temp_c, stamp)`` of the latest sample stamped at or before ``t``.

        Returns
        -------
        tuple of float or None
            None when every sample held is later than ``t`` (or none was received).

        """
        ts = self._t
        if ts and ts[-1] <= t:
            return self._c[-1], ts[-1]
        i = bisect.bisect_right(ts, t)
        return (self._c[i - 1], ts[i - 1]) if i else None

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
