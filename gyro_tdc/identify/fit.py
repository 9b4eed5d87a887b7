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
Identification of the compensation model from thermal runs (section 3.2 of the paper).

:func:`fit_model`: normalised effect features, k-means RBF centres, regularised least squares
on the shared estimator, optional refinement, and the thermal state's time constants by
variable projection with a profile interval. See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import datetime as _dt
from typing import Any, Mapping, Sequence

from gyro_tdc import __version__
from gyro_tdc.base import DEG2_PER_RAD2, DEG_PER_RAD
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.linear import fit_linear, LinearFit, refine_rbf, RIDGE_GRID
from gyro_tdc.identify.power_cycles import check_sessions
from gyro_tdc.identify.tau import (choose_state, fit_time_constant, ParamSearch, run_blocks,
                                   run_state, TAU_BOUNDS, TWO_NODE_MARGIN)
from gyro_tdc.model import (CompensationModel, EFFECTS, input_ids, KINDS, normalise_ids,
                            REFERENCE_EFFECTS, resolve_params, STATE_TERMS, TEMPERATURE_EFFECTS,
                            THERMAL_EFFECTS, ThermalState, with_implied)
from gyro_tdc.signal import block_length, check_offsets
import numpy as np
from numpy.typing import NDArray

__all__ = ['check_choices', 'check_finite', 'estimate_t0', 'fit_model', 'fit_px4_cubic',
           'FitOptions', 'MIN_SAMPLES', 'MIN_SPAN_C', 'PX4_FEATURES', 'run_state', 'span',
           'TAU_BOUNDS', 'THERMAL_CHOICES', 'TWO_NODE_MARGIN']

#: Fewest samples a fit accepts.
MIN_SAMPLES = 50
#: The PX4-style baseline (``TC_G*``, ``TC_A*``): a cubic in the measured temperature.
PX4_FEATURES: tuple[str, ...] = ('dT', 'dT2', 'dT3')
#: Smallest temperature span (degC) a fit with temperature features accepts.
MIN_SPAN_C = 0.5
#: Values of ``fit_model(thermal=...)`` besides a fixed :class:`ThermalState`.
THERMAL_CHOICES = ('none', 'first_order', 'two_node', 'auto')
#: The effect that makes the model temperature a lagged state (``lag``, the one thermal id).
(_LAG,) = THERMAL_EFFECTS


def estimate_t0(run: Run, *, window_s: float = 60.0) -> float:
    """Return the reference temperature T0: the median over the first ``window_s`` (>= 1 %)."""
    if len(run) == 0:
        raise FitError('Cannot estimate T0 from an empty run.')
    n = max(int(np.searchsorted(run.t, run.t[0] + window_s)), max(len(run) // 100, 1))
    return float(np.median(run.temp[:n]))


def span(arrays: Sequence[NDArray[np.float64]]) -> tuple[float, float]:
    """Return the smallest and the largest value of the non-empty ``arrays``."""
    arrays = [a for a in arrays if a.size]
    return min(float(a.min()) for a in arrays), max(float(a.max()) for a in arrays)


def _labels(runs: Sequence[Run], sessions: Sequence | None) -> list[int] | None:
    """Return a 0-based session label per run (in order of appearance), None for one."""
    if sessions is None:
        return None
    if len(sessions) != len(runs):
        raise FitError(f'Expected one session label per run ({len(runs)}), got '
                       f'{len(sessions)}.')
    index: dict = {}
    labels = [index.setdefault(s, len(index)) for s in sessions]
    return labels if len(index) > 1 else None


def check_finite(run: Run, keys: Sequence[str] = ('temp', 'omega', 'omega_ref')) -> None:
    """Raise FitError naming the first field of ``run`` holding a non-finite value."""
    for key in keys:
        x = np.asarray(getattr(run, key))
        # All finite iff the min and the max are (NaN propagates): no boolean temporary.
        if x.size and not (np.isfinite(x.min()) and np.isfinite(x.max())):
            raise FitError(f'Run {run.name!r} has non-finite values in `{key}`.')


def _check_runs(runs: Sequence[Run], ids: Sequence[str],
                rows: Sequence[NDArray[np.bool_]] | None
                ) -> tuple[list[int], tuple[float, float] | None]:
    """
    Return the samples that count per run and the thermometer's span (None: not needed).

    FitError, naming the problem, when they cannot fit.
    """
    if not runs:
        raise FitError('No training runs given.')
    if rows is not None and (len(rows) != len(runs) or any(
            np.shape(m) != (len(r),) for r, m in zip(runs, rows))):
        raise FitError('Expected `rows` to hold one boolean mask of shape (N,) per run.')
    kept = [len(r) if rows is None else int(np.count_nonzero(rows[i])) for i, r in enumerate(runs)]
    if (n := sum(kept)) < MIN_SAMPLES:
        raise FitError(f'Too few samples to fit: {n} (need at least {MIN_SAMPLES}).')
    for r in runs:
        check_finite(r)
    thermometer = None
    if TEMPERATURE_EFFECTS & set(ids):
        lo, hi = thermometer = span([r.temp if rows is None else r.temp[rows[i]]
                                     for i, r in enumerate(runs)])
        if hi - lo < MIN_SPAN_C:
            raise FitError(f'Temperature span too small to fit: {hi - lo:.3f} degC '
                           f'(need at least {MIN_SPAN_C} degC).')
    needs_ref = sorted(REFERENCE_EFFECTS & set(ids))
    if needs_ref and not any(np.any(np.abs(r.omega_ref) > 1e-9) for r in runs):
        raise FitError(f'Effect `{needs_ref[0]}` needs a non-zero reference rate (rate-table '
                       'data); every training run has omega_ref = 0.')
    return kept, thermometer


def check_choices(kind: str, thermal: str | ThermalState | None) -> None:
    """Refuse a model kind or a thermal front end :func:`fit_model` does not know (FitError)."""
    if kind not in KINDS:
        raise FitError(f'Expected `kind` to be one of {", ".join(KINDS)}, got {kind!r}.')
    if not (thermal is None or isinstance(thermal, ThermalState) or thermal in THERMAL_CHOICES):
        raise FitError(f'Expected `thermal` to be one of {", ".join(THERMAL_CHOICES)} or a '
                       f'ThermalState, got {thermal!r}.')


def _thermal_choice(ids: tuple[str, ...], thermal: str | ThermalState | None,
                    fit_params: bool, params: Mapping | None
                    ) -> tuple[tuple[str, ...], ThermalState | str]:
    """Return the effect ids and the fixed front end, or the mode of its search (a str)."""
    lagged, fixed = _LAG in ids, isinstance(thermal, ThermalState)
    if thermal is None:
        thermal = 'first_order' if lagged else 'none'
    if (thermal.kind if fixed else thermal) == 'none':
        if lagged:
            what = "a thermal front end of kind 'none'" if fixed else "thermal='none'"
            raise FitError(f'`lag` makes the model temperature a lagged state; {what} '
                           'contradicts it.')
        return ids, thermal if fixed else ThermalState()
    ids = with_implied(ids + (_LAG,))
    if fixed or fit_params:
        return ids, thermal
    if thermal == 'two_node':
        raise FitError("thermal='two_node' with fit_params=False needs the time constants: "
                       'pass a ThermalState.')
    return ids, ThermalState('first_order', (resolve_params((_LAG,), params)[_LAG]['tau_s'],))


@dataclass(frozen=True)
class FitOptions:
    """
    How :func:`fit_model` fits: the model's form, its parameters and what it records.

    ``kind`` ``'rbf'`` (``n_centers`` centres, ``seed`` placing them, ``refine`` by nonlinear
    least squares) or ``'poly'``; ``features`` the effect ids (``bias`` implied; with ``lag`` every
    temperature term, the RBF inputs, the scale term and the range follow the thermal state);
    ``t0`` the reference (default :func:`estimate_t0` of the first run). ``fit_params`` fits the
    catalog's fitted parameters (warm-up tau) and the state's time constants by variable
    projection with a 95 % profile interval, else takes them from ``params`` or the catalog.
    ``ridge`` is relative, on the RBF weights only (``'auto'``: cross-validated); longer data
    than ``max_rows`` are block-averaged. ``thermal``: ``'none'``, ``'first_order'``,
    ``'two_node'``, ``'auto'`` (two nodes when they lower the cross-validated error by
    :data:`TWO_NODE_MARGIN`) or a fixed :class:`ThermalState` (default: first order with
    ``lag``). ``check_sessions``: an axis whose curve does not predict a held-out power cycle
    better than its offset keeps the offset only (:mod:`gyro_tdc.identify.power_cycles`);
    with fewer than ``min_folds`` held-out power cycles to judge it, every axis does.
    """

    kind: str = 'rbf'
    features: str | Sequence[str] = ('dT', 'dT2')
    t0: float | None = None
    n_centers: int = 12
    refine: bool = False
    fit_params: bool = True
    params: Mapping[str, Mapping[str, float]] | None = None
    ridge: float | str = 'auto'
    max_rows: int = 200_000
    seed: int = 0
    frame_id: str = 'imu_link'
    sensor_id: str = ''
    created: Mapping | None = None
    thermal: str | ThermalState | None = None
    check_sessions: bool = True
    min_folds: int = 1

    def __post_init__(self) -> None:
        """Check the kind and the thermal front end (:func:`check_choices`)."""
        check_choices(self.kind, self.thermal)


def fit_model(runs: Sequence[Run], options: FitOptions | None = None, *,
              rows: Sequence[NDArray[np.bool_]] | None = None,
              sessions: Sequence | None = None, **kw: Any) -> CompensationModel:
    """
    Identify a compensation model from training runs (``options``, or its fields as ``**kw``).

    The time constants are searched on coarse blocks with a polynomial in the state (an RBF
    network of a slowly lagged state fits any function of time and pins nothing), then the model
    is fitted at them on the shared estimator. ``rows`` (a mask per run) are the samples that
    count (the still ones): the fit, residual, sample count and range use them while the filters
    run over every sample. ``sessions`` (a label per run) give every session its own turn-on
    offset beside one curve: the intercept is their mean (none on an axis without curve where
    the mean does not predict a held-out power cycle's, :func:`~gyro_tdc.signal.check_offsets`),
    ``metrics['sessions']`` holds them.
    """
    o = replace(options or FitOptions(), **kw)
    ids = normalise_ids(o.features)
    if o.kind == 'rbf' and o.n_centers < 1:
        raise FitError(f'`n_centers` must be at least 1 for an rbf model, got {o.n_centers}.')
    ids, th = _thermal_choice(ids, o.thermal, o.fit_params, o.params)
    kept, thermometer = _check_runs(runs, ids, rows)
    n_total = sum(kept)
    labels = _labels(runs, sessions)
    t0 = estimate_t0(runs[0]) if o.t0 is None else o.t0
    inputs = input_ids(ids, state=True)
    par = resolve_params(ids, o.params)
    rows = None if rows is None else [np.asarray(m, dtype=bool) for m in rows]
    block = block_length(sum(len(r) for r in runs), o.max_rows, at_most=True)
    blocks, y, groups = run_blocks(runs, block, rows, labels)
    th, thermal_info = _search(runs, o, ids, inputs, t0, par, th, rows, labels)

    states = [run_state(th, r) for r in runs]
    lo, hi = state_span = span(states if rows is None else [s[m] for s, m in zip(states, rows)])
    if th.kind != 'none' and thermometer is not None and hi - lo < MIN_SPAN_C:
        # The lagged die temperature the model is fitted in spans too little.
        tlo, thi = thermometer
        raise FitError(f'The lagged die temperature (tau {th.tau_total_s:.0f} s) spans '
                       f'{hi - lo:.3f} degC only ({lo:.2f} .. {hi:.2f}; the thermometer '
                       f'{thi - tlo:.2f} degC; need at least {MIN_SPAN_C} degC): record a wider '
                       'range, or give --features without lag.')
    x = np.concatenate([b.features(inputs, t0, par, th, state=s) for b, s in zip(blocks, states)])
    scale_cols = (np.concatenate([b.scale_cols(t0, state=s) for b, s in zip(blocks, states)])
                  if 'scale' in ids else None)
    fit = fit_linear(x, y, scale_cols=scale_cols, kind=o.kind, n_centers=o.n_centers,
                     ridge=o.ridge, seed=o.seed, groups=groups)
    offsets = fit.offsets
    if o.refine and o.kind == 'rbf':
        if groups is None:
            fit = refine_rbf(x, y, scale_cols, fit, ridge=fit.ridge, seed=o.seed)
        else:       # refined with the session offsets held: one offset, their mean
            level = y - (offsets - offsets.mean(axis=0))[groups]
            fit = refine_rbf(x, level, scale_cols, replace(fit, coef=_with_level(fit)),
                             ridge=fit.ridge, seed=o.seed)
            offsets = offsets - offsets.mean(axis=0) + fit.coef[0]
    check, counts = None, np.concatenate([b.counts for b in blocks])
    bstate = np.concatenate([b.mean(s) for b, s in zip(blocks, states)])
    if groups is not None and o.check_sessions:
        fit, offsets, check = check_sessions(fit, offsets, x, y, scale_cols, groups, counts,
                                             bstate, kind=o.kind, n_centers=o.n_centers,
                                             seed=o.seed, min_folds=o.min_folds)
    coef, turn_on = fit.coef, None
    if groups is not None:
        coef = _with_level(fit, offsets)
        if o.check_sessions:
            coef[0], turn_on = check_offsets(offsets, coef, fit.scale)
    if th.kind != 'none':
        par[_LAG] = {'tau_s': th.tau_total_s}
    created = {'utc': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
               'gyro_tdc_version': __version__, **(o.created or {})}
    # The training residual variance per axis at full rate, from the blocks: the drift moves
    # slowly, so sum((y - b)^2) is the within-block scatter plus each block's count times its
    # squared residual; compensation divides by (1 + s dT), so does the residual.
    within = np.concatenate([b.scatter(fit.scale, t0, state=s) if np.any(fit.scale)
                             else b.ss_within for b, s in zip(blocks, states)])
    gain = 1.0 + (bstate - t0)[:, None] * fit.scale
    ss = ((within + counts[:, None] * fit.resid ** 2) / gain ** 2).sum(axis=0)
    residual_var = np.maximum(ss, 0.0) / n_total
    metrics = {'samples': int(n_total), 'runs': [r.name for r in runs],
               'train_bs_dps2': (residual_var * DEG2_PER_RAD2).tolist(),
               'train_rms_dps': np.sqrt(residual_var * DEG2_PER_RAD2).tolist(),
               'raw_bs_dps2': (sum(b.ss_raw for b in blocks) / n_total * DEG2_PER_RAD2).tolist(),
               'ridge': fit.ridge, **({'thermal': thermal_info} if thermal_info else {})}
    if groups is not None:
        metrics['sessions'] = _session_metrics(runs, labels, offsets - coef[0], kept, check,
                                               turn_on)
    return CompensationModel.network(o.kind, ids, par, t0, fit.norm, coef, scale=fit.scale,
                                     temp_range_c=state_span, residual_var=residual_var,
                                     frame_id=o.frame_id, sensor_id=o.sensor_id,
                                     created=created, thermal=th, metrics=metrics)


def _search(runs: Sequence[Run], o: FitOptions, ids: tuple[str, ...], inputs: tuple[str, ...],
            t0: float, par: dict, th: ThermalState | str,
            rows: Sequence[NDArray[np.bool_]] | None, labels: Sequence[int] | None
            ) -> tuple[ThermalState, dict]:
    """
    Fit the effect time constants (into ``par``) and the thermal front end on coarse blocks.

    Returns the front end (``th`` when fixed, else searched in the mode ``th`` names) and the
    search record (empty when fixed).
    A thermal state is searched with a polynomial in it (for an rbf model, the model's
    terms with every power of the state): an RBF network of a slowly lagged state fits any
    function of time, the state turned into a clock, and pins nothing.
    """
    free = ([(eid, name) for eid in inputs for name in EFFECTS[eid].fitted]
            if o.fit_params else [])
    fit_state = isinstance(th, str)
    if not (free or fit_state):
        return th, {}
    mode, th = (th, ThermalState('first_order', (par[_LAG]['tau_s'],))) if fit_state else ('', th)
    search = ParamSearch(runs, input_ids(ids + tuple(STATE_TERMS), state=True)
                         if fit_state and o.kind == 'rbf' else inputs, t0,
                         inner='poly' if fit_state else o.kind, n_centers=o.n_centers,
                         ridge=RIDGE_GRID[1] if o.ridge == 'auto' else o.ridge, seed=o.seed,
                         scale='scale' in ids, rows=rows, labels=labels)
    for _round in range(2 if len(free) + fit_state > 1 else 1):
        for eid, name in free:

            def sse(tau: float, eid: str = eid, name: str = name) -> float:
                return float(search.sse(th, {**par, eid: {**par[eid], name: tau}}).sum())

            par[eid][name] = fit_time_constant(sse, EFFECTS[eid].bounds[name], n_grid=13).tau
        if fit_state:
            tau, seen = search.first_order(par, TAU_BOUNDS)
            th = ThermalState('first_order', (tau,))
    return choose_state(search, mode, par, th.tau_s[0], seen) if fit_state else (th, {})


def _with_level(fit: LinearFit, offsets: NDArray[np.float64] | None = None
                ) -> NDArray[np.float64]:
    """Return the coefficients with the constant the mean of the session offsets."""
    coef = fit.coef.copy()
    coef[0] = (fit.offsets if offsets is None else offsets).mean(axis=0)
    return coef


def _session_metrics(runs: Sequence[Run], labels: Sequence[int], offsets: NDArray[np.float64],
                     kept: Sequence[int], check: dict | None, turn_on: dict | None) -> dict:
    """Return the sessions' names, samples, offsets from the model's (deg/s) and the checks."""
    rel = offsets * DEG_PER_RAD
    own = [[i for i, g in enumerate(labels) if g == k] for k in range(offsets.shape[0])]
    return {'count': int(offsets.shape[0]),
            'names': [', '.join(runs[i].name for i in ii) for ii in own],
            'samples': [sum(kept[i] for i in ii) for ii in own], 'offset_dps': rel.tolist(),
            'spread_dps': (rel.max(axis=0) - rel.min(axis=0)).tolist(),
            **({'heldout': check} if check else {}),
            **({'turn_on': turn_on} if turn_on else {})}


def fit_px4_cubic(runs: Sequence[Run], *, t0: float | None = None, **kw) -> CompensationModel:
    """Fit the PX4-style baseline: a ``poly`` cubic in T - T0 per axis (``fit_model`` ``**kw``)."""
    return fit_model(runs, kind='poly', features=PX4_FEATURES, t0=t0, **kw)
