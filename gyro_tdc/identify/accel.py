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
The accelerometer part itself: its features, its fit on still data, scores and discovery runs.

See :mod:`gyro_tdc.identify` for what the part is; the still data come from
:mod:`gyro_tdc.identify.accel_static`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

from gyro_tdc.data import Coverage, coverage, Run
from gyro_tdc.errors import FeatureError, FitError
from gyro_tdc.identify.accel_static import static_bs, static_data
from gyro_tdc.identify.fit import MIN_SAMPLES, MIN_SPAN_C
from gyro_tdc.identify.linear import fit_linear, LinearFit
from gyro_tdc.identify.runblocks import run_state
from gyro_tdc.model import (batch_features, compensate, CompensationModel, DEFAULT_OUT_OF_RANGE,
                            drift, input_ids, KINDS, MAX_EXTRAPOLATION_C, normalise_ids,
                            resolve_params, STATE_TERMS, THERMAL_EFFECTS)
from gyro_tdc.signal import (block_counts, block_length, block_mean, block_sumsq,
                             has_accelerometer)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['ACCEL_EFFECTS', 'AccelFit', 'G0', 'MG', 'MIN_STATIC_FRACTION', 'PX4_FEATURES',
           'accel_features', 'accel_scores', 'compensate_accel', 'constant_axes',
           'constant_axes_of', 'constant_note', 'constant_values', 'discovery_runs', 'fit_accel']

#: Standard gravity, m/s^2 per g.
G0 = 9.80665
#: One milli-g in m/s^2.
MG = G0 * 1e-3
#: Effects an accelerometer part may hold (the temperature terms, the gradient, the state).
ACCEL_EFFECTS: tuple[str, ...] = ('dT', 'dT2', 'dT3', 'dTdt', 'lag')
#: The PX4-style baseline (``TC_A*``): a cubic in the measured temperature.
PX4_FEATURES: tuple[str, ...] = ('dT', 'dT2', 'dT3')
#: ``evaluate`` reports accelerometer figures for runs at least this still.
MIN_STATIC_FRACTION = 0.5


def constant_axes(values: ArrayLike) -> NDArray[np.bool_]:
    """
    Return, per axis, whether the readings never vary beyond one quantum (a constant).

    An axis is constant when its finite readings take at most two values (two values are
    one quantum apart by definition: the smallest step seen): a driver that fills a fixed
    value (e.g. exactly ``(0, 0, g)``, or a gyro axis of a 2-axis part as 0) or a sensor
    whose drift stays below its resolution. There is nothing to fit on such an axis.

    Parameters
    ----------
    values : ArrayLike, shape (N, 3)
        Readings (NaN rows ignored).

    Returns
    -------
    NDArray[np.bool_], shape (3,)
        True for the constant axes (also when an axis has no finite reading).

    """
    return constant_axes_of([values])


def _finite(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the finite values of ``v`` (``v`` itself, uncopied, when all are)."""
    ok = np.isfinite(v)
    return v if ok.all() else v[ok]


def constant_axes_of(arrays: Sequence[ArrayLike]) -> NDArray[np.bool_]:
    """
    Return :func:`constant_axes` of the readings of several runs taken together.

    Parameters
    ----------
    arrays : sequence of ArrayLike, shape (N_k, 3) each
        The readings of each run (e.g. ``run.omega`` or ``run.accel``; NaN ignored).

    Returns
    -------
    NDArray[np.bool_], shape (3,)
        True for the axes whose finite readings over every run together take at most two
        values (also when an axis has no finite reading at all).

    """
    arrays = [np.asarray(a, dtype=np.float64).reshape(-1, 3) for a in arrays]
    out = np.ones(3, dtype=bool)
    for i in range(3):
        # Three distinct finite values among the first few: not constant, no full pass.
        head = np.unique(np.concatenate([_finite(a[:64, i]) for a in arrays]
                                        or [np.zeros(0)]))
        if head.size > 2:
            out[i] = False
            continue
        cols = [v for v in (_finite(a[:, i]) for a in arrays) if v.size]
        if not cols:
            continue
        lo = min(float(v.min()) for v in cols)
        hi = max(float(v.max()) for v in cols)
        out[i] = lo == hi or all(bool(np.all((v == lo) | (v == hi))) for v in cols)
    return out


def constant_values(arrays: Sequence[ArrayLike]) -> NDArray[np.float64]:
    """
    Return, per axis, the first finite reading of ``arrays`` (NaN for an axis with none).

    What a constant axis reads (:func:`constant_axes_of`), for the report line.
    """
    out = np.full(3, np.nan)
    for a in arrays:
        a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
        for i in np.flatnonzero(np.isnan(out)):
            v = _finite(a[:, i])
            if v.size:
                out[i] = v[0]
    return out


def constant_note(runs: Sequence[Run]) -> str:
    """
    Return why the accelerometer of ``runs`` counts as absent ('' when it does not).

    Every axis of the readings of all the runs together is constant (:func:`constant_axes`).
    """
    acc = [np.asarray(r.accel, dtype=np.float64).reshape(-1, 3) for r in runs
           if r.accel is not None]
    if not acc or not constant_axes_of(acc).all():
        return ''
    rows = [a[np.isfinite(a).all(axis=1)] for a in acc]
    first = next((x[0] for x in rows if len(x)), None)
    value = ', '.join(f'{v:.6g}' for v in (constant_values(acc) if first is None else first))
    return (f'the accelerometer readings are constant (({value}) m/s^2, never varying '
            'beyond one quantum: a driver filling a fixed value); treated as absent')


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
        Per run, its still samples (None: no accelerometer data, or constant readings,
        whose still samples are not looked for).
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


#: Rows per pass of :func:`_force_blocks` (rounded down to whole blocks).
_CHUNK_ROWS = 1 << 17


def _force_blocks(acc: NDArray[np.float64], sel: slice | NDArray[np.int64], n: int,
                  block: int) -> tuple[NDArray[np.float64], ...]:
    """
    Return the block means, counts and within-block sums of squares of ``acc[sel]``.

    The force is centred on its first row (no cancellation in the sums) in passes of whole
    blocks (about :data:`_CHUNK_ROWS` rows): each block's sums are those of one pass over
    the ``n`` rows, without a centred copy of them all.
    """
    first = acc[sel.start] if isinstance(sel, slice) else acc[sel[0]]
    step = block * max(1, _CHUNK_ROWS // block)
    buf = np.empty((min(step, n), acc.shape[1]))
    means, sumsq = [], []
    for c0 in range(0, n, step):
        c1 = min(c0 + step, n)
        rows = (acc[sel.start + c0:sel.start + c1] if isinstance(sel, slice)
                else acc[sel[c0:c1]])
        a = np.subtract(rows, first, out=buf[:c1 - c0])
        means.append(block_mean(a, block))
        sumsq.append(block_sumsq(a, block))
    ya = np.concatenate(means)
    cnt = block_counts(n, block)
    return ya + first, cnt, np.maximum(np.concatenate(sumsq) - cnt[:, None] * ya ** 2, 0.0)


def _reference_design(lf: LinearFit, f: int) -> NDArray[np.float64]:
    """Return the design row at the reference point (every feature zero), (1 + F + K,)."""
    return lf.design(np.zeros((1, f)))[0]


def _segment_blocks(usable: Sequence[tuple], model: CompensationModel, ids: tuple[str, ...],
                    par: dict, block: int) -> tuple[list[dict], tuple[float, float]]:
    """Return per still segment its block means, and the range of the model temperature."""
    th = model.thermal
    segs = []
    lo, hi = math.inf, -math.inf
    for r, d in usable:
        state = run_state(th, r)       # the gyro fit's, not computed again
        x = batch_features(ids, r.t, r.temp, t0=model.t0_c, params=par, state=state)
        acc = np.asarray(r.accel, dtype=np.float64)
        for s in range(d.n_segments):
            idx = np.flatnonzero(d.segment == s)
            if idx.size == 0:
                continue
            # A contiguous segment (a chamber run: all of it) is a view, not a copy.
            sel = slice(idx[0], idx[-1] + 1) if idx[-1] - idx[0] + 1 == idx.size else idx
            ya, cnt, within = _force_blocks(acc, sel, idx.size, block)
            lo = min(lo, float(state[sel].min()))
            hi = max(hi, float(state[sel].max()))
            segs.append({'x': block_mean(x[sel], block), 'y': ya, 'n': cnt, 'within': within,
                         't': block_mean(r.t[sel], block),
                         'temp': block_mean(r.temp[sel], block)})
    return segs, (lo, hi)


def _sums_of_squares(segs: Sequence[dict], lf: LinearFit, coef: NDArray[np.float64],
                     offsets: NDArray[np.float64]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the full-rate sums of squares of the fit's residual and of the raw force (3,).

    From the blocks: the scatter within each block plus each block's count times its
    squared residual (the drift is constant within a block); raw around each segment's mean.
    """
    ss = np.zeros(3)
    ss_raw = np.zeros(3)
    for g, sg in enumerate(segs):
        n = sg['n'][:, None]
        e = sg['y'] - (lf.design(sg['x']) @ coef + offsets[g])
        ss += sg['within'].sum(axis=0) + (n * e ** 2).sum(axis=0)
        mean = (n * sg['y']).sum(axis=0) / n.sum()
        ss_raw += sg['within'].sum(axis=0) + (n * (sg['y'] - mean) ** 2).sum(axis=0)
    return ss, ss_raw


def fit_accel(runs: Sequence[Run], model: CompensationModel, *,
              features: str | Sequence[str] | None = None, kind: str | None = None,
              n_centers: int | None = None, ridge: float | str = 'auto', seed: int = 0,
              max_rows: int = 20_000, bin_c: float = 5.0) -> AccelFit:
    """
    Fit the accelerometer part of ``model`` on the still data of ``runs``.

    Per still sample ``a = c_g + f(x) + noise``: ``c_g`` one constant per orientation
    segment (gravity and the static offset, not thermal), ``f`` the network of the features
    ``x`` of the model's thermal state, fitted with one offset per segment
    (:func:`gyro_tdc.identify.fit_linear` with ``groups``); its intercept is then set so
    ``f`` is zero at the reference point (T0, dynamic terms settled).

    Parameters
    ----------
    runs : sequence of Run
        Training runs (those without ``accel`` data are skipped).
    model : CompensationModel
        The gyro model (format 2): its thermal state, T0 and sensor ids are shared. It does
        not judge stillness (a model still being judged would reject still data).
    features : str or sequence of str, optional
        See :func:`accel_features`.
    kind : str, optional
        ``'rbf'`` or ``'poly'`` (default: the gyro model's).
    n_centers : int, optional
        RBF centres (default: the gyro model's, at least 1).
    ridge : float or 'auto'
        Relative ridge on the RBF weights (:func:`gyro_tdc.identify.fit_linear`).
    seed : int
        Seed of the centre placement.
    max_rows : int
        Rows of the solve; longer still data are block-averaged inside each segment (the
        offset moves over minutes: 20,000 blocks of a 1 h run are 0.18 s each).
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
    # No prior rate: a model still being judged (a conventional f(dT) leaves degrees per
    # second) would reject still data; the scatter, reference and accelerometer decide.
    # A constant accelerometer is absent: its still data are not looked for (they could
    # show no orientation change either).
    present = [r for r in runs if has_accelerometer(r.accel)]
    constant = constant_note(present) if present else ''
    if constant:
        return AccelFit(None, note=constant, static=[None] * len(runs),
                        total=sum(len(r) for r in present))
    datas = [static_data(r) for r in runs]
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
    segs, span = _segment_blocks(usable, model, ids, par,
                                 block_length(n_static, max_rows, at_most=True))
    g0 = len(segs)
    out.samples = n_static
    # Coverage of the still data from its block means (the minutes per bin are the same).
    out.coverage = coverage([Run(sg['t'], sg['temp'], np.zeros((sg['t'].size, 3)),
                                 np.zeros((sg['t'].size, 3))) for sg in segs], bin_c=bin_c)
    if n_static < MIN_SAMPLES:
        out.note = f'too few still samples ({n_static}, need at least {MIN_SAMPLES})'
        return out
    if span[1] - span[0] < MIN_SPAN_C:
        out.note = (f'the still data span {span[1] - span[0]:.3g} degC of the model '
                    f'temperature (need at least {MIN_SPAN_C} degC)')
        return out
    groups = np.concatenate([np.full(sg['n'].size, g) for g, sg in enumerate(segs)])
    lf = fit_linear(np.concatenate([sg['x'] for sg in segs]),
                    np.concatenate([sg['y'] for sg in segs]), kind=kind, n_centers=n_centers,
                    ridge=ridge, seed=seed, groups=groups)
    coef = lf.coef.copy()
    coef[0] = -(_reference_design(lf, f)[1:] @ coef[1:])     # zero at the reference point
    offsets = lf.offsets - coef[0]                             # c_g: the still force at T0
    ss, ss_raw = _sums_of_squares(segs, lf, coef, offsets)
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
    out.part = CompensationModel.network(
        kind, ids, par, model.t0_c, lf.norm, coef, temp_range_c=span,
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
        ``'linear'``, ``'clamp'`` or ``'extrapolate'`` (:mod:`gyro_tdc.model.out_of_range`).
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
        :func:`static_bs` of the raw data; None when the run has no accelerometer data,
        constant readings (:func:`constant_axes`) or is still for less than
        :data:`MIN_STATIC_FRACTION` of its samples.
    per_model : list of (NDArray[np.float64] or None)
        The same after each model.

    """
    data = static_data(run)
    if data is None or data.fraction < MIN_STATIC_FRACTION or constant_note([run]):
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
