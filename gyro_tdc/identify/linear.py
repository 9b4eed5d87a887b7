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
The linear stage of identification: RBF centre placement, ridge choice and the weights.

:func:`fit_linear` is the inner solve of every variable-projection search in the package
(the thermal state, warm-up, discovery, the accelerometer part); :func:`refine_rbf`
refines centres and widths by nonlinear least squares.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import warnings

from gyro_tdc.base import need
from gyro_tdc.model import rbf_design
from gyro_tdc.signal import fit_columns, Folds, solve_normal, within
import numpy as np
from numpy.typing import NDArray

__all__ = ['fit_linear', 'LinearFit', 'refine_rbf', 'RIDGE_GRID']


def _place_centers(xn: NDArray[np.float64], k: int, seed: int
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Place ``k`` centres by k-means on normalised rows and derive widths."""
    rng = np.random.default_rng(seed)
    if xn.shape[0] > 20_000:
        xn = xn[rng.choice(xn.shape[0], 20_000, replace=False)]
    k = min(k, np.unique(np.round(xn, 9), axis=0).shape[0])
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        # A costly import: only k-means.
        centers, _ = need('scipy.cluster.vq').kmeans2(xn, k, seed=rng, minit='++')
    centers = np.unique(centers, axis=0)
    k = centers.shape[0]
    if k == 1:
        return centers, np.ones(1)
    d = np.sqrt(((centers[:, None, :] - centers[None, :, :]) ** 2).sum(axis=2))
    np.fill_diagonal(d, np.inf)
    return centers, np.maximum(np.sort(d, axis=1)[:, :min(2, k - 1)].mean(axis=1), 1e-3)


#: Relative penalty on the linear tail (conditioning only: the tail is the physics).
_TAIL_RIDGE = 1e-9
#: Relative ridge values tried by ``ridge='auto'`` on the RBF weights.
RIDGE_GRID = (1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 1e-1, 3e-1, 1.0)


def _penalty(p: int, f: int, ridge: float, n: int) -> NDArray[np.float64]:
    """Return the square-root penalty per design column: none on w0, tiny on the tail."""
    pen = np.full(p, math.sqrt(ridge * n))
    pen[0] = 0.0
    pen[1:1 + f] = math.sqrt(_TAIL_RIDGE * n)
    return pen


def _fit_weights(design: NDArray[np.float64], y: NDArray[np.float64],
                 scale_cols: NDArray[np.float64] | None, f: int, ridge: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return the ridge solution for all axes: coefficients (P, 3), scale (3,), residual."""
    pen = _penalty(design.shape[1], f, ridge, design.shape[0])
    if scale_cols is None:
        coef, scale = fit_columns(design, y, penalty=pen), np.zeros(3)
    else:
        p = design.shape[1]
        coef, scale, pen = np.empty((p, 3)), np.empty(3), np.append(pen, 0.0)
        for ax in range(3):
            sol = fit_columns(np.column_stack([design, scale_cols[:, ax]]), y[:, ax], penalty=pen)
            coef[:, ax], scale[ax] = sol[:p], sol[p]
    return coef, scale, design @ coef - y + (0.0 if scale_cols is None else scale_cols * scale)


def _fold_sums(d: NDArray[np.float64], y: NDArray[np.float64], folds: Folds
               ) -> tuple[NDArray[np.float64], ...]:
    """Return per fold's held-out rows ``d'd`` (F, Q, Q), ``d'y`` (F, Q, M), ``y'y`` (F, M)."""
    sums = [(dj.T @ dj, dj.T @ yj, np.einsum('ij,ij->j', yj, yj))
            for dj, yj in ((d[test], y[test]) for test, _train in folds)]
    return tuple(np.array(s) for s in zip(*sums))


def _choose_ridge(design: NDArray[np.float64], y: NDArray[np.float64],
                  scale_cols: NDArray[np.float64] | None, f: int) -> float:
    """
    Pick the RBF ridge by cross-validation over interleaved contiguous segments.

    Holding out whole segments (``Folds.segments``: 5 % of the rows each) tests what matters
    for a drift model: interpolation across a gap in the temperatures covered, where an
    under-regularised network wiggles. Everything comes from each fold's Gram matrix,
    ``d'y`` and ``y'y`` (one pass over the rows): a fold's training problem is the total
    minus its own, its held-out error ``|d w - y|^2 = w'Gw - 2 w'b + y'y``, so the grid
    search costs almost nothing.
    """
    n, p = design.shape
    folds = Folds.segments(n)
    n_trs = [int(np.count_nonzero(train)) for _test, train in folds]
    # Without scale columns every axis shares the design: its sums are computed once.
    shared = None if scale_cols is not None else _fold_sums(design, y, folds)
    errors = np.zeros(len(RIDGE_GRID))
    for ax in range(3):
        col = 0 if shared is None else ax
        gs, bs, ys = shared or _fold_sums(np.column_stack([design, scale_cols[:, ax]]),
                                          y[:, ax:ax + 1], folds)
        g_all, b_all = gs.sum(axis=0), bs[:, :, col].sum(axis=0)
        # A column that is zero in every row (the constant, centred per group) has weight 0:
        # solve without it (else every solve is singular and falls back to least squares).
        live = np.flatnonzero(np.diag(g_all) != 0.0)
        sub = np.ix_(live, live)
        for k in range(len(folds)):
            gk, bk, yyk = gs[k][sub], bs[k, live, col], float(ys[k, col])
            g, b = g_all[sub] - gk, b_all[live] - bk
            for i, ridge in enumerate(RIDGE_GRID):
                pen = np.append(_penalty(p, f, ridge, n_trs[k]) ** 2, np.zeros(gs.shape[1] - p))
                w = solve_normal(g + np.diag(pen[live]), b)
                errors[i] += float(w @ (gk @ w)) - 2.0 * float(w @ bk) + yyk
    # The largest ridge within 1 % of the best error: prefer the smoother network.
    # (abs: on noise-free data the expanded error may round to just below zero.)
    ok = np.flatnonzero(errors <= errors.min() + 0.01 * abs(errors.min()))
    return float(RIDGE_GRID[int(ok.max())])


@dataclass(frozen=True, eq=False)
class LinearFit:
    """
    A drift network fitted by :func:`fit_linear`: normalisation, centres and weights.

    Inputs are normalised as ``(x - mean) / std``; ``centers`` (K, F) and ``widths`` (K,) are in
    normalised units (K = 0 for ``poly``); ``coef`` (1 + F + K, 3) weighs ``[1, x~, phi]``,
    ``scale`` (3,) the ``scale_cols``; ``resid`` is prediction minus target, ``sse`` its sum of
    squares; with ``groups``, ``coef[0]`` is zero and ``offsets`` (G, 3) holds each group's
    constant in the order of ``np.unique(groups)``.
    """

    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    centers: NDArray[np.float64]
    widths: NDArray[np.float64]
    coef: NDArray[np.float64]
    scale: NDArray[np.float64]
    sse: float
    resid: NDArray[np.float64]
    ridge: float
    offsets: NDArray[np.float64] | None = None

    @property
    def norm(self) -> tuple:
        """Return ``(mean, std, centers, widths)``: the network's inputs and centres."""
        return (self.mean, self.std, self.centers, self.widths)

    def design(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the design matrix ``[1, x~, phi(x~)]`` (N, 1 + F + K) of feature rows ``x``."""
        return rbf_design(self.norm, x)

    def predict(self, x: NDArray[np.float64],
                scale_cols: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return the fitted drift (N, 3) at feature rows ``x`` (and ``dT omega_ref``)."""
        return self.design(x) @ self.coef + (0 if scale_cols is None else scale_cols * self.scale)


def fit_linear(x: NDArray[np.float64], y: NDArray[np.float64], *,
               scale_cols: NDArray[np.float64] | None = None, kind: str = 'poly',
               n_centers: int = 12, ridge: float | str = 'auto', seed: int = 0,
               groups: NDArray[np.int64] | None = None) -> LinearFit:
    """
    Fit the drift network on one feature matrix (N, F) to the target (N, 3) by ridge regression.

    For ``rbf`` the centres are placed by k-means on the normalised rows (each width the mean
    distance to the two nearest other centres); the weights of ``[1, x~, phi(x~)]`` (and of
    ``scale_cols``, ``dT * omega_ref`` per axis) get no penalty on the constant, a tiny one on the
    linear tail (conditioning only) and the relative ``ridge`` on the RBF weights (``'auto'``:
    chosen from :data:`RIDGE_GRID` by cross-validation over interleaved contiguous segments, for
    ``rbf`` with at least 40 rows). ``groups`` give each group its own constant (the
    within-group problem solved exactly, e.g. one offset per session or orientation).
    """
    mean, std = x.mean(axis=0), x.std(axis=0)
    std = np.where(std > 1e-12 * np.maximum(np.abs(mean), 1.0), std, 1.0)
    xn = (x - mean) / std
    centers, widths = (_place_centers(xn, n_centers, seed) if kind == 'rbf' and x.shape[1]
                       else (np.zeros((0, x.shape[1])), np.zeros(0)))
    design = rbf_design((mean, std, centers, widths), x)
    f = x.shape[1]
    if groups is not None:
        dmeans, design = within(design, groups)
        ymeans, y = within(np.asarray(y, dtype=np.float64), groups)
        if scale_cols is not None:
            smeans, scale_cols = within(scale_cols, groups)
    if ridge == 'auto':
        ridge = (_choose_ridge(design, y, scale_cols, f) if centers.shape[0]
                 and design.shape[0] >= 40 else RIDGE_GRID[1])
    coef, scale, resid = _fit_weights(design, y, scale_cols, f, ridge)
    offsets = None
    if groups is not None:          # the centred constant column is zero: no w0
        coef[0] = 0.0
        offsets = ymeans - dmeans @ coef
        if scale_cols is not None:
            offsets -= smeans * scale
    return LinearFit(mean=mean, std=std, centers=centers, widths=widths, coef=coef,
                     scale=scale, sse=float((resid ** 2).sum()), resid=resid,
                     ridge=float(ridge), offsets=offsets)


def refine_rbf(x: NDArray[np.float64], y: NDArray[np.float64],
               scale_cols: NDArray[np.float64] | None, fit: LinearFit, *, ridge: float,
               seed: int, max_rows: int = 2000) -> LinearFit:
    """Refine centres and widths by nonlinear least squares (variable projection)."""
    least_squares = need('scipy.optimize').least_squares     # a costly import: --refine only

    k, f = fit.centers.shape
    if k == 0:
        return fit
    rows = np.random.default_rng(seed).choice(x.shape[0], min(max_rows, x.shape[0]), replace=False)
    xs, ys = x[rows], y[rows]
    ss = None if scale_cols is None else scale_cols[rows]

    def norm(theta: NDArray[np.float64]) -> tuple:
        return fit.mean, fit.std, theta[:k * f].reshape(k, f), np.exp(theta[k * f:])

    def resid(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return _fit_weights(rbf_design(norm(theta), xs), ys, ss, f, ridge)[2].ravel()

    theta0 = np.concatenate([fit.centers.ravel(), np.log(fit.widths)])
    sol = least_squares(resid, theta0, method='trf', max_nfev=20, x_scale='jac')
    if sol.cost * 2 >= float((resid(theta0) ** 2).sum()):
        return fit
    _mean, _std, centers, widths = best = norm(sol.x)
    coef, scale, r = _fit_weights(rbf_design(best, x), y, scale_cols, f, ridge)
    return replace(fit, centers=centers, widths=widths, coef=coef, scale=scale, resid=r,
                   sse=float((r ** 2).sum()))
