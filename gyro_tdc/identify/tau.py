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
Time constants: the bounded search and the profile-likelihood interval.

:func:`fit_time_constant` is the one "log grid, then bounded Brent" search of the package;
:func:`profile_interval` turns the residual profile into a 95 % interval, with the
residual's autocorrelation counted by :func:`effective_samples`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Callable, Mapping

from gyro_tdc.base import plain
from gyro_tdc.errors import FitError
import numpy as np
from numpy.typing import NDArray

__all__ = ['effective_samples', 'fit_time_constant', 'MAX_TAU_RATIO', 'PROFILE_LEVEL',
           'profile_interval', 'TauProfile', 'TimeConstantFit']

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
        from scipy.optimize import minimize_scalar   # imported while the bags are read

        res = minimize_scalar(objective, bounds=(a, b), method='bounded', options={'xatol': xatol})
        if res.fun <= vals[i]:
            best, best_sse = res.x, float(res.fun)
    tau = float(math.exp(best)) if log else float(best)
    return TimeConstantFit(tau=tau, sse=best_sse,
                           grid_tau=np.exp(grid) if log else grid, grid_sse=vals)


def effective_samples(resid: NDArray[np.float64], *, min_batches: int = 32
                      ) -> NDArray[np.float64]:
    """
    Return per column the number of independent samples a correlated residual is worth (1..N).

    ``n / inflation``, the variance inflation of the mean being the larger of the AR(1) value
    ``(1 + rho) / (1 - rho)`` and the batch-means values ``m var(mean of m rows) / var(row)`` for
    ``m = 2, 4, ...`` while ``min_batches`` batches remain (memory longer than one lag).
    """
    r = np.asarray(resid, dtype=np.float64)
    r = r.reshape(r.shape[0], -1)
    n = r.shape[0]
    if n < 3:
        return np.full(r.shape[1], float(max(n, 1)))
    r = r - r.mean(axis=0)
    var = np.maximum((r * r).mean(axis=0), 1e-300)
    rho = np.clip((r[1:] * r[:-1]).mean(axis=0) / var, 0.0, 0.999)
    inflation = (1.0 + rho) / (1.0 - rho)
    m = 2
    while n // m >= min_batches:
        k = n // m * m
        means = r[:k].reshape(-1, m, r.shape[1]).mean(axis=1)
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
        while True:
            u = u0 + side * d
            u = max(u, bound) if side < 0 else min(u, bound)
            if stat(math.exp(u)) > level:
                outside = u
                break
            inside = u
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
    lo = min(math.exp(ends[0]), float(within.min()))
    hi = max(math.exp(ends[1]), float(within.max()))
    lo, hi = max(min(lo, tau), lo_b), min(max(hi, tau), hi_b)
    eps = 1e-9
    ident = lo > lo_b * (1 + eps) and hi < hi_b * (1 - eps) and hi <= max_ratio * lo
    return TauProfile(tau=float(tau), interval=(lo, hi), identifiable=bool(ident),
                      grid_tau=grid, stat=st, n_eff=n_eff, bounds=(lo_b, hi_b))
