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
The linear model discovery searches and the statistics of its false-discovery guard.

:class:`LinearModel` builds the design of one effect set on the block grid (per-run offsets,
effect columns, gain and scale terms), fits it by weighted least squares and gives the
held-out residuals of cross-validation; :func:`hac_pvalue` is the guard's significance test,
:func:`make_folds` the held-out test's folds, :func:`bandwidth` the noise memory both use.
See ``doc/internals/identify.md``.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence
import warnings

from gyro_tdc.identify.discover.data import BlockData
from gyro_tdc.model import input_ids, THERMAL_EFFECTS
from gyro_tdc.signal import fit_columns, Folds, heldout, pinv_fit, solve_normal
import numpy as np
from numpy.typing import NDArray

__all__ = ['ar1', 'bandwidth', 'corr', 'DEG', 'gap', 'hac_pvalue', 'LinearModel', 'make_folds',
           'mse', 'ols_hac', 'weighted_corr', 'wsse']

#: rad/s to deg/s.
DEG = 180.0 / math.pi


def wsse(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the block-weighted sum of squares of a residual (K, 3) over blocks and axes."""
    return float((data.w[:, None] * r * r).sum())


def mse(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the block-weighted mean square of a residual (K, 3) over blocks and axes."""
    return float(wsse(data, r) / (3.0 * data.w.sum()))


def gap(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the weighted RMS over blocks and axes of a residual (K, 3), in deg/s."""
    return math.sqrt(mse(data, r)) * DEG


def make_folds(data: BlockData, memory: int, n_folds: int = 5) -> tuple[Folds, int]:
    """
    Return the cross-validation folds and the buffer used.

    Several runs: leave one run out. One run: blocked cross-validation over up to
    ``4 n_folds`` contiguous segments dealt round-robin into ``n_folds`` folds (so every fold
    is predicted by interpolation, never by extrapolation in temperature), with a buffer of
    ``memory`` blocks (the noise memory, at most one segment) on each side of every held-out
    segment left out of the training rows (h-block cross-validation), so that slowly varying
    noise cannot leak from the training rows into the held-out ones.
    """
    if data.n_runs >= 2:
        return Folds.sessions(data.run), 0
    k = data.K
    n_seg = int(min(4 * n_folds, max(k // 3, 2)))
    buffer = int(max(0, min(memory, k // n_seg)))
    return Folds.segments(k, n_segments=n_seg, n_folds=min(n_folds, n_seg), buffer=buffer,
                          min_train=max(4, k // 10)), buffer


def ar1(r: NDArray[np.float64]) -> float:
    """Return the lag-1 autocorrelation of ``r`` (0 for fewer than 3 values)."""
    if r.shape[0] < 3:
        return 0.0
    c = r - r.mean()
    den = float(c @ c)
    return float(c[1:] @ c[:-1]) / den if den > 0 else 0.0


def bandwidth(r: NDArray[np.float64], *, floor: bool = True) -> int:
    """
    Return a Newey-West bandwidth, in lags, that covers the residual's memory.

    Sokal's automatic window on the integrated autocorrelation time: the smallest ``M`` with
    ``M >= 5 (1 + 2 sum_{l<=M} rho_l)``. Unlike an AR(1) plug-in it sees a weak but slow
    component (bias instability) under white noise, which is what makes a smooth candidate
    look significant when it is not. With ``floor`` the bandwidth is at least ``1.3 sqrt(K)``
    (the rule of Lazarus, Lewis, Stock and Watson for a test's bandwidth); without, it is the
    noise memory itself.
    """
    k = r.shape[0]
    c = r - r.mean()
    n = 1 << int(math.ceil(math.log2(2 * k)))
    f = np.fft.rfft(c, n)
    acf = np.fft.irfft(f * np.conj(f), n)[:k]
    if acf[0] <= 0:
        return 1
    rho = acf / acf[0]
    tau = 1.0 + 2.0 * np.cumsum(rho[1:])
    m = np.arange(1, k)
    ok = np.flatnonzero(m >= 5.0 * tau)
    lag = int(m[ok[0]]) if ok.size else k // 3
    if floor:
        lag = max(lag, int(math.ceil(1.3 * math.sqrt(k))))
    return int(min(max(lag, 1), max(k // 3, 1)))


def ols_hac(y: NDArray[np.float64], x: NDArray[np.float64], maxlags: int
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return OLS coefficients (K,) and their small-sample corrected Newey-West covariance (K, K).

    Bit for bit statsmodels' ``OLS(y, x).fit(cov_type='HAC', cov_kwds={'maxlags': L,
    'use_correction': True})`` (``params``, ``cov_params()``): the same pseudo-inverse (SVD,
    singular values below 1e-15 of the largest dropped), sandwich and order of operations
    (checked in ``test/identify/discover/test_linear.py``), without importing statsmodels and
    pandas. ``y`` (N,), ``x`` (N, K); ``maxlags`` is the Bartlett bandwidth in lags.
    """
    x = np.asarray(x)
    params, pinv = pinv_fit(x, y)       # statsmodels' pinv_extended
    bread = np.dot(pinv, np.transpose(pinv))
    xu = x * (y - np.dot(x, params))[:, None]
    weights = 1 - np.arange(maxlags + 1) / (maxlags + 1.0)
    meat = weights[0] * np.dot(xu.T, xu)
    for lag in range(1, maxlags + 1):
        c = np.dot(xu[lag:].T, xu[:-lag])
        meat += weights[lag] * (c + c.T)
    cov = np.dot(np.dot(bread, meat), bread.T)
    nobs, k = xu.shape
    cov *= nobs / float(nobs - k)
    return params, cov


def hac_pvalue(model: LinearModel, coef: NDArray[np.float64], cand: Sequence[int],
               lags: Sequence[int]) -> float:
    """
    Return the HAC Wald p-value of the columns ``cand`` (smallest over axes, times 3).

    Newey-West (Bartlett) errors of OLS (:func:`ols_hac`: statsmodels' ``cov_type='HAC'``
    with its small-sample correction), the bandwidth ``lags[a]`` from the noise's
    integrated autocorrelation time (:func:`bandwidth`); the Wald statistic is referred to
    an F distribution with the estimator's equivalent degrees of freedom, ``1.5 K / L`` (a
    long bandwidth leaves few independent pieces of information, so the test does not
    pretend to more).
    """
    from scipy.special import fdtrc     # imported while the bags are read (cli.train)

    d = model.data
    ps = []
    for a in range(3):
        x = model.design(a) * d.sw[:, None]
        keep = np.linalg.norm(x, axis=0) > 0
        sel = [int(np.count_nonzero(keep[:i])) for i in cand if keep[i]]
        if not sel:
            continue
        xs = x[:, keep] / np.linalg.norm(x[:, keep], axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')   # near-collinear columns: the F test says so
            params, cov = ols_hac(d.y[:, a] * d.sw, xs, int(lags[a]))
        try:
            f = float(params[sel] @ solve_normal(cov[np.ix_(sel, sel)], params[sel],
                                                 fallback=False)) / len(sel)
        except np.linalg.LinAlgError:
            continue
        dof = max(min(1.5 * d.K / lags[a], d.K - xs.shape[1]), 1.0)
        # scipy.stats.f.sf(f, len(sel), dof), without importing scipy.stats (slow): the
        # same function, and 1 below the distribution's support.
        ps.append(1.0 if f <= 0.0 else float(fdtrc(len(sel), dof, f)))
    return min(1.0, 3.0 * min(ps)) if ps else 1.0


def corr(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Return the correlation (about zero) of two arrays, flattened (0 when one is zero)."""
    a, b = a.ravel(), b.ravel()
    den = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(a @ b) / den if den > 0 else 0.0


def weighted_corr(a: NDArray[np.float64], b: NDArray[np.float64],
                  w: NDArray[np.float64]) -> float:
    """Return the weighted correlation of two (K, 3) contributions, flattened."""
    return corr(a * np.sqrt(w)[:, None], b * np.sqrt(w)[:, None])


class LinearModel:
    """Design matrices, least squares, cross-validation and the HAC test for one effect set."""

    def __init__(self, data: BlockData, effects: Sequence[str],
                 params: Mapping[str, Mapping[str, float]], *,
                 extra: NDArray[np.float64] | None = None) -> None:
        self.data = data
        self.effects = tuple(effects)
        self.params = {k: dict(v) for k, v in params.items()}
        #: Time constant of the thermal state (s), None without ``lag``.
        state = bool(THERMAL_EFFECTS & set(self.effects))
        self.state_tau = float(self.params['lag']['tau_s']) if state else None
        self.inputs = input_ids(self.effects, state=state)
        self.labels = [f'offset:{r}' for r in range(data.n_runs)] + list(self.inputs)
        cols = [data.offsets] + [data.column(e, self.params, state_tau=self.state_tau)[:, None]
                                 for e in self.inputs]
        self.common = np.hstack(cols)
        # Per-axis columns: the rate table's gain, scale only on axes whose rate steps can
        # separate it, and a column of its own (the J test).
        ax = {'gain': data.ref * data.gain_axes[None, :] if np.any(data.gain_axes) else None,
              'scale': (data.dtref if self.state_tau is None else data.state_columns(
                  self.state_tau)['dtref']) * data.scale_axes[None, :]
              if 'scale' in self.effects else None,
              'extra': None if extra is None else np.asarray(extra, dtype=np.float64)}
        ax = {k: v for k, v in ax.items() if v is not None}
        self.axis_labels = list(ax)
        self.axis = np.stack(list(ax.values()), axis=2) if ax else np.zeros((data.K, 3, 0))
        self.p = self.common.shape[1] + self.axis.shape[2]

    def columns_of(self, eid: str) -> list[int]:
        """
        Return the design columns that belong to effect ``eid``.

        ``lag`` has none: it changes the temperature columns instead (the thermal state).
        ``'extra'`` is the per-axis column given to the constructor.
        """
        if eid in ('scale', 'extra'):
            return [self.common.shape[1] + self.axis_labels.index(eid)]
        return [i for i, lab in enumerate(self.labels) if lab == eid]

    def design(self, a: int) -> NDArray[np.float64]:
        """Return the design matrix of axis ``a`` (K, p)."""
        return np.hstack([self.common, self.axis[:, a, :]])

    def fit(self, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Return the coefficients (p, 3) fitted on ``rows`` (all by default)."""
        d, rows = self.data, slice(None) if rows is None else rows
        return np.column_stack([fit_columns(self.design(a)[rows], d.y[rows, a], weights=d.w[rows],
                                            normalise=True, rcond=1e-12) for a in range(3)])

    def predict(self, coef: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the simulated block means (K, 3)."""
        return np.column_stack([self.design(a) @ coef[:, a] for a in range(3)])

    def residual(self, coef: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return measured minus simulated (K, 3), rad/s."""
        return self.data.y - self.predict(self.fit() if coef is None else coef)

    def sse(self) -> float:
        """Return the weighted sum of squared residuals over blocks and axes."""
        return wsse(self.data, self.residual())

    def cv_residual(self, folds: Folds) -> NDArray[np.float64]:
        """
        Return held-out residuals (K, 3): each block predicted by a fit without its fold.

        A run with no block in the training rows (leave-one-run-out) has no fitted offset;
        its held-out residual is re-anchored to zero mean (:func:`gyro_tdc.signal.heldout`).
        """
        d = self.data
        return heldout(lambda test, train: d.y[test] - self.predict(self.fit(train))[test],
                       folds, (d.K, 3), groups=d.run, weights=d.w)
