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
Still detection: the one test of whether an IMU is still, batch and streaming.

Pure (numpy only). Every part of the package that needs still data calls this module: the
trainer (``train --still-only``, :mod:`gyro_tdc.field_training`), the accelerometer part's
still windows (:func:`gyro_tdc.accel.static_data`) and the compensator's re-anchoring
(:class:`gyro_tdc.stillness.StillnessDetector`: it keeps its own window sums, for the
re-anchoring's block-means standard error, and asks :func:`noise_thresholds` and
:func:`judge_windows` for the verdict). :func:`detect_still` is the batch form;
:class:`StreamingStill` the streaming one, one sample at a time, returning each still
stretch (:class:`StillSegment`: its mean rate and temperature) as it ends, equal to the
batch form on the same samples once the noise floor is known.

**The test.** Samples are cut into windows of ``window_s`` (at least
:data:`MIN_WINDOW_SAMPLES` sample periods). A window is still when

* its raw rate's per-axis standard deviation is at most the gyro threshold, and, when the
  IMU has an accelerometer (:func:`has_accelerometer`), its acceleration's per-axis standard
  deviation is at most the accelerometer threshold: the scatter stays within what the
  sensor's own noise explains. *Auto* thresholds (the default) are :data:`NOISE_FACTOR`
  times the noise floor, the smallest window standard deviation per axis over the windows
  that may be still (the batch form: the whole run; the streaming form: so far), so the
  test scales with the sensor and the sample rate without tuning; a positive ``gyro_std``
  or ``accel_std`` is a fixed override;
* no sample of it is vetoed by a motion report (``moving``: a ``cmd_vel`` Twist or an
  Odometry stream held onto the IMU stamps by :func:`motion_veto`, or a non-zero rate-table
  reference): still only while the vehicle reports zero motion;
* with a prior (``rate``: the rate compensated by a model, minus any reference), its mean
  is at most ``max_rate`` per axis;
* and it belongs to a stretch of consecutive still windows lasting ``min_still_s`` or
  more.

**What rejects a slow constant turn.** A turn at a constant 0.5-5 deg/s has no more
scatter than rest. Without a motion topic it is rejected only by (1) the mean-rate test
when a prior is known and the turn exceeds ``max_rate`` (the compensator always has its
model), (2) the accelerometer, when the rotation has a horizontal component: gravity then
turns in the sensor frame (0.5 deg/s turns it 5 degrees in a 10 s window, hundreds of times
the accelerometer's noise), (3) the vibration that comes with driving, and (4) in the
trainer, after the fit: a still stretch whose mean rate departs from the bias-vs-temperature
curve of the others is dropped as an outlier (:mod:`gyro_tdc.field_training`). A perfectly
smooth constant turn about the vertical, with no accelerometer change, no vibration, no
prior and no motion topic, cannot be told from a bias: the ``motion`` veto exists for that.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['MAX_RATE', 'MIN_STILL_S', 'MIN_WINDOW_SAMPLES', 'MOTION_EPS', 'NOISE_FACTOR',
           'NOISE_WINDOWS', 'REASONS', 'STILL_WINDOW_S', 'StillSegment', 'Stillness',
           'StreamingStill', 'detect_still', 'has_accelerometer', 'judge_windows',
           'motion_veto', 'noise_floor', 'noise_thresholds']

#: Default window, s: the shortest still stretch judged (and the re-anchoring window).
STILL_WINDOW_S = 10.0
#: Auto thresholds: this many times the noise floor (the quietest window's std).
NOISE_FACTOR = 4.0
#: Streaming: windows seen before the noise floor alone sets the auto gyro threshold.
NOISE_WINDOWS = 3
#: Fewest samples per window (the window grows at low rates).
MIN_WINDOW_SAMPLES = 20
#: Largest mean compensated rate of a still window, rad/s (a session-to-session offset).
MAX_RATE = 0.02
#: Default shortest still stretch kept by :func:`detect_still`, s.
MIN_STILL_S = 60.0
#: A motion report above this (m/s or rad/s, any component) is motion.
MOTION_EPS = 1e-6

#: Why a window is not still (``''`` when it is), in the order they are checked.
REASONS = ('samples', 'non-finite', 'motion', 'gyro', 'accel', 'rate', 'brief')


def has_accelerometer(accel: ArrayLike | None) -> bool:
    """
    Return True when ``accel`` holds accelerometer data (not None, not all zero or NaN).

    A driver without an accelerometer publishes zeros with
    ``linear_acceleration_covariance[0] = -1`` (REP 145).
    """
    if accel is None:
        return False
    a = np.asarray(accel, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] == 0:
        return False
    # In chunks, stopping at the first finite non-zero row: a real accelerometer answers at
    # once, without a pass (and copies) over a long run.
    step = 1 << 16
    for i in range(0, a.shape[0], step):
        c = a[i:i + step]
        if np.any(np.isfinite(c).all(axis=1) & (c != 0.0).any(axis=1)):
            return True
    return False


def noise_floor(std: ArrayLike, ok: ArrayLike | None = None) -> NDArray[np.float64]:
    """
    Return the noise floor: the smallest positive window standard deviation per axis.

    Parameters
    ----------
    std : ArrayLike, shape (W, 3)
        Per-window standard deviations.
    ok : ArrayLike of bool, shape (W,), optional
        Windows that may be still (default all).

    Returns
    -------
    NDArray[np.float64], shape (3,)
        The floor per axis, inf where no window qualifies.

    """
    s = np.asarray(std, dtype=np.float64).reshape(-1, 3)
    use = np.ones(s.shape[0], dtype=bool) if ok is None else np.asarray(ok, dtype=bool)
    out = np.full(3, math.inf)
    for a in range(3):
        v = s[use, a]
        v = v[np.isfinite(v) & (v > 0.0)]
        if v.size:
            out[a] = float(v.min())
    return out


def noise_thresholds(gyro_floor: ArrayLike, accel_floor: ArrayLike | None = None, *,
                     gyro_std: float = 0.0, accel_std: float = 0.0,
                     prior_std: ArrayLike | None = None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the gyro and accelerometer thresholds in force, fixed or auto.

    Parameters
    ----------
    gyro_floor, accel_floor : ArrayLike, shape (3,)
        Noise floors (:func:`noise_floor`; inf: none yet).
    gyro_std, accel_std : float
        Fixed thresholds, rad/s and m/s^2; 0: auto, :data:`NOISE_FACTOR` times the floor.
    prior_std : ArrayLike, shape (3,), rad/s, optional
        A prior of the gyro's scatter (the model's residual standard deviation): the auto
        gyro threshold is held below :data:`NOISE_FACTOR` times it (the streaming form, over
        its first :data:`NOISE_WINDOWS` windows, so a first window that moves is not taken as
        the floor).

    Returns
    -------
    gyro, accel : NDArray[np.float64], shape (3,)
        Thresholds per axis (inf: nothing known yet).

    """
    if gyro_std > 0:
        g = np.full(3, float(gyro_std))
    else:
        g = NOISE_FACTOR * np.asarray(gyro_floor, dtype=np.float64)
        if prior_std is not None:
            g = np.minimum(g, NOISE_FACTOR * np.asarray(prior_std, dtype=np.float64))
    if accel_std > 0:
        a = np.full(3, float(accel_std))
    elif accel_floor is None:
        a = np.full(3, math.inf)
    else:
        a = NOISE_FACTOR * np.asarray(accel_floor, dtype=np.float64)
    return g, a


def judge_windows(gyro_std: ArrayLike, accel_std: ArrayLike | None, gyro_thr: ArrayLike,
                  accel_thr: ArrayLike, *, mean_rate: ArrayLike | None = None,
                  max_rate: float = MAX_RATE, moving: ArrayLike | None = None
                  ) -> NDArray[np.str_]:
    """
    Judge windows: the still test proper (one home for the batch and streaming forms).

    Parameters
    ----------
    gyro_std : ArrayLike, shape (W, 3), rad/s
        Raw-rate standard deviation per window.
    accel_std : ArrayLike, shape (W, 3), m/s^2, or None
        Acceleration standard deviation per window (None: no accelerometer).
    gyro_thr, accel_thr : ArrayLike, shape (3,)
        Thresholds (:func:`noise_thresholds`).
    mean_rate : ArrayLike, shape (W, 3), rad/s, optional
        Mean compensated rate per window (with a prior); at most ``max_rate`` when given.
    max_rate : float, rad/s
        Largest mean compensated rate.
    moving : ArrayLike of bool, shape (W,), optional
        Windows a motion report vetoes.

    Returns
    -------
    NDArray[np.str_], shape (W,)
        ``''`` for a still window, else the first failed test: ``'motion'``, ``'gyro'``,
        ``'accel'`` or ``'rate'``.

    """
    g = np.asarray(gyro_std, dtype=np.float64).reshape(-1, 3)
    w = g.shape[0]
    why = np.full(w, '', dtype='<U10')
    checks = []
    if moving is not None:
        checks.append(('motion', np.asarray(moving, dtype=bool).reshape(w)))
    checks.append(('gyro', ~np.all(g <= np.asarray(gyro_thr), axis=1)))
    if accel_std is not None:
        a = np.asarray(accel_std, dtype=np.float64).reshape(-1, 3)
        checks.append(('accel', ~np.all(a <= np.asarray(accel_thr), axis=1)))
    if mean_rate is not None:
        m = np.asarray(mean_rate, dtype=np.float64).reshape(-1, 3)
        checks.append(('rate', ~np.all(np.abs(m) <= max_rate, axis=1)))
    for name, bad in reversed(checks):      # the first failed test wins
        why[bad] = name
    return why


def motion_veto(t: ArrayLike, motion_t: ArrayLike, moving: ArrayLike) -> NDArray[np.bool_]:
    """
    Hold motion reports onto the IMU stamps: True where the latest report says motion.

    Parameters
    ----------
    t : ArrayLike, shape (N,), s
        IMU stamps.
    motion_t : ArrayLike, shape (M,), s
        Stamps of the motion reports (``cmd_vel``, odometry), any order.
    moving : ArrayLike, shape (M,) of bool, or (M, K) of float
        Per report, motion (bool) or its components (m/s, rad/s: motion when any exceeds
        :data:`MOTION_EPS` in magnitude).

    Returns
    -------
    NDArray[np.bool_], shape (N,)
        Vetoed samples: the latest report at or before the stamp reports motion, or there is
        no report yet (still only while the stream reports zero motion).

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


def _window_stats(x: NDArray[np.float64], starts: NDArray[np.int64],
                  counts: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return per-window means and standard deviations (W, 3) of ``x`` (ddof 1)."""
    c = x[0]
    d = x - c
    s = np.add.reduceat(d, starts, axis=0)
    q = np.add.reduceat(np.multiply(d, d, out=d), starts, axis=0)   # d is ours: square it
    n = counts[:, None]
    mean = s / n
    with np.errstate(invalid='ignore', divide='ignore'):
        var = np.maximum(q - s * mean, 0.0) / (n - 1.0)
    return mean + c, np.sqrt(var)


def detect_still(t: ArrayLike, gyro: ArrayLike, accel: ArrayLike | None = None, *,
                 rate: ArrayLike | None = None, moving: ArrayLike | None = None,
                 window_s: float = STILL_WINDOW_S, min_still_s: float = MIN_STILL_S,
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
    min_still_s : float, s
        Shortest stretch of consecutive still windows kept (0 keeps every still window).
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
    k = np.floor((t - t[0]) / window).astype(np.int64)
    starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
    counts = np.diff(np.append(starts, n))
    fc = counts.astype(np.float64)
    finite = np.isfinite(g).all(axis=1)
    if acc is not None:
        finite &= np.isfinite(acc).all(axis=1)
    bad = np.add.reduceat((~finite).astype(np.int64), starts) > 0
    all_finite = bool(finite.all())     # then no zeroed copy of the (long) inputs
    g_mean, g_std = _window_stats(g if all_finite else np.where(finite[:, None], g, 0.0),
                                  starts, fc)
    a_mean = a_std = None
    if acc is not None:
        a_mean, a_std = _window_stats(
            acc if all_finite else np.where(finite[:, None], acc, 0.0), starts, fc)
    usable = (counts >= max(3, MIN_WINDOW_SAMPLES // 2)) & ~bad
    vetoed = (np.zeros(starts.size, dtype=bool) if moving is None else
              np.add.reduceat(np.asarray(moving, dtype=bool).astype(np.int64), starts) > 0)
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
    # Stretches of consecutive still windows; the short ones are dropped.
    still_w = why == ''
    ends = np.append(starts[1:], n)
    edges = np.diff(np.concatenate([[0], still_w.astype(np.int8), [0]]))
    first_w, stop_w = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    segments, durations = [], []
    for a, b in zip(first_w.tolist(), stop_w.tolist()):
        i0, i1 = int(starts[a]), int(ends[b - 1])
        dur = float(t[i1 - 1] - t[i0]) + dt
        if dur + 1e-9 < min_still_s:
            why[a:b] = 'brief'
            continue
        segments.append((i0, i1))
        durations.append(dur)
    mask = np.zeros(n, dtype=bool)
    for i0, i1 in segments:
        mask[i0:i1] = True
    mask &= finite
    reason = ''
    if not segments:
        rej = {r: int(np.count_nonzero(why == r)) for r in REASONS if np.any(why == r)}
        if rej.get('motion', 0) == starts.size:
            reason = 'every window is vetoed by a motion report'
        elif rej.get('brief'):
            reason = (f'no still stretch of {min_still_s:g} s or more (the longest still '
                      'stretch is shorter)')
        else:
            reason = 'no still window (the IMU moves)'
    return Stillness(mask, tuple(segments), window, starts, counts, why, g_mean, g_std, a_mean,
                     a_std, g_thr, None if acc is None else a_thr, np.asarray(durations),
                     g_floor, a_floor, reason)


@dataclass(frozen=True)
class StillSegment:
    """
    One finished still stretch of a stream (:class:`StreamingStill`).

    Parameters
    ----------
    t0_s, t1_s : float, s
        First and last stamp.
    samples : int
        Samples in it.
    gyro_mean : tuple of 3 float, rad/s
        Mean raw rate (the bias while still).
    gyro_std : tuple of 3 float, rad/s
        Standard deviation of the raw rate around its window means (RMS over the windows).
    rate_mean : tuple of 3 float, rad/s, or None
        Mean of the ``rate`` given (e.g. the compensated rate), None when none was.
    temp_c : float, degC
        Mean of the ``temp_c`` given (e.g. the model temperature); NaN when none was.

    """

    t0_s: float
    t1_s: float
    samples: int
    gyro_mean: tuple
    gyro_std: tuple
    rate_mean: tuple | None
    temp_c: float

    @property
    def duration_s(self) -> float:
        """Return the span of the stamps, s."""
        return self.t1_s - self.t0_s


class StreamingStill:
    """
    The still test one sample at a time: still stretches as they end (the streaming form).

    Windows are cut on the grid ``floor((t - t_first) / window_s)`` as in
    :func:`detect_still` (a window is judged when the first sample of the next one arrives;
    set ``window_s`` to at least :data:`MIN_WINDOW_SAMPLES` sample periods, the batch form
    lengthens it itself); the verdict is :func:`judge_windows` with :func:`noise_thresholds`
    of the running noise floor (the quietest window so far that a motion report did not
    veto), held below the prior over the first :data:`NOISE_WINDOWS` windows when one is
    given; when the floor drops, the windows of the current stretch that the new thresholds
    refuse are dropped with everything before them. Consecutive still windows make a
    stretch; it is returned by :meth:`update` when the first window that is not still ends
    it, if it lasted ``min_still_s``. With fixed
    thresholds the stretches are exactly those of :func:`detect_still` on the same samples;
    with auto thresholds they match once the floor is known (the batch form knows it from
    the start).

    Parameters
    ----------
    window_s : float, s
        Window length.
    min_still_s : float, s
        Shortest stretch returned.
    gyro_std, accel_std : float
        Fixed thresholds, rad/s and m/s^2; 0: auto.
    max_rate : float, rad/s
        Largest mean of the ``rate`` given over a still window.
    prior_std : sequence of 3 float, rad/s, optional
        Prior of the gyro's scatter (a model's residual standard deviation).

    """

    def __init__(self, window_s: float = STILL_WINDOW_S, *, min_still_s: float = MIN_STILL_S,
                 gyro_std: float = 0.0, accel_std: float = 0.0, max_rate: float = MAX_RATE,
                 prior_std: ArrayLike | None = None) -> None:
        if not (math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f'Expected `window_s` > 0, got {window_s!r}.')
        self.window_s = float(window_s)
        self.min_still_s = float(min_still_s)
        self.gyro_std, self.accel_std, self.max_rate = float(gyro_std), float(accel_std), \
            float(max_rate)
        self.prior_std = None if prior_std is None else np.asarray(prior_std, float).reshape(3)
        self.reset()

    def reset(self) -> None:
        """Forget everything (noise floor included); the next sample starts the grid."""
        self.gyro_floor = np.full(3, math.inf)
        self.accel_floor = np.full(3, math.inf)
        self.windows_seen = 0
        self.rejected = {r: 0 for r in REASONS}
        self.last_why: str | None = None
        self._t_first: float | None = None
        self._k: int | None = None
        self._stretch: list[tuple] = []
        self._w: dict | None = None

    def _new(self, t: float, raw: ArrayLike, accel: ArrayLike | None,
             rate: ArrayLike | None) -> dict:
        """Return the sums of a window starting at this sample."""
        return {'t0': t, 't1': t, 'n': 0, 'cg': [float(v) for v in raw], 'sg': [0.0] * 3,
                'qg': [0.0] * 3,
                'ca': None if accel is None else [float(v) for v in accel],
                'sa': [0.0] * 3, 'qa': [0.0] * 3,
                'cr': None if rate is None else [float(v) for v in rate], 'sr': [0.0] * 3,
                'temp': 0.0, 'nt': 0, 'moving': False}

    def update(self, t: float, raw: ArrayLike, accel: ArrayLike | None = None, *,
               rate: ArrayLike | None = None, temp_c: float = math.nan,
               moving: bool = False) -> StillSegment | None:
        """
        Add one sample; return the still stretch it ended, if any.

        Parameters
        ----------
        t : float, s
            Stamp (increasing).
        raw : sequence of 3 float, rad/s
            Raw rate.
        accel : sequence of 3 float, m/s^2, optional
            Acceleration (an IMU with an accelerometer gives it with every sample).
        rate : sequence of 3 float, rad/s, optional
            The rate compensated by a prior: a still window's mean of it is at most
            ``max_rate``.
        temp_c : float, degC
            Temperature to average over the stretch (e.g. the model temperature).
        moving : bool
            A motion report vetoes this sample (:func:`motion_veto` of the latest report).

        Returns
        -------
        StillSegment or None
            The stretch that just ended (at least ``min_still_s``), else None.

        """
        if self._t_first is None:
            self._t_first = float(t)
        k = int(math.floor((t - self._t_first) / self.window_s))
        done = None
        if self._w is not None and k != self._k:
            done = self._judge()
        if self._w is None:
            self._w = self._new(t, raw, accel, rate)
            self._k = k
        w = self._w
        w['t1'] = t
        w['n'] += 1
        c, sg, qg = w['cg'], w['sg'], w['qg']
        x, y, z = raw[0] - c[0], raw[1] - c[1], raw[2] - c[2]
        sg[0] += x
        sg[1] += y
        sg[2] += z
        qg[0] += x * x
        qg[1] += y * y
        qg[2] += z * z
        if accel is not None and w['ca'] is not None:
            c, sa, qa = w['ca'], w['sa'], w['qa']
            x, y, z = accel[0] - c[0], accel[1] - c[1], accel[2] - c[2]
            sa[0] += x
            sa[1] += y
            sa[2] += z
            qa[0] += x * x
            qa[1] += y * y
            qa[2] += z * z
        if rate is not None and w['cr'] is not None:
            c, sr = w['cr'], w['sr']
            sr[0] += rate[0] - c[0]
            sr[1] += rate[1] - c[1]
            sr[2] += rate[2] - c[2]
        if temp_c == temp_c:              # not NaN
            w['temp'] += temp_c
            w['nt'] += 1
        if moving:
            w['moving'] = True
        return done

    def flush(self) -> StillSegment | None:
        """Judge the window in progress and return the stretch it ends (at shutdown)."""
        done = self._judge() if self._w is not None else None
        return done if done is not None else self._close()

    def _judge(self) -> StillSegment | None:
        """Judge the finished window; extend the stretch, or end it."""
        w, self._w = self._w, None
        n = w['n']
        finite = all(math.isfinite(v) for v in w['sg'] + w['qg'] + w['sa'] + w['qa'])
        mean = [c + s / n for c, s in zip(w['cg'], w['sg'])]
        std = [math.sqrt(max(q - s * s / n, 0.0) / (n - 1)) if n > 1 else math.nan
               for s, q in zip(w['sg'], w['qg'])]
        a_std = None
        if w['ca'] is not None and has_accelerometer([w['ca']]):
            a_std = [math.sqrt(max(q - s * s / n, 0.0) / (n - 1)) if n > 1 else math.nan
                     for s, q in zip(w['sa'], w['qa'])]
        self.windows_seen += 1
        if finite and not w['moving'] and n >= max(3, MIN_WINDOW_SAMPLES // 2):
            self.gyro_floor = np.minimum(self.gyro_floor, np.where(np.asarray(std) > 0,
                                                                   std, math.inf))
            if a_std is not None:
                self.accel_floor = np.minimum(self.accel_floor, np.where(
                    np.asarray(a_std) > 0, a_std, math.inf))
        early = self.windows_seen < NOISE_WINDOWS
        g_thr, a_thr = noise_thresholds(self.gyro_floor,
                                        None if a_std is None else self.accel_floor,
                                        gyro_std=self.gyro_std, accel_std=self.accel_std,
                                        prior_std=self.prior_std if early else None)
        rate_mean = (None if w['cr'] is None else
                     [c + s / n for c, s in zip(w['cr'], w['sr'])])
        why = str(judge_windows([std], None if a_std is None else [a_std], g_thr, a_thr,
                                mean_rate=None if rate_mean is None else [rate_mean],
                                max_rate=self.max_rate, moving=[w['moving']])[0])
        if not finite:
            why = 'non-finite'
        if n < max(3, MIN_WINDOW_SAMPLES // 2):
            why = 'samples'
        self.last_why = why
        if why:
            self.rejected[why] += 1
            return self._close()
        # A lower floor may show earlier windows of the stretch as moving: keep what follows.
        st = self._stretch
        for j in range(len(st) - 1, -1, -1):
            old = judge_windows([st[j][2]], None if st[j][4] is None else [st[j][4]], g_thr,
                                a_thr)[0]
            if old:
                self.rejected[str(old)] += j + 1
                del st[:j + 1]
                break
        st.append((w, mean, std, rate_mean, a_std))
        return None

    def _close(self) -> StillSegment | None:
        """End the current stretch; return it when long enough."""
        st, self._stretch = self._stretch, []
        if not st:
            return None
        t0, t1 = st[0][0]['t0'], st[-1][0]['t1']
        n = sum(w['n'] for w, *_ in st)
        period = (t1 - t0) / max(n - 1, 1)
        if t1 - t0 + period + 1e-9 < self.min_still_s:
            self.rejected['brief'] += len(st)
            return None
        g_mean = tuple(sum(m[i] * w['n'] for w, m, *_ in st) / n for i in range(3))
        g_std = tuple(math.sqrt(sum(s[i] ** 2 for _, _, s, *_ in st) / len(st))
                      for i in range(3))
        r_mean = None
        if all(x[3] is not None for x in st):
            r_mean = tuple(sum(x[3][i] * x[0]['n'] for x in st) / n for i in range(3))
        nt = sum(w['nt'] for w, *_ in st)
        temp = sum(w['temp'] for w, *_ in st) / nt if nt else math.nan
        return StillSegment(float(t0), float(t1), int(n), g_mean, g_std, r_mean, float(temp))
