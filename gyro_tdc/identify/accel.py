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
The accelerometer part: its still data, orientation segments, features, fit, scores.

A MEMS accelerometer's offset moves with the die temperature; the part holds that change per
axis, of the gyro model's thermal state, zero at T0. Gravity dominates, so it is learnt only
while still with a fixed orientation: :func:`static_data` keeps the still windows of the one
still test and splits them where gravity's direction jumps (each orientation its own offset,
never fitted as drift). See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

from gyro_tdc.base import G0, MG, plain, RAD_PER_DEG
from gyro_tdc.data import Coverage, coverage, Run
from gyro_tdc.errors import FeatureError, FitError, ModelFileError
from gyro_tdc.identify.axes import constant_note
from gyro_tdc.identify.fit import check_choices, MIN_SAMPLES, MIN_SPAN_C, span
from gyro_tdc.identify.linear import fit_linear
from gyro_tdc.identify.power_cycles import check_sessions, MIN_FOLDS, SLOW_CURVE_S, told_alone
from gyro_tdc.identify.tau import run_state
from gyro_tdc.model import (batch_features, check_accel, compensate, CompensationModel,
                            DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C, normalise_ids,
                            resolve_params, STATE_TERMS, static_slope, THERMAL_EFFECTS)
from gyro_tdc.signal import (block_length, BlockGrid, curve_untold, detect_still,
                             has_accelerometer, MAX_RATE, MIN_SESSION_SPAN_C, STILL_WINDOW_S,
                             within)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['ACCEL_EFFECTS', 'AccelFit', 'accel_features', 'accel_scores', 'compensate_accel',
           'discovery_runs', 'fit_accel', 'G0', 'JUMP_SIGMAS', 'MAX_GAP_WINDOWS', 'MG',
           'MIN_JUMP_DEG', 'MIN_SEGMENT_S', 'MIN_STATIC_FRACTION', 'OrientationChange',
           'static_bs', 'static_data', 'StaticData']

#: Effects an accelerometer part may hold (the temperature terms, the gradient, the state).
ACCEL_EFFECTS: tuple[str, ...] = ('dT', 'dT2', 'dT3', 'dTdt', 'lag')
#: ``evaluate`` reports accelerometer figures for runs at least this still.
MIN_STATIC_FRACTION = 0.5
#: An orientation jump must exceed this many standard deviations of its noise ...
JUMP_SIGMAS = 8.0
#: ... and turn gravity by at least this much, deg (1.7 mg): smaller is not told from drift.
MIN_JUMP_DEG = 0.1
#: More non-still windows than this between two still ones start a new orientation segment.
MAX_GAP_WINDOWS = 6
#: Shortest orientation segment kept, s.
MIN_SEGMENT_S = 60.0
#: Trend of the specific force: median step over this many previous still windows.
_TREND_WINDOWS = 5


@dataclass(frozen=True)
class OrientationChange:
    """A jump of gravity's direction (``angle_deg``) in ``run`` at ``t_s``: mean force around."""

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
        return plain({'run': self.run, 't_s': float(self.t_s), 'angle_deg': float(self.angle_deg),
                      'before_mps2': self.before, 'after_mps2': self.after})


@dataclass(frozen=True, eq=False)
class StaticData:
    """
    The still samples (``mask``) of one run, grouped by orientation.

    ``segment`` numbers each still sample's orientation segment (-1 elsewhere), ``changes``
    the orientation changes found; ``reason`` says why no sample is still.
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
    return math.degrees(math.acos(min(1.0, max(-1.0, float(np.dot(u, v)) / (nu * nv)))))


def static_data(run: Run, *, model: CompensationModel | None = None) -> StaticData | None:
    """
    Find the still samples of a run and split them at orientation changes (None: no accel).

    The still windows are the one still test's (:func:`gyro_tdc.signal.detect_still`) with a
    non-zero reference rate as the motion veto and, with a gyro ``model``, a mean compensated
    rate of at most :data:`gyro_tdc.signal.MAX_RATE` (a slow constant turn has no spread);
    orientation segments shorter than :data:`MIN_SEGMENT_S` are dropped.
    """
    if not has_accelerometer(run.accel):
        return None
    (acc, t), n = (np.asarray(x, dtype=np.float64) for x in (run.accel, run.t)), len(run)
    moves = np.asarray(run.omega_ref) != 0.0      # OR-ed column by column below: no axis reduction
    rate = None if model is None else compensate(
        model, t, run.temp, run.omega, out_of_range=DEFAULT_OUT_OF_RANGE) - run.omega_ref
    # The one still test: every still window counts, the segments set the shortest stretch.
    st = detect_still(t, run.omega, acc, rate=rate, moving=moves[:, 0] | moves[:, 1] | moves[:, 2],
                      window_s=STILL_WINDOW_S, min_still_s=0.0, max_rate=MAX_RATE)

    def none(reason: str) -> StaticData:
        return StaticData(run.name, np.zeros(n, dtype=bool), np.full(n, -1), 0, (), st.window_s,
                          reason)

    if st.reason == 'too few samples to judge stillness':
        return none(st.reason)
    starts, counts, a_mean = st.starts, st.counts.astype(np.float64), st.accel_mean
    if not np.any(st.still_windows):
        return none('the reference rate is not zero (a turning rate table is not static)'
                    if np.all(np.isin(st.why, ('motion', 'samples', 'non-finite'))) else
                    'no still window (the IMU moves)')
    # Orientation segments over the still windows.
    seg_of, changes, steps = np.full(starts.size, -1, dtype=np.int64), [], []
    seg, prev = -1, -1
    var_mean = st.accel_std ** 2 / counts[:, None]    # variance of each window's mean, per axis
    for j in np.flatnonzero(st.still_windows).tolist():
        new = prev < 0 or j - prev - 1 > MAX_GAP_WINDOWS
        if not new:
            gap = j - prev
            trend = np.median(np.array(steps[-_TREND_WINDOWS:]), axis=0) if steps else 0.0
            e = a_mean[j] - (a_mean[prev] + gap * trend)
            se = math.sqrt(float(np.sum(var_mean[j] + var_mean[prev])))
            jump = float(np.linalg.norm(e)) > JUMP_SIGMAS * se
            if jump and (angle := _angle_deg(a_mean[prev], a_mean[j])) >= MIN_JUMP_DEG:
                new = True
                changes.append(OrientationChange(run.name, float(t[starts[j]]), angle,
                                                 a_mean[prev].copy(), a_mean[j].copy()))
            elif gap == 1:
                steps.append(a_mean[j] - a_mean[prev])
        if new:
            seg, steps = seg + 1, []
        seg_of[j], prev = seg, j
    # Drop short segments, renumber the rest.
    ends = np.append(starts[1:], n)
    keep_ids = [s for s in range(seg + 1) for w in [np.flatnonzero(seg_of == s)]
                if t[ends[w[-1]] - 1] - t[starts[w[0]]] >= MIN_SEGMENT_S or seg == 0]
    remap = np.full(seg + 2, -1, dtype=np.int64)        # remap[-1]: not still, stays -1
    remap[keep_ids] = np.arange(len(keep_ids))
    per_sample = np.repeat(remap[seg_of], counts.astype(np.int64))
    mask = (per_sample >= 0) & np.isfinite(acc).all(axis=1)
    return StaticData(run.name, mask, np.where(mask, per_sample, -1), len(keep_ids),
                      tuple(changes), st.window_s, '' if mask.any() else
                      'no still stretch long enough')


def static_bs(accel: ArrayLike, data: StaticData) -> NDArray[np.float64] | None:
    """
    Return the accelerometer bias stability (3,), (m/s^2)^2 (None without still samples).

    The variance of the still samples around their mean: each orientation segment's own mean
    (pooled) when there are several.
    """
    m = data.mask
    if not np.any(m):
        return None
    r = within(np.asarray(accel, dtype=np.float64)[m], data.segment[m])[1]
    return np.einsum('ij,ij->j', r, r) / float(r.shape[0])


def accel_features(model: CompensationModel, features: str | Sequence[str] | None = None
                   ) -> tuple[str, ...]:
    """
    Return the effect ids (catalog order) of an accelerometer part for a gyro model.

    Default ``dT, dT2`` plus the model's other temperature terms; ids among
    :data:`ACCEL_EFFECTS` otherwise; ``lag`` follows the thermal state either way (a
    FeatureError for a foreign id, or ``lag`` with an unlagged state).
    """
    lagged = model.thermal.kind != 'none'
    if features is None:
        ids = normalise_ids(('dT', 'dT2') + tuple(e for e in model.features if e in STATE_TERMS))
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
    return normalise_ids(ids + (() if any(e in STATE_TERMS for e in ids) else ('dT',))
                         + (('lag',) if lagged else ()))


@dataclass(eq=False)
class AccelFit:
    """
    What :func:`fit_accel` found: the part (or why none, ``note``) and its training figures.

    ``static`` holds per run its :class:`StaticData` (None: no accelerometer data, or
    constant readings); ``coverage`` the still data's; ``raw_bs``, ``train_bs`` the training
    BS before and after, (m/s^2)^2; ``samples`` the still samples fitted of ``total``.
    """

    part: CompensationModel | None
    note: str = ''
    static: list = field(default_factory=list)
    coverage: Coverage | None = None
    raw_bs: NDArray[np.float64] | None = None
    train_bs: NDArray[np.float64] | None = None
    samples: int = 0
    total: int = 0
    #: The held-out check across power cycles (``check_sessions``'s record, in mg^2).
    check: dict | None = None

    @property
    def changes(self) -> list:
        """Return every orientation change found, in run order."""
        return [c for d in self.static if d is not None for c in d.changes]

    def lines(self) -> list[str]:
        """Return the training report of the accelerometer part (no coverage table)."""
        changes = [c.line() for c in self.changes]
        if self.part is None:
            return [f'accelerometer: not fitted: {self.note}'] + _check_lines(self.check) + changes
        p = self.part
        segs = sum(d.n_segments for d in self.static if d is not None)
        state = ('the thermal state shared with the gyro' if p.thermal.kind != 'none'
                 else 'the measured temperature')
        lo, hi = p.temp_range_c
        return [f'accelerometer: {p.kind} f({", ".join(p.inputs)}) of {state}, zero at T0 = '
                f'{p.t0_c:.3f} degC (only the change with temperature is removed); '
                f'{self.samples} still samples of {self.total} '
                f'({100.0 * self.samples / max(self.total, 1):.3g} %), {segs} orientation '
                f'segment(s), range {lo:.2f} .. {hi:.2f} degC',
                'accelerometer bias stability BS (variance around the mean), (m/s^2)^2:',
                f'  {"":<13}' + ''.join(f'{a:>12}' for a in 'xyz'),
                _row('raw', self.raw_bs), _row('compensated', self.train_bs),
                _row('RMS (mg)', np.sqrt(self.train_bs) / MG),
                _row('change/degC', static_slope(p) / MG)
                + '   (mg per degC: static change, mean slope over the range)'
                ] + _check_lines(self.check) + changes


def _check_lines(record: dict | None) -> list[str]:
    """Return the report lines of the accelerometer's check across power cycles."""
    if not record or 'curve_ms_mg2' not in record:
        return []
    out = ['accelerometer: the change with temperature held out on each power cycle '
           f"({record['folds']} sessions, {record['blocks']} blocks inside the others' "
           'temperatures, each orientation segment re-anchored), mean square, mg^2:',
           _row('curve', record['curve_ms_mg2']), _row('none', record['offset_ms_mg2']),
           '  power cycles predicted worse by the curve: '
           + '  '.join(f'{v:d}' for v in record['worse_folds'])]
    if record['offset_only']:
        out.append(f"accelerometer axes {', '.join(record['offset_only'])}: the change with "
                   'temperature does not predict every held-out power cycle better than '
                   'none: the part removes none there')
    return out


def _row(label: str, values: ArrayLike) -> str:
    """Format one table row of three per-axis numbers."""
    return f'  {label:<13}' + ''.join(f'{float(v):>12.4g}' for v in values)


def _segment_blocks(usable: Sequence[tuple], model: CompensationModel, ids: tuple[str, ...],
                    par: dict, block: int) -> tuple[list[dict], tuple[float, float]]:
    """
    Return per still segment its block means, and the range of the model temperature.

    The force's block means and scatter are centred on the segment's first row (gravity
    dwarfs the scatter), summed in passes: no full copy of the force.
    """
    segs = []
    for k, (r, d) in enumerate(usable):
        state = run_state(model.thermal, r)       # the gyro fit's, not computed again
        x = batch_features(ids, r.t, r.temp, t0=model.t0_c, params=par, state=state)
        for s in np.unique(d.segment[d.mask]):     # the segments with still samples
            idx = np.flatnonzero(d.segment == s)
            grid = BlockGrid(idx.size, block, take=idx)
            ya, within = grid.moments(r.accel, centred=True)
            segs.append({'run': k, 'x': grid.mean(x), 'y': ya, 'n': grid.counts, 'within': within,
                         't': grid.mean(r.t), 'temp': grid.mean(r.temp),
                         'state': grid.mean(state)})
    return segs, span([run_state(model.thermal, r)[d.mask] for r, d in usable])


def fit_accel(runs: Sequence[Run], model: CompensationModel, *,
              features: str | Sequence[str] | None = None, kind: str | None = None,
              n_centers: int | None = None, ridge: float | str = 'auto', seed: int = 0,
              max_rows: int = 20_000, bin_c: float = 5.0, min_folds: int = 1,
              judge: bool = True) -> AccelFit:
    """
    Fit the accelerometer part of ``model`` on the still data of ``runs``.

    Per still sample ``a = c_g + f(x) + noise``: ``c_g`` one constant per orientation segment
    (gravity and the static offset), ``f`` the network of the features of the model's thermal
    state (``fit_linear`` with ``groups``), its intercept set so ``f`` is zero at T0 (dynamic
    terms settled). ``kind`` and ``n_centers`` default to the gyro model's; still data longer
    than ``max_rows`` are block-averaged inside each segment. As the gyro's curve, the change
    is judged on each power cycle (run) held out (``check_sessions``, ``min_folds`` of them
    at least; ``judge`` False: unchecked, as the PX4-style baseline is fitted): an axis where
    it does not predict better than none removes none. The gyro
    model does not judge stillness (a model being judged would reject still data). The
    AccelFit says why there is no part: no accelerometer data, no still data, too small a
    span, too few samples, no axis that carries.
    """
    ids = accel_features(model, features)
    kind = model.kind if kind is None else kind
    check_choices(kind, None)
    n_centers = max(model.n_centers, 1) if n_centers is None else n_centers
    # A constant accelerometer is absent: its still data are not looked for.
    present = [r for r in runs if has_accelerometer(r.accel)]
    if constant := constant_note(present):
        return AccelFit(None, note=constant, static=[None] * len(runs),
                        total=sum(len(r) for r in present))
    datas = [static_data(r) for r in runs]      # None where a run has no accelerometer
    out = AccelFit(None, static=datas, total=sum(len(r) for r in present))
    usable = [(r, d) for r, d in zip(runs, datas) if d is not None and d.mask.any()]
    if not usable:
        out.note = ('no static data: ' + '; '.join(sorted(
            {d.reason for d in datas if d is not None})) if present else
            'no accelerometer data in the bags (all zero: the IMU publishes none)')
        return out
    th = model.thermal
    par = {**resolve_params(ids, {k: v for k, v in model.effect_params.items() if k in ids}),
           **({} if th.kind == 'none' else {'lag': {'tau_s': th.tau_total_s}})}
    out.samples = n_static = sum(int(d.mask.sum()) for _, d in usable)
    segs, range_c = _segment_blocks(usable, model, ids, par,
                                    block_length(n_static, max_rows, at_most=True))
    # Coverage of the still data from its block means (the minutes per bin are the same).
    out.coverage = coverage([Run(sg['t'], sg['temp'], np.zeros((sg['t'].size, 3)),
                                 np.zeros((sg['t'].size, 3))) for sg in segs], bin_c=bin_c)
    groups = np.concatenate([np.full(sg['n'].size, g) for g, sg in enumerate(segs)])
    widest = curve_untold(np.concatenate([sg['state'] for sg in segs]), groups)
    out.note = (f'too few still samples ({n_static}, need at least {MIN_SAMPLES})'
                if n_static < MIN_SAMPLES else
                f'the still data span {range_c[1] - range_c[0]:.3g} degC of the model temperature '
                f'(need at least {MIN_SPAN_C} degC)' if range_c[1] - range_c[0] < MIN_SPAN_C else
                f'no still segment spans {MIN_SESSION_SPAN_C:g} degC of the model temperature '
                f'of its own (widest {widest:.3g} degC of {len(segs)}): with a constant per '
                'segment, a curve is told only within one' if widest is not None else '')
    if out.note:
        return out
    x, y = (np.concatenate([sg[k] for sg in segs]) for k in ('x', 'y'))
    linear = {'kind': kind, 'n_centers': n_centers, 'seed': seed}
    lf = fit_linear(x, y, ridge=ridge, groups=groups, **linear)
    lf, offsets, out.check, out.note = (_carried(lf, segs, x, y, groups, min_folds, linear)
                                        if judge else (lf, lf.offsets, None, ''))
    if out.note:
        return out
    coef = lf.coef.copy()
    coef[0] = -(lf.design(np.zeros((1, lf.mean.size)))[0][1:] @ coef[1:])  # zero at T0
    # The full-rate sums of squares of the residual and of the raw force (raw around each
    # segment's mean): the scatter within each block plus each block's count times its
    # squared residual (the drift is constant within a block). c_g, the still force at T0:
    # each segment's offset less the constant.
    ss, ss_raw, c_g = np.zeros(3), np.zeros(3), offsets - coef[0]
    for g, sg in enumerate(segs):
        n = sg['n'][:, None]
        e = sg['y'] - (lf.design(sg['x']) @ coef + c_g[g])
        ss += sg['within'].sum(axis=0) + (n * e ** 2).sum(axis=0)
        mean = (n * sg['y']).sum(axis=0) / n.sum()
        ss_raw += sg['within'].sum(axis=0) + (n * (sg['y'] - mean) ** 2).sum(axis=0)
    out.raw_bs, out.train_bs = ss_raw / n_static, ss / n_static
    metrics = {
        'samples': int(n_static), 'runs': [r.name for r, _ in usable], 'segments': len(segs),
        'raw_bs_m2_s4': out.raw_bs.tolist(), 'train_bs_m2_s4': out.train_bs.tolist(),
        'train_rms_mg': (np.sqrt(out.train_bs) / MG).tolist(),
        'ridge': float(lf.ridge), 'orientation_changes': [c.to_dict() for c in out.changes],
        **({} if out.check is None else {'held_out': out.check})}
    part = CompensationModel.network(
        kind, ids, par, model.t0_c, lf.norm, coef, temp_range_c=range_c,
        residual_var=out.train_bs, frame_id=model.frame_id, sensor_id=model.sensor_id,
        metrics=metrics, created={}, thermal=th)
    try:
        check_accel(part)             # an optional part never keeps the gyro model unwritten
        out.part = part
    except ModelFileError as exc:
        out.note = f'the part fitted is implausible, loading would refuse it ({exc})'
    return out


def _carried(lf, segs: Sequence[dict], x: NDArray[np.float64], y: NDArray[np.float64],
             groups: NDArray[np.int64], min_folds: int, linear: dict) -> tuple:
    """
    Judge the change on each power cycle held out, as the gyro's curve; return the fit.

    Each held-out orientation segment is re-anchored (``check_sessions`` with the runs as
    ``units``); with one power cycle nothing is held out, and a curve of stops
    (``min_folds`` >= MIN_FOLDS) then needs a segment of SLOW_CURVE_S spanning
    MIN_SESSION_SPAN_C; ``linear`` are the refits' ``fit_linear`` options. Returns the fit,
    the segments' offsets, the check's record (mg^2; None: none) and why no part ('': one).
    """
    units = np.concatenate([np.full(sg['n'].size, sg['run']) for sg in segs])
    if np.unique(units).size < 2:
        slow = told_alone([(np.ptp(sg['state']), np.ptp(sg['t'])) for sg in segs])
        return lf, lf.offsets, None, '' if slow or min_folds < MIN_FOLDS else (
            f'one power cycle of stops, and no still segment of {SLOW_CURVE_S / 60:g} min or '
            f'more spans {MIN_SESSION_SPAN_C:g} degC of its own: no held-out power cycle can '
            'tell whether the change carries to the next')
    n, state = (np.concatenate([sg[k] for sg in segs]) for k in ('n', 'state'))
    lf, offsets, check = check_sessions(lf, lf.offsets, x, y, None, groups, n.astype(np.float64),
                                        state, units=units, min_folds=min_folds,
                                        unit=('mg2', 1.0 / MG ** 2), **linear)
    if check is None or len(check['offset_only']) < 3:
        return lf, offsets, check, ''
    why = ('the change with temperature does not predict every held-out power cycle better '
           'than none on any axis' if 'worse_folds' in check else
           f"judged on {check['folds']} held-out power cycle(s) of {check['sessions']} only: "
           f'fewer than {min_folds} cannot tell whether a change of stops carries to the next '
           'power cycle')
    return lf, offsets, check, why


def compensate_accel(model: CompensationModel, t: ArrayLike, temp: ArrayLike,
                     accel: ArrayLike, *, out_of_range: str = DEFAULT_OUT_OF_RANGE,
                     max_extrapolation_c: float = MAX_EXTRAPOLATION_C) -> NDArray[np.float64]:
    """
    Remove the accelerometer part's change with temperature from a run (batch form), (N, 3).

    Equal, to rounding, to stepping ``StreamingCompensator(model).accel`` sample by sample;
    FeatureError when the model has no accelerometer part.
    """
    if model.accel is None:
        raise FeatureError('the model has no accelerometer part (train with accelerometer '
                           'data, without --no-accel)')
    return compensate(model.accel, *(np.asarray(x, dtype=np.float64) for x in (t, temp, accel)),
                      out_of_range=out_of_range, max_extrapolation_c=max_extrapolation_c)


def accel_scores(run: Run, models: Sequence[CompensationModel], *,
                 out_of_range: str = DEFAULT_OUT_OF_RANGE,
                 max_extrapolation_c: float = MAX_EXTRAPOLATION_C
                 ) -> tuple[NDArray[np.float64] | None, list]:
    """
    Return the accelerometer BS of a static run, raw and after each model (None: no part).

    Raw is None (and every model's) when the run has no accelerometer data, constant
    readings, or is still for less than :data:`MIN_STATIC_FRACTION` of its samples.
    """
    data = static_data(run)
    if data is None or data.fraction < MIN_STATIC_FRACTION or constant_note([run]):
        return None, [None] * len(models)
    return static_bs(run.accel, data), [
        None if m.accel is None else static_bs(compensate_accel(
            m, run.t, run.temp, run.accel, out_of_range=out_of_range,
            max_extrapolation_c=max_extrapolation_c), data) for m in models]


def discovery_runs(runs: Sequence[Run]) -> list[Run]:
    """
    Return the still stretches of runs as runs of the accelerometer for discovery.

    Each orientation segment of each run becomes one run (``BAG``, or ``BAG#k`` of several):
    discovery fits one offset per run (gravity and the static offset). Its ``omega`` is the
    specific force in mg scaled by pi/180, so discovery's deg/s read in mg; the reference is
    zero; a segment without samples is left out. FitError when no run has still accelerometer
    data.
    """
    out, notes = [], set()
    for r in runs:
        d = static_data(r)
        if d is None or not d.mask.any():
            notes.add(f'{r.name}: ' + ('no accelerometer data' if d is None else d.reason))
            continue
        for s in np.unique(d.segment[d.mask]):     # a segment without samples: none
            idx = np.flatnonzero(d.segment == s)
            a = np.asarray(r.accel, dtype=np.float64)[idx] / MG * RAD_PER_DEG
            out.append(Run(r.t[idx], r.temp[idx], a, np.zeros_like(a),
                           r.name if d.n_segments == 1 else f'{r.name}#{s + 1}',
                           {'source': 'accel', 'changes': [c.to_dict() for c in d.changes]}))
    if not out:
        raise FitError('no still accelerometer data to discover effects on: '
                       + '; '.join(sorted(notes)))
    return out
