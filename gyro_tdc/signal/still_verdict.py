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
The still test proper: its constants, noise floor, thresholds, window verdict, motion veto.

Shared by the batch form (:mod:`gyro_tdc.signal.still_batch`) and the streaming one
(:mod:`gyro_tdc.signal.still_stream`). See doc/internals/signal.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['auto_window', 'has_accelerometer', 'judge_windows', 'MAX_RATE', 'MAX_STILL_SE',
           'MIN_STILL_S', 'MIN_STILL_SAMPLES', 'MIN_WINDOW_SAMPLES', 'MOTION_EPS',
           'motion_veto', 'NOISE_DOF', 'NOISE_FACTOR', 'NOISE_WINDOWS', 'noise_floor',
           'noise_thresholds', 'REASONS', 'SHORT_WINDOW_S', 'STILL_WINDOW_S', 'windows_moving']

#: Default window, s: the shortest still stretch judged (and the re-anchoring window).
STILL_WINDOW_S = 10.0
#: Auto thresholds: this many times the noise floor (the quietest window's std).
NOISE_FACTOR = 4.0
#: Streaming: windows seen before the noise floor alone sets the auto gyro threshold.
NOISE_WINDOWS = 3
#: Fewest samples per window (the window grows at low rates).
MIN_WINDOW_SAMPLES = 20
#: Streaming: the noise floor is the variance pooled over consecutive windows of at least this
#: many degrees of freedom (one window at 10 Hz and up, six 10 s windows at 1 Hz), so it does
#: not sink with the sample count or the length of the stream.
NOISE_DOF = 2 * MIN_WINDOW_SAMPLES
#: Largest mean compensated rate of a still window, rad/s (a session-to-session offset).
MAX_RATE = 0.02
#: Default shortest still stretch kept by :func:`detect_still`, s.
MIN_STILL_S = 60.0
#: Auto still test (``min_still_s=None``): a shorter stretch is kept when it holds at least
#: this many samples ...
MIN_STILL_SAMPLES = 250
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


def auto_window(t: ArrayLike) -> float:
    """
    Return the trainers' auto still window for stamps ``t``, s (:data:`SHORT_WINDOW_S`).

    Short at high rates (a 15 s still stretch between flights holds whole windows), at least
    :data:`MIN_WINDOW_SAMPLES` sample periods, and never longer than :data:`STILL_WINDOW_S`
    unless the rate asks for it.
    """
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


def windows_moving(t_start: ArrayLike, t_end: ArrayLike, motion_t: ArrayLike,
                   moving: ArrayLike) -> NDArray[np.bool_]:
    """
    Return which windows overlap a moving interval of the motion reports.

    A report at stamp ``t`` holds from ``t`` until the next report. Before the first report
    nothing is vetoed (the streaming form: a stream without a motion input is judged by the
    noise test alone); at a report's stamp the held state is that of :func:`motion_veto`.

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
