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
The online learner's records: settings, the stretch being learned, points, windows, report.

:class:`Entry` is one point of the point table (a bin's entry), :class:`RecentStretch` the
windows of one recent stretch the check and the offset use; ``gyro_tdc.learn.store`` writes
both to the learn_file as plain lists.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import NamedTuple

from gyro_tdc.base import SESSION_GAP_S
from gyro_tdc.signal import MIN_SESSION_SPAN_C, STILL_WINDOW_S, Window
import numpy as np
from numpy.typing import NDArray

__all__ = ['Entry', 'held_out_line', 'keep_power_up', 'LearnConfig', 'OpenStretch', 'pool',
           'POWER_UP_WINDOWS', 'POWER_UPS', 'RecentStretch', 'relabel_power_ups', 'remember']

#: Power cycles whose first still windows the learner keeps (the newest).
POWER_UPS = 100
#: Still windows a power cycle's first still time pools at most (10 s each).
POWER_UP_WINDOWS = 6


@dataclass(slots=True)
class Entry:
    """One point of the learner's table: the mean of a bin's still windows in one entry group."""

    #: Stamp of its newest window's end (its age), s.
    t_end: float
    #: Samples it averages (its weight).
    samples: float
    #: Mean model temperature, degC.
    temp_c: float
    #: Mean raw rate (x, y, z), rad/s.
    bias: tuple[float, float, float]
    #: Its entry group (a stretch, or an ``entry_s`` part of a long one).
    group: int
    #: The session (power cycle) it was learned in.
    session: int


class RecentStretch(NamedTuple):
    """A recent stretch: its number, session and windows ``[n, temp, bx, by, bz, t_end]``."""

    stretch: int
    session: int
    rows: list


@dataclass(frozen=True)
class LearnConfig:
    """Settings of the learner: its table's bins and ageing, its still test and its timing."""

    #: Temperature bin width, degC.
    bin_c: float = 1.0
    #: Age (by message stamp) at which an entry weighs half, s.
    half_life_s: float = 86400.0
    #: Still test window, s.
    window_s: float = STILL_WINDOW_S
    #: Shortest stretch learned, s; None (auto) for the trainers' rule
    #: (:func:`gyro_tdc.signal.long_enough`), :data:`~gyro_tdc.signal.MIN_STILL_S` or two
    #: windows of samples whose mean is known well enough (a 20 s stop of a 25 Hz
    #: flight-controller log).
    min_still_s: float | None = None
    #: A thermometer reading older than this (by stamp) gives no temperature, s.
    temperature_timeout: float = 5.0
    #: Stamp time between periodic saves, s.
    save_period_s: float = 180.0
    #: A still stretch longer than this (s) is learned every ``commit_s`` while it goes on.
    commit_s: float = 300.0
    #: A bin's entry gathers one stretch's windows over at most this long (s; then a new
    #: entry begins), so a long stop is learned as many points, each of its hours aged apart.
    entry_s: float = 3600.0
    #: The current session's offset is the mean over the newest ``offset_s`` (s) of its still
    #: windows of the raw rate minus the fitted shape (the offset wanders: a random walk,
    #: bias instability); 0: the fit's intercept of the session.
    offset_s: float = 1800.0
    #: The core hands the learner at most one sample per ``1 / max_rate_hz`` of stamps
    #: (by stamp, so a replay at any speed hands the same samples): from a faster IMU the
    #: mean of the samples since the last hand-off (a 1 kHz IMU is learned from means of
    #: 10, a tenth of the noise variance of one sample), plenty for 10 s still windows.
    max_rate_hz: float = 100.0
    #: A gap in the IMU stamps longer than this (s) starts a new session (a power-up, the
    #: gyro's turn-on offset changes; each session gets its own intercept in the fit), when
    #: it is also longer than :data:`GAP_PERIODS` sample periods and, in a stream that pauses
    #: regularly (bursts), than :data:`BURST_FACTOR` times its median pause; stamps that step
    #: back by over ``RESTART_BACK_S`` (a device clock restarted) start one too.
    session_gap_s: float = SESSION_GAP_S
    #: An accepted candidate takes effect this long (s, by stamp) after the sample that let
    #: it be computed (:meth:`Learner.take_swaps`), so its effective stamp is fixed by the
    #: data, not by when :meth:`Learner.step` happens to run.
    swap_delay_s: float = 5.0


@dataclass
class OpenStretch:
    """
    The current still stretch: its windows not learned yet, its first stamp and samples.

    ``rows`` are :class:`gyro_tdc.signal.Window` without samples; once part of the stretch
    is learned (``learned``), only the windows since are kept.
    """

    rows: list[Window] = field(default_factory=list)
    t0: float = math.nan
    n: int = 0
    learned: bool = False

    def add(self, win: Window) -> None:
        """Append a still window."""
        if not self.rows and not self.learned:
            self.t0 = win.t0
        self.rows.append(win)
        self.n += win.n

    def span(self) -> float:
        """Return the stretch's duration so far, s (one sample period included)."""
        if not self.rows:
            return 0.0
        d = self.rows[-1].t1 - self.t0
        return d + d / max(self.n - 1, 1)

    def mean_se(self) -> NDArray[np.float64]:
        """Return the standard error of the stretch's mean raw rate per axis, rad/s."""
        n = np.array([r.n for r in self.rows], dtype=np.float64)
        mean = np.array([r.gyro_mean for r in self.rows])
        std = np.array([r.gyro_std for r in self.rows])
        ss = (n - 1.0) @ std ** 2 + n @ (mean - n @ mean / n.sum()) ** 2
        return np.sqrt(ss / max(n.sum() - 1.0, 1.0) / n.sum())

    def keep_from(self, j: int) -> None:
        """Drop the windows before ``j`` (a stretch not learned yet)."""
        self.rows = self.rows[j:]
        self.n = sum(r.n for r in self.rows)
        self.t0 = self.rows[0].t0 if self.rows else math.nan


def held_out_line(fit: dict | None) -> str:
    """Return what the held-out power cycles said of a learned fit's curve (one line)."""
    rec = None if fit is None else fit.get('held_out')
    if rec is None:
        return 'no curve' if fit is not None else 'no learned model yet'
    if not rec['folds']:
        head = (f"not judged ({rec['sessions']} session(s), no other power cycle over the "
                'same temperatures)')
        if rec['offset_only']:
            return (f'{head}, and none spans {MIN_SESSION_SPAN_C:g} degC of its own: offset '
                    'only on every axis, each power-up re-anchored')
        return f'{head}: the curve is kept, each power-up re-anchored'
    figs = ', '.join(f'{a} {c:.3g} vs {o:.3g}' for a, c, o in zip(
        'xyz', rec['curve_ms_dps2'], rec['offset_ms_dps2']))
    only = ', '.join(rec['offset_only'])
    return (f"curve vs offset only, held out on {rec['folds']} of {rec['sessions']} power "
            f"cycles ({rec['points']} points), mean square (deg/s)^2: {figs}; "
            + (f'offset only on {only} (the curve does not beat it held out)' if only
               else 'the curve is kept on every axis'))


def pool(parts: list) -> tuple[float, float, tuple[float, float, float]]:
    """Return the samples, mean temperature and mean rate of ``(samples, temp, rate)`` parts."""
    m = sum(p[0] for p in parts)
    return (m, sum(p[0] * p[1] for p in parts) / m,
            tuple(sum(p[0] * p[2][a] for p in parts) / m for a in range(3)))


def remember(recent: list[RecentStretch], new: RecentStretch, stretches: int, rows: int) -> None:
    """
    Keep ``new`` windows in ``recent`` (newest last) for the check and the offset.

    Windows of the newest stretch join it; at most ``stretches`` stretches and ``rows``
    windows are kept, the oldest dropped first.
    """
    if recent and recent[-1][:2] == new[:2]:      # the same stretch and session
        recent[-1].rows.extend(new.rows)
    else:
        recent.append(new)
    del recent[:-stretches]
    while (excess := sum(len(r.rows) for r in recent) - rows) > 0:
        del recent[0].rows[:excess]
        if not recent[0].rows:
            del recent[0]


def keep_power_up(ups: list, session: int, win: Window) -> bool:
    """
    Pool a still window ``win`` into ``session``'s power-up row; return whether it stays open.

    A power cycle's row ``[session, windows, samples, temp, bx, by, bz]`` pools its first
    still windows (up to :data:`POWER_UP_WINDOWS`): its turn-on offset, whether or not a
    stretch of it is ever learned. The newest :data:`POWER_UPS` rows are kept.
    """
    if not ups or ups[-1][0] != session:
        ups.append([session, 0, win.n, win.temp_c, *win.gyro_mean])
        del ups[:-POWER_UPS]
    else:
        row = ups[-1]
        m, temp, bias = pool([(row[2], row[3], row[4:7]), (win.n, win.temp_c, win.gyro_mean)])
        row[2:] = [m, temp, *bias]
    ups[-1][1] += 1
    return ups[-1][1] < POWER_UP_WINDOWS


def relabel_power_ups(ups: list, relabel: dict) -> list:
    """Return ``ups`` relabelled (``relabel``: merged sessions); the first row of each stays."""
    out: dict = {}
    for row in ups:
        out.setdefault(relabel.get(row[0], row[0]), row[1:])
    return [[s, *rest] for s, rest in out.items()]
