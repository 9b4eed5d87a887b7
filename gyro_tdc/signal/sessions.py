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
The session-break rule (a power cycle in the stamps), in batch and streaming form.

:func:`gap_limit` is the rule, :func:`session_gap` and :func:`gap_breaks` apply it to a
whole run (the batch session cutter) and :class:`SessionTracker` one stamp step at a time,
keeping the session a stream is in (the compensator's core and the learner); see
doc/internals/signal.md.
"""

from __future__ import annotations

from itertools import accumulate
import math
from typing import Sequence

from gyro_tdc.base import RESTART_BACK_S, SESSION_GAP_PERIODS, SESSION_GAP_S
import numpy as np
from numpy.typing import NDArray

__all__ = ['BURST_FACTOR', 'BURST_MAX_S', 'BURST_PAUSES', 'break_why', 'GAP_PERIODS',
           'gap_breaks', 'gap_limit', 'PAUSES_KEPT', 'PERIOD_STEPS', 'session_gap',
           'SessionTracker']

#: A pause starts a new session when it is longer than ``gap_s`` and this many periods ...
GAP_PERIODS = SESSION_GAP_PERIODS
#: ... and, once the stream pauses regularly (this many pauses over GAP_PERIODS periods) ...
BURST_PAUSES = 5
#: ... than this many times the median of its pauses (a bursty logger's rhythm) ...
BURST_FACTOR = 3.0
#: ... but a pause longer than this (s) is no part of a rhythm: the burst limit never exceeds
#: it, and such pauses are not counted in the median (a vehicle off every night is no logger).
BURST_MAX_S = 3600.0
#: The streaming form keeps the newest this many pauses.
PAUSES_KEPT = 64
#: :meth:`SessionTracker.median_period` is the median of the stream's first this many steps.
PERIOD_STEPS = 64


def gap_limit(period: float, pauses: Sequence[float], gap_s: float = SESSION_GAP_S) -> float:
    """
    Return the stamp gap (s) above which a stream starts a new session.

    The longest of ``gap_s``, :data:`GAP_PERIODS` sample periods and, with
    :data:`BURST_PAUSES` or more ``pauses`` (steps over GAP_PERIODS periods, at most
    :data:`BURST_MAX_S`), :data:`BURST_FACTOR` times their median, at most BURST_MAX_S.
    """
    gap = max(gap_s, GAP_PERIODS * period) if period > 0 else gap_s
    if len(pauses) >= BURST_PAUSES:
        gap = max(gap, min(BURST_FACTOR * float(np.median(pauses)), BURST_MAX_S))
    return gap


def break_why(d: float) -> str:
    """Return a break's words: ``'gap of X s'``, or a restart for a step back (``d < 0``)."""
    return f'gap of {d:.0f} s' if d > 0 else f'restart (stamps back by {-d:.0f} s)'


def session_gap(t: NDArray[np.float64], gap_s: float = 0.0, *,
                steps: NDArray[np.float64] | None = None) -> float:
    """
    Return the gap (s) above which a whole run starts a new session (the batch form).

    ``gap_s`` > 0 is a fixed threshold (``--session-gap``); 0: :func:`gap_limit` with the
    median step as the period and every step over GAP_PERIODS of them (up to BURST_MAX_S)
    as the pauses; inf for fewer than two stamps. ``steps``: ``np.diff(t)``, when known.
    """
    if gap_s > 0:
        return float(gap_s)
    dt = np.diff(np.asarray(t, dtype=np.float64)) if steps is None else steps
    if dt.size == 0:
        return math.inf
    period = float(np.median(dt))
    pauses = dt[(dt > GAP_PERIODS * period) & (dt <= BURST_MAX_S)]
    return gap_limit(period, pauses, SESSION_GAP_S)


def gap_breaks(t: NDArray[np.float64], gap_s: float = 0.0) -> list[tuple[int, float]]:
    """Return the gaps of increasing stamps ``t`` that start a session: (first sample, gap s)."""
    dt = np.diff(np.asarray(t, dtype=np.float64))
    gap = session_gap(t, gap_s, steps=dt)
    return [(i + 1, float(dt[i])) for i in np.flatnonzero(dt > gap).tolist()]


class SessionTracker:
    """
    The session one stream is in: the rule, the current session and the breaks that began them.

    The caller estimates the sample period and shows the steps it judges (at least every
    step over ``gap_s``); :meth:`judge` keeps the pauses among them (the stream's rhythm,
    over sessions, in :attr:`rhythm`) and says which step is a break, :meth:`start` begins the
    session a break starts, :meth:`period` is the session's mean sample period (its pauses
    left out), :meth:`median_period` the median of the stream's first steps (a stream seen in
    batches) and :meth:`merges` relabels the sessions whose gap the rule, having learned the
    stream's rhythm since, no longer cuts at.

    Parameters
    ----------
    gap_s : float, s
        The shortest gap that is a break.
    first : int
        The first session's number.

    """

    def __init__(self, gap_s: float = SESSION_GAP_S, first: int = 0) -> None:
        self.gap_s = float(gap_s)
        #: The stream's pauses over GAP_PERIODS periods (at most BURST_MAX_S), the newest
        #: :data:`PAUSES_KEPT`: its rhythm, kept over sessions.
        self.rhythm: list[float] = []
        #: The sessions a gap started, ``(session, gap s)``, the newest :data:`PAUSES_KEPT`.
        self.gaps: list[tuple[int, float]] = []
        #: The median of the stream's first :data:`PERIOD_STEPS` positive steps (None before).
        self.median: float | None = None
        self._steps: list[float] = []
        self.session = int(first) - 1
        self.start(None, '')                # the first session, before its first stamp

    def median_period(self, dt: NDArray[np.float64]) -> float | None:
        """Take the stream's next steps ``dt`` (s); return the median period once known."""
        if self.median is None:
            self._steps.extend(dt[dt > 0.0][:PERIOD_STEPS - len(self._steps)].tolist())
            if len(self._steps) >= PERIOD_STEPS:
                self.median = float(np.median(self._steps))
        return self.median

    def pause_s(self) -> float:
        """
        Return the step (s) over which a stream's step is shown to :meth:`judge`.

        :attr:`gap_s` while the median period is unknown (the caller shows every step to
        :meth:`median_period` then), then GAP_PERIODS median periods, at most gap_s.
        """
        return self.gap_s if self.median is None else min(self.gap_s, GAP_PERIODS * self.median)

    def begin(self, t: float, k: int = 0) -> None:
        """Note the stream's first sample: stamp ``t`` (s), the ``k``-th counted."""
        self.t0, self.k0 = t, k

    def period(self, t_last: float | None, k: int) -> float:
        """
        Return the session's mean sample period, s (0: unknown).

        ``t_last`` is the last stamp before the step judged and ``k`` the count of the
        sample after it; the pauses judged in the session are left out.
        """
        steps = k - self.k0 - 1 - self.pauses
        if steps <= 0 or self.t0 is None or t_last is None:
            return 0.0
        return (t_last - self.t0 - self.paused_s) / steps

    def limit(self, period: float) -> float:
        """Return the gap (s) above which a step is a break now (:func:`gap_limit`)."""
        return gap_limit(period, self.rhythm, self.gap_s)

    def judge(self, d: float, period: float) -> str:
        """
        Judge a stamp step ``d`` (s) of a stream sampled every ``period`` s.

        Returns
        -------
        str
            ``''``: no break (a pause over GAP_PERIODS periods is kept in the rhythm, and
            the step counts as a pause of the session); else :func:`break_why`: stamps back
            by over ``RESTART_BACK_S``, or a gap over :meth:`limit` (judged with this pause
            counted).

        """
        if d < -RESTART_BACK_S:
            return break_why(d)
        why = ''
        if d > GAP_PERIODS * period:          # NaN: no break
            if d <= BURST_MAX_S:
                self.rhythm = (self.rhythm + [float(d)])[-PAUSES_KEPT:]
            why = break_why(d) if d > self.limit(period) else ''
        if not why:
            self.pauses += 1
            self.paused_s += d
        return why

    def start(self, t: float | None, why: str, k: int = 0, gap: float = 0.0) -> int:
        """
        Begin a new session at stamp ``t`` (the ``k``-th sample) after ``why``; return it.

        ``gap`` > 0 (s) is the gap that started it: :meth:`merges` may take it back.
        """
        self.session += 1
        #: The current session's first stamp (None before any), the sample count at it and
        #: what started it (``''`` for the first).
        self.t0, self.k0, self.why = t, k, why
        #: The steps judged since the session started that were no break, and their sum.
        self.pauses, self.paused_s = 0, 0.0
        if gap > 0:
            self.gaps = (self.gaps + [(self.session, float(gap))])[-PAUSES_KEPT:]
        return self.session

    def merges(self, period: float) -> dict[int, int] | None:
        """
        Merge the sessions whose gap is no break under the rule now; return the relabelling.

        Returns
        -------
        dict of int to int, or None
            The new label of every session up to the current one (None: nothing merged).

        """
        limit = self.limit(period)
        merge = {s for s, gap in self.gaps if gap <= limit and s <= self.session}
        if not merge:
            return None
        # A merged session takes its predecessor's label; the others count on.
        new = dict(enumerate(accumulate(int(k > 0 and k not in merge)
                                        for k in range(self.session + 1))))
        self.gaps = [(new[s], g) for s, g in self.gaps if s not in merge and s in new]
        self.session = new[self.session]
        return new
