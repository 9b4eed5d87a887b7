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

The procedure follows section 3.2 of the paper with the usual modern refinements:

1. the drift samples are the raw output minus the reference rate; the inputs are the effect
   features of the model temperature (``dT`` and ``dT^2`` for the paper's modified model),
   which is the measured temperature, or with ``lag`` the thermal state (the estimated die
   temperature, :mod:`gyro_tdc.thermal_state`);
2. the inputs are normalised; RBF centres are placed by k-means over the input samples and
   each width is the mean distance to the two nearest other centres;
3. the output weights (with a constant and linear tail, and the per-axis ``scale`` term when
   asked) are found by regularised linear least squares;
4. optionally the centres and widths are refined with ``scipy.optimize.least_squares``
   (variable projection: weights re-solved at every step), which does what the paper's
   gradient rule (eq. 28) does, faster and with a stopping rule;
5. effect parameters (the warm-up time constant) and the thermal state's time constant(s)
   are fitted by variable projection: an outer bounded search over ``log tau``
   (:func:`fit_time_constant`), the weights re-solved at every trial (:func:`fit_linear`);
   the state's time constant gets a 95 % profile-likelihood interval
   (:func:`profile_interval`, with the residual's autocorrelation counted by
   :func:`effective_samples`), and a profile too flat to pin it marks the state as not
   identifiable. ``thermal='auto'`` also fits the two-node state (two cascaded lags) and
   keeps it only when it lowers the cross-validated error by :data:`TWO_NODE_MARGIN`.

Long runs are block-averaged before the linear solve: temperature moves slowly, so averaging
a few samples loses nothing of the drift and bounds memory and time.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import datetime as _dt
import math
from typing import Callable, Mapping, Sequence
import warnings

from gyro_tdc import __version__
from gyro_tdc.blocks import block_counts, block_length, block_mean, block_sum, block_sumsq
from gyro_tdc.effects import (batch_features, EFFECTS, input_ids, normalise_ids,
                              REFERENCE_EFFECTS, resolve_params, STATE_TERMS,
                              TEMPERATURE_EFFECTS, THERMAL_EFFECTS, with_implied)
from gyro_tdc.errors import FitError
from gyro_tdc.model import CompensationModel, KINDS, rbf_design
from gyro_tdc.runs import Run
from gyro_tdc.thermal_state import ThermalState
import numpy as np
from numpy.typing import NDArray
from scipy.cluster.vq import kmeans2
from scipy.optimize import least_squares, minimize_scalar

__all__ = ['effective_samples', 'estimate_t0', 'fit_linear', 'fit_model', 'fit_px4_cubic',
           'fit_time_constant', 'LinearFit', 'MAX_TAU_RATIO', 'MIN_SAMPLES', 'MIN_SPAN_C',
           'PROFILE_LEVEL', 'profile_interval', 'RIDGE_GRID', 'TAU_BOUNDS', 'THERMAL_CHOICES',
           'TimeConstantFit', 'TauProfile', 'TWO_NODE_MARGIN']

#: Fewest samples a fit accepts.
MIN_SAMPLES = 50
#: Smallest temperature span (degC) a fit with temperature features accepts.
MIN_SPAN_C = 0.5
#: Profile-likelihood level of a 95 % interval on one parameter (chi-square, 1 dof).
PROFILE_LEVEL = 3.841
#: A time-constant interval wider than this ratio (hi / lo) does not pin the time constant.
MAX_TAU_RATIO = 3.0
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
        err = run.omega - run.omega_ref
        self.rows = None if rows is None else np.asarray(rows, dtype=bool)
        self.keep = None
        if self.rows is None:
            self.counts = block_counts(len(run), block)
            self.ss_raw = np.einsum('ij,ij->j', err, err)
        else:
            c = block_sum(self.rows.astype(np.float64), block)
            self.keep = c > 0
            self.counts = c[self.keep]
            e = err[self.rows]
            self.ss_raw = np.einsum('ij,ij->j', e, e)
        self.y = self._mean(err)
        self.ref = self._mean(run.omega_ref)
        self.ss_within = self._scatter(err, self.y)

    def _sel(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the rows of ``x`` (one per block) of the blocks kept."""
        return x if self.keep is None else x[self.keep]

    def _mean(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the block means of ``x`` (N, ...) over the rows that count."""
        if self.rows is None:
            return block_mean(x, self.block)
        x = np.asarray(x, dtype=np.float64)
        shape = (-1,) + (1,) * (x.ndim - 1)
        sums = block_sum(np.where(self.rows.reshape(shape), x, 0.0), self.block)
        return sums[self.keep] / self.counts.reshape(shape)

    def _scatter(self, err: NDArray[np.float64], mean: NDArray[np.float64]
                 ) -> NDArray[np.float64]:
        """Per block and axis, the sum of squared deviations of ``err`` from ``mean``."""
        if self.rows is not None:
            err = np.where(self.rows[:, None], err, 0.0)
        return self._sel(block_sumsq(err, self.block)) - self.counts[:, None] * mean ** 2

    def state(self, thermal: ThermalState) -> NDArray[np.float64]:
        """Return the thermal state at full rate (N,), degC."""
        return thermal.temperature(self.run.t, self.run.temp)

    def scatter(self, scale: NDArray[np.float64], t0: float,
                state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return, per block, the sum of squared deviations from the block mean (per axis).

        The error is taken after removing the sensitivity term ``scale * dT * omega_ref``
        (``dT`` of the full-rate ``state``, or of the measured temperature), which changes
        within a block when the rate table steps.
        """
        err = self.run.omega - self.run.omega_ref
        if np.any(scale):
            temp = self.run.temp if state is None else state
            err = err - (temp - t0)[:, None] * self.run.omega_ref * scale
        return self._scatter(err, self._mean(err))

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


def _place_centers(xn: NDArray[np.float64], k: int, seed: int
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Place ``k`` centres by k-means on normalised rows and derive widths."""
    rng = np.random.default_rng(seed)
    if xn.shape[0] > 20_000:
        xn = xn[rng.choice(xn.shape[0], 20_000, replace=False)]
    uniq = np.unique(np.round(xn, 9), axis=0)
    k = min(k, uniq.shape[0])
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        centers, _ = kmeans2(xn, k, seed=rng, minit='++')
    centers = np.unique(centers, axis=0)
    k = centers.shape[0]
    if k == 1:
        return centers, np.ones(1)
    d = np.sqrt(((centers[:, None, :] - centers[None, :, :]) ** 2).sum(axis=2))
    np.fill_diagonal(d, np.inf)
    nn = np.sort(d, axis=1)[:, :min(2, k - 1)]
    widths = np.maximum(nn.mean(axis=1), 1e-3)
    return centers, widths


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


def _solve(design: NDArray[np.float64], y: NDArray[np.float64],
           scale_cols: NDArray[np.float64] | None, pen: NDArray[np.float64]
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Solve the regularised least squares for all axes.

    Returns the coefficients (P, 3) and the per-axis scale coefficients (3,).
    """
    p = design.shape[1]
    reg = np.diag(pen)[1:]
    if scale_cols is None:
        a = np.vstack([design, reg])
        b = np.vstack([y, np.zeros((p - 1, 3))])
        coef = np.linalg.lstsq(a, b, rcond=None)[0]
        return coef, np.zeros(3)
    coef = np.empty((p, 3))
    scale = np.empty(3)
    for ax in range(3):
        a = np.vstack([np.column_stack([design, scale_cols[:, ax]]),
                       np.column_stack([reg, np.zeros(p - 1)])])
        b = np.concatenate([y[:, ax], np.zeros(p - 1)])
        sol = np.linalg.lstsq(a, b, rcond=None)[0]
        coef[:, ax], scale[ax] = sol[:p], sol[p]
    return coef, scale


def _choose_ridge(design: NDArray[np.float64], y: NDArray[np.float64],
                  scale_cols: NDArray[np.float64] | None, f: int, *,
                  n_segments: int = 20, n_folds: int = 5) -> float:
    """
    Pick the RBF ridge by cross-validation over interleaved contiguous segments.

    Holding out whole segments (5 % of the rows each) tests what matters for a drift model:
    interpolation across a gap in the temperatures covered, where an under-regularised
    network wiggles. Normal equations per fold make the grid search cost almost nothing.
    """
    n, p = design.shape
    axes = []
    for ax in range(3):
        d = design if scale_cols is None else np.column_stack([design, scale_cols[:, ax]])
        axes.append((d, y[:, ax]))
    fold = (np.arange(n) * n_segments // n) % n_folds
    errors = np.zeros(len(RIDGE_GRID))
    for d, yy in axes:
        q = d.shape[1]
        g_all, b_all = d.T @ d, d.T @ yy
        for k in range(n_folds):
            m = fold == k
            dk, yk = d[m], yy[m]
            g, b = g_all - dk.T @ dk, b_all - dk.T @ yk
            n_tr = n - int(m.sum())
            for i, ridge in enumerate(RIDGE_GRID):
                pen = np.zeros(q)
                pen[:p] = _penalty(p, f, ridge, n_tr) ** 2
                try:
                    w = np.linalg.solve(g + np.diag(pen), b)
                except np.linalg.LinAlgError:
                    w = np.linalg.lstsq(g + np.diag(pen), b, rcond=None)[0]
                r = dk @ w - yk
                errors[i] += float(r @ r)
    # The largest ridge within 1 % of the best error: prefer the smoother network.
    ok = np.flatnonzero(errors <= errors.min() * 1.01)
    return float(RIDGE_GRID[int(ok.max())])


@dataclass(frozen=True, eq=False)
class LinearFit:
    """
    A drift network fitted by :func:`fit_linear`: normalisation, centres and weights.

    Parameters
    ----------
    mean, std : NDArray[np.float64], shape (F,)
        Input normalisation, ``x~ = (x - mean) / std``.
    centers : NDArray[np.float64], shape (K, F)
        RBF centres in normalised units (K = 0 for ``poly``).
    widths : NDArray[np.float64], shape (K,)
        RBF widths in normalised units.
    coef : NDArray[np.float64], shape (1 + F + K, 3)
        Weights of the design columns ``[1, x~, phi]`` per axis.
    scale : NDArray[np.float64], shape (3,)
        Per-axis coefficients of the ``scale_cols`` (zeros without them).
    sse : float
        Sum of squared residuals over rows and axes.
    resid : NDArray[np.float64], shape (N, 3)
        Residuals ``prediction - y`` of the fitted rows.
    ridge : float
        Relative ridge penalty used on the RBF weights.
    offsets : NDArray[np.float64], shape (G, 3), optional
        With ``groups``: the constant of each group (``coef[0]`` is then zero).

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

    def design(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """
        Return the design matrix ``[1, x~, phi(x~)]`` of feature rows ``x``.

        Parameters
        ----------
        x : NDArray[np.float64], shape (N, F)
            Raw feature rows.

        Returns
        -------
        NDArray[np.float64], shape (N, 1 + F + K)
            Design matrix (:func:`gyro_tdc.model.rbf_design`).

        """
        return rbf_design((self.mean, self.std, self.centers, self.widths), x)

    def predict(self, x: NDArray[np.float64],
                scale_cols: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return the fitted drift at feature rows ``x``.

        Parameters
        ----------
        x : NDArray[np.float64], shape (N, F)
            Raw feature rows.
        scale_cols : NDArray[np.float64], shape (N, 3), optional
            ``dT * omega_ref`` per axis, when the fit has a ``scale`` term.

        Returns
        -------
        NDArray[np.float64], shape (N, 3)
            Predicted drift per axis.

        """
        out = self.design(x) @ self.coef
        if scale_cols is not None:
            out += scale_cols * self.scale
        return out


def _residual(design: NDArray[np.float64], y: NDArray[np.float64],
              scale_cols: NDArray[np.float64] | None, pen: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Solve the weights and return them with the scale coefficients and the residual."""
    coef, scale = _solve(design, y, scale_cols, pen)
    resid = design @ coef - y
    if scale_cols is not None:
        resid += scale_cols * scale
    return coef, scale, resid


def _within(a: NDArray[np.float64], inverse: NDArray[np.int64], counts: NDArray[np.float64]
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the group means of the rows of ``a`` and ``a`` minus its group's mean."""
    means = np.zeros((counts.size,) + a.shape[1:])
    np.add.at(means, inverse, a)
    means /= counts.reshape((-1,) + (1,) * (a.ndim - 1))
    return means, a - means[inverse]


def fit_linear(x: NDArray[np.float64], y: NDArray[np.float64], *,
               scale_cols: NDArray[np.float64] | None = None, kind: str = 'poly',
               n_centers: int = 12, ridge: float | str = 'auto', seed: int = 0,
               groups: NDArray[np.int64] | None = None) -> LinearFit:
    """
    Fit the drift network on one feature matrix by regularised linear least squares.

    The inputs are normalised to zero mean and unit deviation; for ``rbf`` the centres are
    placed by k-means on the normalised rows (each width the mean distance to the two nearest
    other centres); then the weights of ``[1, x~, phi(x~)]`` (and of ``scale_cols``) are
    solved with no penalty on the constant, a tiny one on the linear tail (conditioning
    only) and the relative ``ridge`` on the RBF weights.

    Parameters
    ----------
    x : NDArray[np.float64], shape (N, F)
        Feature rows (effect columns, :func:`gyro_tdc.effects.batch_features`).
    y : NDArray[np.float64], shape (N, 3)
        Drift target per axis.
    scale_cols : NDArray[np.float64], shape (N, 3), optional
        ``dT * omega_ref`` per axis: fits the per-axis ``scale`` coefficient too.
    kind : str
        ``'poly'`` (linear in the features) or ``'rbf'``.
    n_centers : int
        RBF centres K (``rbf`` only; fewer when the rows have fewer distinct values).
    ridge : float or 'auto'
        Relative ridge on the RBF weights; ``'auto'`` picks it from :data:`RIDGE_GRID` by
        cross-validation over interleaved contiguous segments (``rbf`` with at least 40
        rows), else uses ``RIDGE_GRID[1]``.
    seed : int
        Seed of the centre placement.
    groups : NDArray[np.int64], shape (N,), optional
        A label per row: each group gets its own constant instead of the common ``w0``
        (the within-group problem is solved exactly: design columns and target centred per
        group), e.g. one offset per accelerometer orientation.

    Returns
    -------
    LinearFit
        Normalisation, centres, weights, residuals and the ridge used (with ``groups``,
        ``coef[0]`` is zero and ``offsets`` holds the constant of each group, in the order
        of ``np.unique(groups)``).

    """
    mean = x.mean(axis=0) if x.shape[1] else np.zeros(0)
    std = x.std(axis=0) if x.shape[1] else np.ones(0)
    std = np.where(std > 1e-12 * np.maximum(np.abs(mean), 1.0), std, 1.0)
    xn = (x - mean) / std
    if kind == 'rbf' and x.shape[1]:
        centers, widths = _place_centers(xn, n_centers, seed)
    else:
        centers, widths = np.zeros((0, x.shape[1])), np.zeros(0)
    design = rbf_design((mean, std, centers, widths), x)
    f = x.shape[1]
    if groups is not None:
        _, inverse, counts = np.unique(np.asarray(groups), return_inverse=True,
                                       return_counts=True)
        inverse = inverse.reshape(-1)
        counts = counts.astype(np.float64)
        dmeans, design = _within(design, inverse, counts)
        ymeans, y = _within(np.asarray(y, dtype=np.float64), inverse, counts)
        if scale_cols is not None:
            smeans, scale_cols = _within(scale_cols, inverse, counts)
    if ridge == 'auto':
        ridge = (_choose_ridge(design, y, scale_cols, f) if centers.shape[0]
                 and design.shape[0] >= 40 else RIDGE_GRID[1])
    pen = _penalty(design.shape[1], f, ridge, design.shape[0])
    coef, scale, resid = _residual(design, y, scale_cols, pen)
    offsets = None
    if groups is not None:          # the centred constant column is zero: no w0
        coef[0] = 0.0
        offsets = ymeans - dmeans @ coef
        if scale_cols is not None:
            offsets -= smeans * scale
    return LinearFit(mean=mean, std=std, centers=centers, widths=widths, coef=coef,
                     scale=scale, sse=float((resid ** 2).sum()), resid=resid,
                     ridge=float(ridge), offsets=offsets)


@dataclass(frozen=True, eq=False)
class TimeConstantFit:
    """
    A time constant chosen by :func:`fit_time_constant`, with its residual profile.

    Parameters
    ----------
    tau : float, s
        The best time constant found.
    sse : float
        The objective at ``tau``.
    grid_tau : NDArray[np.float64], shape (G,), s
        Time constants of the search grid, increasing.
    grid_sse : NDArray[np.float64], shape (G,)
        The objective at each grid point (the profile, e.g. for an interval on ``tau``).

    """

    tau: float
    sse: float
    grid_tau: NDArray[np.float64]
    grid_sse: NDArray[np.float64]


def fit_time_constant(sse: Callable[[float], float], bounds: tuple[float, float], *,
                      n_grid: int = 13, log: bool = True, xatol: float = 1e-3
                      ) -> TimeConstantFit:
    """
    Minimise ``sse(tau)`` over a bounded range: a grid, then a bounded Brent search.

    The grid (log-spaced by default) finds the basin; :func:`scipy.optimize.minimize_scalar`
    (``method='bounded'``) then searches between the neighbours of the best grid point, and
    its answer is kept when it is no worse than that grid point.

    Parameters
    ----------
    sse : callable
        ``sse(tau) -> float``, the objective (e.g. the least-squares residual with the linear
        weights re-solved at every trial: variable projection).
    bounds : tuple of float, s
        ``(lo, hi)``, ``0 < lo <= hi`` (``0 <= lo`` when ``log`` is False).
    n_grid : int
        Grid points, >= 1.
    log : bool
        Grid and search in ``log(tau)`` (True) or in ``tau``.
    xatol : float
        Absolute tolerance of the bounded search, in the search variable (``log(tau)``
        when ``log``).

    Returns
    -------
    TimeConstantFit
        The best ``tau``, its objective and the grid profile.

    """
    lo, hi = (float(v) for v in bounds)
    if not (math.isfinite(lo) and math.isfinite(hi) and (lo > 0.0 if log else lo >= 0.0)
            and lo <= hi):
        raise FitError(f'Expected `bounds` (lo, hi) with {"0 <" if log else "0 <="} lo <= hi, '
                       f'got {bounds!r}.')
    if n_grid < 1:
        raise FitError(f'Expected `n_grid` >= 1, got {n_grid!r}.')
    if log:
        def objective(v: float) -> float:
            return sse(math.exp(v))
        grid = np.linspace(math.log(lo), math.log(hi), n_grid)
    else:
        objective = sse
        grid = np.linspace(lo, hi, n_grid)
    vals = np.array([objective(g) for g in grid], dtype=np.float64)
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best, best_sse = grid[i], float(vals[i])
    if b > a:
        res = minimize_scalar(objective, bounds=(a, b), method='bounded',
                              options={'xatol': xatol})
        if res.fun <= vals[i]:
            best, best_sse = res.x, float(res.fun)
    tau = float(math.exp(best)) if log else float(best)
    return TimeConstantFit(tau=tau, sse=best_sse,
                           grid_tau=np.exp(grid) if log else grid, grid_sse=vals)


def effective_samples(resid: NDArray[np.float64], *, min_batches: int = 32
                      ) -> NDArray[np.float64]:
    """
    Return, per column, the number of independent samples a correlated residual is worth.

    A residual with memory (slow noise, or drift the model misses) carries less information
    than its length: ``n_eff = n / inflation`` with the variance inflation of its mean taken
    as the larger of the AR(1) value ``(1 + rho) / (1 - rho)`` (``rho`` the lag-1
    autocorrelation, ``n_eff = n (1 - rho) / (1 + rho)``) and the batch-means values
    ``m var(mean of m rows) / var(row)`` for ``m = 2, 4, ...`` while at least
    ``min_batches`` batches remain (memory longer than one lag).

    Parameters
    ----------
    resid : NDArray[np.float64], shape (N,) or (N, A)
        Residual rows in time order.
    min_batches : int
        Fewest batches a batch-means value is taken from.

    Returns
    -------
    NDArray[np.float64], shape (A,)
        ``n_eff`` per column, between 1 and N.

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

    Parameters
    ----------
    tau : float, s
        The best time constant.
    interval : tuple of float, s
        ``(lo, hi)``: every evaluated ``tau`` whose statistic is within ``level`` (the
        hull, ends resolved by bisection).
    identifiable : bool
        False when the interval reaches a search bound or ``hi / lo > max_ratio``.
    grid_tau : NDArray[np.float64], shape (G,), s
        Every evaluated time constant, increasing.
    stat : NDArray[np.float64], shape (G,)
        The profile statistic at each: ``sum_a n_eff_a ln(SSE_a(tau) / SSE_a(tau_best))``,
        0 at the best point.
    n_eff : NDArray[np.float64], shape (A,)
        Effective samples per residual column (:func:`effective_samples`).
    bounds : tuple of float, s
        The search bounds.

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
        return {'tau_s': float(self.tau), 'interval_s': [float(v) for v in self.interval],
                'identifiable': bool(self.identifiable),
                'bounds_s': [float(v) for v in self.bounds],
                'n_eff': [float(v) for v in self.n_eff],
                'profile_tau_s': [float(v) for v in self.grid_tau],
                'profile_stat': [float(v) for v in self.stat]}


def profile_interval(sse: Callable[[float], NDArray[np.float64]], tau: float,
                     bounds: tuple[float, float], n_eff: NDArray[np.float64], *,
                     evaluated: Mapping[float, NDArray[np.float64]] | None = None,
                     level: float = PROFILE_LEVEL, max_ratio: float = MAX_TAU_RATIO,
                     step: float = 0.005, bisections: int = 8) -> TauProfile:
    """
    Return the profile-likelihood interval of a time constant fitted by variable projection.

    With Gaussian residuals of unknown variance per column, ``-2 ln L = sum_a n_a ln SSE_a``
    once the linear weights are re-solved (the profile over them); the 95 % interval is
    ``{tau : sum_a n_eff_a ln(SSE_a(tau) / SSE_a(tau_best)) <= level}``, ``n_eff`` counting the
    residual's memory. From ``tau`` the profile is walked outwards in ``log tau`` with
    doubling steps (from ``step``) until the statistic exceeds ``level`` or a bound is
    reached, and each end is bisected ``bisections`` times; points already ``evaluated``
    (e.g. the search grid) join the profile, and the interval is the hull of every point
    within the level (a flat or multi-modal profile widens it).

    Parameters
    ----------
    sse : callable
        ``sse(tau) -> NDArray (A,)``: the residual sum of squares per column at ``tau``.
    tau : float, s
        The best time constant (a minimum of ``sum(sse(tau))``).
    bounds : tuple of float, s
        The search bounds ``(lo, hi)``, ``0 < lo <= tau <= hi``.
    n_eff : NDArray[np.float64], shape (A,)
        Effective samples per column (:func:`effective_samples` of the residual at ``tau``).
    evaluated : mapping, optional
        ``{tau: sse per column}`` already known (no re-evaluation).
    level : float
        Threshold of the statistic (:data:`PROFILE_LEVEL`: 95 %).
    max_ratio : float
        Widest ``hi / lo`` that still counts as identifiable.
    step : float
        First step of the walk, in ``log tau``.
    bisections : int
        Bisections of each end.

    Returns
    -------
    TauProfile
        The interval, whether it pins ``tau``, and the profile.

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
        if outside is not None:
            for _ in range(bisections):
                mid = 0.5 * (inside + outside)
                if stat(math.exp(mid)) > level:
                    outside = mid
                else:
                    inside = mid
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


def _refine(x: NDArray[np.float64], y: NDArray[np.float64],
            scale_cols: NDArray[np.float64] | None, fit: LinearFit, *, ridge: float,
            seed: int, max_rows: int = 2000) -> LinearFit:
    """Refine centres and widths by nonlinear least squares (variable projection)."""
    k, f = fit.centers.shape
    if k == 0:
        return fit
    rng = np.random.default_rng(seed)
    rows = rng.choice(x.shape[0], min(max_rows, x.shape[0]), replace=False)
    xs, ys = x[rows], y[rows]
    ss = None if scale_cols is None else scale_cols[rows]
    mean, std = fit.mean, fit.std

    def unpack(theta: NDArray[np.float64]) -> tuple:
        return theta[:k * f].reshape(k, f), np.exp(theta[k * f:])

    def resid(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        centers, widths = unpack(theta)
        d = rbf_design((mean, std, centers, widths), xs)
        return _residual(d, ys, ss, _penalty(d.shape[1], f, ridge, d.shape[0]))[2].ravel()

    theta0 = np.concatenate([fit.centers.ravel(), np.log(fit.widths)])
    sol = least_squares(resid, theta0, method='trf', max_nfev=20, x_scale='jac')
    if sol.cost * 2 >= float((resid(theta0) ** 2).sum()):
        return fit
    centers, widths = unpack(sol.x)
    design = rbf_design((mean, std, centers, widths), x)
    pen = _penalty(design.shape[1], f, ridge, design.shape[0])
    coef, scale, r = _residual(design, y, scale_cols, pen)
    return replace(fit, centers=centers, widths=widths, coef=coef, scale=scale, resid=r,
                   sse=float((r ** 2).sum()))


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
            if not np.all(np.isfinite(getattr(r, key))):
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
                 rows: Sequence[NDArray[np.bool_]] | None = None) -> None:
        block = block_length(n_total, 20_000, at_most=True)
        self.blocks = [_Blocks(r, block, None if rows is None else rows[i])
                       for i, r in enumerate(runs)]
        self.y = np.concatenate([b.y for b in self.blocks])
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
                sc: NDArray[np.float64] | None) -> LinearFit:
        return fit_linear(x, y, scale_cols=sc, kind=self.inner, n_centers=self.n_centers,
                          ridge=self.ridge, seed=self.seed)

    def fit(self, thermal: ThermalState, par: Mapping) -> LinearFit:
        """Return the linear fit on the coarse rows with this front end and parameters."""
        x, sc = self.design(thermal, par)
        return self._linear(x, self.y, sc)

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
        n = x.shape[0]
        fold = (np.arange(n) * n_segments // n) % n_folds
        resid = np.zeros_like(self.y)
        for k in range(n_folds):
            test = fold == k
            if not test.any() or test.all():
                continue
            fit = self._linear(x[~test], self.y[~test], None if sc is None else sc[~test])
            resid[test] = fit.predict(x[test], None if sc is None else sc[test]) - self.y[test]
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
              rows: Sequence[NDArray[np.bool_]] | None = None) -> CompensationModel:
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
        :class:`~gyro_tdc.thermal_state.ThermalState` (nothing fitted). A lagged choice
        adds ``lag`` to the features. Default: ``'first_order'`` with ``lag``, else
        ``'none'``.
    rows : sequence of NDArray[np.bool_], shape (N,) each, optional
        Per run, the samples that count (e.g. the still ones, ``train --still-only``): the
        fit, the residual, the sample count and the trained range use them only, while the
        filters (thermal state, dT/dt, warm-up) run over every sample of the run, so the
        die temperature evolves through the samples that do not count. None: every sample.

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
                         rows=rows)
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
                     seed=seed)
    if refine and kind == 'rbf':
        fit = _refine(x, y, scale_cols, fit, ridge=fit.ridge, seed=seed)
    f = len(inputs)
    coef = fit.coef
    counted = states if rows is None else [s[m] for s, m in zip(states, rows)]
    lo = min(float(s.min()) for s in counted if s.size)
    hi = max(float(s.max()) for s in counted if s.size)
    if th.kind != 'none':
        par[_LAG] = {'tau_s': th.tau_total_s}
    info = {'utc': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
            'gyro_tdc_version': __version__}
    info.update(dict(created or {}))
    model = CompensationModel(
        kind=kind, features=ids, effect_params=par, t0_c=float(t0),
        input_mean=fit.mean, input_std=fit.std, centers=fit.centers,
        widths=fit.widths, weights=coef[1 + f:], intercept=coef[0], linear=coef[1:1 + f],
        scale=fit.scale, temp_range_c=(lo, hi), residual_var=np.zeros(3),
        frame_id=frame_id, sensor_id=sensor_id, created=info, thermal=th)
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
    return model.replace(residual_var=residual_var, metrics=metrics)


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
