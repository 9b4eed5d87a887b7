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
The still test, written once: its constants, noise floor, thresholds and window verdict.

:func:`judge_windows` is the rule; :class:`NoiseFloor` and :class:`MotionReports` are the
state a stream keeps from window to window (:mod:`gyro_tdc.signal.still_stream`), and
:func:`detect_still` is the batch form over a whole run, whose auto thresholds know the
run's noise floor from the start. See doc/internals/signal.md.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
import math
from typing import Callable

from gyro_tdc.base import DEG_PER_RAD
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['auto_window', 'detect_still', 'has_accelerometer', 'judge_windows', 'long_enough',
           'MAX_RATE', 'MAX_STILL_SE', 'MIN_JUDGED', 'MIN_STILL_S', 'MIN_STILL_SAMPLES',
           'MIN_WINDOW_SAMPLES', 'MotionReports', 'MOTION_EPS', 'motion_veto', 'NOISE_DOF',
           'NOISE_FACTOR', 'NOISE_WINDOWS', 'noise_floor', 'noise_thresholds', 'NoiseFloor',
           'REASONS', 'SHORT_WINDOW_S', 'Stillness', 'STILL_WINDOW_S', 'stretch_edges',
           'window_moments', 'windows_moving']

#: Default window, s: the shortest still stretch judged (and the re-anchoring window).
STILL_WINDOW_S = 10.0
#: Auto thresholds: this many times the noise floor (the quietest window's std).
NOISE_FACTOR = 4.0
#: Streaming: windows seen before the noise floor alone sets the auto gyro threshold.
NOISE_WINDOWS = 3
#: Fewest samples per window (the window grows at low rates).
MIN_WINDOW_SAMPLES = 20
#: Fewest samples of a window that may be still (and lower the noise floor).
MIN_JUDGED = max(3, MIN_WINDOW_SAMPLES // 2)
#: Streaming: the noise floor is the variance pooled over consecutive windows of at least this
#: many degrees of freedom (one window at 10 Hz and up, six 10 s windows at 1 Hz), so it does
#: not sink with the sample count or the length of the stream.
NOISE_DOF = 2 * MIN_WINDOW_SAMPLES
#: Largest mean compensated rate of a still window, rad/s (a session-to-session offset).
MAX_RATE = 0.02
#: Default shortest still stretch kept by :func:`detect_still`, s.
MIN_STILL_S = 60.0
#: Auto still test (``min_still_s=None``): a shorter stretch is kept when it lasts two windows,
#: holds at least this many samples (five windows of the fewest; 12 s at 8 Hz, a stop of an
#: SD-card log) ...
MIN_STILL_SAMPLES = 100
#: ... and the standard error of its mean rate is at most this, rad/s (0.01 deg/s), on every
#: axis: a 15 s stretch at 25 Hz of a quiet MEMS gyro, or 2 s at 1 kHz.
MAX_STILL_SE = 1.75e-4
#: Auto window of the trainers (``window_s=None``): this long, s, or
#: :data:`MIN_WINDOW_SAMPLES` sample periods, at most :data:`STILL_WINDOW_S`, so that a
#: short stretch of a fast log holds whole windows.
SHORT_WINDOW_S = 2.5
#: A motion report above this (m/s or rad/s, any component) is motion.
MOTION_EPS = 1e-6

#: Why a window is not still (``''`` when it is), in the order they are checked.
REASONS = ('samples', 'non-finite', 'motion', 'gyro', 'accel', 'rate', 'brief')


def auto_window(t: ArrayLike, dt: float | None = None) -> float:
    """
    Return the trainers' auto still window for stamps ``t``, s (:data:`SHORT_WINDOW_S`).

    Short at high rates (a 15 s still stretch between flights holds whole windows), at least
    :data:`MIN_WINDOW_SAMPLES` sample periods, and never longer than :data:`STILL_WINDOW_S`
    unless the rate asks for it. ``dt``: the median step of ``t``, when known.
    """
    if dt is None:
        t = np.asarray(t, dtype=np.float64)
        dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    return max(min(STILL_WINDOW_S, SHORT_WINDOW_S), MIN_WINDOW_SAMPLES * dt) if dt > 0 else (
        STILL_WINDOW_S)


def has_accelerometer(accel: ArrayLike | None) -> bool:
    """
    Return True when ``accel`` holds accelerometer data (not None, not all zero or NaN).

    A driver without an accelerometer publishes zeros with
    ``linear_acceleration_covariance[0] = -1`` (REP 145).
    """
    a = None if accel is None else np.asarray(accel, dtype=np.float64)
    # In chunks, stopping at the first finite non-zero row: a real accelerometer answers at
    # once, without a pass (and copies) over a long run.
    step = 1 << 16
    return a is not None and a.ndim == 2 and any(
        np.any(np.isfinite(c).all(axis=1) & (c != 0.0).any(axis=1))
        for c in (a[i:i + step] for i in range(0, a.shape[0], step)))


def noise_floor(std: ArrayLike, ok: ArrayLike | None = None) -> NDArray[np.float64]:
    """
    Return the noise floor: the smallest positive window standard deviation per axis (3,).

    ``std`` (W, 3) are the windows' standard deviations, ``ok`` (W,) those that may be still
    (default all); inf where no window qualifies.
    """
    s = np.asarray(std, dtype=np.float64).reshape(-1, 3)
    use = np.isfinite(s) & (s > 0.0)
    if ok is not None:
        use &= np.asarray(ok, dtype=bool)[:, None]
    return np.where(use, s, math.inf).min(axis=0, initial=math.inf)


def noise_thresholds(gyro_floor: ArrayLike, accel_floor: ArrayLike | None = None, *,
                     gyro_std: float = 0.0, accel_std: float = 0.0,
                     prior_std: ArrayLike | None = None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the gyro and accelerometer thresholds in force (3,) each, fixed or auto.

    ``gyro_std``/``accel_std`` > 0 (rad/s, m/s^2) are fixed; 0: :data:`NOISE_FACTOR` times the
    floor (:func:`noise_floor`; inf: none yet). ``prior_std`` (the model's residual standard
    deviation) holds the auto gyro threshold below NOISE_FACTOR times it (the streaming form,
    over its first :data:`NOISE_WINDOWS` windows, so a first window that moves is not the floor).
    """
    def thr(fixed: float, floor: ArrayLike | None) -> NDArray[np.float64]:
        if fixed > 0:
            return np.full(3, float(fixed))
        return np.full(3, math.inf) if floor is None else NOISE_FACTOR * np.asarray(floor, float)
    g = thr(gyro_std, gyro_floor)
    if not gyro_std > 0 and prior_std is not None:
        g = np.minimum(g, NOISE_FACTOR * np.asarray(prior_std, dtype=np.float64))
    return g, thr(accel_std, accel_floor)


def judge_windows(gyro_std: ArrayLike, accel_std: ArrayLike | None, gyro_thr: ArrayLike,
                  accel_thr: ArrayLike, *, mean_rate: ArrayLike | None = None,
                  max_rate: float = MAX_RATE, moving: ArrayLike | None = None,
                  counts: ArrayLike | None = None, min_samples: int = MIN_JUDGED,
                  finite: ArrayLike | None = None) -> NDArray[np.str_]:
    """
    Judge windows: the still test proper, one home for the batch and streaming forms.

    Per window (W,): too few samples (``counts`` below ``min_samples``), a non-finite sample
    (``finite`` False), a motion veto (``moving``), a raw-rate or acceleration standard
    deviation (W, 3) over its threshold (:func:`noise_thresholds`; ``accel_std`` None: no
    accelerometer), or a mean compensated rate (``mean_rate``, with a prior) over ``max_rate``.
    Returns ``''`` for a still window, else the first failed test of :data:`REASONS`.
    """
    def over(x: ArrayLike, limit: ArrayLike) -> NDArray[np.bool_]:
        return ~np.all(np.asarray(x, dtype=np.float64).reshape(-1, 3) <= limit, axis=1)
    w = np.asarray(gyro_std).reshape(-1, 3).shape[0]
    checks = [('samples', counts, lambda c: np.asarray(c).reshape(w) < min_samples),
              ('non-finite', finite, lambda f: ~np.asarray(f, dtype=bool).reshape(w)),
              ('motion', moving, lambda m: np.asarray(m, dtype=bool).reshape(w)),
              ('gyro', gyro_std, lambda g: over(g, np.asarray(gyro_thr))),
              ('accel', accel_std, lambda a: over(a, np.asarray(accel_thr))),
              ('rate', mean_rate, lambda m: over(np.abs(np.asarray(m, float)), max_rate))]
    why = np.full(w, '', dtype='<U10')
    for name, given, bad in reversed(checks):      # the first failed test wins
        if given is not None:
            why[bad(given)] = name
    return why


def motion_veto(t: ArrayLike, motion_t: ArrayLike, moving: ArrayLike) -> NDArray[np.bool_]:
    """
    Hold motion reports onto the IMU stamps ``t`` (N,): True where the latest says motion.

    ``motion_t`` (M,) are the reports' stamps (``cmd_vel``, odometry; any order), ``moving``
    per report a bool or its components (m/s, rad/s: motion when any exceeds
    :data:`MOTION_EPS`). Before the first report every sample is vetoed (still only while the
    stream reports zero motion).
    """
    t = np.asarray(t, dtype=np.float64)
    mt = np.asarray(motion_t, dtype=np.float64).reshape(-1)
    if mt.size == 0:
        return np.ones(t.shape[0], dtype=bool)
    mv = np.asarray(moving)
    if mv.dtype != bool:
        v = np.asarray(moving, dtype=np.float64).reshape(mt.size, -1)
        mv = ~np.all(np.isfinite(v) & (np.abs(v) <= MOTION_EPS), axis=1)
    mv = mv.reshape(mt.size)
    order = np.argsort(mt, kind='stable')
    mt, mv = mt[order], mv[order]
    held = np.searchsorted(mt, t, side='right') - 1
    return np.where(held >= 0, mv[np.clip(held, 0, None)], True)


def windows_moving(t_start: ArrayLike, t_end: ArrayLike, motion_t: ArrayLike,
                   moving: ArrayLike) -> NDArray[np.bool_]:
    """
    Return which windows ``[t_start, t_end]`` (W,) overlap a moving interval of the reports.

    A report (``motion_t`` increasing, ``moving`` bool) holds from its stamp until the next:
    True where the report held at ``t_start`` or any report within ``(t_start, t_end]`` says
    motion. Before the first report nothing is vetoed (a stream without a motion input is
    judged by the noise test alone); at a report's stamp the held state is
    :func:`motion_veto`'s.
    """
    t0 = np.atleast_1d(np.asarray(t_start, dtype=np.float64))
    t1 = np.atleast_1d(np.asarray(t_end, dtype=np.float64))
    mt = np.asarray(motion_t, dtype=np.float64).reshape(-1)
    mv = np.asarray(moving, dtype=bool).reshape(-1)
    if mt.size == 0:
        return np.zeros(t0.shape, dtype=bool)
    held = motion_veto(t0, mt, mv) & (t0 >= mt[0])
    # Moving reports within (t_start, t_end]: a difference of a running count.
    count = np.concatenate([[0], np.cumsum(mv)])
    inside = (count[np.searchsorted(mt, t1, side='right')]
              - count[np.searchsorted(mt, t0, side='right')])
    return held | (inside > 0)


class MotionReports:
    """
    Outside motion reports (``cmd_vel``, odometry): each holds from its stamp to the next.

    A window that overlaps a moving interval is vetoed (:func:`windows_moving`; before the
    first report nothing is). Reports are kept from the one held at the window in progress on.
    """

    def __init__(self) -> None:
        #: Reports (stamp, moving), in stamp order.
        self.reports: list[tuple[float, bool]] = []

    def add(self, t: float, moving: bool) -> None:
        """Record a report (a non-finite stamp is ignored)."""
        if math.isfinite(t := float(t)):
            self.reports.append((t, bool(moving)))
            if len(self.reports) > 1 and t < self.reports[-2][0]:     # out of order
                self.reports.sort(key=lambda r: r[0])

    def veto(self, t0: float, t1: float) -> bool:
        """Return whether ``[t0, t1]`` overlaps motion; drop reports before the one held at t1."""
        mo = self.reports
        mt = [r[0] for r in mo]
        moving = bool(windows_moving([t0], [t1], mt, [r[1] for r in mo])[0])
        held = max(int(np.searchsorted(mt, t1, side='right')) - 1, 0)
        del mo[:held]
        return moving


class NoiseFloor:
    """
    A running noise floor per axis: the lowest standard deviation pooled over windows.

    Each window adds its variance and degrees of freedom (samples - 1); the variance pooled
    over the newest consecutive windows holding at least :data:`NOISE_DOF` of them is a
    candidate, and the floor is the lowest candidate so far, at least the quantisation noise
    ``q / sqrt(12)`` of the finest step seen between two readings (``q``). An axis whose
    windows never vary has no floor (inf). Pooling makes the floor a property of the noise,
    not of the window's sample count or of how many windows the stream has had: the lowest
    single window of ten samples sinks to a sixth of the noise over a day of them.
    """

    def __init__(self) -> None:
        self.floor, self.quantum = np.full(3, math.inf), np.full(3, math.inf)
        self._windows: deque[tuple[int, NDArray[np.float64]]] = deque()
        self._dof = 0

    def add(self, dof: int, var: NDArray[np.float64], step: NDArray[np.float64]) -> None:
        """Add a window: its degrees of freedom, variance (3,) and finest step (3,; inf)."""
        self.quantum = np.minimum(self.quantum, step)
        win = self._windows
        win.append((dof, var))
        self._dof += dof
        while win and self._dof - win[0][0] >= NOISE_DOF:
            self._dof -= win.popleft()[0]
        if self._dof < NOISE_DOF:
            return
        pooled = sum(d * v for d, v in win) / self._dof
        q = np.where(np.isfinite(self.quantum), self.quantum, 0.0)
        cand = np.maximum(np.sqrt(pooled), q / math.sqrt(12.0))
        cand = np.where(cand > 0.0, cand, math.inf)
        self.floor = np.minimum(self.floor, cand)


@dataclass(frozen=True, eq=False)
class Stillness:
    """
    The still samples of one run and how its windows were judged (:func:`detect_still`).

    ``mask`` (N,) the still samples (finite ones only); ``segments`` the kept stretches as
    half-open sample ranges, ``durations_s`` theirs; per window (W,) ``starts``, ``counts``,
    ``why`` (``''`` or one of :data:`REASONS`) and the raw rate's and acceleration's mean and
    standard deviation (rad/s, m/s^2; the acceleration's None without an accelerometer); the
    thresholds applied and the noise floors of the auto ones (3,); ``reason``: why no sample is
    still ('' when some are).
    """

    mask: NDArray[np.bool_]
    segments: tuple
    window_s: float
    starts: NDArray[np.int64]
    counts: NDArray[np.int64]
    why: NDArray[np.str_]
    gyro_mean: NDArray[np.float64]
    gyro_std: NDArray[np.float64]
    accel_mean: NDArray[np.float64] | None
    accel_std: NDArray[np.float64] | None
    gyro_threshold: NDArray[np.float64]
    accel_threshold: NDArray[np.float64] | None
    durations_s: NDArray[np.float64]
    gyro_floor: NDArray[np.float64]
    accel_floor: NDArray[np.float64] | None
    reason: str = ''
    #: The sample period and window statistics, for :func:`detect_still`'s ``again``.
    stats: tuple = field(default=(), repr=False)

    @property
    def still_windows(self) -> NDArray[np.bool_]:
        """Return the still windows, shape (W,)."""
        return self.why == ''

    @property
    def still_s(self) -> float:
        """Return the still time, s (the sum of the stretches' durations)."""
        return float(self.durations_s.sum())

    @property
    def fraction(self) -> float:
        """Return the fraction of samples that are still."""
        return float(self.mask.mean()) if self.mask.size else 0.0

    def rejected(self) -> dict[str, int]:
        """Return the number of windows each test refused (reasons with a count only)."""
        return {r: int(np.count_nonzero(self.why == r)) for r in REASONS if np.any(self.why == r)}


#: Rows per pass of :func:`window_moments` (its temporaries stay in the cache: under 1 MB).
_CHUNK_ROWS = 1 << 15


@np.errstate(invalid='ignore', divide='ignore')        # a non-finite row, a single row
def window_moments(x: NDArray[np.float64], starts: NDArray[np.int64],
                   counts: NDArray[np.int64], finite: NDArray[np.bool_] | None = None
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return per-window means and standard deviations (W, 3) of ``x`` (ddof 1).

    The one home of the still test's window statistics, batch and streaming. Each window is
    centred on its first row: an axis that never changes has a scatter of exactly zero, and
    a non-finite row spoils its own window only; rows where ``finite`` is False count as
    zeros. The sums run in passes of about :data:`_CHUNK_ROWS` rows of whole windows.
    """
    n, w = x.shape[0], starts.size
    s, q = np.empty((w, x.shape[1])), np.empty((w, x.shape[1]))
    ends = np.append(starts[1:], n)
    buf = np.empty((min(n, max(_CHUNK_ROWS, int(counts.max()))), x.shape[1]))
    i = 0
    while i < w:
        j = max(i + 1, int(np.searchsorted(ends, starts[i] + _CHUNK_ROWS, side='right')))
        a, b, loc = int(starts[i]), int(ends[j - 1]), starts[i:j] - starts[i]
        d = buf[:b - a]
        d[...] = x[a:b]
        if finite is not None:
            d[~finite[a:b]] = 0.0
        c = d[loc]
        d -= np.repeat(c, counts[i:j], axis=0)
        s[i:j] = np.add.reduceat(d, loc, axis=0)
        q[i:j] = np.add.reduceat(np.multiply(d, d, out=d), loc, axis=0)
        s[i:j] /= counts[i:j, None]
        q[i:j] = np.maximum(q[i:j] - s[i:j] * s[i:j] * counts[i:j, None], 0.0)
        s[i:j] += c
        i = j
    return s, np.sqrt(q / (counts[:, None] - 1.0))


def _windows(t: NDArray[np.float64], g: NDArray[np.float64], acc: NDArray[np.float64] | None,
             window: float) -> tuple:
    """
    Return a run's windows: starts, counts, finite rows and windows with a non-finite row.

    Then the raw rate's and acceleration's means and standard deviations (None without one).
    """
    n = t.shape[0]
    k = np.subtract(t, t[0])           # window index floor((t - t0) / window), in place
    np.floor(np.divide(k, window, out=k), out=k)
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    counts = np.diff(np.append(starts, n))
    finite = np.ones(n, dtype=bool)
    for f in (np.isfinite(x) for x in (g, acc) if x is not None):
        finite &= f[:, 0] & f[:, 1] & f[:, 2]      # column by column: faster than all(axis=1)
    zeroed = None if finite.all() else finite      # non-finite rows count as zeros
    return (starts, counts, finite, np.logical_or.reduceat(~finite, starts),
            *window_moments(g, starts, counts, zeroed),
            *((None, None) if acc is None else window_moments(acc, starts, counts, zeroed)))


def long_enough(n: int, duration: float, se: Callable[[], ArrayLike], window: float,
                min_still_s: float | None) -> bool:
    """
    Return whether a still stretch of ``n`` samples over ``duration`` s is kept (trained on).

    ``min_still_s`` s or more; None (auto): :data:`MIN_STILL_S`, or two ``window`` of
    :data:`MIN_STILL_SAMPLES` samples or more whose mean is known to :data:`MAX_STILL_SE`
    (``se()``: the standard error of the mean raw rate per axis, rad/s, asked only then).
    """
    if min_still_s is not None:
        return duration + 1e-9 >= min_still_s
    return duration + 1e-9 >= MIN_STILL_S or (
        n >= MIN_STILL_SAMPLES and duration + 1e-6 >= 2.0 * window
        and bool(np.all(np.asarray(se(), dtype=np.float64) <= MAX_STILL_SE)))


def stretch_edges(still: NDArray[np.bool_], steps: NDArray[np.float64], window: float,
                  cuts: ArrayLike = ()) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """
    Return the starts and stops (half-open) of the runs of True in ``still``: its stretches.

    The still test's one gap rule: a step of the stamps between neighbours (``steps``, one
    fewer than ``still``) longer than ``window`` (the logger stopped) ends a stretch; so does
    each index ``i`` of ``cuts`` (between ``i`` and ``i + 1``: a session's end).
    """
    joined = still[1:] & still[:-1] & (steps <= window)
    joined[np.asarray(cuts, dtype=np.int64)] = False
    return (np.flatnonzero(still & ~np.r_[False, joined]),
            np.flatnonzero(still & ~np.r_[joined, False]) + 1)


def _still_stretches(t: NDArray[np.float64], g: NDArray[np.float64],
                     starts: NDArray[np.int64], why: NDArray[np.str_], dt: float,
                     window: float, min_still_s: float | None) -> tuple[list, list]:
    """
    Return the kept stretches of consecutive still windows and their durations.

    A stretch is a half-open sample range ``(start, stop)``; its duration, s, spans its
    stamps plus one sample period ``dt``. A gap in the stamps longer than a ``window``
    (the logger stopped) ends a stretch. The windows of a stretch too short to keep
    (:func:`long_enough`) are marked ``'brief'`` in ``why``, in place.
    """
    ends = np.append(starts[1:], t.shape[0])
    first_w, stop_w = stretch_edges(why == '', t[starts[1:]] - t[starts[1:] - 1], window)
    segments, durations = [], []
    for a, b in zip(first_w.tolist(), stop_w.tolist()):
        i0, i1 = int(starts[a]), int(ends[b - 1])
        n, dur = i1 - i0, float(t[i1 - 1] - t[i0]) + dt
        if not long_enough(n, dur, lambda: np.nanstd(g[i0:i1], axis=0, ddof=1) / math.sqrt(n),
                           window, min_still_s):
            why[a:b] = 'brief'
            continue
        segments.append((i0, i1))
        durations.append(dur)
    return segments, durations


def _no_still_reason(why: NDArray[np.str_], min_still_s: float | None) -> str:
    """Return why a run has no still stretch, from the verdicts ``why`` of its windows."""
    if np.all(why == 'motion'):
        return 'every window is vetoed by a motion report'
    if np.any(why == 'brief'):
        return (f'no still stretch of {min_still_s:g} s or more (the longest still '
                'stretch is shorter)' if min_still_s is not None else
                f'no still stretch of {MIN_STILL_S:g} s, or of two windows and '
                f'{MIN_STILL_SAMPLES} samples with a mean known to '
                f'{MAX_STILL_SE * DEG_PER_RAD:.2g} deg/s (the still stretches are shorter '
                'or noisier)')
    return 'no still window (the IMU moves)'


def detect_still(t: ArrayLike, gyro: ArrayLike, accel: ArrayLike | None = None, *,
                 rate: ArrayLike | None = None, moving: ArrayLike | None = None,
                 window_s: float | None = STILL_WINDOW_S, min_still_s: float | None = MIN_STILL_S,
                 gyro_std: float = 0.0, accel_std: float = 0.0, max_rate: float = MAX_RATE,
                 gyro_floor: ArrayLike | None = None, accel_floor: ArrayLike | None = None,
                 again: Stillness | None = None) -> Stillness:
    """
    Find the still samples of a run: the batch form of the still test.

    ``t`` (N,) increasing stamps, ``gyro`` (N, 3) raw rate, ``accel`` (N, 3) acceleration
    (ignored when it holds no data, :func:`has_accelerometer`); ``rate`` the rate compensated
    by a prior minus any reference, whose window mean is at most ``max_rate``; ``moving`` (N,)
    samples a motion report vetoes. Windows last ``window_s`` (None: :func:`auto_window`), at
    least :data:`MIN_WINDOW_SAMPLES` sample periods. A stretch of consecutive still windows is kept
    when it lasts ``min_still_s`` (0 keeps every still window); None judges it by its samples
    and its noise: :data:`MIN_STILL_S`, or two windows and :data:`MIN_STILL_SAMPLES`
    samples whose mean rate has a standard error of at most :data:`MAX_STILL_SE` on every
    axis; a gap in the stamps longer than a window ends a stretch. ``gyro_std``/``accel_std``
    > 0 are fixed thresholds; ``gyro_floor``/``accel_floor`` replace this run's own noise floors
    (e.g. the quietest window of several bags of one sensor): a run that never stops would look
    still to itself. ``again``: this call's own result on the same samples and windows, whose
    window statistics are judged again (with other floors, veto or rate) instead of recomputed.
    """
    t, g = np.asarray(t, dtype=np.float64), np.asarray(gyro, dtype=np.float64)
    n = t.shape[0]
    if t.ndim != 1 or g.shape != (n, 3):
        raise ValueError(f'Expected `t` of shape (N,) and `gyro` of shape (N, 3), got '
                         f'{t.shape} and {g.shape}.')
    acc = np.asarray(accel, dtype=np.float64) if has_accelerometer(accel) else None
    if acc is not None and acc.shape != (n, 3):
        raise ValueError(f'Expected `accel` of shape {(n, 3)}, got {acc.shape}.')
    stats = again.stats if again is not None and again.mask.shape == (n,) else ()
    dt = stats[0] if stats else float(np.median(np.diff(t))) if n > 1 else 1.0
    window = (auto_window(t, dt) if window_s is None else
              max(float(window_s), MIN_WINDOW_SAMPLES * dt))
    if stats and (again.window_s != window or (stats[-1] is None) != (acc is None)):
        stats = ()                    # other windows or sensors: its statistics do not apply
    if n < 3:
        e, z, inf = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.full(3, math.inf)
        za, infa = (None, None) if acc is None else (z, inf)
        return Stillness(np.zeros(n, dtype=bool), (), window, e, e, np.zeros(0, dtype='<U10'),
                         z, z, za, za, inf, infa, np.zeros(0), inf, infa,
                         'too few samples to judge stillness')
    _, starts, counts, finite, bad, g_mean, g_std, a_mean, a_std = stats = stats or (
        dt, *_windows(t, g, acc, window))
    vetoed = (np.zeros(starts.size, dtype=bool) if moving is None else
              np.logical_or.reduceat(np.asarray(moving, dtype=bool), starts))
    may = (counts >= MIN_JUDGED) & ~bad & ~vetoed      # windows that may be still
    g_floor = noise_floor(g_std, may) if gyro_floor is None else np.asarray(gyro_floor, float)
    a_floor = (None if a_std is None else noise_floor(a_std, may) if accel_floor is None
               else np.asarray(accel_floor, float))
    g_thr, a_thr = noise_thresholds(g_floor, a_floor, gyro_std=gyro_std, accel_std=accel_std)
    r = None if rate is None else np.asarray(rate, dtype=np.float64)
    mean_rate = None if r is None else window_moments(r, starts, counts)[0]
    why = judge_windows(g_std, a_std, g_thr, a_thr, mean_rate=mean_rate, max_rate=max_rate,
                        moving=vetoed, counts=counts, finite=~bad)
    segments, durations = _still_stretches(t, g, starts, why, dt, window, min_still_s)
    mask = np.repeat(why == '', counts) & finite      # the rows of the kept stretches
    reason = '' if segments else _no_still_reason(why, min_still_s)
    return Stillness(mask, tuple(segments), window, starts, counts, why, g_mean, g_std, a_mean,
                     a_std, g_thr, None if acc is None else a_thr, np.asarray(durations),
                     g_floor, a_floor, reason, stats)
