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
Time constants: the one search, its profile interval, the thermal state's on the block grid.

:func:`fit_time_constant` is the one "log grid, then bounded Brent" search of the package;
:func:`profile_interval` turns the residual profile into a 95 % interval, with the
residual's autocorrelation counted by :func:`effective_samples`. :class:`RunBlocks` reduces
one run to block means (over the rows that count) on :class:`gyro_tdc.signal.BlockGrid`;
:func:`run_state` holds each run's full-rate thermal state once for the gyro fit and the
accelerometer part. :class:`ParamSearch` re-solves the linear weights on coarse blocks at every
trial time constant (variable projection); :func:`choose_state` picks the thermal front end.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
import math
from typing import Callable, Mapping, Sequence
import weakref

from gyro_tdc.base import need, plain
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.linear import fit_linear, LinearFit
from gyro_tdc.model import batch_features, EFFECTS, ThermalState
from gyro_tdc.signal import block_length, block_mean, BlockGrid, Folds, heldout
import numpy as np
from numpy.typing import NDArray

__all__ = ['choose_state', 'effective_samples', 'fit_time_constant', 'MAX_TAU_RATIO',
           'ParamSearch', 'PROFILE_LEVEL', 'profile_interval', 'run_blocks', 'run_state',
           'RunBlocks', 'TAU_BOUNDS', 'TauProfile', 'TimeConstantFit', 'TWO_NODE_MARGIN']

#: Profile-likelihood level of a 95 % interval on one parameter (chi-square, 1 dof).
PROFILE_LEVEL = 3.841
#: A time-constant interval wider than this ratio (hi / lo) does not pin the time constant.
MAX_TAU_RATIO = 3.0


@dataclass(frozen=True, eq=False)
class TimeConstantFit:
    """The best ``tau`` of :func:`fit_time_constant`, its objective, and the grid profile."""

    tau: float
    sse: float
    grid_tau: NDArray[np.float64]
    grid_sse: NDArray[np.float64]


def fit_time_constant(sse: Callable[[float], float], bounds: tuple[float, float], *,
                      n_grid: int = 13, log: bool = True, xatol: float = 1e-3
                      ) -> TimeConstantFit:
    """
    Minimise ``sse(tau)`` over ``bounds``: a grid, then a bounded Brent search.

    The grid (``n_grid`` points, in ``log(tau)`` when ``log``) finds the basin;
    :func:`scipy.optimize.minimize_scalar` then searches between the neighbours of the best grid
    point (``xatol`` in the search variable), and its answer is kept when it is no worse.
    FitError for bounds that are not ``0 < lo <= hi`` (``0 <=`` without ``log``) or ``n_grid < 1``.
    """
    lo, hi = (float(v) for v in bounds)
    if not (math.isfinite(lo) and math.isfinite(hi) and (lo > 0.0 if log else lo >= 0.0)
            and lo <= hi):
        raise FitError(f'Expected `bounds` (lo, hi) with {"0 <" if log else "0 <="} lo <= hi, '
                       f'got {bounds!r}.')
    if n_grid < 1:
        raise FitError(f'Expected `n_grid` >= 1, got {n_grid!r}.')
    objective = (lambda v: sse(math.exp(v))) if log else sse
    grid = np.linspace(math.log(lo), math.log(hi), n_grid) if log else np.linspace(lo, hi, n_grid)
    vals = np.array([objective(g) for g in grid], dtype=np.float64)
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best, best_sse = grid[i], float(vals[i])
    if b > a:
        minimize_scalar = need('scipy.optimize').minimize_scalar
        res = minimize_scalar(objective, bounds=(a, b), method='bounded', options={'xatol': xatol})
        if res.fun <= vals[i]:
            best, best_sse = res.x, float(res.fun)
    return TimeConstantFit(tau=float(math.exp(best)) if log else float(best), sse=best_sse,
                           grid_tau=np.exp(grid) if log else grid, grid_sse=vals)


def effective_samples(resid: NDArray[np.float64], *, min_batches: int = 32
                      ) -> NDArray[np.float64]:
    """
    Return per column the number of independent samples a correlated residual is worth (1..N).

    ``n / inflation``, the variance inflation of the mean being the larger of the AR(1) value
    ``(1 + rho) / (1 - rho)`` and the batch-means values ``m var(mean of m rows) / var(row)`` for
    ``m = 2, 4, ...`` while ``min_batches`` batches remain (memory longer than one lag).
    """
    r = np.asarray(resid, dtype=np.float64).reshape(len(resid), -1)
    n = r.shape[0]
    if n < 3:
        return np.full(r.shape[1], float(max(n, 1)))
    r = r - r.mean(axis=0)
    var = np.maximum((r * r).mean(axis=0), 1e-300)
    rho = np.clip((r[1:] * r[:-1]).mean(axis=0) / var, 0.0, 0.999)
    inflation = (1.0 + rho) / (1.0 - rho)
    m = 2
    while n // m >= min_batches:
        means = r[:n // m * m].reshape(-1, m, r.shape[1]).mean(axis=1)
        inflation = np.maximum(inflation, m * means.var(axis=0) / var)
        m *= 2
    return np.clip(n / np.maximum(inflation, 1.0), 1.0, float(n))


@dataclass(frozen=True, eq=False)
class TauProfile:
    """
    The profile of a fit over one time constant, and the interval it gives.

    ``interval`` is the hull of every evaluated ``tau`` within the level; ``identifiable`` is
    False when it reaches a search bound or ``hi / lo > max_ratio``; ``stat`` is
    ``sum_a n_eff_a ln(SSE_a(tau) / SSE_a(tau_best))`` at each ``grid_tau``.
    """

    tau: float
    interval: tuple[float, float]
    identifiable: bool
    grid_tau: NDArray[np.float64]
    stat: NDArray[np.float64]
    n_eff: NDArray[np.float64]
    bounds: tuple[float, float]

    def to_dict(self) -> dict:
        """Return the profile as plain types (for a model's training metrics)."""
        return plain({'tau_s': self.tau, 'interval_s': self.interval,
                      'identifiable': self.identifiable, 'bounds_s': self.bounds,
                      'n_eff': self.n_eff, 'profile_tau_s': self.grid_tau,
                      'profile_stat': self.stat})


def profile_interval(sse: Callable[[float], NDArray[np.float64]], tau: float,
                     bounds: tuple[float, float], n_eff: NDArray[np.float64], *,
                     evaluated: Mapping[float, NDArray[np.float64]] | None = None,
                     level: float = PROFILE_LEVEL, max_ratio: float = MAX_TAU_RATIO,
                     step: float = 0.005, bisections: int = 8) -> TauProfile:
    """
    Return the profile-likelihood interval of a time constant fitted by variable projection.

    With Gaussian residuals of unknown variance per column the 95 % interval is
    ``{tau : sum_a n_eff_a ln(SSE_a(tau) / SSE_a(tau_best)) <= level}``, ``n_eff`` counting the
    residual's memory. From ``tau`` the profile is walked outwards in ``log tau`` with doubling
    steps (from ``step``) until the statistic exceeds ``level`` or a bound is reached, and each
    end is bisected ``bisections`` times; points already ``evaluated`` join the profile, and the
    interval is the hull of every point within the level (a flat or multi-modal profile widens
    it).
    """
    lo_b, hi_b = (float(v) for v in bounds)
    if not (0.0 < lo_b <= tau <= hi_b):
        raise FitError(f'Expected 0 < lo <= tau <= hi, got bounds {bounds!r} and tau {tau!r}.')
    n_eff = np.asarray(n_eff, dtype=np.float64).ravel()
    pts: dict[float, NDArray[np.float64]] = {
        float(k): np.asarray(v, dtype=np.float64).ravel() for k, v in (evaluated or {}).items()}

    def at(v: float) -> NDArray[np.float64]:
        if v not in pts:
            pts[v] = np.asarray(sse(v), dtype=np.float64).ravel()
        return pts[v]

    floor = np.maximum(at(float(tau)), 1e-300)

    def stat(v: float) -> float:
        return float((n_eff * np.log(np.maximum(at(v), 1e-300) / floor)).sum())

    u0, u_lo, u_hi = math.log(tau), math.log(lo_b), math.log(hi_b)
    ends = []
    for side, bound in ((-1.0, u_lo), (1.0, u_hi)):
        inside, outside, d = u0, None, step
        while outside is None:
            u = max(u0 - d, bound) if side < 0 else min(u0 + d, bound)
            inside, outside = (inside, u) if stat(math.exp(u)) > level else (u, None)
            if u == bound:
                break
            d *= 2.0
        for _ in range(bisections if outside is not None else 0):
            mid = 0.5 * (inside + outside)
            inside, outside = (inside, mid) if stat(math.exp(mid)) > level else (mid, outside)
        ends.append(inside)
    grid = np.array(sorted(pts))
    st = np.array([stat(v) for v in grid])
    st -= min(0.0, float(st.min()))
    within = grid[st <= level]
    lo = max(min(math.exp(ends[0]), float(within.min()), tau), lo_b)
    hi = min(max(math.exp(ends[1]), float(within.max()), tau), hi_b)
    ident = lo > lo_b * (1 + 1e-9) and hi < hi_b * (1 - 1e-9) and hi <= max_ratio * lo
    return TauProfile(tau=float(tau), interval=(lo, hi), identifiable=bool(ident),
                      grid_tau=grid, stat=st, n_eff=n_eff, bounds=(lo_b, hi_b))


#: Relative cross-validated error a two-node state must save over first order to be kept.
TWO_NODE_MARGIN = 0.05
#: Search bounds of the thermal state's time constants, s (the ``lag`` effect's bounds).
TAU_BOUNDS: tuple[float, float] = tuple(EFFECTS['lag'].bounds['tau_s'])

# Full-rate thermal states by run, while the run lives (a weak reference: a run dropped drops
# its state): fit_model's are the accelerometer part's.
_STATES: dict[int, tuple[weakref.ref, tuple, NDArray[np.float64]]] = {}
_STATES_KEPT = 8


def run_state(thermal: ThermalState, run: Run) -> NDArray[np.float64]:
    """Return ``thermal.temperature(run.t, run.temp)``, once per run and front end (read-only)."""
    key = (thermal.kind, tuple(float(v) for v in thermal.tau_s), id(run.t), id(run.temp))
    rid = id(run)
    if (hit := _STATES.get(rid)) is not None and hit[0]() is run and hit[1] == key:
        return hit[2]
    state = thermal.temperature(run.t, run.temp)
    state.flags.writeable = False
    _STATES.pop(rid, None)
    _STATES[rid] = (weakref.ref(run, lambda _ref, rid=rid: _STATES.pop(rid, None)), key, state)
    while len(_STATES) > _STATES_KEPT:
        _STATES.pop(next(iter(_STATES)))
    return state


class RunBlocks:
    """
    Block means of one run: stamps, temperature, drift target and reference rate.

    With ``rows`` (the samples that count, e.g. the still ones) every mean but the stamps' and
    the temperature's is over those rows only and blocks without any are dropped; the filters
    (thermal state, dT/dt, warm-up) still run over every sample.
    """

    def __init__(self, run: Run, block: int, rows: NDArray[np.bool_] | None = None) -> None:
        self.run, self.block = run, block
        self.t, self.temp = block_mean(run.t, block), block_mean(run.temp, block)
        # No reference rate (a chamber run): x - 0 is x and the means of zeros are zeros.
        self.has_ref = bool(np.any(run.omega_ref))
        err, self.grid = self._err(), BlockGrid(len(run), block, rows=rows)
        self.rows, self.counts, self.mean = self.grid.rows, self.grid.counts, self.grid.mean
        e = err if self.rows is None else err[self.rows]
        self.ss_raw = np.einsum('ij,ij->j', e, e)
        self.y, self.ss_within = self.grid.moments(err)
        self.ref = self.mean(run.omega_ref) if self.has_ref else np.zeros(self.y.shape)

    def _err(self) -> NDArray[np.float64]:
        return self.run.omega - self.run.omega_ref if self.has_ref else self.run.omega

    def scatter(self, scale: NDArray[np.float64], t0: float,
                state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return per block the squared deviations of the error less ``scale dT omega_ref``."""
        temp = self.run.temp if state is None else state     # called with a non-zero scale
        err = self._err() - (temp - t0)[:, None] * self.run.omega_ref * scale
        return self.grid.moments(err)[1]

    def features(self, ids: Sequence[str], t0: float, params: Mapping, thermal: ThermalState,
                 state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return block-mean features: with the run's ``state`` from full rate, else coarse."""
        if state is not None and self.block > 1:
            return self.mean(batch_features(ids, self.run.t, self.run.temp, t0=t0,
                                            params=params, state=state))
        return self.grid.sel(batch_features(ids, self.t, self.temp, t0=t0, params=params,
                                            state=thermal.temperature(self.t, self.temp)))

    def scale_cols(self, t0: float, state: NDArray[np.float64] | None = None,
                   thermal: ThermalState | None = None) -> NDArray[np.float64]:
        """Return block means of ``dT * omega_ref`` (N, 3): exact, or with ``thermal`` coarse."""
        if thermal is not None:
            return (self.grid.sel(thermal.temperature(self.t, self.temp)) - t0)[:, None] * self.ref
        d = (self.run.temp if state is None else state) - t0
        return self.mean(d[:, None] * self.run.omega_ref)


def run_blocks(runs: Sequence[Run], block: int, rows: Sequence[NDArray[np.bool_]] | None,
               labels: Sequence[int] | None) -> tuple[list[RunBlocks], NDArray[np.float64],
                                                      NDArray[np.int64] | None]:
    """
    Return the runs' blocks, their stacked drift target and the session of every block row.

    Each run's blocks are over its ``rows`` when given; the sessions are None for one session.
    """
    blocks = [RunBlocks(r, block, None if rows is None else rows[i]) for i, r in enumerate(runs)]
    groups = None if labels is None else np.concatenate(
        [np.full(b.y.shape[0], g, dtype=np.int64) for b, g in zip(blocks, labels)])
    return blocks, np.concatenate([b.y for b in blocks]), groups


class ParamSearch:
    """
    The nonlinear-parameter search of ``fit_model``, on coarse blocks (<= 20k rows).

    ``sse(thermal, params)`` is the residual sum of squares per axis with the linear weights
    re-solved (variable projection) by ``fit_linear(kind=inner)`` on the ``inputs``.
    """

    def __init__(self, runs: Sequence[Run], inputs: Sequence[str], t0: float, *, inner: str,
                 n_centers: int, ridge: float, seed: int, scale: bool,
                 rows: Sequence[NDArray[np.bool_]] | None = None,
                 labels: Sequence[int] | None = None) -> None:
        self.blocks, self.y, self.groups = run_blocks(
            runs, block_length(sum(map(len, runs)), 20_000, at_most=True), rows, labels)
        self.inputs, self.t0, self.scale = tuple(inputs), t0, scale
        self._linear = partial(fit_linear, kind=inner, n_centers=n_centers, ridge=ridge, seed=seed)

    def design(self, thermal: ThermalState, par: Mapping
               ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Return the coarse feature rows and scale columns of a front end."""
        x = np.concatenate([b.features(self.inputs, self.t0, par, thermal) for b in self.blocks])
        lagged = thermal if thermal.kind != 'none' else None
        return x, (np.concatenate([b.scale_cols(self.t0, thermal=lagged) for b in self.blocks])
                   if self.scale else None)

    def fit(self, thermal: ThermalState, par: Mapping) -> LinearFit:
        """Return the linear fit on the coarse rows with this front end and parameters."""
        x, sc = self.design(thermal, par)
        return self._linear(x, self.y, scale_cols=sc, groups=self.groups)

    def sse(self, thermal: ThermalState, par: Mapping) -> NDArray[np.float64]:
        """Return the residual sum of squares per axis (3,)."""
        r = self.fit(thermal, par).resid
        return np.einsum('ij,ij->j', r, r)

    def cv_sse(self, thermal: ThermalState, par: Mapping) -> float:
        """
        Return the cross-validated SSE of the slow error.

        Each row is predicted by a fit without its fold (20 interleaved contiguous segments in 5
        folds); the out-of-fold residuals are averaged over 60 s windows before squaring, so the
        white noise shrinks and the figure measures the drift the model misses.
        """
        x, sc = self.design(thermal, par)
        g = self.groups

        def residual(test: NDArray[np.bool_], train: NDArray[np.bool_]) -> NDArray[np.float64]:
            fit = self._linear(x[train], self.y[train], scale_cols=None if sc is None else
                               sc[train], groups=None if g is None else g[train])
            r = fit.predict(x[test], None if sc is None else sc[test]) - self.y[test]
            if g is not None:           # the fitted offset of every session trained on
                for j, grp in enumerate(np.unique(g[train])):
                    r[g[test] == grp] += fit.offsets[j]
            return r

        folds = Folds.segments(x.shape[0], n_segments=20, n_folds=5)
        resid = heldout(residual, folds, self.y.shape, groups=g)
        steps = np.concatenate([np.diff(b.t) for b in self.blocks])
        dt = float(np.median(steps)) if steps.size else 60.0
        w = max(1, int(round(60.0 / dt))) if dt > 0 else 1
        return float((block_mean(resid, w) ** 2).sum())

    def first_order(self, par: Mapping, bounds: tuple[float, float]) -> tuple[float, dict]:
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

        With two nodes the other time constant is re-fitted at every point (a full profile),
        kept on its side: the larger one for ``i = 0``, the smaller for ``i = 1`` (the
        cascade commutes, so only the order names the nodes).
        """
        one = len(taus) == 1
        other = taus[1 - i] if not one else 0.0

        def pair(v: float, w: float) -> ThermalState:
            return ThermalState('two_node', (v, w) if i == 0 else (w, v))

        def sse(v: float) -> NDArray[np.float64]:
            if one:
                return self.sse(ThermalState('first_order', (v,)), par)
            lo, hi = max(bounds[0], other / 3.0), min(bounds[1], other * 3.0)
            lo, hi = (max(lo, v), hi) if i == 0 else (lo, min(hi, v))
            if lo >= hi:
                w = lo if i == 0 else hi
            else:
                minimize_scalar = need('scipy.optimize').minimize_scalar
                w = math.exp(minimize_scalar(
                    lambda u: float(self.sse(pair(v, math.exp(u)), par).sum()),
                    bounds=(math.log(lo), math.log(hi)), method='bounded',
                    options={'xatol': 0.02}).x)
            return self.sse(pair(v, w), par)

        n_eff = effective_samples(self.fit(ThermalState(
            'first_order' if one else 'two_node', taus), par).resid)
        return profile_interval(sse, taus[i], bounds, n_eff, evaluated=seen,
                                bisections=8 if one else 5)

    def two_node(self, par: Mapping, tau_fo: float, bounds: tuple[float, float]
                 ) -> tuple[float, float]:
        """
        Search two cascaded time constants ``(a, b)``, ``a <= b``.

        The split ``q = a / (a + b)`` runs over a log grid in [0.01, 0.5] then a bounded
        search; for each split the total ``a + b`` is searched within a factor 4 of the
        first-order time constant.
        """
        span = (max(bounds[0], tau_fo / 4.0), min(bounds[1], tau_fo * 4.0))
        memo: dict[float, TimeConstantFit] = {}

        def best_total(q: float) -> TimeConstantFit:
            if q not in memo:
                memo[q] = fit_time_constant(lambda total: float(self.sse(ThermalState(
                    'two_node', (q * total, (1.0 - q) * total)), par).sum()), span, n_grid=7,
                    xatol=0.01)
            return memo[q]

        best_q = fit_time_constant(lambda q: best_total(q).sse, (0.01, 0.5), n_grid=7,
                                   xatol=0.05).tau
        total = best_total(best_q).tau
        return best_q * total, (1.0 - best_q) * total


def choose_state(search: ParamSearch, mode: str, par: Mapping, tau_fo: float, seen: Mapping
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
