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
Identification of the compensation model from thermal runs.

:func:`fit_model` follows section 3.2 of the paper with modern refinements: normalised
effect features, k-means RBF centres, regularised least squares, optional refinement, and
the thermal state's time constants by variable projection with a profile interval.
See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import replace
import datetime as _dt
import math
from typing import Mapping, Sequence
import weakref

from gyro_tdc import __version__
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.linear import fit_linear, LinearFit, refine_rbf, RIDGE_GRID
from gyro_tdc.identify.tau import (effective_samples, fit_time_constant, profile_interval,
                                   TauProfile, TimeConstantFit)
from gyro_tdc.model import (batch_features, CompensationModel, EFFECTS, input_ids, KINDS,
                            normalise_ids, REFERENCE_EFFECTS, resolve_params, STATE_TERMS,
                            TEMPERATURE_EFFECTS, THERMAL_EFFECTS, ThermalState, with_implied)
from gyro_tdc.signal import block_length, block_mean, BlockGrid, Folds, heldout
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

__all__ = ['estimate_t0', 'fit_model', 'fit_px4_cubic', 'MIN_SAMPLES', 'MIN_SPAN_C', 'run_state',
           'TAU_BOUNDS', 'THERMAL_CHOICES', 'TWO_NODE_MARGIN']

#: Fewest samples a fit accepts.
MIN_SAMPLES = 50
#: Smallest temperature span (degC) a fit with temperature features accepts.
MIN_SPAN_C = 0.5
#: Relative cross-validated error a two-node state must save over first order to be kept.
TWO_NODE_MARGIN = 0.05
#: Values of ``fit_model(thermal=...)`` besides a fixed :class:`ThermalState`.
THERMAL_CHOICES = ('none', 'first_order', 'two_node', 'auto')
#: Search bounds of the thermal state's time constants, s (the ``lag`` effect's bounds).
TAU_BOUNDS: tuple[float, float] = tuple(EFFECTS['lag'].bounds['tau_s'])


def estimate_t0(run: Run, *, window_s: float = 60.0) -> float:
    """
    Estimate the reference temperature T0: the stable initial temperature of a run.

    Parameters
    ----------
    run : Run
        A run.
    window_s : float, s
        Length of the initial window averaged (at least the first 1 % of samples are used).

    Returns
    -------
    float, degC
        Median temperature over the initial window.

    """
    if len(run) == 0:
        raise FitError('Cannot estimate T0 from an empty run.')
    n = max(int(np.searchsorted(run.t, run.t[0] + window_s)), max(len(run) // 100, 1))
    return float(np.median(run.temp[:n]))


# Full-rate thermal states by run, while the run lives (a weak reference to it: a run
# dropped drops its state): fit_model's are the accelerometer part's.
_STATES: dict[int, tuple[weakref.ref, tuple, NDArray[np.float64]]] = {}
_STATES_KEPT = 8


def run_state(thermal: ThermalState, run: Run) -> NDArray[np.float64]:
    """
    Return ``thermal.temperature(run.t, run.temp)``, computed once per run and front end.

    The result is read-only (shared by the callers: the fit and the accelerometer part).
    """
    key = (thermal.kind, tuple(float(v) for v in thermal.tau_s), id(run.t), id(run.temp))
    hit = _STATES.get(id(run))
    if hit is not None and hit[0]() is run and hit[1] == key:
        return hit[2]
    state = thermal.temperature(run.t, run.temp)
    state.flags.writeable = False
    rid = id(run)
    _STATES.pop(rid, None)
    _STATES[rid] = (weakref.ref(run, lambda _ref, rid=rid: _STATES.pop(rid, None)), key, state)
    while len(_STATES) > _STATES_KEPT:
        _STATES.pop(next(iter(_STATES)))
    return state


class _Blocks:
    """
    Block means of one run: stamps, temperature, drift target and reference rate.

    With ``rows`` (the samples that count, e.g. the still ones of ``train --still-only``)
    every mean but the stamps' and the temperature's is over those rows only and the blocks
    without any are dropped; the filters (thermal state, dT/dt, warm-up) still run over every
    sample, so the die temperature evolves through the rows that do not count.
    """

    def __init__(self, run: Run, block: int, rows: NDArray[np.bool_] | None = None) -> None:
        self.run = run
        self.block = block
        self.t = block_mean(run.t, block)
        self.temp = block_mean(run.temp, block)
        # A chamber run has no reference rate: skip subtracting and averaging its zeros (the
        # same numbers: x - 0 is x, and the block means of zeros are zeros).
        self.has_ref = bool(np.any(run.omega_ref))
        err = run.omega - run.omega_ref if self.has_ref else run.omega
        self.grid = BlockGrid(len(run), block, rows=rows)
        self.rows, self.counts = self.grid.rows, self.grid.counts
        e = err if self.rows is None else err[self.rows]
        self.ss_raw = np.einsum('ij,ij->j', e, e)
        self.y = self._mean(err)
        self.ref = self._mean(run.omega_ref) if self.has_ref else np.zeros(self.y.shape)
        self.ss_within = self.grid.scatter(err, self.y)

    def _sel(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the rows of ``x`` (one per block) of the blocks kept."""
        return self.grid.sel(x)

    def _mean(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the block means of ``x`` (N, ...) over the rows that count."""
        return self.grid.mean(x)

    def state(self, thermal: ThermalState) -> NDArray[np.float64]:
        """Return the thermal state at full rate (N,), degC."""
        return run_state(thermal, self.run)

    def scatter(self, scale: NDArray[np.float64], t0: float,
                state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return, per block, the sum of squared deviations from the block mean (per axis).

        The error is taken after removing the sensitivity term ``scale * dT * omega_ref``
        (``dT`` of the full-rate ``state``, or of the measured temperature), which changes
        within a block when the rate table steps.
        """
        err = self.run.omega - self.run.omega_ref if self.has_ref else self.run.omega
        if np.any(scale):
            temp = self.run.temp if state is None else state
            err = err - (temp - t0)[:, None] * self.run.omega_ref * scale
        return self.grid.scatter(err, self._mean(err))

    def features(self, ids: Sequence[str], t0: float, params: Mapping, *,
                 exact: bool, thermal: ThermalState,
                 state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return block-mean features with the model temperature of ``thermal``.

        ``exact`` computes them at full rate first (with the full-rate ``state`` when
        given); else from the block means (the parameter search).
        """
        if exact and self.block > 1:
            run = self.run
            s = self.state(thermal) if state is None else state
            x = batch_features(ids, run.t, run.temp, t0=t0, params=params, state=s)
            return self._mean(x)
        return self._sel(batch_features(ids, self.t, self.temp, t0=t0, params=params,
                                        state=thermal.temperature(self.t, self.temp)))

    def scale_cols(self, t0: float, state: NDArray[np.float64] | None = None,
                   thermal: ThermalState | None = None) -> NDArray[np.float64]:
        """
        Return block means of ``dT * omega_ref`` (N, 3).

        ``dT`` of the full-rate ``state`` (exact), else with ``thermal`` of the block-mean
        state times the block-mean rate (the parameter search; the temperature is slow).
        """
        if thermal is not None:
            return (self._sel(thermal.temperature(self.t, self.temp)) - t0)[:, None] * self.ref
        d = (self.run.temp if state is None else state) - t0
        return self._mean(d[:, None] * self.run.omega_ref)


def _labels(runs: Sequence[Run], sessions: Sequence | None) -> list[int] | None:
    """Return a 0-based session label per run (in order of appearance), None for one."""
    if sessions is None:
        return None
    sessions = list(sessions)
    if len(sessions) != len(runs):
        raise FitError(f'Expected one session label per run ({len(runs)}), got '
                       f'{len(sessions)}.')
    index: dict = {}
    labels = [index.setdefault(s, len(index)) for s in sessions]
    return labels if len(index) > 1 else None


def _block_groups(blocks: Sequence['_Blocks'], labels: Sequence[int] | None
                  ) -> NDArray[np.int64] | None:
    """Return the session of every block row (None: one session)."""
    if labels is None:
        return None
    return np.concatenate([np.full(b.y.shape[0], g, dtype=np.int64)
                           for b, g in zip(blocks, labels)])


def _check_runs(runs: Sequence[Run], ids: Sequence[str],
                rows: Sequence[NDArray[np.bool_]] | None = None) -> None:
    """Reject data that cannot support a fit, with a message naming the problem."""
    if not runs:
        raise FitError('No training runs given.')
    if rows is not None and (len(rows) != len(runs) or any(
            np.shape(m) != (len(r),) for r, m in zip(runs, rows))):
        raise FitError('Expected `rows` to hold one boolean mask of shape (N,) per run.')
    n = sum(len(r) for r in runs) if rows is None else int(sum(np.count_nonzero(m)
                                                               for m in rows))
    if n < MIN_SAMPLES:
        raise FitError(f'Too few samples to fit: {n} (need at least {MIN_SAMPLES}).')
    for r in runs:
        for key in ('temp', 'omega', 'omega_ref'):
            x = np.asarray(getattr(r, key))
            # All finite iff the min and the max are (NaN propagates): no boolean temporary.
            if x.size and not (np.isfinite(x.min()) and np.isfinite(x.max())):
                raise FitError(f'Run {r.name!r} has non-finite values in `{key}`.')
    if TEMPERATURE_EFFECTS & set(ids):
        temps = [r.temp if rows is None else r.temp[rows[i]] for i, r in enumerate(runs)]
        lo = min(float(x.min()) for x in temps if x.size)
        hi = max(float(x.max()) for x in temps if x.size)
        if hi - lo < MIN_SPAN_C:
            raise FitError(f'Temperature span too small to fit: {hi - lo:.3f} degC '
                           f'(need at least {MIN_SPAN_C} degC).')
    needs_ref = sorted(REFERENCE_EFFECTS & set(ids))
    if needs_ref and not any(np.any(np.abs(r.omega_ref) > 1e-9) for r in runs):
        raise FitError(f'Effect `{needs_ref[0]}` needs a non-zero reference rate (rate-table '
                       'data); every training run has omega_ref = 0.')


#: The effect that makes the model temperature a lagged state (``lag``, the one thermal id).
(_LAG,) = THERMAL_EFFECTS


class _Search:
    """
    The nonlinear-parameter search of :func:`fit_model`, on coarse blocks (<= 20k rows).

    ``sse(thermal, params)`` is the residual sum of squares per axis with the linear weights
    re-solved (variable projection) by ``fit_linear(kind=inner)`` on the ``inputs``.
    """

    def __init__(self, runs: Sequence[Run], inputs: Sequence[str], t0: float, *, inner: str,
                 n_centers: int, ridge: float, seed: int, scale: bool, n_total: int,
                 rows: Sequence[NDArray[np.bool_]] | None = None,
                 labels: Sequence[int] | None = None) -> None:
        block = block_length(n_total, 20_000, at_most=True)
        self.blocks = [_Blocks(r, block, None if rows is None else rows[i])
                       for i, r in enumerate(runs)]
        self.y = np.concatenate([b.y for b in self.blocks])
        self.groups = _block_groups(self.blocks, labels)
        self.inputs, self.t0, self.scale, self.inner = tuple(inputs), t0, scale, inner
        self.n_centers, self.ridge, self.seed = n_centers, ridge, seed

    def design(self, thermal: ThermalState, par: Mapping
               ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Return the coarse feature rows and scale columns of a front end."""
        lagged = thermal.kind != 'none'
        x = np.concatenate([b.features(self.inputs, self.t0, par, exact=False, thermal=thermal)
                            for b in self.blocks])
        sc = (np.concatenate([b.scale_cols(self.t0, thermal=thermal if lagged else None)
                              for b in self.blocks]) if self.scale else None)
        return x, sc

    def _linear(self, x: NDArray[np.float64], y: NDArray[np.float64],
                sc: NDArray[np.float64] | None,
                groups: NDArray[np.int64] | None = None) -> LinearFit:
        return fit_linear(x, y, scale_cols=sc, kind=self.inner, n_centers=self.n_centers,
                          ridge=self.ridge, seed=self.seed, groups=groups)

    def fit(self, thermal: ThermalState, par: Mapping) -> LinearFit:
        """Return the linear fit on the coarse rows with this front end and parameters."""
        x, sc = self.design(thermal, par)
        return self._linear(x, self.y, sc, self.groups)

    def sse(self, thermal: ThermalState, par: Mapping) -> NDArray[np.float64]:
        """Return the residual sum of squares per axis (3,)."""
        r = self.fit(thermal, par).resid
        return np.einsum('ij,ij->j', r, r)

    def cv_sse(self, thermal: ThermalState, par: Mapping, *, window_s: float = 60.0,
               n_segments: int = 20, n_folds: int = 5) -> float:
        """
        Return the cross-validated SSE of the slow error.

        Each row is predicted by a fit without its fold (interleaved contiguous segments);
        the out-of-fold residuals are averaged over ``window_s`` windows before squaring, so
        the white noise shrinks and the figure measures the drift the model misses.
        """
        x, sc = self.design(thermal, par)
        g = self.groups

        def residual(test: NDArray[np.bool_], train: NDArray[np.bool_]) -> NDArray[np.float64]:
            fit = self._linear(x[train], self.y[train], None if sc is None else sc[train],
                               None if g is None else g[train])
            r = fit.predict(x[test], None if sc is None else sc[test]) - self.y[test]
            if g is not None:           # the fitted offset of every session trained on
                seen, gt = np.unique(g[train]), g[test]
                for j, grp in enumerate(seen):
                    r[gt == grp] += fit.offsets[j]
            return r

        folds = Folds.segments(x.shape[0], n_segments=n_segments, n_folds=n_folds)
        resid = heldout(residual, folds, self.y.shape, groups=g)
        steps = np.concatenate([np.diff(b.t) for b in self.blocks])
        dt = float(np.median(steps)) if steps.size else window_s
        w = max(1, int(round(window_s / dt))) if dt > 0 else 1
        return float((block_mean(resid, w) ** 2).sum())

    # -- thermal state ---------------------------------------------------------------

    def first_order(self, par: Mapping, bounds: tuple[float, float]
                    ) -> tuple[float, dict]:
        """Search the first-order time constant; return it and every point evaluated."""
        seen: dict[float, NDArray[np.float64]] = {}

        def objective(tau: float) -> float:
            seen[tau] = self.sse(ThermalState('first_order', (tau,)), par)
            return float(seen[tau].sum())

        return fit_time_constant(objective, bounds, n_grid=13).tau, seen

    def profile(self, taus: tuple[float, ...], i: int, par: Mapping,
                bounds: tuple[float, float], seen: Mapping | None = None) -> TauProfile:
        """
        Return the profile interval of time constant ``i``.

        With two nodes the other time constant is re-fitted at every point (a full profile,
        not a conditional one), kept on its side: the larger one for ``i = 0``, the smaller
        for ``i = 1`` (the cascade commutes, so only the order names the nodes).
        """
        if len(taus) == 1:
            def sse(v: float) -> NDArray[np.float64]:
                return self.sse(ThermalState('first_order', (v,)), par)
        else:
            other = taus[1 - i]

            def pair(v: float, w: float) -> ThermalState:
                return ThermalState('two_node', (v, w) if i == 0 else (w, v))

            def sse(v: float) -> NDArray[np.float64]:
                lo, hi = max(bounds[0], other / 3.0), min(bounds[1], other * 3.0)
                lo, hi = (max(lo, v), hi) if i == 0 else (lo, min(hi, v))
                if lo >= hi:
                    w = lo if i == 0 else hi
                else:
                    res = minimize_scalar(
                        lambda u: float(self.sse(pair(v, math.exp(u)), par).sum()),
                        bounds=(math.log(lo), math.log(hi)), method='bounded',
                        options={'xatol': 0.02})
                    w = math.exp(res.x)
                return self.sse(pair(v, w), par)

        n_eff = effective_samples(self.fit(ThermalState(
            'first_order' if len(taus) == 1 else 'two_node', taus), par).resid)
        return profile_interval(sse, taus[i], bounds, n_eff, evaluated=seen,
                                bisections=8 if len(taus) == 1 else 5)

    def two_node(self, par: Mapping, tau_fo: float, bounds: tuple[float, float]
                 ) -> tuple[float, float]:
        """
        Search two cascaded time constants ``(a, b)``, ``a <= b``.

        The split ``q = a / (a + b)`` runs over a log grid in [0.01, 0.5] then a bounded
        search; for each split the total ``a + b`` is searched within a factor 4 of the
        first-order time constant.
        """
        lo, hi = bounds
        span = (max(lo, tau_fo / 4.0), min(hi, tau_fo * 4.0))
        memo: dict[float, TimeConstantFit] = {}

        def best_total(q: float) -> TimeConstantFit:
            if q not in memo:
                def objective(total: float) -> float:
                    return float(self.sse(ThermalState(
                        'two_node', (q * total, (1.0 - q) * total)), par).sum())
                memo[q] = fit_time_constant(objective, span, n_grid=7, xatol=0.01)
            return memo[q]

        lq = np.linspace(math.log(0.01), math.log(0.5), 7)
        vals = [best_total(math.exp(v)).sse for v in lq]
        i = int(np.argmin(vals))
        a, b = lq[max(i - 1, 0)], lq[min(i + 1, lq.size - 1)]
        best_q = math.exp(lq[i])
        res = minimize_scalar(lambda v: best_total(math.exp(v)).sse, bounds=(a, b),
                              method='bounded', options={'xatol': 0.05})
        if res.fun < vals[i]:
            best_q = math.exp(res.x)
        total = best_total(best_q).tau
        return best_q * total, (1.0 - best_q) * total


def _thermal_choice(ids: tuple[str, ...], thermal: str | ThermalState | None,
                    fit_params: bool, params: Mapping | None
                    ) -> tuple[tuple[str, ...], str, ThermalState | None]:
    """Return the effect ids, the thermal search mode and the fixed front end (or None)."""
    lagged = _LAG in ids
    if isinstance(thermal, ThermalState):
        if thermal.kind == 'none':
            if lagged:
                raise FitError('`lag` makes the model temperature a lagged state; a thermal '
                               "front end of kind 'none' contradicts it.")
            return ids, 'fixed', thermal
        return with_implied(ids + (_LAG,)), 'fixed', thermal
    if thermal is None:
        thermal = 'first_order' if lagged else 'none'
    if thermal not in THERMAL_CHOICES:
        raise FitError(f'Unknown thermal front end {thermal!r}; expected one of '
                       f'{", ".join(THERMAL_CHOICES)} or a ThermalState.')
    if thermal == 'none':
        if lagged:
            raise FitError("`lag` makes the model temperature a lagged state; thermal='none' "
                           'contradicts it.')
        return ids, 'fixed', ThermalState()
    ids = with_implied(ids + (_LAG,))
    if not fit_params:
        if thermal == 'two_node':
            raise FitError("thermal='two_node' with fit_params=False needs the time constants: "
                           'pass a ThermalState.')
        tau = resolve_params((_LAG,), params)[_LAG]['tau_s']
        return ids, 'fixed', ThermalState('first_order', (tau,))
    return ids, thermal, None


def fit_model(runs: Sequence[Run], *, kind: str = 'rbf',
              features: str | Sequence[str] = ('dT', 'dT2'), t0: float | None = None,
              n_centers: int = 12, refine: bool = False, fit_params: bool = True,
              params: Mapping[str, Mapping[str, float]] | None = None,
              ridge: float | str = 'auto',
              max_rows: int = 200_000, seed: int = 0, frame_id: str = 'imu_link',
              sensor_id: str = '', created: Mapping | None = None,
              thermal: str | ThermalState | None = None,
              rows: Sequence[NDArray[np.bool_]] | None = None,
              sessions: Sequence | None = None) -> CompensationModel:
    """
    Identify a compensation model from training runs.

    With ``lag`` among the features (or a lagged ``thermal``) the model temperature is the
    thermal state, the estimated die temperature: every temperature term, the RBF inputs,
    the scale term and the valid range follow it (``dT`` is implied when no temperature term
    is given). Its time constant is fitted by variable projection (an outer search over
    ``log tau``, the weights re-solved at every trial), with a 95 %
    profile-likelihood interval (:func:`profile_interval`); when the interval reaches a
    search bound or spans more than :data:`MAX_TAU_RATIO` the front end is recorded as not
    identifiable. The profiles go to ``metrics['thermal']``. The time constants are searched
    with a polynomial in the state (for an ``rbf`` model its terms and every power of the
    state up to the cube): a flexible network of a slowly lagged state can fit any function
    of time (the state becomes a clock) and would pin nothing; the network is then fitted
    at the time constants found.

    Parameters
    ----------
    runs : sequence of Run
        Training runs (each a continuous recording; filters restart per run).
    kind : str
        ``'rbf'`` or ``'poly'``.
    features : str or sequence of str
        Effect ids (``'dT,dT2'`` is the paper's modified model; ``bias`` is implied).
    t0 : float, optional, degC
        Reference temperature; default: :func:`estimate_t0` of the first run.
    n_centers : int
        RBF centres K (``rbf`` only).
    refine : bool
        Refine centres and widths by nonlinear least squares.
    fit_params : bool
        Fit the effect parameters marked as fitted in the catalog (warm-up tau) and the
        thermal state's time constants. False: take them from ``params`` (``lag.tau_s`` is
        then the first-order state's time constant) or the catalog defaults.
    params : mapping, optional
        Starting or fixed effect parameters.
    ridge : float or 'auto'
        Relative ridge penalty on the RBF weights (the constant and linear tail are not
        shrunk); ``'auto'`` picks it by cross-validation over interleaved contiguous
        segments of the data, which guards the network against wiggling across gaps.
    max_rows : int
        Rows of the linear solve; longer data are block-averaged down to this.
    seed : int
        Seed of the centre placement.
    frame_id, sensor_id : str
        Recorded in the model.
    created : mapping, optional
        Extra creation info (command line, bag names).
    thermal : str or ThermalState, optional
        The thermal front end: ``'none'`` (the measured temperature), ``'first_order'``,
        ``'two_node'`` (two cascaded lags), ``'auto'`` (first order, or two nodes when they
        lower the cross-validated error by :data:`TWO_NODE_MARGIN`), or a fixed
        :class:`~gyro_tdc.model.thermal_state.ThermalState` (nothing fitted). A lagged choice
        adds ``lag`` to the features. Default: ``'first_order'`` with ``lag``, else
        ``'none'``.
    rows : sequence of NDArray[np.bool_], shape (N,) each, optional
        Per run, the samples that count (e.g. the still ones, ``train --still-only``): the
        fit, the residual, the sample count and the trained range use them only, while the
        filters (thermal state, dT/dt, warm-up) run over every sample of the run, so the
        die temperature evolves through the samples that do not count. None: every sample.
    sessions : sequence, optional
        A session label per run (:func:`gyro_tdc.data.split_sessions`): runs with one label
        share one turn-on offset, and every session has its own, fitted beside one shared
        thermal curve (one indicator column per session instead of one intercept). The
        model's ``intercept`` is then the mean of the session offsets (each session weighs
        the same), so its drift at any temperature is the mean session's; the offsets, as
        differences from that mean, go to ``metrics['sessions']``. None, or one label:
        one offset (the model and its id as without the argument).

    Returns
    -------
    CompensationModel
        The fitted model (format 2: ``model.thermal`` holds the front end).

    """
    ids = normalise_ids(features)
    if kind not in KINDS:
        raise FitError(f'Unknown model kind {kind!r}; expected one of {", ".join(KINDS)}.')
    if kind == 'rbf' and n_centers < 1:
        raise FitError(f'`n_centers` must be at least 1 for an rbf model, got {n_centers}.')
    ids, mode, th = _thermal_choice(ids, thermal, fit_params, params)
    _check_runs(runs, ids, rows)
    labels = _labels(runs, sessions)
    if t0 is None:
        t0 = estimate_t0(runs[0])
    inputs = input_ids(ids, state=True)
    par = resolve_params(ids, params)
    n_all = sum(len(r) for r in runs)
    rows = None if rows is None else [np.asarray(m, dtype=bool) for m in rows]
    n_total = n_all if rows is None else int(sum(np.count_nonzero(m) for m in rows))
    block = block_length(n_all, max_rows, at_most=True)
    blocks = [_Blocks(r, block, None if rows is None else rows[i]) for i, r in enumerate(runs)]
    y = np.concatenate([b.y for b in blocks])
    groups = _block_groups(blocks, labels)

    free = [(eid, name) for eid in inputs for name in EFFECTS[eid].fitted] if fit_params else []
    search_ridge = RIDGE_GRID[1] if ridge == 'auto' else ridge
    fit_state = th is None
    thermal_info: dict = {}
    if free or fit_state:
        # Parameter search on a coarser grid (<= 20k rows): cheap and smooth in log tau.
        # A thermal state is searched with a polynomial in it (for an rbf model, the model's
        # terms with every power of the state): an RBF network of a slowly lagged state
        # fits any function of time, the state turned into a clock, and pins nothing.
        search_inputs, inner = inputs, kind
        if fit_state:
            th = ThermalState('first_order', (par[_LAG]['tau_s'],))
            if kind == 'rbf':
                search_inputs = input_ids(ids + tuple(STATE_TERMS), state=True)
            inner = 'poly'
        search = _Search(runs, search_inputs, t0, inner=inner, n_centers=n_centers,
                         ridge=search_ridge, seed=seed, scale='scale' in ids, n_total=n_all,
                         rows=rows, labels=labels)
        n_rounds = 2 if len(free) + fit_state > 1 else 1
        for _round in range(n_rounds):
            for eid, name in free:

                def sse(tau: float, eid: str = eid, name: str = name) -> float:
                    trial = {k: dict(v) for k, v in par.items()}
                    trial[eid][name] = tau
                    return float(search.sse(th, trial).sum())

                par[eid][name] = fit_time_constant(sse, EFFECTS[eid].bounds[name],
                                                   n_grid=13).tau
            if fit_state:
                tau, seen = search.first_order(par, TAU_BOUNDS)
                th = ThermalState('first_order', (tau,))
        if fit_state:
            th, thermal_info = _choose_state(search, mode, par, th.tau_s[0], seen)

    states = [b.state(th) for b in blocks]
    x = np.concatenate([b.features(inputs, t0, par, exact=True, thermal=th, state=s)
                        for b, s in zip(blocks, states)])
    scale_cols = (np.concatenate([b.scale_cols(t0, state=s) for b, s in zip(blocks, states)])
                  if 'scale' in ids else None)
    fit = fit_linear(x, y, scale_cols=scale_cols, kind=kind, n_centers=n_centers, ridge=ridge,
                     seed=seed, groups=groups)
    offsets = fit.offsets
    if refine and kind == 'rbf':
        if groups is None:
            fit = refine_rbf(x, y, scale_cols, fit, ridge=fit.ridge, seed=seed)
        else:       # refined with the session offsets held: one offset, their mean
            level = y - (offsets - offsets.mean(axis=0))[groups]
            fit = refine_rbf(x, level, scale_cols, replace(fit, coef=_with_level(fit)),
                             ridge=fit.ridge, seed=seed)
            offsets = offsets - offsets.mean(axis=0) + fit.coef[0]
    coef = fit.coef if groups is None else _with_level(fit, offsets)
    counted = states if rows is None else [s[m] for s, m in zip(states, rows)]
    lo = min(float(s.min()) for s in counted if s.size)
    hi = max(float(s.max()) for s in counted if s.size)
    if th.kind != 'none':
        par[_LAG] = {'tau_s': th.tau_total_s}
    info = {'utc': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
            'gyro_tdc_version': __version__}
    info.update(dict(created or {}))
    model = CompensationModel.network(
        kind, ids, par, t0, fit.norm, coef, scale=fit.scale, temp_range_c=(lo, hi),
        residual_var=np.zeros(3), frame_id=frame_id, sensor_id=sensor_id, created=info,
        thermal=th)
    # Training residual at full rate without a second pass over the samples: the drift
    # moves slowly, so sum((y - b)^2) = within-block scatter + n_B * (block residual)^2.
    # Compensation divides by (1 + s dT): so does the residual.
    counts = np.concatenate([b.counts for b in blocks])
    within = np.concatenate([b.scatter(fit.scale, t0, state=s) if np.any(fit.scale)
                             else b.ss_within for b, s in zip(blocks, states)])
    bstate = np.concatenate([b._mean(s) for b, s in zip(blocks, states)])
    gain = 1.0 + (bstate - t0)[:, None] * fit.scale
    ss = ((within + counts[:, None] * fit.resid ** 2) / gain ** 2).sum(axis=0)
    residual_var = np.maximum(ss, 0.0) / n_total
    deg2 = (180.0 / math.pi) ** 2
    metrics = {
        'samples': int(n_total),
        'runs': [r.name for r in runs],
        'train_bs_dps2': [float(v) for v in residual_var * deg2],
        'train_rms_dps': [float(v) for v in np.sqrt(residual_var * deg2)],
        'raw_bs_dps2': [float(v) for v in sum(b.ss_raw for b in blocks) / n_total * deg2],
        'ridge': fit.ridge,
    }
    if thermal_info:
        metrics['thermal'] = thermal_info
    if groups is not None:
        metrics['sessions'] = _session_metrics(runs, labels, offsets, rows)
    return model.replace(residual_var=residual_var, metrics=metrics)


def _with_level(fit: LinearFit, offsets: NDArray[np.float64] | None = None
                ) -> NDArray[np.float64]:
    """Return the coefficients with the constant the mean of the session offsets."""
    coef = fit.coef.copy()
    coef[0] = (fit.offsets if offsets is None else offsets).mean(axis=0)
    return coef


def _session_metrics(runs: Sequence[Run], labels: Sequence[int], offsets: NDArray[np.float64],
                     rows: Sequence[NDArray[np.bool_]] | None) -> dict:
    """Return the sessions' names, samples and offsets from their mean (deg/s)."""
    deg = 180.0 / math.pi
    rel = (offsets - offsets.mean(axis=0)) * deg
    names: list[list[str]] = [[] for _ in range(offsets.shape[0])]
    samples = [0] * offsets.shape[0]
    for i, (r, g) in enumerate(zip(runs, labels)):
        names[g].append(r.name)
        samples[g] += len(r) if rows is None else int(np.count_nonzero(rows[i]))
    spread = rel.max(axis=0) - rel.min(axis=0)
    return {'count': int(offsets.shape[0]),
            'names': [', '.join(n) for n in names], 'samples': samples,
            'offset_dps': [[float(v) for v in o] for o in rel],
            'spread_dps': [float(v) for v in spread]}


def _choose_state(search: _Search, mode: str, par: Mapping, tau_fo: float, seen: Mapping
                  ) -> tuple[ThermalState, dict]:
    """Return the fitted front end of ``mode`` with its intervals, and the search record."""
    prof = search.profile((tau_fo,), 0, par, TAU_BOUNDS, seen)
    first = ThermalState('first_order', (tau_fo,), (prof.interval,), prof.identifiable)
    info: dict = {'chosen': 'first_order', 'profiles': [prof.to_dict()]}
    if mode == 'first_order':
        return first, info
    taus = search.two_node(par, tau_fo, TAU_BOUNDS)
    extra: dict = {}
    if mode == 'auto':
        cv = {'first_order': search.cv_sse(first, par),
              'two_node': search.cv_sse(ThermalState('two_node', taus), par)}
        extra = {'cv_sse': cv, 'candidates': {'first_order': list(first.tau_s),
                                              'two_node': list(taus)}}
        if not cv['two_node'] < (1.0 - TWO_NODE_MARGIN) * cv['first_order']:
            return first, dict(info, **extra)
    bounds = (min(TAU_BOUNDS[0], taus[0]), TAU_BOUNDS[1])    # the split may go below 1 s
    profs = [search.profile(taus, i, par, bounds) for i in range(2)]
    two = ThermalState('two_node', taus, tuple(p.interval for p in profs),
                       all(p.identifiable for p in profs))
    return two, {'chosen': 'two_node', 'profiles': [p.to_dict() for p in profs], **extra}


def fit_px4_cubic(runs: Sequence[Run], *, t0: float | None = None, **kw) -> CompensationModel:
    """
    Fit the PX4-style baseline: a cubic in T - T0 per axis, clamped to the trained range.

    Parameters
    ----------
    runs : sequence of Run
        Training runs.
    t0 : float, optional, degC
        Reference temperature (default :func:`estimate_t0` of the first run).
    **kw
        Passed to :func:`fit_model`.

    Returns
    -------
    CompensationModel
        A ``poly`` model with features ``dT, dT2, dT3``.

    """
    return fit_model(runs, kind='poly', features=('dT', 'dT2', 'dT3'), t0=t0, **kw)
