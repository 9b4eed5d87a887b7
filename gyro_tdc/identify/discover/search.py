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

import math
from typing import Any, Callable, Mapping, Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.discover.data import BlockData
from gyro_tdc.identify.discover.linear import LinearModel
from gyro_tdc.identify.discover.maps import residual_adev, residual_maps
from gyro_tdc.identify.discover.results import (CandidateScore, DiscoveryResult, Step,
                                                Unidentifiable)
from gyro_tdc.identify.discover.stats import (bandwidth, COLLINEAR, DEG, gap, hac_pvalue,
                                              make_folds, rel_residual, weighted_corr)
from gyro_tdc.identify.fit import estimate_t0, MIN_SPAN_C
from gyro_tdc.identify.tau import effective_samples, fit_time_constant, profile_interval
from gyro_tdc.model import (EFFECTS, NONLINEAR_EFFECTS, normalise_ids, REFERENCE_EFFECTS,
                            STATIC_EFFECTS, TEMPERATURE_EFFECTS, THERMAL_EFFECTS, ThermalState,
                            with_implied)
from gyro_tdc.signal import fit_columns, Folds
import numpy as np
from numpy.typing import NDArray

__all__ = ['discover']

#: Candidate order (catalog order without ``bias``).
_CANDIDATES = tuple(e for e in EFFECTS if e != 'bias')
#: Effects a temperature span excites (``scale`` needs rate-table steps too: its own test).
_SPAN = tuple(e for e in EFFECTS if e in TEMPERATURE_EFFECTS and e not in REFERENCE_EFFECTS)
#: Of those, the ones with time memory: excited by how the temperature changes.
_RATE = tuple(e for e in _SPAN if e not in STATIC_EFFECTS)
#: Effects whose time constant the search fits: the catalog's fitted ones (the thermal state,
#: warm-up) and the smoothing of ``dTdt``, whose best value is the sensor's (the die's own
#: rate of change, or a slower gradient); it is recorded in the result's parameters, which
#: the model of a discovery and ``train --features auto`` keep.
_TIMED = frozenset(NONLINEAR_EFFECTS | {e for e in EFFECTS if 'tau_s' in EFFECTS[e].params})
#: Search bounds of a time constant the catalog gives no bounds for (the dTdt smoothing), s.
_SMOOTHING_BOUNDS_S = (1.0, 3600.0)
#: A soak (the temperature still) counts from this long, s (and three blocks).
_SOAK_S = 120.0
#: Candidates with time memory, scored beside the static curve too (:func:`_beside_curve`).
_MEMORY = tuple(e for e in _CANDIDATES if e not in STATIC_EFFECTS)
#: The static curve beyond ``dT`` that a time-memory candidate must beat.
_CURVE = ('dT2', 'dT3')


def _tau_bounds(data: BlockData, eid: str) -> tuple[float, float]:
    """Return the search bounds of an effect's time constant, s."""
    lo, hi = EFFECTS[eid].bounds.get('tau_s', _SMOOTHING_BOUNDS_S)
    longest = max(r.duration_s for r in data.runs)
    grid_step = max(float(g[0][1] - g[0][0]) if g[0].size > 1 else 1.0 for g in data.grids)
    lo = max(lo, 2.0 * grid_step)
    if eid == 'warmup':
        lo = max(lo, 3.0 * data.block_s)   # shorter decays are a dummy for the first block
    hi = min(hi, max(2.0 * longest, 4.0 * lo))
    return lo, hi


def _fit_taus(data: BlockData, effects: Sequence[str], params: dict, which: Sequence[str]) -> dict:
    """
    Fit the time constants of ``which`` by a bounded 1-D search on the residual each.

    The linear coefficients are re-solved at every trial (variable projection);
    :func:`gyro_tdc.identify.fit_time_constant` searches a log-spaced grid for the basin and
    refines it with a bounded Brent search.
    """
    params = {k: dict(v) for k, v in params.items()}
    for eid in which:
        def sse(tau: float, eid: str = eid) -> float:
            trial = {k: dict(v) for k, v in params.items()}
            trial.setdefault(eid, {})['tau_s'] = tau
            return LinearModel(data, effects, trial).sse()

        fit = fit_time_constant(sse, _tau_bounds(data, eid), n_grid=14, xatol=0.01)
        params.setdefault(eid, {})['tau_s'] = fit.tau
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
        trial = {k: dict(val) for k, val in model.params.items()}
        trial['lag']['tau_s'] = v
        r = LinearModel(data, model.effects, trial).residual()
        return (data.w[:, None] * r * r).sum(axis=0)

    n_eff = effective_samples(model.residual() * data.sw[:, None])
    prof = profile_interval(sse, tau, (min(lo, tau), max(hi, tau)), n_eff)
    return ThermalState('first_order', (tau,), (prof.interval,), prof.identifiable)


def _moving(data: BlockData) -> NDArray[np.bool_]:
    """Return the blocks whose temperature changes at a measurable rate."""
    rate = data.rate_cpm
    max_rate = float(np.max(np.abs(rate))) if rate.size else 0.0
    return np.abs(rate) > max(0.02, 0.1 * max_rate)


def _directions(data: BlockData, moving: NDArray[np.bool_]) -> tuple[bool, bool]:
    """Return whether the data heat and whether they cool at a measurable rate."""
    return (bool(np.any(moving & (data.rate_cpm > 0))),
            bool(np.any(moving & (data.rate_cpm < 0))))


def _one_way(data: BlockData) -> bool:
    """Return True when the data change temperature in one direction only."""
    heating, cooling = _directions(data, _moving(data))
    return heating != cooling


def _soak_min_s(data: BlockData) -> float:
    """Return the shortest soak (s) that counts: 2 minutes and three blocks."""
    return max(_SOAK_S, 3.0 * data.block_s)


def _first_soaks(data: BlockData, moving: NDArray[np.bool_]) -> NDArray[np.float64]:
    """
    Return, per run, how long it soaks after power-on before the temperature first moves, s.

    Zero for a run with fewer than four blocks before its first move (one block is no soak).
    """
    out = np.zeros(data.n_runs)
    for r in range(data.n_runs):
        m = data.run == r
        tr, mv = data.t_since[m], moving[m]
        first_move = tr[np.argmax(mv)] if np.any(mv) else tr[-1]
        if np.count_nonzero(tr < first_move) >= 4:
            out[r] = first_move
    return out


def _longest_soak(data: BlockData, moving: NDArray[np.bool_]) -> float:
    """
    Return the longest soak next to a ramp, s: a stretch of still blocks in a run that moves.

    A change of rate between a ramp and a soak is what a time constant shows in (the die
    catching up, or starting to lag); a run that never moves, or never stops, has none.
    """
    best = 0.0
    for r in range(data.n_runs):
        idx = np.flatnonzero(data.run == r)
        mv = moving[idx]
        if not np.any(mv) or np.all(mv):
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[1], mv.astype(np.int8), [1]])))
        for a, b in zip(edges[::2], edges[1::2]):      # still stretches [a, b)
            best = max(best, float(data.tlast[idx[b - 1]] - data.tfirst[idx[a]]))
    return best


def _excitation(data: BlockData, base: Sequence[str]) -> tuple[dict, list[str]]:
    """
    Decide which candidates this data cannot excite, before any fit.

    Returns ``{effect: Unidentifiable}`` and a list of notes about the data.
    """
    out: dict[str, Unidentifiable] = {}
    notes: list[str] = []
    span = float(data.temp.max() - data.temp.min())
    rate = data.rate_cpm
    moving = _moving(data)
    heating, cooling = _directions(data, moving)

    def add(eid: str, reason: str, extra: str = '') -> None:
        exp = EFFECTS[eid].excited_by
        out[eid] = Unidentifiable(eid, reason, exp[0].upper() + exp[1:] + extra + '.')

    if span < MIN_SPAN_C:
        for eid in _SPAN:
            add(eid, f'the temperature spans only {span:.2f} degC', ', of at least 10 degC')
    if not np.any(moving):
        for eid in _RATE:
            if eid not in out:
                add(eid, 'the temperature never changes at a measurable rate')
    elif heating != cooling:
        leg = 'heat' if heating else 'cool'
        r = np.abs(rate[moving])
        q1, q3 = np.percentile(r, [25, 75])
        one_rate = (q3 - q1) < 0.25 * float(np.median(r))
        soak = _longest_soak(data, moving)
        if one_rate and soak < _soak_min_s(data):
            # Scored all the same: a die settled at power-on falls behind at the start of the
            # ramp, which shows tau; a recording that starts mid-ramp shows nothing, and the
            # guard then rejects the lag (its profile is flat).
            notes.append(f'The data only {leg} and at one rate (~{np.median(r):.2f} degC/min) '
                         'with no soak before or after the ramp: a lag or dT/dt effect can '
                         'only show where the ramp starts from a die settled at power-on; '
                         'from a recording that starts mid-ramp it is not identifiable, and '
                         'hysteresis between heating and cooling cannot be tested.')
        elif one_rate:
            notes.append(f'The data only {leg} and at one rate (~{np.median(r):.2f} degC/min): '
                         'a lag or dT/dt effect rests on the changes of rate between the ramp '
                         f'and the soaks (the longest {soak:.0f} s: the approach to equilibrium '
                         'there shows a time constant); hysteresis between heating and cooling '
                         'cannot be tested.')
        else:
            notes.append(f'The data only {leg}: hysteresis between heating and cooling cannot '
                         'be tested; a dT/dt or lag effect seen here rests on the change of '
                         f'the {leg}ing rate alone.')
    if not np.any(data.scale_axes):
        if not np.any(np.abs(data.ref) > 1e-12):
            add('scale', 'the reference rate is zero on every run: a sensitivity change has '
                'nothing to scale')
        else:
            add('scale', 'the reference rate is constant on every run, so a sensitivity '
                'change is indistinguishable from dT')
    # Warm-up: some run must start with a soak (no temperature change) after power-on.
    soak_ok = bool(np.any(_first_soaks(data, moving) >= _soak_min_s(data)))
    if not soak_ok:
        add('warmup', 'no run starts with a soak after power-on: a warm-up transient cannot be '
            'told apart from the temperature response and the bias')
    for eid in base:
        out.pop(eid, None)
    return out, notes


def _candidate_params(data: BlockData, model: LinearModel, eid: str) -> dict:
    """
    Return the model's parameters plus those of candidate ``eid`` (its tau fitted).

    With the thermal state in the model (or as the candidate) its tau is refitted with the
    candidate: a curvature named after ``lag`` moves the state's time constant.
    """
    params = {k: dict(v) for k, v in model.params.items()}
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | {eid})
    which = [e for e in (eid, 'lag') if e in _TIMED and e in effects]
    if eid in _TIMED or 'lag' in model.effects:
        for e in which:
            params.setdefault(e, dict(EFFECTS[e].params))
        params = _fit_taus(data, effects, params, list(dict.fromkeys(which)))
    return params


def _n_params(model: LinearModel, eid: str, params: Mapping) -> int:
    """Return the parameters candidate ``eid`` adds to ``model``: coefficients and taus."""
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | {eid})
    cand = LinearModel(model.data, effects, params)
    return (cand.p - model.p) * 3 + (eid in _TIMED)


def _noise_lags(data: BlockData, model: LinearModel, todo: Sequence[str], cparams: Mapping
                ) -> tuple[list, int]:
    """
    Return per-axis HAC bandwidths and the noise memory (blocks) from the richest model.

    The memory of the noise is measured on the residual of the model plus every candidate
    (each with its fitted time constant), so that a second effect not yet in the model does
    not pass for long-memory noise and hide the first.
    """
    params = {k: dict(v) for k, v in model.params.items()}
    for eid in todo:
        if eid in _TIMED:
            params[eid] = dict(cparams[eid][eid])
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | set(todo))
    rich = LinearModel(data, effects, params)
    r = (data.y - rich.predict(rich.fit())) * data.sw[:, None]
    memory = max(bandwidth(r[:, a], floor=False) for a in range(3))
    return [bandwidth(r[:, a]) for a in range(3)], int(memory)


def _heldout_mse(data: BlockData, ho: NDArray[np.float64]) -> float:
    """Return the block-weighted mean square of held-out residuals ``ho`` (K, 3) over axes."""
    return float((data.w[:, None] * ho * ho).sum() / (3.0 * data.w.sum()))


def _curve_model(data: BlockData, model: LinearModel, folds: Folds
                 ) -> tuple[tuple[str, ...], LinearModel, float] | None:
    """
    Return the static curve ``model`` lacks, the model with it and its held-out mean square.

    None when the model has the whole curve (:data:`_CURVE`).
    """
    curve = tuple(e for e in _CURVE if e not in model.effects)
    if not curve:
        return None
    base = LinearModel(data, tuple(e for e in EFFECTS if e in set(model.effects) | set(curve)),
                       model.params)
    ho = base.cv_residual(folds)
    return curve, base, _heldout_mse(data, ho)


def _beside_curve(data: BlockData, curve: tuple, folds: Folds, eid: str, params: dict) -> float:
    """
    Return the held-out gain of a time-memory candidate beside the static curve, (deg/s)^2.

    A candidate with time memory (``lag``, ``dTdt``, ``warmup``) is scored once more against
    the model plus the static curvature it lacks (``dT2``, ``dT3``: ``curve`` from
    :func:`_curve_model`), added to both sides, its time constants refitted there. On a run
    that heats or cools only, the time since power-on and the smoothed rate follow the
    temperature, so a slow decay or a slow rate term can hold curvature the base polynomial
    lacks, curvature the final model (an RBF network of the temperature terms) holds anyway;
    that part is not the candidate's, and off the one direction of ramp it was fitted on it
    extrapolates wrongly (a cooling cycle after heating-only training). :func:`_score`
    requires ``dTdt`` and ``warmup`` to gain here and ranks them by it; ``lag`` (no column of
    its own) is ranked by it when it is the larger gain.
    """
    ids, base, mse_b = curve
    effects = tuple(e for e in EFFECTS if e in set(base.effects) | {eid})
    which = [e for e in (eid, 'lag') if e in _TIMED and e in effects]
    trial = _fit_taus(data, effects, params, which) if which else params
    ho = LinearModel(data, effects, trial).cv_residual(folds)
    mse_c = _heldout_mse(data, ho)
    return (mse_b - mse_c) * DEG ** 2


def _score(data: BlockData, model: LinearModel, coef_m: NDArray[np.float64], sse_m: float,
           mse_ho_m: float, folds: Folds, eid: str, params: dict, *, lags: Sequence[int],
           n_cand: int, alpha: float, min_heldout: float, min_effect: float,
           curve: tuple | None = None
           ) -> tuple[CandidateScore, NDArray[np.float64] | None, dict]:
    """
    Score one candidate against ``model``; returns the score, its contribution and params.

    With ``curve`` (:func:`_curve_model`) a time-memory candidate must also gain held out
    beside the static curve (:func:`_beside_curve`), and is ranked by its gain there.
    """
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | {eid})
    cand = LinearModel(data, effects, params)
    idx = cand.columns_of(eid)
    own = dict(params[eid]) if eid in _TIMED else {}
    # Is it spanned by the current model (per axis)? (The thermal state has no column of
    # its own: it changes the temperature columns; its test is the J test below.)
    rel = []
    for a in range(3):
        xa = cand.design(a) * data.sw[:, None]
        for i in idx:
            if np.linalg.norm(xa[:, i]) > 0:
                rel.append(rel_residual(np.delete(xa, idx, axis=1), xa[:, i]))
    if idx and (not rel or max(rel) < COLLINEAR):
        sc = CandidateScore(eid, own, 1.0, 0.0, 0.0, math.nan, math.nan, False,
                            'collinear', np.zeros((len(idx), 3)))
        return sc, None, params
    coef = cand.fit()
    pred = cand.predict(coef)
    r = data.y - pred
    sse = float((data.w[:, None] * r * r).sum())
    contrib = pred - model.predict(coef_m)
    ho = cand.cv_residual(folds)
    mse_ho = _heldout_mse(data, ho)
    gain = (mse_ho_m - mse_ho) * DEG ** 2
    eff = math.sqrt(max(sse_m - sse, 0.0) / (3.0 * data.w.sum())) * DEG
    if idx:
        p = hac_pvalue(cand, coef, idx, lags)
    else:
        # A candidate that changes the model instead of adding columns (the thermal state)
        # is not nested in it: Davidson and MacKinnon's J test adds its fitted values to
        # the current model as one column per axis and tests that column.
        aug = LinearModel(data, model.effects, model.params, extra=pred)
        p = hac_pvalue(aug, aug.fit(), aug.columns_of('extra'), lags)
    floor = data.floor * DEG
    why = []
    if p >= alpha / max(n_cand, 1):
        why.append(f'p={p:.2g}')
    limit = max(min_heldout * floor ** 2, 0.01 * mse_ho_m * DEG ** 2)
    if gain <= limit:
        why.append('no held-out gain')
    elif curve is not None:
        beside = _beside_curve(data, curve, folds, eid, params)
        if eid in THERMAL_EFFECTS:
            # The thermal state adds no column that could stand in for curvature; beside
            # the curve its cubic of a far-lagging state can run away held out. It is
            # ranked by its gain there when that is a gain.
            gain = beside if beside > gain else gain
        else:
            if beside <= max(min_heldout * floor ** 2, 0.01 * curve[2] * DEG ** 2):
                why.append(f'no held-out gain beside {"+".join(curve[0])}')
            gain = beside          # credited with what the static curve cannot hold
    if eff < min_effect * floor:
        why.append('effect below noise')
    sc = CandidateScore(eid, own, p, gain, eff, gap(data, r), gap(data, ho), not why,
                        ', '.join(why), coef[idx])
    return sc, contrib, params


def discover(runs: Sequence[Run], *, base: str | Sequence[str] = ('bias', 'dT'),
             candidates: str | Sequence[str] | None = None, block_s: float = 10.0,
             t0: float | None = None, alpha: float = 0.01, min_heldout: float = 0.1,
             min_effect: float = 0.6, alias_margin: float = 0.25, alias_corr: float = 0.9,
             max_steps: int = 6, n_folds: int = 5, allan: bool = True,
             progress: Callable[[int, str], None] | None = None) -> DiscoveryResult:
    """
    Find the effects a drift model is missing, one step at a time.

    Parameters
    ----------
    runs : sequence of Run
        Measured runs (each a continuous recording from power-on; filters restart per run).
    base : str or sequence of str
        Effects of the starting model (``'bias,dT'``: eq. 18's conventional model); ``bias``
        is always included, as one offset per run.
    candidates : str or sequence of str, optional
        Effects to try (default: every catalog effect not in ``base``).
    block_s : float, s
        Block length of the analysis; gaps and the noise floor are RMS of block means.
    t0 : float, optional, degC
        Reference temperature (default :func:`gyro_tdc.identify.estimate_t0` of the first run).
    alpha : float
        Family-wise significance level per step (Bonferroni over candidates and axes).
    min_heldout : float
        Smallest held-out gain, as a fraction of the squared noise floor.
    min_effect : float
        Smallest effect RMS, as a fraction of the noise floor.
    alias_margin : float
        A candidate within this fraction of the best held-out gain...
    alias_corr : float
        ...whose fitted contribution correlates at least this much with the best's is an alias.
    max_steps : int
        Most effects added.
    n_folds : int
        Cross-validation folds for a single run (see :func:`make_folds`; several runs: leave one
        run out).
    allan : bool
        Compute the Allan deviation of the residual before and after each step.
    progress : callable, optional
        Called as ``progress(step, effect_id)`` before each candidate is scored (``step``
        counts the effects named so far, from 0), e.g. to drive a progress bar.

    Returns
    -------
    DiscoveryResult
        Steps, final model, unidentifiable effects, maps.

    Raises
    ------
    FitError
        When the runs cannot support the analysis (too few blocks, non-finite values...).
    FeatureError
        When an effect id is unknown.

    """
    runs = list(runs)
    _check(runs, block_s)
    base_ids = with_implied(tuple(normalise_ids(base)) + ('bias',))
    if candidates is None:
        cand_ids = tuple(e for e in _CANDIDATES if e not in base_ids)
    else:
        cand_ids = tuple(e for e in normalise_ids(candidates) if e not in base_ids and e != 'bias')
    if t0 is None:
        t0 = estimate_t0(runs[0])
    data = BlockData(runs, block_s=block_s, t0=t0)
    if data.K < 8:
        raise FitError(f'Too few blocks to analyse: {data.K} blocks of {block_s:g} s '
                       '(need at least 8); record longer or use a shorter block.')
    if 'scale' in base_ids and not np.any(np.abs(data.ref) > 1e-12):
        raise FitError('Effect `scale` in the base model needs a non-zero reference rate '
                       '(rate-table data); every run has omega_ref = 0.')
    p_base = len(base_ids) - 1 + data.n_runs + 2
    if data.K <= p_base + 2:
        raise FitError(f'Too few blocks ({data.K}) for the base model '
                       f'({", ".join(base_ids)}); record longer or use a shorter block.')
    unident, notes = _excitation(data, base_ids)
    one_way = _one_way(data)
    params: dict = {}
    for eid in base_ids:
        if EFFECTS[eid].params:
            params[eid] = dict(EFFECTS[eid].params)
    nonlin = [e for e in base_ids if e in _TIMED]
    if nonlin:
        params = _fit_taus(data, base_ids, params, nonlin)
    effects = base_ids
    model = LinearModel(data, effects, params)
    steps: list[Step] = []
    collinear: list[str] = []
    scores: tuple[CandidateScore, ...] = ()
    adev_cache: tuple | None = None
    first_round = True
    while True:
        coef_m = model.fit()
        r_m = data.y - model.predict(coef_m)
        sse_m = float((data.w[:, None] * r_m * r_m).sum())
        todo = [e for e in cand_ids if e not in effects and e not in unident]
        results = []
        cparams = {eid: _candidate_params(data, model, eid) for eid in todo}
        lags, memory = _noise_lags(data, model, todo, cparams)
        folds, buffer = make_folds(data, memory, n_folds)
        ho_m = model.cv_residual(folds)
        mse_ho_m = _heldout_mse(data, ho_m)
        curve = _curve_model(data, model, folds) if set(todo) & set(_MEMORY) else None
        for eid in todo:
            if progress is not None:
                progress(len(steps), eid)
            sc, contrib, p = _score(data, model, coef_m, sse_m, mse_ho_m, folds, eid,
                                    cparams[eid], lags=lags, n_cand=len(todo), alpha=alpha,
                                    min_heldout=min_heldout, min_effect=min_effect,
                                    curve=curve if eid in _MEMORY else None)
            if sc.why_not == 'collinear':
                if eid not in collinear:
                    collinear.append(eid)
                continue
            results.append((sc, contrib, p))
        results.sort(key=lambda x: (not x[0].passed, -x[0].heldout_gain_dps2))
        scores = tuple(x[0] for x in results)
        if not steps and first_round:
            notes += _confounded(data, model, scores, params)
            first_round = False
        passing = [x for x in results if x[0].passed]
        if not passing or len(steps) >= max_steps:
            break
        best, contrib_b, p_b = passing[0]
        family = [passing[0]]
        for item in results[1:]:
            sc, contrib, _p = item
            if contrib is None or sc.heldout_gain_dps2 <= 0:
                continue
            close = sc.heldout_gain_dps2 >= (1.0 - alias_margin) * best.heldout_gain_dps2
            if close and (abs(weighted_corr(contrib, contrib_b, data.w)) >= alias_corr
                          or (one_way and {sc.effect, best.effect} == {'lag', 'dTdt'}
                              and sc.passed)):
                family.append(item)
        # Among aliases that pass the guard, name the one with the fewest parameters: a
        # lagging die with a linear drift (one time constant) rather than dT/dt (a time
        # constant and a coefficient per axis), whose columns hold the same curve. On data
        # that only heat (or only cool) lag and dT/dt are aliases whenever both pass within
        # the margin: the data hold one sign of the rate, so a dT/dt input of the final model
        # would be extrapolated on the other ramp direction, while the thermal state stays
        # inside the trained temperatures (the other direction lags the other way).
        best, contrib_b, p_b = min((x for x in family if x[0].passed),
                                   key=lambda x: _n_params(model, x[0].effect, x[2]))
        aliases = [x[0].effect for x in family if x[0] is not best]
        new_effects = tuple(e for e in EFFECTS if e in set(effects) | {best.effect})
        new_params = {k: dict(v) for k, v in p_b.items()}
        refit = [e for e in new_effects if e in _TIMED]
        if len(refit) > 1:
            new_params = _fit_taus(data, new_effects, new_params, refit)
        new_model = LinearModel(data, new_effects, new_params)
        coef_n = new_model.fit()
        r_n = data.y - new_model.predict(coef_n)
        ho_n = new_model.cv_residual(folds)
        if allan:
            before = adev_cache or residual_adev(data, model, coef_m)
            after = residual_adev(data, new_model, coef_n)
            adev_cache = after
        else:
            before = after = (np.zeros(0), np.zeros(0))
        thermal = _thermal_state(data, new_model)
        idx = new_model.columns_of(best.effect)
        unit = 1.0 if best.effect == 'scale' else DEG
        steps.append(Step(
            effect=best.effect, aliases=tuple(aliases),
            description=EFFECTS[best.effect].description,
            params=(dict(new_params.get(best.effect, {}))
                    if best.effect in _TIMED else {}),
            coef_dps=coef_n[idx] * unit,
            gap_before_dps=gap(data, r_m), gap_after_dps=gap(data, r_n),
            heldout_gap_before_dps=gap(data, ho_m), heldout_gap_after_dps=gap(data, ho_n),
            candidates=scores, maps_before=residual_maps(data, r_m),
            maps_after=residual_maps(data, r_n),
            adev_tau_s=before[0], adev_before_dps=before[1], adev_after_dps=after[1],
            best=best, thermal=thermal))
        effects, params, model = new_effects, new_params, new_model

    coef = model.fit()
    r = data.y - model.predict(coef)
    ho = model.cv_residual(folds)
    for eid in collinear:
        if eid not in effects and eid not in unident:
            unident[eid] = Unidentifiable(
                eid, 'on this data its feature is a combination of the effects of the model '
                f'({", ".join(effects)})', EFFECTS[eid].excited_by[0].upper()
                + EFFECTS[eid].excited_by[1:] + '.')
    final_coef = _coef_dict(data, model, coef)
    thermal = steps[-1].thermal if steps else _thermal_state(data, model)
    if allan:
        adev = adev_cache or residual_adev(data, model, coef)
    else:
        adev = (np.zeros(0), np.zeros(0))
    return DiscoveryResult(
        base_effects=base_ids, final_effects=effects,
        params={k: dict(v) for k, v in params.items() if k in effects and k in _TIMED},
        noise_floor_dps=data.floor * DEG, noise_floor_axes_dps=data.floor_axes * DEG,
        white_noise_dps=data.white * DEG, block_s=float(block_s), t0_c=float(t0),
        steps=tuple(steps),
        unidentifiable=tuple(unident[e] for e in EFFECTS if e in unident and e in cand_ids),
        candidates=scores, maps=residual_maps(data, r), gap_dps=gap(data, r),
        heldout_gap_dps=gap(data, ho), coef=final_coef, runs=tuple(x.name for x in runs),
        blocks=data.K, notes=tuple(notes),
        settings={'alpha': alpha, 'min_heldout': min_heldout, 'min_effect': min_effect,
                  'alias_margin': alias_margin, 'alias_corr': alias_corr,
                  'folds': 'leave-one-run-out' if data.n_runs >= 2 else
                  f'{len(folds)} blocked folds, buffer {buffer} blocks',
                  'block_s': float(block_s),
                  'block_mean_s': float(data.block_eff_s)},
        adev_tau_s=adev[0], adev_dps=adev[1], thermal=thermal)


def _confounded(data: BlockData, model: LinearModel, scores: Sequence[CandidateScore],
                params: dict) -> list[str]:
    """Return notes on candidate pairs whose columns are strongly correlated on this data."""
    notes = []
    x = model.common
    cols = {}
    for sc in scores:
        if sc.effect == 'lag':          # what the state changes: its dT minus the measured
            col = data.state_columns(sc.params['tau_s'])['dT'] - data.static['dT']
        elif EFFECTS[sc.effect].is_input:
            p = {k: dict(v) for k, v in params.items()}
            p.update({sc.effect: dict(sc.params)} if sc.params else {})
            col = data.column(sc.effect, p, state_tau=model.state_tau)
        else:
            continue
        beta = fit_columns(x, col, weights=data.w, normalise=True, rcond=1e-12)
        cols[sc.effect] = (col - x @ beta) * data.sw
    ids = list(cols)
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            a, b = cols[ids[i]], cols[ids[j]]
            den = float(np.linalg.norm(a) * np.linalg.norm(b))
            c = float(a @ b) / den if den > 0 else 0.0
            if abs(c) >= 0.7:
                how = ('confounded on this data: it cannot tell them apart' if abs(c) >= 0.95
                       else 'partly confounded on this data')
                notes.append(f'{ids[i]} and {ids[j]} are {how} '
                             f'(correlation {c:+.2f} after removing the effects of the model).')
    return notes


def _coef_dict(data: BlockData, model: LinearModel, coef: NDArray[np.float64]) -> dict:
    """Return the final coefficients by name (SI units)."""
    nr = data.n_runs
    out: dict[str, Any] = {'offsets': coef[:nr].copy()}
    for i, lab in enumerate(model.labels[nr:]):
        out[lab] = coef[nr + i].copy()
    j = model.common.shape[1]
    out['gain'] = np.zeros(3)
    out['scale'] = np.zeros(3)
    for lab in model.axis_labels:
        out[lab] = coef[j] * (data.gain_axes if lab == 'gain' else data.scale_axes)
        j += 1
    return out


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
        for key in ('t', 'temp', 'omega', 'omega_ref'):
            if not np.all(np.isfinite(getattr(r, key))):
                raise FitError(f'Run {r.name!r} has non-finite values in `{key}`.')
