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
The accelerometer part of a model: its offset's change with temperature, as PX4 and ArduPilot.

A MEMS accelerometer's offset moves with the die temperature (1-5 mg per 10 degC on
consumer parts). The accelerometer part of a model (:attr:`gyro_tdc.model.
CompensationModel.accel`, model file section ``accel:``) holds that change per axis, in
m/s^2: the same effect library and the same thermal state as the gyro part (the
accelerometer sits on the same die), the same network form (``rbf`` or ``poly``), and
nothing else. It removes only the *change* relative to T0: the intercept is set so the
correction is zero at the reference point (the model temperature at T0, every dynamic term
settled), so the compensated specific force at T0 equals the raw one; the static offset and
the gravity direction belong to the ordinary accelerometer calibration.

**Static data only.** Gravity dominates the accelerometer, so its offset can be learnt only
while the IMU is still with a fixed orientation. :func:`static_data` cuts a run into windows
of :data:`gyro_tdc.stillness.STILL_WINDOW_S` (at least :data:`MIN_WINDOW_SAMPLES` samples)
and keeps the still ones, with the thresholds of the stillness detector
(:mod:`gyro_tdc.stillness`): the raw rate's and the acceleration's per-axis standard
deviation at most :data:`~gyro_tdc.stillness.NOISE_FACTOR` times the quietest window's, a
zero reference rate (a turning rate table is not static), and with a gyro model the mean
compensated rate at most ``max_rate``. In a thermal chamber the whole run is still.

**Orientation.** The orientation must stay fixed: between consecutive still windows the
mean specific force is compared with the local trend; a jump beyond :data:`JUMP_SIGMAS`
times its noise and :data:`MIN_JUMP_DEG` in direction is an orientation change. It is
reported (time, angle) and the run is split there: every orientation (and every still
stretch after more than :data:`MAX_GAP_WINDOWS` windows of motion) gets its own offset, so
a change is never fitted as drift (:func:`gyro_tdc.fitting.fit_linear` with ``groups``).

**Figures.** The accelerometer bias stability (BS) is the variance around the run mean
(around each orientation's mean when there are several), in (m/s^2)^2, raw and compensated
(:func:`static_bs`); ``evaluate`` reports it for static runs (:func:`accel_scores`) beside
the gyro's BS, with a PX4-style cubic in the measured temperature as the baseline
(:data:`PX4_FEATURES`).

**Streaming.** The part is a :class:`~gyro_tdc.model.CompensationModel` in m/s^2, so
:func:`gyro_tdc.model.compensate` (batch) and :attr:`gyro_tdc.model.StreamingCompensator.
accel` (one sample at a time, equal to the batch form) apply it; its ``residual_var`` is in
(m/s^2)^2. :func:`compensate_accel` is the batch form from the whole model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

from gyro_tdc.blocks import block_length, block_mean
from gyro_tdc.coverage import Coverage, coverage
from gyro_tdc.effects import (batch_features, input_ids, normalise_ids, resolve_params,
                              STATE_TERMS, THERMAL_EFFECTS)
from gyro_tdc.errors import FeatureError, FitError
from gyro_tdc.fitting import fit_linear, LinearFit, MIN_SAMPLES, MIN_SPAN_C
from gyro_tdc.model import compensate, CompensationModel, drift, KINDS
from gyro_tdc.out_of_range import DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C
from gyro_tdc.runs import Run
from gyro_tdc.stillness import NOISE_FACTOR, STILL_WINDOW_S
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['ACCEL_EFFECTS', 'AccelFit', 'G0', 'JUMP_SIGMAS', 'MAX_GAP_WINDOWS', 'MG',
           'MIN_JUMP_DEG', 'MIN_SEGMENT_S', 'MIN_STATIC_FRACTION', 'MIN_WINDOW_SAMPLES',
           'OrientationChange', 'PX4_FEATURES', 'StaticData', 'accel_features', 'accel_scores',
           'compensate_accel', 'discovery_runs', 'fit_accel', 'has_accelerometer',
           'static_bs', 'static_data']

#: Standard gravity, m/s^2 per g.
G0 = 9.80665
#: One milli-g in m/s^2.
MG = G0 * 1e-3
#: Effects an accelerometer part may hold (the temperature terms, the gradient, the state).
ACCEL_EFFECTS: tuple[str, ...] = ('dT', 'dT2', 'dT3', 'dTdt', 'lag')
#: The PX4-style baseline (``TC_A*``): a cubic in the measured temperature.
PX4_FEATURES: tuple[str, ...] = ('dT', 'dT2', 'dT3')
#: Fewest samples per still window (the window grows at low rates).
MIN_WINDOW_SAMPLES = 20
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
#: Largest mean compensated rate of a still window (with a gyro model), rad/s (as the node).
MAX_RATE = 0.02
#: Trend of the specific force: median step over this many previous still windows.
_TREND_WINDOWS = 5


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
    fin = np.isfinite(a).all(axis=1)
    return bool(np.any(a[fin] != 0.0))


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


def _window_stats(x: NDArray[np.float64], starts: NDArray[np.int64],
                  counts: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return per-window means and standard deviations (N, 3) of ``x`` (ddof 1)."""
    c = x[0]
    d = x - c
    s = np.add.reduceat(d, starts, axis=0)
    q = np.add.reduceat(d * d, starts, axis=0)
    n = counts[:, None]
    mean = s / n
    with np.errstate(invalid='ignore', divide='ignore'):
        var = np.maximum(q - s * mean, 0.0) / (n - 1.0)
    return mean + c, np.sqrt(var)


def _threshold(std: NDArray[np.float64], ok: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Return NOISE_FACTOR x the quietest positive window std per axis (inf when none)."""
    out = np.full(3, math.inf)
    for a in range(3):
        v = std[ok, a]
        v = v[np.isfinite(v) & (v > 0.0)]
        if v.size:
            out[a] = NOISE_FACTOR * float(v.min())
    return out


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
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    window = max(float(window_s), MIN_WINDOW_SAMPLES * dt)
    if n < 3:
        return StaticData(run.name, empty, np.full(n, -1), 0, (), window,
                          'too few samples to judge stillness')
    k = np.floor((t - t[0]) / window).astype(np.int64)
    starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
    counts = np.diff(np.append(starts, n)).astype(np.float64)
    finite = np.isfinite(acc).all(axis=1)
    bad = np.add.reduceat((~finite).astype(np.float64), starts) > 0
    a_mean, a_std = _window_stats(np.where(finite[:, None], acc, 0.0), starts, counts)
    _, g_std = _window_stats(np.asarray(run.omega, dtype=np.float64), starts, counts)
    ref_moves = np.maximum.reduceat(np.abs(run.omega_ref).max(axis=1), starts) > 0.0
    usable = (counts >= max(3, MIN_WINDOW_SAMPLES // 2)) & ~bad
    g_thr = _threshold(g_std, usable & ~ref_moves)
    a_thr = _threshold(a_std, usable & ~ref_moves)
    still = (usable & ~ref_moves & np.all(g_std <= g_thr, axis=1)
             & np.all(a_std <= a_thr, axis=1))
    if model is not None and np.any(still):
        comp = compensate(model, t, run.temp, run.omega, out_of_range=DEFAULT_OUT_OF_RANGE)
        mean_rate = np.add.reduceat(comp - run.omega_ref, starts, axis=0) / counts[:, None]
        still &= np.all(np.abs(mean_rate) <= max_rate, axis=1)
    if not np.any(still):
        reason = ('the reference rate is not zero (a turning rate table is not static)'
                  if np.all(ref_moves | ~usable) else 'no still window (the IMU moves)')
        return StaticData(run.name, empty, np.full(n, -1), 0, (), window, reason)

    # Orientation segments over the still windows.
    seg_of = np.full(starts.size, -1, dtype=np.int64)
    changes: list[OrientationChange] = []
    seg = -1
    prev = -1
    steps: list[NDArray[np.float64]] = []
    for j in np.flatnonzero(still).tolist():
        new = prev < 0 or j - prev - 1 > MAX_GAP_WINDOWS
        if not new:
            gap = j - prev
            trend = np.median(np.array(steps[-_TREND_WINDOWS:]), axis=0) if steps else 0.0
            e = a_mean[j] - (a_mean[prev] + gap * trend)
            se = math.sqrt(float(np.sum(a_std[j] ** 2 / counts[j]
                                        + a_std[prev] ** 2 / counts[prev])))
            angle = _angle_deg(a_mean[prev], a_mean[j])
            if float(np.linalg.norm(e)) > JUMP_SIGMAS * se and angle >= MIN_JUMP_DEG:
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


def accel_features(model: CompensationModel, features: str | Sequence[str] | None = None
                   ) -> tuple[str, ...]:
    """
    Return the effect ids of an accelerometer part for a gyro model.

    Parameters
    ----------
    model : CompensationModel
        The (format-2) gyro model whose thermal state the part shares.
    features : str or sequence of str, optional
        Ids among :data:`ACCEL_EFFECTS`; default: ``dT, dT2`` plus the gyro model's other
        temperature terms (``dT3``). ``lag`` follows the thermal state either way.

    Returns
    -------
    tuple of str
        Ids in catalog order, ``lag`` included exactly when the state is lagged.

    Raises
    ------
    FeatureError
        An id an accelerometer part cannot hold, or ``lag`` with an unlagged state.

    """
    if model.thermal is None:
        raise FeatureError('an accelerometer part needs a format-2 model (a thermal front end)')
    lagged = model.thermal.kind != 'none'
    if features is None:
        ids = normalise_ids(('dT', 'dT2') + tuple(e for e in model.features
                                                  if e in STATE_TERMS))
    else:
        ids = normalise_ids(features)
        bad = [e for e in ids if e not in ACCEL_EFFECTS]
        if bad:
            raise FeatureError(f'an accelerometer part holds only {", ".join(ACCEL_EFFECTS)}, '
                               f'got {", ".join(bad)}')
        if THERMAL_EFFECTS & set(ids) and not lagged:
            raise FeatureError('lag: the accelerometer part shares the thermal state of the '
                               "model, which has none (kind 'none')")
    ids = tuple(e for e in ids if e not in THERMAL_EFFECTS)
    if not any(e in STATE_TERMS for e in ids):
        ids = ('dT',) + ids
    return normalise_ids(ids + (('lag',) if lagged else ()))


@dataclass(eq=False)
class AccelFit:
    """
    What :func:`fit_accel` found: the part (or why none) and its training figures.

    Parameters
    ----------
    part : CompensationModel or None
        The accelerometer part, or None (see ``note``).
    note : str
        Why there is no part (empty when there is one).
    static : list of StaticData or None
        Per run, its still samples (None: no accelerometer data).
    coverage : Coverage, optional
        Temperature coverage of the still data.
    raw_bs, train_bs : NDArray[np.float64], shape (3,), (m/s^2)^2, optional
        Training BS before and after.
    samples : int
        Still samples fitted.
    total : int
        Samples of the runs with accelerometer data.

    """

    part: CompensationModel | None
    note: str = ''
    static: list = field(default_factory=list)
    coverage: Coverage | None = None
    raw_bs: NDArray[np.float64] | None = None
    train_bs: NDArray[np.float64] | None = None
    samples: int = 0
    total: int = 0

    @property
    def changes(self) -> list:
        """Return every orientation change found, in run order."""
        return [c for d in self.static if d is not None for c in d.changes]

    def lines(self) -> list[str]:
        """Return the training report of the accelerometer part (no coverage table)."""
        if self.part is None:
            return [f'accelerometer: not fitted: {self.note}'] + [
                c.line() for c in self.changes]
        p = self.part
        segs = sum(d.n_segments for d in self.static if d is not None)
        state = ('the thermal state shared with the gyro' if p.thermal.kind != 'none'
                 else 'the measured temperature')
        lo, hi = p.temp_range_c
        out = [f'accelerometer: {p.kind} f({", ".join(p.inputs)}) of {state}, zero at T0 = '
               f'{p.t0_c:.3f} degC (only the change with temperature is removed); '
               f'{self.samples} still samples of {self.total} '
               f'({100.0 * self.samples / max(self.total, 1):.3g} %), {segs} orientation '
               f'segment(s), range {lo:.2f} .. {hi:.2f} degC',
               'accelerometer bias stability BS (variance around the mean), (m/s^2)^2:',
               f'  {"":<13}' + ''.join(f'{a:>12}' for a in 'xyz'),
               _row('raw', self.raw_bs), _row('compensated', self.train_bs),
               _row('RMS (mg)', np.sqrt(self.train_bs) / MG),
               _row('change/degC', _slope_mg(p)) + '   (mg per degC: static change, mean '
                                                   'slope over the range)']
        return out + [c.line() for c in self.changes]


def _row(label: str, values: ArrayLike) -> str:
    """Format one table row of three per-axis numbers."""
    return f'  {label:<13}' + ''.join(f'{float(v):>12.4g}' for v in values)


def _slope_mg(part: CompensationModel) -> NDArray[np.float64]:
    """Return the part's mean static slope over its range, mg per degC (NaN without span)."""
    lo, hi = (float(v) for v in part.temp_range_c)
    if not hi > lo:
        return np.full(3, math.nan)
    t = np.arange(3, dtype=np.float64) * 1e7      # far apart: every dynamic term settled
    b = drift(part, t, np.array([lo, lo, hi]), clamp=True)
    return (b[2] - b[1]) / (hi - lo) / MG


def _reference_design(lf: LinearFit, f: int) -> NDArray[np.float64]:
    """Return the design row at the reference point (every feature zero), (1 + F + K,)."""
    return lf.design(np.zeros((1, f)))[0]


def fit_accel(runs: Sequence[Run], model: CompensationModel, *,
              features: str | Sequence[str] | None = None, kind: str | None = None,
              n_centers: int | None = None, ridge: float | str = 'auto', seed: int = 0,
              max_rows: int = 200_000, bin_c: float = 5.0) -> AccelFit:
    """
    Fit the accelerometer part of ``model`` on the still data of ``runs``.

    Per still sample ``a = c_g + f(x) + noise``: ``c_g`` one constant per orientation
    segment (gravity and the static offset, not thermal), ``f`` the network of the features
    ``x`` of the model's thermal state, fitted with one offset per segment
    (:func:`gyro_tdc.fitting.fit_linear` with ``groups``); its intercept is then set so
    ``f`` is zero at the reference point (T0, dynamic terms settled).

    Parameters
    ----------
    runs : sequence of Run
        Training runs (those without ``accel`` data are skipped).
    model : CompensationModel
        The gyro model (format 2): its thermal state, T0 and sensor ids are shared; it also
        judges stillness (mean compensated rate).
    features : str or sequence of str, optional
        See :func:`accel_features`.
    kind : str, optional
        ``'rbf'`` or ``'poly'`` (default: the gyro model's).
    n_centers : int, optional
        RBF centres (default: the gyro model's, at least 1).
    ridge : float or 'auto'
        Relative ridge on the RBF weights (:func:`gyro_tdc.fitting.fit_linear`).
    seed : int
        Seed of the centre placement.
    max_rows : int
        Rows of the solve; longer still data are block-averaged inside each segment.
    bin_c : float, degC
        Width of the coverage bins.

    Returns
    -------
    AccelFit
        The part (or None with the reason: no accelerometer data, no still data, too small
        a temperature span, too few samples) and the training figures.

    """
    ids = accel_features(model, features)
    kind = model.kind if kind is None else kind
    if kind not in KINDS:
        raise FeatureError(f'Expected `kind` to be one of {", ".join(KINDS)}, got {kind!r}.')
    if n_centers is None:
        n_centers = max(model.n_centers, 1)
    datas = [static_data(r, model=model) for r in runs]
    with_acc = [(r, d) for r, d in zip(runs, datas) if d is not None]
    out = AccelFit(None, static=datas, total=sum(len(r) for r, _ in with_acc))
    if not with_acc:
        out.note = 'no accelerometer data in the bags (all zero: the IMU publishes none)'
        return out
    usable = [(r, d) for r, d in with_acc if d.mask.any()]
    if not usable:
        out.note = 'no static data: ' + '; '.join(sorted({d.reason for _, d in with_acc}))
        return out
    th = model.thermal
    par = resolve_params(ids, {k: v for k, v in model.effect_params.items() if k in ids})
    if th.kind != 'none':
        par['lag'] = {'tau_s': th.tau_total_s}
    inputs = input_ids(ids, state=True)
    f = len(inputs)
    n_static = sum(int(d.mask.sum()) for _, d in usable)
    block = block_length(n_static, max_rows, at_most=True)
    xb, yb, gb, rows = [], [], [], []
    g0 = 0
    static_runs = []
    for r, d in usable:
        state = th.temperature(r.t, r.temp)
        x = batch_features(ids, r.t, r.temp, t0=model.t0_c, params=par, state=state)
        for s in range(d.n_segments):
            idx = np.flatnonzero(d.segment == s)
            if idx.size == 0:
                continue
            xs, acs = x[idx], np.asarray(r.accel, dtype=np.float64)[idx]
            xb.append(block_mean(xs, block))
            yb.append(block_mean(acs, block))
            gb.append(np.full(yb[-1].shape[0], g0))
            rows.append((xs, acs, state[idx], g0))
            static_runs.append(Run(r.t[idx], r.temp[idx], r.omega[idx], r.omega_ref[idx],
                                   r.name))
            g0 += 1
    span = (min(float(s.min()) for _, _, s, _ in rows),
            max(float(s.max()) for _, _, s, _ in rows))
    out.samples = n_static
    out.coverage = coverage(static_runs, bin_c=bin_c)
    if n_static < MIN_SAMPLES:
        out.note = f'too few still samples ({n_static}, need at least {MIN_SAMPLES})'
        return out
    if span[1] - span[0] < MIN_SPAN_C:
        out.note = (f'the still data span {span[1] - span[0]:.3g} degC of the model '
                    f'temperature (need at least {MIN_SPAN_C} degC)')
        return out
    lf = fit_linear(np.concatenate(xb), np.concatenate(yb), kind=kind, n_centers=n_centers,
                    ridge=ridge, seed=seed, groups=np.concatenate(gb))
    coef = lf.coef.copy()
    coef[0] = -(_reference_design(lf, f)[1:] @ coef[1:])     # zero at the reference point
    offsets = lf.offsets - coef[0]                             # c_g: the still force at T0
    ss = np.zeros(3)
    ss_raw = np.zeros(3)
    for xs, acs, _, g in rows:
        for i in range(0, xs.shape[0], 200_000):
            fit = lf.design(xs[i:i + 200_000]) @ coef + offsets[g]
            e = acs[i:i + 200_000] - fit
            ss += np.einsum('ij,ij->j', e, e)
        dev = acs - acs.mean(axis=0)
        ss_raw += np.einsum('ij,ij->j', dev, dev)
    out.raw_bs = ss_raw / n_static
    out.train_bs = ss / n_static
    metrics = {
        'samples': int(n_static), 'runs': [r.name for r, _ in usable], 'segments': int(g0),
        'raw_bs_m2_s4': [float(v) for v in out.raw_bs],
        'train_bs_m2_s4': [float(v) for v in out.train_bs],
        'train_rms_mg': [float(v) for v in np.sqrt(out.train_bs) / MG],
        'ridge': float(lf.ridge),
        'orientation_changes': [c.to_dict() for c in out.changes],
    }
    out.part = CompensationModel(
        kind=kind, features=ids, effect_params=par, t0_c=model.t0_c, input_mean=lf.mean,
        input_std=lf.std, centers=lf.centers, widths=lf.widths, weights=coef[1 + f:],
        intercept=coef[0], linear=coef[1:1 + f], scale=np.zeros(3), temp_range_c=span,
        residual_var=out.train_bs, frame_id=model.frame_id, sensor_id=model.sensor_id,
        metrics=metrics, created={}, thermal=th)
    return out


def compensate_accel(model: CompensationModel, t: ArrayLike, temp: ArrayLike,
                     accel: ArrayLike, *, out_of_range: str = DEFAULT_OUT_OF_RANGE,
                     max_extrapolation_c: float = MAX_EXTRAPOLATION_C) -> NDArray[np.float64]:
    """
    Remove the accelerometer part's change with temperature from a run (batch form).

    Parameters
    ----------
    model : CompensationModel
        A model with an accelerometer part (``model.accel``).
    t : ArrayLike, shape (N,), s
        Stamps of one continuous run.
    temp : ArrayLike, shape (N,), degC
        Measured temperature.
    accel : ArrayLike, shape (N, 3), m/s^2
        Raw specific force.
    out_of_range : str
        ``'linear'``, ``'clamp'`` or ``'extrapolate'`` (:mod:`gyro_tdc.out_of_range`).
    max_extrapolation_c : float, degC
        Reach of the ``linear`` tangent.

    Returns
    -------
    NDArray[np.float64], shape (N, 3), m/s^2
        ``accel`` minus the correction; equal, to rounding, to stepping
        ``StreamingCompensator(model).accel`` sample by sample.

    Raises
    ------
    FeatureError
        When the model has no accelerometer part.

    """
    if model.accel is None:
        raise FeatureError('the model has no accelerometer part (train with accelerometer '
                           'data, without --no-accel)')
    return compensate(model.accel, np.asarray(t, dtype=np.float64),
                      np.asarray(temp, dtype=np.float64), np.asarray(accel, dtype=np.float64),
                      out_of_range=out_of_range, max_extrapolation_c=max_extrapolation_c)


def accel_scores(run: Run, models: Sequence[CompensationModel], *,
                 out_of_range: str = DEFAULT_OUT_OF_RANGE,
                 max_extrapolation_c: float = MAX_EXTRAPOLATION_C
                 ) -> tuple[NDArray[np.float64] | None, list]:
    """
    Return the accelerometer BS of a static run, raw and after each model.

    Parameters
    ----------
    run : Run
        A held-out run.
    models : sequence of CompensationModel
        The models (those without an accelerometer part score None).
    out_of_range : str
        Out-of-range policy.
    max_extrapolation_c : float, degC
        Reach of the ``linear`` tangent.

    Returns
    -------
    raw : NDArray[np.float64], shape (3,), (m/s^2)^2, or None
        :func:`static_bs` of the raw data; None when the run has no accelerometer data or
        is still for less than :data:`MIN_STATIC_FRACTION` of its samples.
    per_model : list of (NDArray[np.float64] or None)
        The same after each model.

    """
    data = static_data(run)
    if data is None or data.fraction < MIN_STATIC_FRACTION:
        return None, [None] * len(models)
    raw = static_bs(run.accel, data)
    out = []
    for m in models:
        if m.accel is None:
            out.append(None)
            continue
        comp = compensate_accel(m, run.t, run.temp, run.accel, out_of_range=out_of_range,
                                max_extrapolation_c=max_extrapolation_c)
        out.append(static_bs(comp, data))
    return raw, out


def discovery_runs(runs: Sequence[Run]) -> list[Run]:
    """
    Return the still stretches of runs as runs of the accelerometer for discovery.

    Each orientation segment of each run becomes one run (discovery fits one offset per
    run: gravity and the static offset) whose ``omega`` is the specific force in mg scaled
    by pi/180, so discovery's figures, printed in deg/s, read in mg; the reference is zero.

    Parameters
    ----------
    runs : sequence of Run
        Runs read with the accelerometer.

    Returns
    -------
    list of Run
        Named ``BAG`` (or ``BAG#k`` for the k-th of several segments).

    Raises
    ------
    FitError
        When no run has still accelerometer data.

    """
    out = []
    notes = set()
    for r in runs:
        d = static_data(r)
        if d is None:
            notes.add(f'{r.name}: no accelerometer data')
            continue
        if not d.mask.any():
            notes.add(f'{r.name}: {d.reason}')
            continue
        for s in range(d.n_segments):
            idx = np.flatnonzero(d.segment == s)
            a = np.asarray(r.accel, dtype=np.float64)[idx] / MG * (math.pi / 180.0)
            name = r.name if d.n_segments == 1 else f'{r.name}#{s + 1}'
            out.append(Run(r.t[idx], r.temp[idx], a, np.zeros_like(a), name,
                           {'source': 'accel', 'changes': [c.to_dict() for c in d.changes]}))
    if not out:
        raise FitError('no still accelerometer data to discover effects on: '
                       + '; '.join(sorted(notes)))
    return out
