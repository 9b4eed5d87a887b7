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
Re-anchoring: average the compensated rate over still windows until its mean is precise.

:class:`StillnessDetector` (the compensator's start-up re-anchoring) stacks the block-means
standard error on the windows of the one streaming still test
(:class:`gyro_tdc.signal.StillWindows`); :func:`reanchor_shift` is the rule on a whole run
(``evaluate --reanchor auto``). :func:`gated_shift` keeps, per axis, the shift the model's
training found worth taking (:data:`REANCHOR_KEY`). See doc/internals/signal.md.

A window of two samples or more ends at a pause (a step longer than the window between two
samples): at the end of a burst, without the next burst's first sample. A bursty stream (one
that has paused) may hold bursts shorter than the window, and a logger that powers its IMU
per burst makes each burst a session of its own, which a window never spans. On such a
stream a window also ends early, at a block boundary once it holds :data:`EARLY_BLOCKS`
whole blocks and :data:`~gyro_tdc.signal.MIN_WINDOW_SAMPLES` samples, when the shift
averaged so far (the run with the window's blocks) is within the tolerance: the window is
judged still or not on those samples, and a still one gives the anchor (``'precision'``). A
continuous stream never pauses: its windows, and its anchors, are the span windows alone.
"""

from __future__ import annotations

from array import array
from dataclasses import replace
import math
from typing import NamedTuple, Sequence

from gyro_tdc.runtime.blockstats import (Anchor, block_length, block_sums, BlockStats,
                                         default_tolerance, early_allowed, EARLY_BLOCKS,
                                         max_windows, Shift, standard_error, stats_of,
                                         STILL_WINDOW_MAX_S, Vec3, window_stats)
from gyro_tdc.signal import MIN_WINDOW_SAMPLES, STILL_WINDOW_S, StillWindows, Window
import numpy as np
from numpy.typing import NDArray

__all__ = ['gated_shift', 'PROVISIONAL', 'REANCHOR_KEY', 'reanchor_shift', 'shift_gate',
           'StillnessDetector']

#: A still run resumed after a pause keeps its windows before it only where their mean and
#: the first window's after it agree within this many combined standard errors on every axis
#: (else the bias moved in the pause: a board warming after a cold start).
PAUSE_AGREE = 4.0
#: The reason of a still run's shift so far (:attr:`StillnessDetector.provisional`), whose
#: axes within :data:`PROVISIONAL_Z` standard errors of zero are zeroed.
PROVISIONAL = 'provisional'
PROVISIONAL_Z = 3.0
#: The ``model.metrics`` key of the trainer's re-anchoring decision
#: (:func:`gyro_tdc.identify.power_cycles.reanchor_rule`): ``min_shift_dps`` per axis.
REANCHOR_KEY = 'reanchor'


def shift_gate(model) -> NDArray[np.float64]:
    """
    Return the smallest start-up shift the node takes per axis, rad/s (0: any).

    The model's training decision (``metrics[REANCHOR_KEY]['min_shift_dps']``); zeros for a
    model without it (a learned model, a fitted one not from ``train``) or with a bad one.
    """
    rec = None if model is None else model.metrics.get(REANCHOR_KEY)
    try:
        gate = np.radians(np.asarray(rec['min_shift_dps'], dtype=np.float64).reshape(3))
    except (KeyError, TypeError, ValueError):
        return np.zeros(3)
    return np.where(gate >= 0.0, gate, 0.0)          # NaN: any shift


def gated_shift(model, delta: Sequence[float]) -> NDArray[np.float64]:
    """Return the start-up shift ``delta`` (rad/s) with the axes below the model's gate zeroed."""
    d = np.asarray(delta, dtype=np.float64).reshape(3)
    return np.where(np.abs(d) > shift_gate(model), d, 0.0)


def _window_end(t: NDArray[np.float64], i0: int, window: float) -> tuple[int, int]:
    """
    Return the last sample of the window starting at ``i0`` and the one that ends it (-1: none).

    The span rule (its first sample ``window`` after ``t[i0]``, included), but a window of two
    samples or more ends before a pause (a step longer than ``window``): without the next
    burst's first sample.
    """
    if not (later := np.flatnonzero(t[i0 + 1:] - t[i0] >= window)).size:
        return -1, -1
    i1 = i0 + 1 + int(later[0])
    return (i1 - 1 if i1 - i0 >= 2 and t[i1] - t[i1 - 1] > window else i1), i1


def _early_end(t: NDArray[np.float64], x: NDArray[np.float64], i0: int, i1: int,
               c: Sequence[float], block_s: float, total: BlockStats,
               tol: Sequence[float]) -> tuple[int, BlockStats] | None:
    """
    Return the first sample a window from ``i0`` leaves out when it ends early, and the stats.

    The window's samples are ``i0 .. i1 - 1`` (``i1``: the sample that ends it, or the end of
    the data); at each block boundary after :data:`EARLY_BLOCKS` whole blocks and
    MIN_WINDOW_SAMPLES samples, ``total`` with those blocks is tested against ``tol``.
    None: it never is precise early.
    """
    if (tt := t[i0:i1]).size < 2:
        return None
    starts, sums, counts = block_sums(tt, x[i0:i1], c, block_s, float(tt[0]))
    if starts.size <= EARLY_BLOCKS:
        return None
    # Running sums over the blocks of what BlockStats sums: s, a, b; n and c2.
    cums = [np.cumsum(a, axis=0) for a in (sums, sums ** 2, sums * counts[:, None])]
    cn, cc = np.cumsum(counts), np.cumsum(counts ** 2)
    for m in range(EARLY_BLOCKS, starts.size):      # the m whole blocks before starts[m]
        if cn[m - 1] < MIN_WINDOW_SAMPLES:
            continue
        st = total + BlockStats(int(cn[m - 1]), m, *(tuple(c[m - 1].tolist()) for c in cums),
                                float(cc[m - 1]))
        if all(v <= w for v, w in zip(standard_error(st), tol)):
            return i0 + int(starts[m]), st
    return None


def reanchor_shift(t: NDArray[np.float64], x: NDArray[np.float64], *,
                   tolerance: Sequence[float], window: float = STILL_WINDOW_S,
                   window_max: float = STILL_WINDOW_MAX_S, paused: bool = False) -> Shift:
    """
    Average the head of a run until the shift is known to ``tolerance`` (the node's rule).

    The windows, blocks, standard error and stopping rule of :class:`StillnessDetector`,
    applied from the first sample without a stillness test (the run is taken as still at
    its start, as ``evaluate --reanchor auto`` does), the early end of a bursty stream's
    window included (from the first step longer than ``window`` on, or from the start with
    ``paused``), and its pause rule (:data:`PAUSE_AGREE`, on the whole window after it).

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
    paused : bool
        The stream paused before the run (the streaming form remembers a pause over
        sessions: a logger that powers its IMU per burst).

    Returns
    -------
    Shift
        Mean, its SE, samples, duration and why it stopped (``'precision'``,
        ``'longest'``, or ``'end of data'`` when the run ends first: every complete window,
        or every sample of a run shorter than one window).

    """
    t, x = np.asarray(t, dtype=np.float64), np.asarray(x, dtype=np.float64)
    if t.ndim != 1 or x.shape != (t.size, 3) or t.size == 0:
        raise ValueError(f'Expected `t` of shape (N,) and `x` of shape (N, 3) with N >= 1, '
                         f'got {t.shape} and {x.shape}.')
    tol = tuple(float(v) for v in tolerance)
    bs = block_length(window)
    c = tuple(x[0].tolist())
    total, first_pause = BlockStats(), t.size      # no early end before the first pause
    if early_allowed(tol, window, window_max):
        long = np.flatnonzero(np.diff(t) > window)
        first_pause = 0 if paused else (int(long[0]) + 1 if long.size else t.size)
    i0, last, reason, start = 0, -1, 'end of data', 0
    for _ in range(max_windows(window, window_max)):
        i1, ends = _window_end(t, i0, window) if i0 < t.size else (-1, -1)
        e = t.size if ends < 0 else ends
        run = total                       # after a pause the run goes on only where it agrees
        if 0 < i0 < t.size and t[i0] - t[i0 - 1] > window and total.n and not _agree(
                total, window_stats(t[i0:e], x[i0:e], c, bs)):
            run = BlockStats()            # with the window after it (once that is taken)
        if first_pause <= i0 < t.size:
            if (early := _early_end(t, x, i0, e, c, bs, run, tol)) is not None:
                (j, total), start = early, start if run is total else i0
                last, reason = j - 1, 'precision'
                break
        if i1 < 0:
            break
        total, start = (run + window_stats(t[i0:i1 + 1], x[i0:i1 + 1], c, bs),
                        start if run is total else i0)
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
    return Shift(delta, standard_error(total), total.n, float(t[last] - t[start]), reason)


def _agree(run: BlockStats, win: BlockStats) -> bool:
    """Return whether two means agree within PAUSE_AGREE combined standard errors."""
    return all(abs(a / run.n - b / win.n) <= PAUSE_AGREE * math.hypot(u, v)
               for a, b, u, v in zip(run.s, win.s, standard_error(run), standard_error(win)))


class _Window(NamedTuple):
    """One still window of the current run."""

    t_start: float
    stats: BlockStats
    gyro_std: Vec3
    accel_std: Vec3 | None


class StillnessDetector:
    """
    Decide from consecutive windows that the gyro is still, and average the shift precisely.

    The windows and their verdict are :class:`gyro_tdc.signal.StillWindows` (cut ``'span'``:
    a window ends with its first sample ``window`` after its first one); consecutive still
    windows make a run, whose block statistics of the compensated rate give the shift and
    its standard error. A window ends before a pause (a step longer than ``window`` between
    two samples given); once the stream has paused (remembered over :meth:`reset`: a new power
    cycle of a bursty logger), a window also ends early when precise (module docstring).

    Parameters
    ----------
    window : float, s
        Window length: the shortest averaging.
    gyro_std : float, rad/s
        Largest raw-rate standard deviation per axis over a window; 0: auto (from the
        stream's noise).
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
        self.window_max = self.window if window_max is None else float(window_max)
        self.fixed_tolerance = float(tolerance or 0.0)
        self.block_s = block_length(self.window)
        self.windows_rejected = 0
        self.tolerance = (self.fixed_tolerance if self.fixed_tolerance > 0 else math.inf,) * 3
        self.noise_prior: Vec3 | None = None
        #: The one streaming still test; re-anchoring windows hold at least two samples.
        self.still = StillWindows(self.window, cut='span', gyro_std=float(gyro_std), min_samples=2,
                                  accel_std=float(accel_std), max_rate=float(max_rate))
        #: The stream has paused (kept over :meth:`reset`) ...
        self.paused = False
        #: ... judged from the stamp of the last sample given (None after an anchor: the
        #: samples that follow are not given until the next reset).
        self._t_last: float | None = None
        self.reset()

    @property
    def default_rule(self) -> bool:
        """Return whether the anchors are the trainer's (default windows, auto tolerance)."""
        return (self.fixed_tolerance <= 0 and self.window == STILL_WINDOW_S
                and self.window_max == STILL_WINDOW_MAX_S)

    def observe_motion(self, t: float, moving: bool) -> None:
        """
        Record a motion report: from stamp ``t`` until the next report, moving or not.

        A window that overlaps a moving interval is not still; :meth:`reset` keeps the
        reports (they are of the vehicle, not of the model).

        Parameters
        ----------
        t : float, s
            Stamp of the report (``cmd_vel``/odometry message).
        moving : bool
            Whether it reports motion.

        """
        self.still.observe_motion(t, moving)

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
        self.still.reset(prior_std=self.noise_prior)
        self._run: list[_Window] = []
        #: The run's shift so far, until its anchor (None: no still run, or no axis off).
        self.provisional: Anchor | None = None
        self._c: Vec3 = (0.0, 0.0, 0.0)
        self._resumed = False              # the next window judged follows a pause
        self._early = early_allowed(self.tolerance, self.window, self.window_max)
        self._end_window()

    def _end_window(self) -> None:
        """Forget the early-end sums of the window in progress (the next sample starts one)."""
        self._w0: float | None = None      # first stamp of the window in progress
        self._n = 0                        # its samples
        self._track = False                # its block sums are kept (the stream has paused)
        self._next_block = math.inf        # stamp from which the next block may start
        self._block = 0                    # index of the block in progress
        self._rows = array('d')            # its stamps and compensated rates (4 a sample)
        self._done = 0                     # samples summed into whole blocks ...
        self._part = BlockStats()          # ... their statistics, around the run's centre

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
        last, self._t_last = self._t_last, t
        found = None
        if last is not None and t - last > self.window:    # a pause
            self.paused = True
            if self._n >= 2:               # the window ends before it (the burst's end)
                found = self._flush()
            self._resumed = True           # the next window judged follows the pause
        if t >= self._next_block:          # a block boundary of a tracked window
            found = self._boundary(t)
        if self._w0 is None:               # a window starts (with a new run, its centre)
            self._w0 = t
            if not self._run:
                self._c = (float(out[0]), float(out[1]), float(out[2]))
            self._track = self.paused and self._early
            self._next_block = t + self.block_s * (1.0 - 1e-9) if self._track else math.inf
        self._n += 1
        if self._track:
            self._rows.extend((t, out[0], out[1], out[2]))
        if (w := self.still.add(t, raw, accel, rate=out, temp_c=temp_c)) is not None:
            self._end_window()
            found = self._judge(w)
        if found is not None:
            self._t_last = None
        return found

    def _boundary(self, t: float) -> Anchor | None:
        """
        Start a block at the sample ``t`` (not yet added); end the window early when precise.

        The window ends here (the samples before ``t``) when it holds EARLY_BLOCKS whole
        blocks and MIN_WINDOW_SAMPLES samples, ``t`` would not end it anyway, and the run with
        its whole blocks is within the tolerance; it is then judged as any window. The whole
        blocks are summed when a test is due (every sample before ``t`` is in one).
        """
        w0, bs = self._w0, self.block_s
        if (k := math.floor((t - w0) / bs)) == self._block:
            return None                    # the rounding of the boundary's estimate
        self._block = k
        self._next_block = w0 + ((k + 1) * bs) * (1.0 - 1e-9)
        n = len(self._rows) // 4
        if n < MIN_WINDOW_SAMPLES or k < EARLY_BLOCKS or t - w0 >= self.window:
            return None
        if n > self._done:             # the whole blocks not yet summed
            new = np.frombuffer(self._rows, dtype=np.float64).reshape(-1, 4)[self._done:n]
            self._part += stats_of(*block_sums(new[:, 0], new[:, 1:], self._c, bs, w0)[1:])
            self._done = n
        if self._part.m < EARLY_BLOCKS:
            return None
        total = sum((r.stats for r in self._run), self._part)
        precise = all(s <= v for s, v in zip(standard_error(total), self.tolerance))
        return self._flush() if precise else None

    def _flush(self) -> Anchor | None:
        """End the window in progress here and judge it."""
        w = self.still.flush()
        self._end_window()
        return None if w is None else self._judge(w)

    def _judge(self, w: Window) -> Anchor | None:
        """Extend, drop or finish the run with the window that just ended."""
        if not self._run:                 # a run starts: its centring constant
            self._c = tuple(w.rate[0].tolist())
        self.provisional = None
        resumed, self._resumed = self._resumed, False     # this window follows a pause
        if w.why:
            self.windows_rejected += 1
            run, self._run = self._run, []
            # Motion ends a still run before the tolerance was met: its mean is the best this
            # stop gives (a flight log's stops last seconds), as reanchor_shift takes a run
            # that ends first; with no still window yet there is nothing to take.
            return (self._anchor(run, sum((r.stats for r in run), BlockStats()), w.t0,
                                 float(w.temp[0]), 'motion') if run else None)
        run = self._run
        stats = window_stats(w.t, w.rate, self._c, self.block_s)
        if resumed and run and not _agree(sum((r.stats for r in run), BlockStats()), stats):
            del run[:]                    # the bias moved in the pause: start again here
        run.append(_Window(w.t0, stats, w.gyro_std, w.accel_std))
        if (j := self.still.last_refused(run, w.thresholds)[0]) >= 0:
            del run[:j + 1]
            self.windows_rejected += 1
        total = sum((r.stats for r in run), BlockStats())
        if j < 0 and all(s <= v for s, v in zip(standard_error(total), self.tolerance)):
            reason = 'precision'
        elif j < 0 and len(run) >= max_windows(self.window, self.window_max):
            reason = 'longest'
        else:                             # a refused window, or the run goes on
            # The run's shift so far (PROVISIONAL): the axes beyond PROVISIONAL_Z standard
            # errors, none when no axis is (or the run is empty).
            if run:
                a = self._anchor(run, total, w.t1, float(w.temp[-1]), PROVISIONAL)
                delta = tuple(d if abs(d) > PROVISIONAL_Z * e else 0.0
                              for d, e in zip(a.delta, a.se))
                self.provisional = replace(a, delta=delta) if any(delta) else None
            return None
        if len(run) == 1 and self.window_max <= self.window:
            reason = ''
        self._run = []
        return self._anchor(run, total, w.t1, float(w.temp[-1]), reason)

    def _anchor(self, run: list[_Window], total: BlockStats, t_end: float, temp_c: float,
                reason: str) -> Anchor:
        """Return the anchor of the still windows ``run`` (``total`` their block statistics)."""
        delta = tuple(ci + si / total.n for ci, si in zip(self._c, total.s))
        g_rms = tuple(math.sqrt(sum(r.gyro_std[i] ** 2 for r in run) / len(run)) for i in range(3))
        return Anchor(t_end, delta, total.n, g_rms, temp_c, t_end - run[0].t_start,
                      standard_error(total), self.tolerance, reason)
