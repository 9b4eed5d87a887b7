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
The batch form of the still test: :func:`detect_still` over a whole run.

The verdict is :mod:`gyro_tdc.signal.still_verdict`'s; the auto thresholds know the run's noise
floor from the start. See doc/internals/signal.md.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.signal.still_verdict import (has_accelerometer, judge_windows, MAX_RATE,
                                           MAX_STILL_SE, MIN_STILL_S, MIN_STILL_SAMPLES,
                                           MIN_WINDOW_SAMPLES, noise_floor, noise_thresholds,
                                           REASONS, STILL_WINDOW_S)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['detect_still', 'Stillness']


@dataclass(frozen=True, eq=False)
class Stillness:
    """
    The still samples of one run and how its windows were judged (:func:`detect_still`).

    Parameters
    ----------
    mask : NDArray[np.bool_], shape (N,)
        Still samples.
    segments : tuple of (int, int)
        Still stretches as half-open sample ranges ``(start, stop)``, in time order.
    window_s : float, s
        Window length used.
    starts, counts : NDArray[np.int64], shape (W,)
        First sample and number of samples of every window.
    why : NDArray[np.str_], shape (W,)
        ``''`` for a still window, else why not (one of :data:`REASONS`).
    gyro_mean, gyro_std : NDArray[np.float64], shape (W, 3), rad/s
        Raw-rate mean and standard deviation per window.
    accel_mean, accel_std : NDArray[np.float64], shape (W, 3), m/s^2, or None
        The acceleration's (None without an accelerometer).
    gyro_threshold : NDArray[np.float64], shape (3,), rad/s
        Gyro threshold applied.
    accel_threshold : NDArray[np.float64], shape (3,), m/s^2, or None
        Accelerometer threshold applied (None without an accelerometer).
    gyro_floor : NDArray[np.float64], shape (3,), rad/s
        The noise floor of the auto gyro threshold (the quietest window that may be still).
    accel_floor : NDArray[np.float64], shape (3,), m/s^2, or None
        The accelerometer's.
    durations_s : NDArray[np.float64], shape (S,), s
        Duration of every still stretch.
    reason : str
        Why no sample is still (empty when some are).

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
        return {r: int(np.count_nonzero(self.why == r)) for r in REASONS
                if np.any(self.why == r)}


#: Rows per pass of :func:`_window_stats` (its temporaries stay small: a few MB).
_CHUNK_ROWS = 1 << 17


def _window_stats(x: NDArray[np.float64], starts: NDArray[np.int64],
                  counts: NDArray[np.float64], finite: NDArray[np.bool_] | None = None
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return per-window means and standard deviations (W, 3) of ``x`` (ddof 1).

    Rows where ``finite`` is False count as zeros. The sums run over whole windows in
    passes of about :data:`_CHUNK_ROWS` rows, each window's in the same order as one pass
    over all rows would (so the same numbers), without a full-length temporary.
    """
    n = x.shape[0]
    c = x[0] if finite is None or finite[0] else np.zeros(x.shape[1])
    w = starts.size
    s = np.empty((w, x.shape[1]))
    q = np.empty((w, x.shape[1]))
    ends = np.append(starts[1:], n)
    zero = 0.0 - c                       # a zeroed row, centred
    buf = np.empty((min(n, max(_CHUNK_ROWS, int(counts.max()))), x.shape[1]))
    i = 0
    while i < w:
        j = max(i + 1, int(np.searchsorted(ends, starts[i] + _CHUNK_ROWS, side='right')))
        a, b = int(starts[i]), int(ends[j - 1])
        d = np.subtract(x[a:b], c, out=buf[:b - a])
        if finite is not None:
            d[~finite[a:b]] = zero
        loc = starts[i:j] - a
        s[i:j] = np.add.reduceat(d, loc, axis=0)
        q[i:j] = np.add.reduceat(np.multiply(d, d, out=d), loc, axis=0)
        i = j
    n = counts[:, None]
    mean = s / n
    with np.errstate(invalid='ignore', divide='ignore'):
        var = np.maximum(q - s * mean, 0.0) / (n - 1.0)
    return mean + c, np.sqrt(var)


def _long_enough(g: NDArray[np.float64], duration: float, min_still_s: float | None) -> bool:
    """Return whether a still stretch (its raw rate, its duration in s) is kept."""
    if min_still_s is not None:
        return duration + 1e-9 >= min_still_s
    if duration + 1e-9 >= MIN_STILL_S:
        return True
    n = g.shape[0]
    if n < MIN_STILL_SAMPLES:
        return False
    se = np.nanstd(g, axis=0, ddof=1) / math.sqrt(n)
    return bool(np.all(se <= MAX_STILL_SE))


def _still_stretches(t: NDArray[np.float64], g: NDArray[np.float64],
                     starts: NDArray[np.int64], why: NDArray[np.str_], dt: float,
                     min_still_s: float | None) -> tuple[list, list]:
    """
    Return the kept stretches of consecutive still windows and their durations.

    A stretch is a half-open sample range ``(start, stop)``; its duration, s, spans its
    stamps plus one sample period ``dt``. The windows of a stretch too short to keep
    (:func:`_long_enough`) are marked ``'brief'`` in ``why``, in place.
    """
    n = t.shape[0]
    ends = np.append(starts[1:], n)
    edges = np.diff(np.concatenate([[0], (why == '').astype(np.int8), [0]]))
    first_w, stop_w = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    segments, durations = [], []
    for a, b in zip(first_w.tolist(), stop_w.tolist()):
        i0, i1 = int(starts[a]), int(ends[b - 1])
        dur = float(t[i1 - 1] - t[i0]) + dt
        if not _long_enough(g[i0:i1], dur, min_still_s):
            why[a:b] = 'brief'
            continue
        segments.append((i0, i1))
        durations.append(dur)
    return segments, durations


def _no_still_reason(why: NDArray[np.str_], min_still_s: float | None) -> str:
    """Return why a run has no still stretch, from the verdicts ``why`` of its windows."""
    rej = {r: int(np.count_nonzero(why == r)) for r in REASONS if np.any(why == r)}
    if rej.get('motion', 0) == why.size:
        return 'every window is vetoed by a motion report'
    if rej.get('brief'):
        return (f'no still stretch of {min_still_s:g} s or more (the longest still '
                'stretch is shorter)' if min_still_s is not None else
                f'no still stretch of {MIN_STILL_S:g} s or of {MIN_STILL_SAMPLES} '
                f'samples with a mean known to {MAX_STILL_SE * 180.0 / math.pi:g} deg/s '
                '(the still stretches are shorter or noisier)')
    return 'no still window (the IMU moves)'


def detect_still(t: ArrayLike, gyro: ArrayLike, accel: ArrayLike | None = None, *,
                 rate: ArrayLike | None = None, moving: ArrayLike | None = None,
                 window_s: float = STILL_WINDOW_S, min_still_s: float | None = MIN_STILL_S,
                 gyro_std: float = 0.0, accel_std: float = 0.0, max_rate: float = MAX_RATE,
                 gyro_floor: ArrayLike | None = None,
                 accel_floor: ArrayLike | None = None) -> Stillness:
    """
    Find the still samples of a run (the batch form of the still test; module docstring).

    Parameters
    ----------
    t : ArrayLike, shape (N,), s
        Increasing stamps.
    gyro : ArrayLike, shape (N, 3), rad/s
        Raw rate.
    accel : ArrayLike, shape (N, 3), m/s^2, optional
        Acceleration; ignored when it holds no data (:func:`has_accelerometer`).
    rate : ArrayLike, shape (N, 3), rad/s, optional
        The rate compensated by a prior (a model), minus any reference: a still window's mean
        of it is at most ``max_rate``.
    moving : ArrayLike of bool, shape (N,), optional
        Samples a motion report vetoes (:func:`motion_veto`, a non-zero reference).
    window_s : float, s
        Window length (at least :data:`MIN_WINDOW_SAMPLES` sample periods).
    min_still_s : float or None, s
        Shortest stretch of consecutive still windows kept (0 keeps every still window).
        None: judged by its samples and its noise -- a stretch of :data:`MIN_STILL_S` or
        more, or one of at least :data:`MIN_STILL_SAMPLES` samples whose mean rate has a
        standard error of at most :data:`MAX_STILL_SE` on every axis.
    gyro_std, accel_std : float
        Fixed thresholds, rad/s and m/s^2; 0: auto (:func:`noise_thresholds`).
    max_rate : float, rad/s
        Largest mean of ``rate`` over a still window.
    gyro_floor, accel_floor : ArrayLike, shape (3,), optional
        Noise floors to use with the auto thresholds instead of this run's own (e.g. the
        quietest window of several bags of one sensor, :attr:`Stillness.gyro_floor`): auto
        thresholds take the quietest window as the noise, so a run that never stops would
        look still to itself.

    Returns
    -------
    Stillness
        The still samples, stretches and the verdict of every window.

    """
    t = np.asarray(t, dtype=np.float64)
    g = np.asarray(gyro, dtype=np.float64)
    n = t.shape[0]
    if t.ndim != 1 or g.shape != (n, 3):
        raise ValueError(f'Expected `t` of shape (N,) and `gyro` of shape (N, 3), got '
                         f'{t.shape} and {g.shape}.')
    use_accel = has_accelerometer(accel)
    acc = np.asarray(accel, dtype=np.float64) if use_accel else None
    if acc is not None and acc.shape != (n, 3):
        raise ValueError(f'Expected `accel` of shape {(n, 3)}, got {acc.shape}.')
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    window = max(float(window_s), MIN_WINDOW_SAMPLES * dt)
    if n < 3:
        e = np.zeros(0, dtype=np.int64)
        z = np.zeros((0, 3))
        return Stillness(np.zeros(n, dtype=bool), (), window, e, e, np.zeros(0, dtype='<U10'),
                         z, z, None if acc is None else z, None if acc is None else z,
                         np.full(3, math.inf), None if acc is None else np.full(3, math.inf),
                         np.zeros(0), np.full(3, math.inf),
                         None if acc is None else np.full(3, math.inf),
                         'too few samples to judge stillness')
    k = np.subtract(t, t[0])           # window index floor((t - t0) / window), in place
    k /= window
    np.floor(k, out=k)
    edge = np.empty(n, dtype=bool)
    edge[0] = True
    np.not_equal(k[1:], k[:-1], out=edge[1:])
    starts = np.flatnonzero(edge)
    counts = np.diff(np.append(starts, n))
    fc = counts.astype(np.float64)
    f = np.isfinite(g)                  # rows: column by column (3x faster than all(axis=1))
    finite = f[:, 0] & f[:, 1] & f[:, 2]
    if acc is not None:
        f = np.isfinite(acc)
        finite &= f[:, 0] & f[:, 1] & f[:, 2]
    bad = np.logical_or.reduceat(~finite, starts)
    zeroed = None if finite.all() else finite      # non-finite rows count as zeros
    g_mean, g_std = _window_stats(g, starts, fc, zeroed)
    a_mean = a_std = None
    if acc is not None:
        a_mean, a_std = _window_stats(acc, starts, fc, zeroed)
    usable = (counts >= max(3, MIN_WINDOW_SAMPLES // 2)) & ~bad
    vetoed = (np.zeros(starts.size, dtype=bool) if moving is None else
              np.logical_or.reduceat(np.asarray(moving, dtype=bool), starts))
    may = usable & ~vetoed
    g_floor = noise_floor(g_std, may) if gyro_floor is None else np.asarray(gyro_floor, float)
    a_floor = None
    if a_std is not None:
        a_floor = (noise_floor(a_std, may) if accel_floor is None
                   else np.asarray(accel_floor, float))
    g_thr, a_thr = noise_thresholds(g_floor, a_floor, gyro_std=gyro_std, accel_std=accel_std)
    mean_rate = None
    if rate is not None:
        r = np.asarray(rate, dtype=np.float64)
        mean_rate, _ = _window_stats(np.where(np.isfinite(r), r, np.inf), starts, fc)
    why = judge_windows(g_std, a_std, g_thr, a_thr, mean_rate=mean_rate, max_rate=max_rate,
                        moving=vetoed)
    why[bad] = 'non-finite'
    why[counts < max(3, MIN_WINDOW_SAMPLES // 2)] = 'samples'
    segments, durations = _still_stretches(t, g, starts, why, dt, min_still_s)
    mask = np.zeros(n, dtype=bool)
    for i0, i1 in segments:
        mask[i0:i1] = True
    mask &= finite
    reason = '' if segments else _no_still_reason(why, min_still_s)
    return Stillness(mask, tuple(segments), window, starts, counts, why, g_mean, g_std, a_mean,
                     a_std, g_thr, None if acc is None else a_thr, np.asarray(durations),
                     g_floor, a_floor, reason)
