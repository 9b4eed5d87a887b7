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
The search: name the missing effect, add it, refit, repeat until nothing passes.

:func:`discover` scores every candidate against the current model with the three tests of
the false-discovery guard, adds the best, refits the time constants and repeats; effects the
data cannot excite are reported before any fit. See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
import math
from typing import Any, Callable, Mapping, Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.axes import fit_varying
from gyro_tdc.identify.discover.data import (bandwidth, BlockData, COLLINEAR, corr, DEG,
                                             excitation, gap, hac_pvalue, LinearModel,
                                             make_folds, mse, rel_residual, unidentifiable, wsse)
from gyro_tdc.identify.discover.report import residual_adev, residual_maps
from gyro_tdc.identify.discover.results import CandidateScore, DiscoveryResult, Step
from gyro_tdc.identify.fit import check_finite, estimate_t0, fit_model, MIN_SPAN_C, span
from gyro_tdc.identify.tau import effective_samples, fit_time_constant, profile_interval
from gyro_tdc.model import (EFFECTS, NONLINEAR_EFFECTS, normalise_ids, STATIC_EFFECTS,
                            TEMPERATURE_EFFECTS, THERMAL_EFFECTS, ThermalState, with_implied)
from gyro_tdc.signal import fit_columns, Folds
import numpy as np
from numpy.typing import NDArray

__all__ = ['build_model', 'discover', 'DiscoverOptions', 'model_features']

#: Candidate order (catalog order without ``bias``).
_CANDIDATES = tuple(e for e in EFFECTS if e != 'bias')
#: Effects whose time constant the search fits: the catalog's fitted ones (the thermal state,
#: warm-up) and the smoothing of ``dTdt``, whose best value is the sensor's (the die's own
#: rate of change, or a slower gradient); it is recorded in the result's parameters, which
#: the model of a discovery and ``train --features auto`` keep.
_TIMED = frozenset(NONLINEAR_EFFECTS | {e for e in EFFECTS if 'tau_s' in EFFECTS[e].params})
#: Search bounds of a time constant the catalog gives no bounds for (the dTdt smoothing), s.
_SMOOTHING_BOUNDS_S = (1.0, 3600.0)
#: Candidates with time memory, scored beside the static curve too (:func:`_score`).
_MEMORY = tuple(e for e in _CANDIDATES if e not in STATIC_EFFECTS)
#: The static curve beyond ``dT`` that a time-memory candidate must beat.
_CURVE = ('dT2', 'dT3')
#: The Allan deviation of a search without it (``allan=False``).
_NO_ADEV = (np.zeros(0), np.zeros(0))


def _effects(*groups: Sequence[str]) -> tuple[str, ...]:
    """Return the effects of ``groups`` together, in catalog order."""
    ids = set().union(*groups)
    return tuple(e for e in EFFECTS if e in ids)


def _tau_bounds(data: BlockData, eid: str) -> tuple[float, float]:
    """Return the search bounds of an effect's time constant, s."""
    lo, hi = EFFECTS[eid].bounds.get('tau_s', _SMOOTHING_BOUNDS_S)
    grid_step = max(float(g[0][1] - g[0][0]) for g in data.grids)    # every grid: 2+ points
    # A warm-up shorter than three blocks is a dummy for the first block.
    lo = max(lo, 2.0 * grid_step, 3.0 * data.block_s if eid == 'warmup' else 0.0)
    return lo, min(hi, max(2.0 * max(r.duration_s for r in data.runs), 4.0 * lo))


def _fit_taus(data: BlockData, effects: Sequence[str], params: dict, which: Sequence[str]) -> dict:
    """
    Fit the time constants of ``which`` by a bounded 1-D search on the residual each.

    An effect of ``which`` without parameters starts from the catalog's. The linear
    coefficients are re-solved at every trial (variable projection);
    :func:`gyro_tdc.identify.fit_time_constant` searches a log-spaced grid for the basin and
    refines it with a bounded Brent search.
    """
    params = {k: dict(v) for k, v in params.items()}     # its inner dicts change below
    for eid in which:
        params.setdefault(eid, dict(EFFECTS[eid].params))
    for eid in which:
        def sse(tau: float, eid: str = eid) -> float:
            trial = {**params, eid: {**params[eid], 'tau_s': tau}}
            return wsse(data, LinearModel(data, effects, trial).residual())

        params[eid]['tau_s'] = fit_time_constant(sse, _tau_bounds(data, eid), n_grid=14,
                                                 xatol=0.01).tau
    return params


def _thermal_state(data: BlockData, model: LinearModel) -> ThermalState | None:
    """
    Return the model's thermal state with the profile interval of its tau (None without).

    The profile is the weighted residual sum of squares per axis with every coefficient
    re-solved at each trial tau (the other time constants held);
    :func:`gyro_tdc.identify.profile_interval` turns it into a 95 % interval, counting the
    residual's memory (:func:`gyro_tdc.identify.effective_samples` of the block means), and
    says whether it pins tau.
    """
    if model.state_tau is None:
        return None
    tau = model.state_tau
    lo, hi = _tau_bounds(data, 'lag')

    def sse(v: float) -> NDArray[np.float64]:
        r = LinearModel(data, model.effects, {**model.params, 'lag': {'tau_s': v}}).residual()
        return (data.w[:, None] * r * r).sum(axis=0)

    n_eff = effective_samples(model.residual() * data.sw[:, None])
    prof = profile_interval(sse, tau, (min(lo, tau), max(hi, tau)), n_eff)
    return ThermalState('first_order', (tau,), (prof.interval,), prof.identifiable)


def _candidate(data: BlockData, base: Sequence[str], params: Mapping, eid: str
               ) -> tuple[tuple[str, ...], dict]:
    """
    Return the effects ``base`` plus candidate ``eid``, and ``params`` with its tau fitted.

    With the thermal state in the model (or as the candidate) its tau is refitted with the
    candidate: a curvature named after ``lag`` moves the state's time constant.
    """
    effects = _effects(base, {eid})
    timed = dict.fromkeys(e for e in (eid, 'lag') if e in _TIMED and e in effects)
    return effects, _fit_taus(data, effects, params, list(timed))


def _n_params(model: LinearModel, eid: str, params: Mapping) -> int:
    """Return the parameters candidate ``eid`` adds to ``model``: coefficients and taus."""
    cand = LinearModel(model.data, _effects(model.effects, {eid}), params)
    return (cand.p - model.p) * 3 + (eid in _TIMED)


def _noise_lags(data: BlockData, model: LinearModel, todo: Sequence[str], cparams: Mapping
                ) -> tuple[list, int]:
    """
    Return per-axis HAC bandwidths and the noise memory (blocks) from the richest model.

    The memory of the noise is measured on the residual of the model plus every candidate
    (each with its fitted time constant), so that a second effect not yet in the model does
    not pass for long-memory noise and hide the first.
    """
    params = {**model.params, **{eid: cparams[eid][eid] for eid in todo if eid in _TIMED}}
    r = LinearModel(data, _effects(model.effects, todo), params).residual() * data.sw[:, None]
    memory = max(bandwidth(r[:, a], floor=False) for a in range(3))
    return [bandwidth(r[:, a]) for a in range(3)], int(memory)


@dataclass
class _Round:
    """One round of scoring: the current model's fit, folds, held-out residual and scores."""

    coef: NDArray[np.float64]
    resid: NDArray[np.float64]
    folds: Folds
    buffer: int
    heldout: NDArray[np.float64]
    results: list


def _score(data: BlockData, model: LinearModel, rnd: _Round, eid: str, params: dict,
           o: DiscoverOptions, lags: Sequence[int], n_cand: int, curve: tuple | None
           ) -> tuple[CandidateScore, NDArray[np.float64] | None, dict]:
    """
    Score one candidate against ``model`` (fitted in ``rnd``): its score, contribution, params.

    With ``curve`` (:func:`_score_round`) a time-memory candidate must also gain held out
    beside the static curve, and is ranked by its gain there.
    """
    cand = LinearModel(data, _effects(model.effects, {eid}), params)
    idx = cand.columns_of(eid)
    own = dict(params[eid]) if eid in _TIMED else {}
    # Is it spanned by the current model (per axis)? (The thermal state has no column of
    # its own: it changes the temperature columns; its test is the J test below.)
    rel = [rel_residual(np.delete(xa, idx, axis=1), xa[:, i])
           for xa in (cand.design(a) * data.sw[:, None] for a in range(3))
           for i in idx if np.linalg.norm(xa[:, i]) > 0]
    if idx and (not rel or max(rel) < COLLINEAR):
        return CandidateScore(eid, own, 1.0, 0.0, 0.0, math.nan, math.nan, False, 'collinear',
                              np.zeros((len(idx), 3))), None, params
    coef = cand.fit()
    pred = cand.predict(coef)
    r = data.y - pred
    ho = cand.cv_residual(rnd.folds)
    mse_m = mse(data, rnd.heldout)
    gain = (mse_m - mse(data, ho)) * DEG ** 2
    eff = math.sqrt(max(wsse(data, rnd.resid) - wsse(data, r), 0.0) / (3.0 * data.w.sum())) * DEG
    # A candidate that changes the model instead of adding columns (the thermal state) is
    # not nested in it: Davidson and MacKinnon's J test adds its fitted values to the
    # current model as one column per axis and tests that column.
    aug = None if idx else LinearModel(data, model.effects, model.params, extra=pred)
    p = hac_pvalue(cand, idx, lags) if idx else hac_pvalue(aug, aug.columns_of('extra'), lags)
    floor = data.floor * DEG
    why = [f'p={p:.2g}'] if p >= o.alpha / max(n_cand, 1) else []
    if gain <= max(o.min_heldout * floor ** 2, 0.01 * mse_m * DEG ** 2):
        why.append('no held-out gain')
    elif curve is not None:
        # On a run that heats or cools only, a slow decay or rate term can hold curvature the
        # final RBF network holds anyway, and it extrapolates wrongly off the one ramp
        # direction it was fitted on: scored once more with the static curvature the model
        # lacks on both sides, its time constants refitted there.
        effects, trial = _candidate(data, curve[1], params, eid)
        ho_curve = LinearModel(data, effects, trial).cv_residual(rnd.folds)
        beside = (curve[2] - mse(data, ho_curve)) * DEG ** 2
        if eid not in THERMAL_EFFECTS and beside <= max(o.min_heldout * floor ** 2,
                                                        0.01 * curve[2] * DEG ** 2):
            why.append(f'no held-out gain beside {"+".join(curve[0])}')
        # A candidate is credited with what the static curve cannot hold. The thermal state
        # adds no column that could stand in for curvature; beside the curve its cubic of a
        # far-lagging state can run away held out: it is ranked by its gain there when that
        # is a gain.
        gain = beside if eid not in THERMAL_EFFECTS else max(gain, beside)
    if eff < o.min_effect * floor:
        why.append('effect below noise')
    sc = CandidateScore(eid, own, p, gain, eff, gap(data, r), gap(data, ho), not why,
                        ', '.join(why), coef[idx])
    return sc, pred - model.predict(rnd.coef), params


@dataclass(frozen=True)
class DiscoverOptions:
    """What :func:`discover` starts from, the candidates it tries and its false-discovery guard."""

    #: Effects of the starting model (``'bias,dT'``: eq. 18's conventional model); ``bias``
    #: is always included, as one offset per run.
    base: str | Sequence[str] = ('bias', 'dT')
    #: Effects to try (default: every catalog effect not in ``base``).
    candidates: str | Sequence[str] | None = None
    #: Block length of the analysis, s; gaps and the noise floor are RMS of block means.
    block_s: float = 10.0
    #: Reference temperature, degC (default :func:`gyro_tdc.identify.estimate_t0` of the
    #: first run).
    t0: float | None = None
    #: Family-wise significance level per step (Bonferroni over candidates and axes).
    alpha: float = 0.01
    #: Smallest held-out gain, as a fraction of the squared noise floor.
    min_heldout: float = 0.1
    #: Smallest effect RMS, as a fraction of the noise floor.
    min_effect: float = 0.6
    #: A candidate within this fraction of the best held-out gain...
    alias_margin: float = 0.25
    #: ...whose fitted contribution correlates at least this much with the best's is an alias.
    alias_corr: float = 0.9
    #: Most effects added.
    max_steps: int = 6
    #: Cross-validation folds for a single run (:func:`make_folds`; several runs: leave one
    #: run out).
    n_folds: int = 5
    #: Compute the Allan deviation of the residual before and after each step.
    allan: bool = True


def discover(runs: Sequence[Run], options: DiscoverOptions | None = None, *,
             progress: Callable[[int, str], None] | None = None, **kw: Any) -> DiscoveryResult:
    """
    Find the effects a drift model is missing, one step at a time.

    ``runs``: measured runs, each a continuous recording from power-on (filters restart per
    run). ``options`` (or its fields as ``**kw``): base, candidates and guard. ``progress(step,
    effect_id)`` is called before each candidate is scored (``step``: effects named so far,
    from 0), e.g. for a progress bar. Returns the steps, final model, unidentifiable effects
    and maps. Raises FitError when the runs cannot support the analysis (too few blocks,
    non-finite values...), FeatureError for an unknown effect id.
    """
    o = replace(options or DiscoverOptions(), **kw)
    runs = list(runs)
    _check(runs, o.block_s)
    base_ids = with_implied(tuple(normalise_ids(o.base)) + ('bias',))
    pool = _CANDIDATES if o.candidates is None else normalise_ids(o.candidates)
    cand_ids = tuple(e for e in pool if e not in base_ids and e != 'bias')
    data = BlockData(runs, block_s=o.block_s, t0=estimate_t0(runs[0]) if o.t0 is None else o.t0)
    _check_blocks(data, base_ids, o.block_s)
    unident, notes = excitation(data, base_ids)
    model = LinearModel(data, base_ids,
                        _fit_taus(data, base_ids, {}, [e for e in base_ids if e in _TIMED]))
    steps, collinear, adev = [], [], None
    while True:
        todo = [e for e in cand_ids if e not in model.effects and e not in unident]
        rnd = _score_round(data, model, todo, o, collinear, progress, len(steps))
        if not steps:           # the first round: the base model
            notes += _confounded(data, model, [x[0] for x in rnd.results])
        passing = [x for x in rnd.results if x[0].passed]
        if not passing or len(steps) >= o.max_steps:
            break
        step, model, adev = _add_best(data, model, rnd, passing, o, adev)
        steps.append(step)
    # The result of the last round (the final model's): gaps, maps and the record.
    effects = model.effects
    unident.update({eid: unidentifiable(eid, 'on this data its feature is a combination of the '
                                        f'effects of the model ({", ".join(effects)})')
                    for eid in collinear if eid not in effects and eid not in unident})
    adev = (adev or residual_adev(data, model, rnd.coef)) if o.allan else _NO_ADEV
    folds = ('leave-one-run-out' if data.n_runs >= 2
             else f'{len(rnd.folds)} blocked folds, buffer {rnd.buffer} blocks')
    settings = {k: getattr(o, k) for k in ('alpha', 'min_heldout', 'min_effect', 'alias_margin',
                                           'alias_corr')}
    settings.update(folds=folds, block_s=float(o.block_s), block_mean_s=float(data.block_eff_s))
    return DiscoveryResult(
        base_effects=base_ids, final_effects=effects,
        params={k: dict(v) for k, v in model.params.items() if k in effects and k in _TIMED},
        noise_floor_dps=data.floor * DEG, noise_floor_axes_dps=data.floor_axes * DEG,
        white_noise_dps=data.white * DEG, block_s=float(o.block_s), t0_c=float(data.t0),
        steps=tuple(steps), notes=tuple(notes), settings=settings, blocks=data.K,
        unidentifiable=tuple(unident[e] for e in EFFECTS if e in unident and e in cand_ids),
        candidates=tuple(x[0] for x in rnd.results), maps=residual_maps(data, rnd.resid),
        gap_dps=gap(data, rnd.resid), heldout_gap_dps=gap(data, rnd.heldout),
        coef=_coef_dict(data, model, rnd.coef), runs=tuple(x.name for x in data.runs),
        adev_tau_s=adev[0], adev_dps=adev[1],
        thermal=steps[-1].thermal if steps else _thermal_state(data, model))


def _score_round(data: BlockData, model: LinearModel, todo: Sequence[str], o: DiscoverOptions,
                 collinear: list, progress: Callable[[int, str], None] | None, step: int
                 ) -> _Round:
    """Score every candidate of ``todo`` against ``model``; collinear ones go to the list."""
    coef = model.fit()
    cparams = {eid: _candidate(data, model.effects, model.params, eid)[1] for eid in todo}
    lags, memory = _noise_lags(data, model, todo, cparams)
    folds, buffer = make_folds(data, memory, o.n_folds)
    rnd = _Round(coef, data.y - model.predict(coef), folds, buffer, model.cv_residual(folds), [])
    # The static curve the model lacks (of :data:`_CURVE`), beside which a time-memory
    # candidate is scored too: its effects and held-out mean square.
    missing = tuple(e for e in _CURVE if e not in model.effects)
    effects = _effects(model.effects, missing)
    curve = ((missing, effects, mse(data, LinearModel(data, effects, model.params).cv_residual(
        folds))) if missing and set(todo) & set(_MEMORY) else None)
    for eid in todo:
        if progress is not None:
            progress(step, eid)
        item = _score(data, model, rnd, eid, cparams[eid], o, lags, len(todo),
                      curve if eid in _MEMORY else None)
        if item[0].why_not != 'collinear':
            rnd.results.append(item)
        elif eid not in collinear:
            collinear.append(eid)
    rnd.results.sort(key=lambda x: (not x[0].passed, -x[0].heldout_gain_dps2))
    return rnd


def _add_best(data: BlockData, model: LinearModel, rnd: _Round, passing: list,
              o: DiscoverOptions, adev: tuple | None) -> tuple[Step, LinearModel, tuple]:
    """
    Add the best passing candidate (of its aliases, the one with the fewest parameters).

    Among aliases that pass the guard, the one with the fewest parameters is named: a
    lagging die with a linear drift (one time constant) rather than dT/dt (a time constant
    and a coefficient per axis), whose columns hold the same curve. On data that only heat
    (or only cool) lag and dT/dt are aliases whenever both pass within the margin: a dT/dt
    input would be extrapolated on the other ramp direction, while the thermal state stays
    inside the trained temperatures. Returns the step, the new model and its Allan deviation.
    """
    best, contrib_b, _p = passing[0]
    one = data.heating != data.cooling      # data that only heat, or only cool
    family = [passing[0]] + [
        item for item in rnd.results[1:] for sc, contrib, _p in [item]
        if contrib is not None and sc.heldout_gain_dps2 > 0
        and sc.heldout_gain_dps2 >= (1.0 - o.alias_margin) * best.heldout_gain_dps2
        and (abs(corr(contrib * data.sw[:, None], contrib_b * data.sw[:, None])) >= o.alias_corr
             or (one and {sc.effect, best.effect} == {'lag', 'dTdt'} and sc.passed))]
    best, _c, p_b = min((x for x in family if x[0].passed),
                        key=lambda x: _n_params(model, x[0].effect, x[2]))
    effects = _effects(model.effects, {best.effect})
    refit = [e for e in effects if e in _TIMED]
    new = LinearModel(data, effects,
                      _fit_taus(data, effects, p_b, refit) if len(refit) > 1 else p_b)
    coef = new.fit()
    r_n = data.y - new.predict(coef)
    before, after = ((adev or residual_adev(data, model, rnd.coef),
                      residual_adev(data, new, coef)) if o.allan else (_NO_ADEV, _NO_ADEV))
    return Step(
        effect=best.effect, aliases=tuple(x[0].effect for x in family if x[0] is not best),
        description=EFFECTS[best.effect].description,
        params=dict(new.params.get(best.effect, {})) if best.effect in _TIMED else {},
        coef_dps=coef[new.columns_of(best.effect)] * (1.0 if best.effect == 'scale' else DEG),
        gap_before_dps=gap(data, rnd.resid), gap_after_dps=gap(data, r_n),
        heldout_gap_before_dps=gap(data, rnd.heldout),
        heldout_gap_after_dps=gap(data, new.cv_residual(rnd.folds)),
        candidates=tuple(x[0] for x in rnd.results), maps_before=residual_maps(data, rnd.resid),
        maps_after=residual_maps(data, r_n), adev_tau_s=before[0], adev_before_dps=before[1],
        adev_after_dps=after[1], best=best, thermal=_thermal_state(data, new)), new, after


def _check_blocks(data: BlockData, base_ids: tuple[str, ...], block_s: float) -> None:
    """Refuse block data too short for the base model, or a base it cannot excite."""
    if data.K < 8:
        raise FitError(f'Too few blocks to analyse: {data.K} blocks of {block_s:g} s '
                       '(need at least 8); record longer or use a shorter block.')
    if 'scale' in base_ids and not np.any(np.abs(data.ref) > 1e-12):
        raise FitError('Effect `scale` in the base model needs a non-zero reference rate '
                       '(rate-table data); every run has omega_ref = 0.')
    if data.K <= len(base_ids) - 1 + data.n_runs + 2 + 2:     # the base's parameters, and 2
        raise FitError(f'Too few blocks ({data.K}) for the base model '
                       f'({", ".join(base_ids)}); record longer or use a shorter block.')


def _confounded(data: BlockData, model: LinearModel, scores: Sequence[CandidateScore]
                ) -> list[str]:
    """Return notes on candidate pairs whose columns are strongly correlated on this data."""
    x, cols, notes = model.common, {}, []
    for sc in scores:
        if sc.effect == 'lag':          # what the state changes: its dT minus the measured
            col = data.state_columns(sc.params['tau_s'])['dT'] - data.static['dT']
        elif EFFECTS[sc.effect].is_input:
            col = data.column(sc.effect, {sc.effect: sc.params}, state_tau=model.state_tau)
        else:
            continue
        beta = fit_columns(x, col, weights=data.w, normalise=True, rcond=1e-12)
        cols[sc.effect] = (col - x @ beta) * data.sw
    for (a, col_a), (b, col_b) in combinations(cols.items(), 2):
        if abs(c := corr(col_a, col_b)) >= 0.7:
            how = ('confounded on this data: it cannot tell them apart' if abs(c) >= 0.95
                   else 'partly confounded on this data')
            notes.append(f'{a} and {b} are {how} '
                         f'(correlation {c:+.2f} after removing the effects of the model).')
    return notes


def _coef_dict(data: BlockData, model: LinearModel, coef: NDArray[np.float64]) -> dict:
    """Return the final coefficients by name (SI units)."""
    nr, j = data.n_runs, model.common.shape[1]
    return {'offsets': coef[:nr].copy(), **{
        lab: coef[nr + i].copy() for i, lab in enumerate(model.labels[nr:])},
        'gain': np.zeros(3), 'scale': np.zeros(3),
        **{lab: coef[j + i] * (data.gain_axes if lab == 'gain' else data.scale_axes)
           for i, lab in enumerate(model.axis_labels)}}


def _check(runs: Sequence[Run], block_s: float) -> None:
    """Reject input that cannot be analysed, naming what is wrong."""
    if not isinstance(block_s, (int, float)) or not math.isfinite(block_s) or block_s <= 0:
        raise FitError(f'Expected `block_s` to be a positive number of seconds, got {block_s!r}.')
    if not runs:
        raise FitError('No runs given to discover.')
    for r in runs:
        if not isinstance(r, Run):
            raise FitError(f'Expected gyro_tdc.data.runs.Run objects, got {type(r).__name__}.')
        if len(r) < 16:
            raise FitError(f'Run {r.name!r} has {len(r)} samples; need at least 16.')
        check_finite(r, ('t', 'temp', 'omega', 'omega_ref'))


def build_model(result: DiscoveryResult, runs: Sequence[Run], *, kind: str = 'poly',
                created: Mapping | None = None):
    """
    Fit the compensation model of the discovered effects, ready for ``save_model``.

    The per-run offsets and the constant scale-factor error :func:`discover` found in ``runs``
    (the runs of ``result``) are removed first: they are not thermal (the compensator
    re-anchors its offset at start-up; a rate-table gain error is a separate calibration).
    :func:`gyro_tdc.identify.fit_model` then fits the final effects with the fitted time
    constants and, with ``lag``, discovery's thermal state: a format 2 model whose every
    temperature term follows the state. ``kind``: ``'poly'`` (exactly the linear model
    discovery validated) or ``'rbf'``; ``created``: extra creation info. A constant gyro axis
    is passed through as ``train`` does (:func:`gyro_tdc.identify.axes.fit_varying`).
    """
    if len(runs) != len(result.runs):
        raise FitError(f'Expected the {len(result.runs)} runs discovery analysed, '
                       f'got {len(runs)}.')
    off = np.asarray(result.coef['offsets'])
    mean_off = off.mean(axis=0)
    gain = np.asarray(result.coef['gain'])
    adjusted = [Run(run.t, run.temp, run.omega - (off[r] - mean_off)[None, :]
                    - gain[None, :] * run.omega_ref, run.omega_ref, run.name, dict(run.info))
                for r, run in enumerate(runs)]
    features = model_features(result, runs)
    info = {'discover': {'final_effects': list(result.final_effects),
                         'noise_floor_dps': result.noise_floor_dps,
                         'gain_removed': [float(g) for g in gain]}, **dict(created or {})}
    # A constant gyro axis (train's rule) is fitted as train fits it: not at all (its
    # columns exactly zero, passed through), its figures the raw ones.
    return fit_varying(runs, lambda fitted: fit_model(
        fitted, kind=kind, features=features, t0=result.t0_c, fit_params=False, created=info,
        params={k: v for k, v in result.params.items() if k != 'lag'},
        thermal=result.thermal if 'lag' in features else None), fitted=adjusted)


def model_features(result: DiscoveryResult, runs: Sequence[Run]) -> tuple[str, ...]:
    """
    Return the effects of the model file (catalog order): the final effects the data support.

    With a temperature span of ``runs`` under :data:`gyro_tdc.identify.MIN_SPAN_C` (a warm-up
    at a fixed ambient) the temperature effects, base ``dT`` included, are left out: the data
    say nothing about them.
    """
    lo, hi = span([r.temp for r in runs])
    return tuple(e for e in result.final_effects
                 if hi - lo >= MIN_SPAN_C or e not in TEMPERATURE_EFFECTS)
