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
Stillness and re-anchoring: is the IMU still, and how precisely is the offset shift known.

Pure (numpy only); the one home of the stillness test and of the re-anchoring rule, used by
the compensator's start-up re-anchoring (:class:`StillnessDetector`, fed one sample at a
time by :class:`gyro_tdc.runtime.core.CompensatorCore`) and by ``evaluate --reanchor
auto`` (:func:`reanchor_shift`, on a whole run).

**Windows.** Samples are cut into consecutive windows: a window ends at the first sample at
least ``window`` seconds after its first one. The stillness test judges whole windows: the
raw rate's per-axis standard deviation, the mean compensated rate (the shift, at most
``max_rate``) and, when there is one, the acceleration's standard deviation.

**Thresholds from the stream's own noise.** The still test itself (statistic, thresholds,
verdict) is :mod:`gyro_tdc.signal`, the one home the trainer and the accelerometer part use
too; this detector is its streaming form: it keeps the window sums and the running noise
floor and asks :func:`gyro_tdc.signal.noise_thresholds` and
:func:`gyro_tdc.signal.judge_windows` for the verdict. ``gyro_std`` and ``accel_std`` of 0
(the default) mean *auto*: the threshold is :data:`NOISE_FACTOR` times the noise floor, the
smallest window standard deviation seen so far (per axis: the quietest window), so the test
scales with the sensor and the sample rate (1 Hz to 2 kHz) without tuning. Until
:data:`NOISE_WINDOWS` windows have been seen the gyro threshold is also held below
:data:`NOISE_FACTOR` times the model's residual standard deviation (the prior the
compensator passes with :meth:`StillnessDetector.reset`), so a first window that moves is
not taken as the floor. When the floor drops, windows of the current run above the new
threshold are dropped with everything before them. A slow constant turn has no spread: the
shift bound ``max_rate`` (a plausible session-to-session bias offset, not a noise figure)
and the accelerometer reject it. A positive ``gyro_std``/``accel_std`` is a fixed override.

**Precision-driven re-anchoring.** Once a window is still, averaging goes on over the
following still windows until the standard error (SE) of the mean shift is at most the
tolerance on every axis, or :func:`max_windows` windows (``window_max`` seconds) have been
averaged. The SE comes from the scatter of block means (:func:`standard_error`): each window
is cut into blocks of :func:`block_length` (``window / 50``, at most 1 s), and
``SE^2 = m / (m - 1) * sum_k n_k^2 (mean_k - mean)^2 / N^2`` over the ``m`` blocks of ``n_k``
samples (``N`` in all): one sample per block at 1 Hz gives the usual ``s / sqrt(N)``; at
2 kHz a block holds hundreds of samples, so noise correlated over less than a block (an
oversampled, low-passed stream) still gives an honest SE. The default tolerance is
:func:`default_tolerance`: :data:`TOLERANCE_FRACTION` (0.1) of the model's residual standard
deviation per axis, at least :data:`TOLERANCE_FLOOR` (1e-5 rad/s, 2 deg/h): the anchor is
then ten times more precise than the model's own scatter, and as the SE of a mean over time
does not depend on the sample rate, a 1 Hz and a 1 kHz stream of one sensor stop at the
same precision. Motion before the tolerance is met drops the run (an imprecise anchor can
add more noise than the offset it removes); re-anchoring waits for the next still period.

**Motion veto.** A vehicle turning slowly at a constant rate has no spread and an
accelerometer that may not see it: its windows pass the noise test (false stillness). An
outside motion report (``cmd_vel``, odometry) vetoes them: :meth:`StillnessDetector.
observe_motion` (and :meth:`gyro_tdc.learn.learner.Learner.observe_motion`) take ``(t, moving)``;
a report holds from its stamp until the next one, and a window that overlaps a moving
interval is not still (:func:`windows_moving`; at a report's stamp the held state is that
of :func:`gyro_tdc.signal.motion_veto`, the trainer's batch form). Until the first report
the veto is off and the noise test alone decides (a stream with no motion input behaves as
before; a node with a motion topic sees its first report within a window of starting).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import NamedTuple, Sequence

from gyro_tdc.signal import (judge_windows, motion_veto, NOISE_FACTOR, noise_thresholds,
                             NOISE_WINDOWS, STILL_WINDOW_S)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['Anchor', 'BLOCKS_PER_WINDOW', 'BlockStats', 'MAX_BLOCK_S', 'NOISE_FACTOR',
           'NOISE_WINDOWS', 'STILL_WINDOW_MAX_S', 'STILL_WINDOW_S', 'Shift',
           'StillnessDetector', 'TOLERANCE_FLOOR', 'TOLERANCE_FRACTION', 'Vec3',
           'block_length', 'default_tolerance', 'max_windows', 'reanchor_shift',
           'standard_error', 'window_stats', 'windows_moving']

Vec3 = tuple[float, float, float]

# STILL_WINDOW_S (the default shortest averaging, the stillness window), NOISE_FACTOR and
# NOISE_WINDOWS come from gyro_tdc.signal, the home of the still test.
#: Default longest averaging, s.
STILL_WINDOW_MAX_S = 600.0
#: Blocks per window in the block-means standard error ...
BLOCKS_PER_WINDOW = 50
#: ... each at most this long, s.
MAX_BLOCK_S = 1.0
#: Default tolerance: this fraction of the model's residual standard deviation ...
TOLERANCE_FRACTION = 0.1
#: ... and at least this, rad/s.
TOLERANCE_FLOOR = 1e-5

_INF3 = (math.inf, math.inf, math.inf)


@dataclass(frozen=True)
class Anchor:
    """
    The result of re-anchoring: the offset shift that zeroes the compensated rate.

    Parameters
    ----------
    t : float, s
        Stamp of the last sample averaged.
    delta : tuple of 3 float, rad/s
        Shift added to the model's drift.
    samples : int
        Samples averaged.
    gyro_std : tuple of 3 float, rad/s
        Standard deviation of the raw rate within the still windows (RMS over them).
    temp_c : float, degC
        Temperature at the end.
    duration_s : float, s
        Stamp of the last sample averaged minus that of the first.
    se : tuple of 3 float, rad/s
        Standard error of ``delta`` (block means; see the module docstring).
    tolerance : tuple of 3 float, rad/s
        The tolerance the SE was held to.
    reason : str
        ``'precision'`` (SE within the tolerance), ``'longest'`` (``window_max`` reached)
        or ``'end of data'`` (:func:`reanchor_shift` only); ``''`` for a single window.

    """

    t: float
    delta: Vec3
    samples: int
    gyro_std: Vec3
    temp_c: float
    duration_s: float = 0.0
    se: Vec3 = _INF3
    tolerance: Vec3 = _INF3
    reason: str = ''


class BlockStats(NamedTuple):
    """
    Sums over blocks of ``x - c`` (``c`` a constant of the run) for the block-means SE.

    ``n`` samples, ``m`` non-empty blocks, ``s`` the sum, ``a`` the sum of squared block
    sums, ``b`` the sum of block sums times block counts (per axis), ``c2`` the sum of
    squared block counts. Window statistics add up.
    """

    n: int = 0
    m: int = 0
    s: Vec3 = (0.0, 0.0, 0.0)
    a: Vec3 = (0.0, 0.0, 0.0)
    b: Vec3 = (0.0, 0.0, 0.0)
    c2: float = 0.0

    def __add__(self, other: object) -> 'BlockStats':
        """Return the statistics of two sets of blocks together."""
        if not isinstance(other, BlockStats):
            return NotImplemented
        return BlockStats(self.n + other.n, self.m + other.m,
                          tuple(u + v for u, v in zip(self.s, other.s)),
                          tuple(u + v for u, v in zip(self.a, other.a)),
                          tuple(u + v for u, v in zip(self.b, other.b)),
                          self.c2 + other.c2)


class Shift(NamedTuple):
    """What :func:`reanchor_shift` found: the mean and its precision over the head of a run."""

    delta: Vec3
    se: Vec3
    samples: int
    duration_s: float
    reason: str


def block_length(window: float) -> float:
    """Return the block length (s) of the block-means SE for a stillness window (s)."""
    return min(MAX_BLOCK_S, float(window) / BLOCKS_PER_WINDOW)


def max_windows(window: float, window_max: float) -> int:
    """Return how many windows the averaging may hold: ``window_max / window``, at least 1."""
    return max(1, int(float(window_max) / float(window) + 1e-9))


def default_tolerance(residual_var: Sequence[float]) -> Vec3:
    """
    Return the default re-anchoring tolerance from a model's residual variance.

    Parameters
    ----------
    residual_var : sequence of 3 float, (rad/s)^2
        The model's residual variance per axis.

    Returns
    -------
    tuple of 3 float, rad/s
        ``max(TOLERANCE_FRACTION * sqrt(residual_var), TOLERANCE_FLOOR)`` per axis.

    """
    return tuple(max(TOLERANCE_FRACTION * math.sqrt(max(float(v), 0.0)), TOLERANCE_FLOOR)
                 for v in residual_var)


def standard_error(st: BlockStats) -> Vec3:
    """
    Return the standard error of the mean from block statistics (inf below two blocks).

    ``SE^2 = m / (m - 1) * sum_k (S_k - n_k mu)^2 / N^2`` with ``mu = S / N``, expanded
    over the running sums so a stream needs no block history.
    """
    if st.m < 2 or st.n == 0:
        return _INF3
    n = float(st.n)
    k = st.m / (st.m - 1.0)
    out = []
    for s, a, b in zip(st.s, st.a, st.b):
        mu = s / n
        out.append(math.sqrt(max(k * (a - 2.0 * mu * b + mu * mu * st.c2), 0.0)) / n)
    return tuple(out)


def window_stats(t: NDArray[np.float64], x: NDArray[np.float64], c: Sequence[float],
                 block_s: float) -> BlockStats:
    """
    Return the block statistics of one window (batch form of the streaming sums).

    Parameters
    ----------
    t : NDArray[np.float64], shape (N,), s
        Stamps of the window's samples (blocks start at ``t[0]``).
    x : NDArray[np.float64], shape (N, 3)
        The values averaged (the compensated rate, or its error).
    c : sequence of 3 float
        The run's centring constant.
    block_s : float, s
        Block length.

    """
    t = np.asarray(t, dtype=np.float64)
    if t.size == 0:
        return BlockStats()
    k = np.floor((t - t[0]) / block_s)
    starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
    sums = np.add.reduceat(np.asarray(x, dtype=np.float64) - np.asarray(c), starts, axis=0)
    counts = np.diff(np.append(starts, t.size)).astype(np.float64)
    return BlockStats(int(t.size), int(starts.size), tuple(sums.sum(axis=0).tolist()),
                      tuple((sums ** 2).sum(axis=0).tolist()),
                      tuple((sums * counts[:, None]).sum(axis=0).tolist()),
                      float((counts ** 2).sum()))


def _window_end(t: NDArray[np.float64], i0: int, window: float) -> int:
    """Return the index of the last sample of the window starting at ``i0`` (-1: none)."""
    later = np.flatnonzero(t[i0 + 1:] - t[i0] >= window)
    return i0 + 1 + int(later[0]) if later.size else -1


def reanchor_shift(t: NDArray[np.float64], x: NDArray[np.float64], *,
                   tolerance: Sequence[float], window: float = STILL_WINDOW_S,
                   window_max: float = STILL_WINDOW_MAX_S) -> Shift:
    """
    Average the head of a run until the shift is known to ``tolerance`` (the node's rule).

    The windows, blocks, standard error and stopping rule of :class:`StillnessDetector`,
    applied from the first sample without a stillness test (the run is taken as still at
    its start, as ``evaluate --reanchor`` does).

    Parameters
    ----------
    t : NDArray[np.float64], shape (N,), s
        Increasing stamps.
    x : NDArray[np.float64], shape (N, 3)
        Values to average (e.g. compensated minus reference rate), rad/s.
    tolerance : sequence of 3 float, rad/s
        Largest standard error of the mean, per axis.
    window, window_max : float, s
        Shortest and longest averaging.

    Returns
    -------
    Shift
        Mean, its SE, samples, duration and why it stopped (``'precision'``,
        ``'longest'``, or ``'end of data'`` when the run ends first: every complete window,
        or every sample of a run shorter than one window).

    """
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if t.ndim != 1 or x.shape != (t.size, 3) or t.size == 0:
        raise ValueError(f'Expected `t` of shape (N,) and `x` of shape (N, 3) with N >= 1, '
                         f'got {t.shape} and {x.shape}.')
    tol = tuple(float(v) for v in tolerance)
    bs = block_length(window)
    c = tuple(x[0].tolist())
    total = BlockStats()
    i0, last, reason = 0, -1, 'end of data'
    for _ in range(max_windows(window, window_max)):
        i1 = _window_end(t, i0, window) if i0 < t.size else -1
        if i1 < 0:
            break
        total = total + window_stats(t[i0:i1 + 1], x[i0:i1 + 1], c, bs)
        last, i0 = i1, i1 + 1
        if all(s <= v for s, v in zip(standard_error(total), tol)):
            reason = 'precision'
            break
    else:
        reason = 'longest'
    if last < 0:                      # shorter than one window: all of it
        last = t.size - 1
        total = window_stats(t, x, c, bs)
    delta = tuple(ci + si / total.n for ci, si in zip(c, total.s))
    return Shift(delta, standard_error(total), total.n, float(t[last] - t[0]), reason)


def windows_moving(t_start: ArrayLike, t_end: ArrayLike, motion_t: ArrayLike,
                   moving: ArrayLike) -> NDArray[np.bool_]:
    """
    Return which windows overlap a moving interval of the motion reports.

    A report at stamp ``t`` holds from ``t`` until the next report. Before the first report
    nothing is vetoed (see the module docstring).

    Parameters
    ----------
    t_start, t_end : ArrayLike, shape (W,), s
        First and last stamp of each window.
    motion_t : ArrayLike, shape (M,), s
        Report stamps, increasing.
    moving : ArrayLike, shape (M,) of bool
        Per report, whether it says the vehicle moves.

    Returns
    -------
    NDArray[np.bool_], shape (W,)
        True where the report held at ``t_start`` or any report within
        ``(t_start, t_end]`` says motion.

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


class _Window(NamedTuple):
    """One still window of the current run."""

    t_start: float
    t_end: float
    stats: BlockStats
    gyro_std: Vec3
    accel_std: Vec3 | None
    temp_c: float


class StillnessDetector:
    """
    Decide from consecutive windows that the gyro is still, and average the shift precisely.

    Parameters
    ----------
    window : float, s
        Window length: the shortest averaging.
    gyro_std : float, rad/s
        Largest raw-rate standard deviation per axis over a window; 0: auto (from the
        stream's noise, see the module docstring).
    max_rate : float, rad/s
        Largest mean compensated rate over a window (the largest shift).
    accel_std : float, m/s^2
        Largest acceleration standard deviation over a window; 0: auto.
    window_max : float, s, optional
        Longest averaging (default ``window``: one window, no precision target).
    tolerance : float, rad/s, optional
        Largest SE of the shift on every axis; None or 0: :func:`default_tolerance` of the
        residual variance given to :meth:`reset` (a single window when none was given).

    """

    def __init__(self, window: float, gyro_std: float = 0.0, max_rate: float = 0.02,
                 accel_std: float = 0.0, *, window_max: float | None = None,
                 tolerance: float | None = None) -> None:
        self.window = float(window)
        self.gyro_std = float(gyro_std)
        self.max_rate = float(max_rate)
        self.accel_std = float(accel_std)
        self.window_max = self.window if window_max is None else float(window_max)
        self.fixed_tolerance = float(tolerance or 0.0)
        self.block_s = block_length(self.window)
        self.windows_rejected = 0
        self.tolerance: Vec3 = ((self.fixed_tolerance,) * 3 if self.fixed_tolerance > 0
                                else _INF3)
        self.noise_prior: Vec3 | None = None
        #: Motion reports (stamp, moving) from the one held at the window in progress on.
        self.motion: list[tuple[float, bool]] = []
        self.reset()

    def observe_motion(self, t: float, moving: bool) -> None:
        """
        Record a motion report: from stamp ``t`` until the next report, moving or not.

        A window that overlaps a moving interval is not still (the module docstring);
        :meth:`reset` keeps the reports (they are of the vehicle, not of the model).

        Parameters
        ----------
        t : float, s
            Stamp of the report (``cmd_vel``/odometry message).
        moving : bool
            Whether it reports motion.

        """
        t = float(t)
        if not math.isfinite(t):
            return
        rep = (t, bool(moving))
        if not self.motion or t >= self.motion[-1][0]:
            self.motion.append(rep)
        else:                                   # out of order: keep the list sorted
            self.motion.append(rep)
            self.motion.sort(key=lambda r: r[0])

    def _moving(self, t_start: float, t_end: float) -> bool:
        """Return whether the window overlaps motion; forget reports before its end."""
        mo = self.motion
        if not mo:
            return False
        moving = bool(windows_moving([t_start], [t_end], [r[0] for r in mo],
                                     [r[1] for r in mo])[0])
        held = 0
        while held + 1 < len(mo) and mo[held + 1][0] <= t_end:
            held += 1
        del mo[:held]                           # keep the report held at the next window
        return moving

    def reset(self, *, residual_var: Sequence[float] | None = None) -> None:
        """
        Start over with the next sample (noise floor included).

        Parameters
        ----------
        residual_var : sequence of 3 float, (rad/s)^2, optional
            The model's residual variance: the default tolerance and the prior of the auto
            gyro threshold (kept when None).

        """
        if residual_var is not None:
            self.noise_prior = tuple(math.sqrt(max(float(v), 0.0)) for v in residual_var)
            if self.fixed_tolerance <= 0:
                self.tolerance = default_tolerance(residual_var)
        self.noise_gyro = [math.inf] * 3
        self.noise_accel = [math.inf] * 3
        self.windows_seen = 0
        self._run: list[_Window] = []
        self._c: Vec3 = (0.0, 0.0, 0.0)
        self._start()

    def _start(self) -> None:
        """Start a new window with the next sample."""
        self._t0: float | None = None
        self._n = 0
        self._g = [[0.0, 0.0] for _ in range(3)]     # Welford mean, M2 of the raw rate
        self._a = [[0.0, 0.0] for _ in range(3)]     # ... of the acceleration
        self._accel = True
        self._k = None                               # current block, its count and sums
        self._bn = 0
        self._bs = [0.0, 0.0, 0.0]
        self._st = [0, 0, [0.0] * 3, [0.0] * 3, [0.0] * 3, 0.0]   # n m s a b c2

    def _fold(self) -> None:
        """Add the current block to the window's sums."""
        if not self._bn:
            return
        st, n = self._st, self._bn
        st[0] += n
        st[1] += 1
        for i, v in enumerate(self._bs):
            st[2][i] += v
            st[3][i] += v * v
            st[4][i] += v * n
        st[5] += float(n * n)

    def update(self, t: float, raw: Sequence[float], out: Sequence[float],
               accel: Sequence[float] | None, temp_c: float) -> Anchor | None:
        """
        Add one clean sample; return an :class:`Anchor` when the shift is known well enough.

        Parameters
        ----------
        t : float, s
            Stamp.
        raw, out : sequence of 3 float, rad/s
            Raw and compensated rate.
        accel : sequence of 3 float, m/s^2, or None
            Acceleration when the IMU has an accelerometer.
        temp_c : float, degC
            Temperature used for the sample.

        Returns
        -------
        Anchor or None
            The anchor when the averaging just ended, else None.

        """
        if self._t0 is None:
            self._t0 = t
            if not self._run:
                self._c = (float(out[0]), float(out[1]), float(out[2]))
        self._n += 1
        n = self._n
        for w, v in zip(self._g, raw):
            d = v - w[0]
            w[0] += d / n
            w[1] += d * (v - w[0])
        if accel is None:
            self._accel = False
        else:
            for w, v in zip(self._a, accel):
                d = v - w[0]
                w[0] += d / n
                w[1] += d * (v - w[0])
        k = math.floor((t - self._t0) / self.block_s)
        if k != self._k:
            self._fold()
            self._k, self._bn, self._bs = k, 0, [0.0, 0.0, 0.0]
        self._bn += 1
        bs, c = self._bs, self._c
        bs[0] += out[0] - c[0]
        bs[1] += out[1] - c[1]
        bs[2] += out[2] - c[2]
        if t - self._t0 < self.window or n < 2:
            return None
        self._fold()
        return self._judge(t, temp_c)

    def _thresholds(self) -> tuple[list[float], list[float]]:
        """Return the gyro and accelerometer thresholds in force (fixed or auto)."""
        early = self.windows_seen < NOISE_WINDOWS
        g, a = noise_thresholds(self.noise_gyro, self.noise_accel, gyro_std=self.gyro_std,
                                accel_std=self.accel_std,
                                prior_std=self.noise_prior if early else None)
        return g.tolist(), a.tolist()

    def _judge(self, t: float, temp_c: float) -> Anchor | None:
        """Judge the window that just ended; extend, drop or finish the run."""
        n = self._n
        st = self._st
        stats = BlockStats(st[0], st[1], tuple(st[2]), tuple(st[3]), tuple(st[4]), st[5])
        g_std = tuple(math.sqrt(w[1] / (n - 1)) for w in self._g)
        a_std = tuple(math.sqrt(w[1] / (n - 1)) for w in self._a) if self._accel else None
        mean_out = [ci + si / st[0] for ci, si in zip(self._c, st[2])]
        t_start = self._t0
        self._start()
        self.windows_seen += 1
        for i, v in enumerate(g_std):
            if v > 0:
                self.noise_gyro[i] = min(self.noise_gyro[i], v)
        if a_std is not None:
            for i, v in enumerate(a_std):
                if v > 0:
                    self.noise_accel[i] = min(self.noise_accel[i], v)
        g_thr, a_thr = self._thresholds()
        if self._moving(t_start, t):
            self.windows_rejected += 1
            self._run = []          # the vehicle reports motion: not still, start over
            return None

        def quiet(g: Vec3, a: Vec3 | None) -> bool:
            return judge_windows([g], None if a is None else [a], g_thr, a_thr)[0] == ''

        if judge_windows([g_std], None if a_std is None else [a_std], g_thr, a_thr,
                         mean_rate=[mean_out], max_rate=self.max_rate)[0]:
            self.windows_rejected += 1
            self._run = []          # motion before the tolerance was met: start over
            return None
        run = self._run
        run.append(_Window(t_start, t, stats, g_std, a_std, float(temp_c)))
        # A lower floor may show earlier windows of the run as moving: keep what follows.
        for j in range(len(run) - 1, -1, -1):
            if not quiet(run[j].gyro_std, run[j].accel_std):
                del run[:j + 1]
                self.windows_rejected += 1
                return None
        total = BlockStats()
        for w in run:
            total = total + w.stats
        se = standard_error(total)
        if all(s <= v for s, v in zip(se, self.tolerance)):
            reason = 'precision'
        elif len(run) >= max_windows(self.window, self.window_max):
            reason = 'longest'
        else:
            return None
        if len(run) == 1 and self.window_max <= self.window:
            reason = ''
        delta = tuple(ci + si / total.n for ci, si in zip(self._c, total.s))
        g_rms = tuple(math.sqrt(sum(w.gyro_std[i] ** 2 for w in run) / len(run))
                      for i in range(3))
        anchor = Anchor(t, delta, total.n, g_rms, float(temp_c), t - run[0].t_start, se,
                        self.tolerance, reason)
        self._run = []
        return anchor
