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
The nonlinear-parameter search of the trainer: time constants by variable projection.

:class:`ParamSearch` re-solves the linear weights (:func:`gyro_tdc.identify.fit_linear`) on
coarse blocks at every trial time constant; :func:`choose_state` picks the thermal front
end (first order, or two nodes when they lower the cross-validated error) with its profile
intervals.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

from gyro_tdc.data import Run
from gyro_tdc.identify.linear import fit_linear, LinearFit
from gyro_tdc.identify.runblocks import block_groups, RunBlocks
from gyro_tdc.identify.tau import (effective_samples, fit_time_constant, profile_interval,
                                   TauProfile, TimeConstantFit)
from gyro_tdc.model import EFFECTS, ThermalState
from gyro_tdc.signal import block_length, block_mean, Folds, heldout
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

__all__ = ['choose_state', 'ParamSearch', 'TAU_BOUNDS', 'TWO_NODE_MARGIN']

#: Relative cross-validated error a two-node state must save over first order to be kept.
TWO_NODE_MARGIN = 0.05
#: Search bounds of the thermal state's time constants, s (the ``lag`` effect's bounds).
TAU_BOUNDS: tuple[float, float] = tuple(EFFECTS['lag'].bounds['tau_s'])


class ParamSearch:
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
        self.blocks = [RunBlocks(r, block, None if rows is None else rows[i])
                       for i, r in enumerate(runs)]
        self.y = np.concatenate([b.y for b in self.blocks])
        self.groups = block_groups(self.blocks, labels)
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
