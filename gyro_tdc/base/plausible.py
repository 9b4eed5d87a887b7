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
The plausibility gate of thermometer readings, one home for driver, node, trainer and learner.

A reading is plausible inside ``TEMP_PLAUSIBLE_C`` and within ``TEMP_SLEW_MARGIN_C`` plus
``MAX_TEMP_SLEW_C_S`` per second of the last plausible one (:func:`temperature_ok`); a
rejected reading never becomes the reference, so one glitch costs one reading and a real
jump is taken once the allowance has grown to it. See ``doc/internals/runtime.md``.
"""

from __future__ import annotations

import math

from gyro_tdc.base.limits import MAX_TEMP_SLEW_C_S, TEMP_PLAUSIBLE_C, TEMP_SLEW_MARGIN_C
import numpy as np
from numpy.typing import NDArray

__all__ = ['TemperatureGate', 'plausible_temperatures', 'temperature_ok']

_LO, _HI = TEMP_PLAUSIBLE_C


def temperature_ok(t_prev: float | None, c_prev: float | None, t: float, c: float) -> bool:
    """
    Return whether reading ``c`` (degC) at ``t`` (s) is plausible after ``c_prev`` at ``t_prev``.

    False for a non-finite stamp or reading, one outside ``TEMP_PLAUSIBLE_C``, or one further
    from ``c_prev`` than ``TEMP_SLEW_MARGIN_C + MAX_TEMP_SLEW_C_S * |t - t_prev|``
    (``c_prev`` None: no plausible reading yet, the range alone decides).
    """
    if not (_LO <= c <= _HI and math.isfinite(t)):      # NaN fails the compare
        return False
    if c_prev is None:
        return True
    return abs(c - c_prev) <= TEMP_SLEW_MARGIN_C + MAX_TEMP_SLEW_C_S * abs(t - t_prev)


class TemperatureGate:
    """
    The gate of one thermometer stream: the last plausible reading and what was rejected.

    ``last`` is ``(stamp, degC)`` of the last accepted reading (None before any),
    ``rejected`` the readings refused.
    """

    __slots__ = ('last', 'rejected')

    def __init__(self) -> None:
        self.last: tuple[float, float] | None = None
        self.rejected = 0

    def accept(self, t: float, c: float) -> bool:
        """Return whether reading ``c`` (degC) at ``t`` (s) passes; remember it when it does."""
        if temperature_ok(*(self.last or (None, None)), t, c):
            self.last = (t, c)
            return True
        self.rejected += 1
        return False


def plausible_temperatures(t: NDArray[np.float64], c: NDArray[np.float64]
                           ) -> NDArray[np.bool_]:
    """
    Return which readings a :class:`TemperatureGate` fed in stamp order accepts.

    Vectorised where consecutive readings pass; one scalar step per rejected reading.

    Parameters
    ----------
    t, c : NDArray[np.float64], shape (N,), s and degC
        Stamps and readings, any order (ties keep their order).

    Returns
    -------
    NDArray[np.bool_], shape (N,)
        True where the reading is plausible, in the order of the input.

    """
    t, c = np.asarray(t, dtype=np.float64), np.asarray(c, dtype=np.float64)
    order = np.argsort(t, kind='stable')
    ts, cs = t[order], c[order]
    ok = (cs >= _LO) & (cs <= _HI) & np.isfinite(ts)
    idx = np.flatnonzero(ok)               # in range, in stamp order
    ti, ci = ts[idx], cs[idx]
    step_ok = np.abs(np.diff(ci)) <= TEMP_SLEW_MARGIN_C + MAX_TEMP_SLEW_C_S * np.abs(np.diff(ti))
    bad = np.flatnonzero(~step_ok)          # reading k + 1 jumps from reading k
    keep = np.ones(idx.size, dtype=bool)
    n, b = idx.size, 0
    while b < bad.size:
        ref = int(bad[b])                   # accepted; the next reading jumps from it
        i = ref + 1
        while i < n and not temperature_ok(ti[ref], ci[ref], ti[i], ci[i]):
            keep[i] = False
            i += 1
        # i is accepted (or the end): readings after it pass until the next failing step.
        b = int(np.searchsorted(bad, i, side='left'))
    ok[idx[~keep]] = False
    out = np.empty(ok.size, dtype=bool)
    out[order] = ok
    return out
