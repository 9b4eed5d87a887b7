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
Still data of one run: the still windows and the orientation segments of the accelerometer.

The orientation test of :mod:`gyro_tdc.identify` (see there); the still windows are those of
the one still test, :func:`gyro_tdc.signal.detect_still` (its window length, noise factor and
thresholds), with a non-zero reference rate as the motion veto.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.data import Run
from gyro_tdc.model import compensate, CompensationModel, DEFAULT_OUT_OF_RANGE
from gyro_tdc.signal import (detect_still, has_accelerometer, MAX_RATE, MIN_WINDOW_SAMPLES,
                             STILL_WINDOW_S)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['JUMP_SIGMAS', 'MAX_GAP_WINDOWS', 'MAX_RATE', 'MIN_JUMP_DEG', 'MIN_SEGMENT_S',
           'MIN_WINDOW_SAMPLES', 'OrientationChange', 'StaticData', 'has_accelerometer',
           'static_bs', 'static_data']

#: An orientation jump must exceed this many standard deviations of its noise ...
JUMP_SIGMAS = 8.0
#: ... and turn gravity by at least this much, deg (1.7 mg): smaller is not told from drift.
MIN_JUMP_DEG = 0.1
#: More non-still windows than this between two still ones start a new orientation segment.
MAX_GAP_WINDOWS = 6
#: Shortest orientation segment kept, s.
MIN_SEGMENT_S = 60.0
#: ``evaluate`` reports accelerometer figures for runs at least this still.
MIN_STATIC_FRACTION = 0.5
#: Trend of the specific force: median step over this many previous still windows.
_TREND_WINDOWS = 5


@dataclass(frozen=True)
class OrientationChange:
    """
    A jump of the gravity direction between two still windows of a run.

    Parameters
    ----------
    run : str
        The run (bag) it happened in.
    t_s : float, s
        Stamp of the first still sample after the change.
    angle_deg : float, deg
        Angle between the mean specific force before and after.
    before, after : NDArray[np.float64], shape (3,), m/s^2
        Mean specific force of the still windows on either side.

    """

    run: str
    t_s: float
    angle_deg: float
    before: NDArray[np.float64]
    after: NDArray[np.float64]

    def line(self) -> str:
        """Return the change as one report line."""
        return (f'orientation changed in {self.run} at t = {self.t_s:.1f} s by '
                f'{self.angle_deg:.3g} deg (gravity direction jump beyond noise): split '
                'there, each part its own offset (never fitted as drift)')

    def to_dict(self) -> dict:
        """Return the change as plain types."""
        return {'run': self.run, 't_s': float(self.t_s), 'angle_deg': float(self.angle_deg),
                'before_mps2': [float(v) for v in self.before],
                'after_mps2': [float(v) for v in self.after]}


@dataclass(frozen=True, eq=False)
class StaticData:
    """
    The still samples of one run, grouped by orientation.

    Parameters
    ----------
    run : str
        The run's name.
    mask : NDArray[np.bool_], shape (N,)
        Still samples (in a still window of a kept segment, finite acceleration).
    segment : NDArray[np.int64], shape (N,)
        Orientation segment of every still sample (0, 1, ...), -1 elsewhere.
    n_segments : int
        Number of segments.
    changes : tuple of OrientationChange
        The orientation changes found (each starts a segment).
    window_s : float, s
        Window length used.
    reason : str
        Why no sample is still (empty when some are).

    """

    run: str
    mask: NDArray[np.bool_]
    segment: NDArray[np.int64]
    n_segments: int
    changes: tuple
    window_s: float
    reason: str = ''

    @property
    def fraction(self) -> float:
        """Return the fraction of the run's samples that are still."""
        return float(self.mask.mean()) if self.mask.size else 0.0


def _angle_deg(u: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Return the angle between two vectors, deg."""
    nu, nv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    if nu == 0.0 or nv == 0.0:
        return 0.0
    c = float(np.dot(u, v)) / (nu * nv)
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def static_data(run: Run, *, model: CompensationModel | None = None,
                window_s: float = STILL_WINDOW_S, max_rate: float = MAX_RATE,
                min_segment_s: float = MIN_SEGMENT_S) -> StaticData | None:
    """
    Find the still samples of a run and split them at orientation changes.

    Parameters
    ----------
    run : Run
        A run with ``accel``.
    model : CompensationModel, optional
        A gyro model: a still window must also have a mean compensated rate (minus the
        reference) of at most ``max_rate`` (a slow constant turn has no spread).
    window_s : float, s
        Window length (at least :data:`MIN_WINDOW_SAMPLES` sample periods).
    max_rate : float, rad/s
        Largest mean compensated rate of a still window (with ``model``).
    min_segment_s : float, s
        Orientation segments shorter than this are dropped.

    Returns
    -------
    StaticData or None
        None when the run has no accelerometer data (:func:`has_accelerometer`).

    """
    acc = run.accel
    if not has_accelerometer(acc):
        return None
    acc = np.asarray(acc, dtype=np.float64)
    t = np.asarray(run.t, dtype=np.float64)
    n = len(run)
    empty = np.zeros(n, dtype=bool)
    moves = np.asarray(run.omega_ref) != 0.0      # rows column by column: 3x faster
    ref_moves = moves[:, 0] | moves[:, 1] | moves[:, 2]
    rate = None
    if model is not None:
        rate = compensate(model, t, run.temp, run.omega,
                          out_of_range=DEFAULT_OUT_OF_RANGE) - run.omega_ref
    # The one still test (gyro_tdc.signal): every still window counts, the orientation
    # segments below set the shortest stretch kept.
    st = detect_still(t, run.omega, acc, rate=rate, moving=ref_moves, window_s=window_s,
                      min_still_s=0.0, max_rate=max_rate)
    window = st.window_s
    if st.reason == 'too few samples to judge stillness':
        return StaticData(run.name, empty, np.full(n, -1), 0, (), window, st.reason)
    starts, counts = st.starts, st.counts.astype(np.float64)
    a_mean, a_std = st.accel_mean, st.accel_std
    finite = np.isfinite(acc)
    finite = finite[:, 0] & finite[:, 1] & finite[:, 2]
    still = st.still_windows
    if not np.any(still):
        usable = ~np.isin(st.why, ('samples', 'non-finite'))
        reason = ('the reference rate is not zero (a turning rate table is not static)'
                  if np.all((st.why == 'motion') | ~usable) else
                  'no still window (the IMU moves)')
        return StaticData(run.name, empty, np.full(n, -1), 0, (), window, reason)

    # Orientation segments over the still windows.
    seg_of = np.full(starts.size, -1, dtype=np.int64)
    changes: list[OrientationChange] = []
    seg = -1
    prev = -1
    steps: list[NDArray[np.float64]] = []
    var_mean = a_std ** 2 / counts[:, None]      # variance of each window's mean, per axis
    for j in np.flatnonzero(still).tolist():
        new = prev < 0 or j - prev - 1 > MAX_GAP_WINDOWS
        if not new:
            gap = j - prev
            trend = np.median(np.array(steps[-_TREND_WINDOWS:]), axis=0) if steps else 0.0
            e = a_mean[j] - (a_mean[prev] + gap * trend)
            se = math.sqrt(float(np.sum(var_mean[j] + var_mean[prev])))
            jump = float(np.linalg.norm(e)) > JUMP_SIGMAS * se
            angle = _angle_deg(a_mean[prev], a_mean[j]) if jump else 0.0
            if jump and angle >= MIN_JUMP_DEG:
                new = True
                changes.append(OrientationChange(run.name, float(t[starts[j]]), angle,
                                                 a_mean[prev].copy(), a_mean[j].copy()))
            elif gap == 1:
                steps.append(a_mean[j] - a_mean[prev])
        if new:
            seg += 1
            steps = []
        seg_of[j] = seg
        prev = j
    # Drop short segments, renumber the rest.
    ends = np.append(starts[1:], n)
    keep_ids = []
    for s in range(seg + 1):
        w = np.flatnonzero(seg_of == s)
        if t[ends[w[-1]] - 1] - t[starts[w[0]]] >= min_segment_s or seg == 0:
            keep_ids.append(s)
    remap = np.full(seg + 1, -1, dtype=np.int64)
    remap[keep_ids] = np.arange(len(keep_ids))
    seg_of = np.where(seg_of >= 0, remap[np.maximum(seg_of, 0)], -1)
    per_sample = np.repeat(seg_of, counts.astype(np.int64))
    mask = (per_sample >= 0) & finite
    per_sample = np.where(mask, per_sample, -1)
    reason = '' if mask.any() else 'no still stretch long enough'
    return StaticData(run.name, mask, per_sample, len(keep_ids), tuple(changes), window, reason)


def static_bs(accel: ArrayLike, data: StaticData) -> NDArray[np.float64] | None:
    """
    Return the accelerometer bias stability: the variance around the run mean, (m/s^2)^2.

    Over the still samples of ``data``; with several orientation segments, around each
    segment's own mean (pooled).

    Parameters
    ----------
    accel : ArrayLike, shape (N, 3), m/s^2
        Raw or compensated specific force of the run.
    data : StaticData
        Its still samples (:func:`static_data`).

    Returns
    -------
    NDArray[np.float64], shape (3,), (m/s^2)^2, or None
        Per axis; None without still samples.

    """
    m = data.mask
    if not np.any(m):
        return None
    a = np.asarray(accel, dtype=np.float64)[m]
    seg = data.segment[m]
    counts = np.bincount(seg, minlength=data.n_segments).astype(np.float64)
    means = np.zeros((data.n_segments, 3))
    np.add.at(means, seg, a)
    means /= np.maximum(counts, 1.0)[:, None]
    r = a - means[seg]
    return np.einsum('ij,ij->j', r, r) / float(a.shape[0])
