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
Statistics of the search: gaps, cross-validation folds, noise memory and HAC Wald tests.

The functions here work on block-mean residuals; none of them knows which effects are
searched, nor imports the modules that do: :class:`Blocks` and :class:`Design` name what they
read of the block data and of a linear model. :func:`hac_pvalue` is the significance test of
the false-discovery guard, :func:`make_folds` the held-out test's folds, :func:`bandwidth` the
noise memory both use.
"""

from __future__ import annotations

import math
from typing import Protocol, Sequence
import warnings

from gyro_tdc.signal import fit_columns, Folds, pinv_fit, solve_normal
import numpy as np
from numpy.typing import NDArray
from scipy.special import fdtrc

__all__ = ['ar1', 'bandwidth', 'Blocks', 'COLLINEAR', 'DEG', 'Design', 'gap', 'hac_pvalue',
           'make_folds', 'ols_hac', 'rel_residual', 'weighted_corr']


#: rad/s to deg/s.
DEG = 180.0 / math.pi
#: Relative norm below which a column is taken as spanned by the others.
COLLINEAR = 1e-3


class Blocks(Protocol):
    """What the statistics read of block data (:class:`~.data.BlockData` is one)."""

    #: Number of blocks.
    K: int
    #: Number of runs, and the run of each block (K,).
    n_runs: int
    run: NDArray[np.int64]
    #: Block weights (K,), their square roots, and the block-mean rate error (K, 3).
    w: NDArray[np.float64]
    sw: NDArray[np.float64]
    y: NDArray[np.float64]


class Design(Protocol):
    """What :func:`hac_pvalue` reads of a linear model (:class:`~.linear.LinearModel` is one)."""

    data: Blocks

    def design(self, a: int) -> NDArray[np.float64]:
        """Return the design matrix of axis ``a``, one row per block (K, p)."""


def rel_residual(x: NDArray[np.float64], col: NDArray[np.float64]) -> float:
    """Return ``|col - projection on span(x)| / |col - mean|`` (0: col is in the span)."""
    c = col - col.mean()
    nc = float(np.linalg.norm(c))
    if nc == 0.0:
        return 0.0
    if x.shape[1] == 0:
        return 1.0
    beta = fit_columns(x, col, normalise=True)
    return float(np.linalg.norm(col - x @ beta)) / nc


def gap(data: Blocks, r: NDArray[np.float64]) -> float:
    """Return the weighted RMS over blocks and axes of a residual (K, 3), in deg/s."""
    return float(np.sqrt((data.w[:, None] * r * r).sum() / (3.0 * data.w.sum()))) * DEG


def make_folds(data: Blocks, memory: int, n_folds: int = 5) -> tuple[Folds, int]:
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
    Return the OLS coefficients and their Newey-West (Bartlett) covariance, small-sample corrected.

    The numbers of statsmodels' ``OLS(y, x).fit(cov_type='HAC', cov_kwds={'maxlags': L,
    'use_correction': True})`` (``params``, ``cov_params()``), bit for bit: the same
    pseudo-inverse (SVD, singular values below 1e-15 of the largest dropped), the same
    sandwich and the same operations in the same order (checked against statsmodels in
    ``test/identify/test_discover_stats.py``), without importing statsmodels and pandas
    (~0.5 s a process).

    Parameters
    ----------
    y : NDArray[np.float64], shape (N,)
        The regressand.
    x : NDArray[np.float64], shape (N, K)
        The design.
    maxlags : int
        Bartlett bandwidth, lags.

    Returns
    -------
    params : NDArray[np.float64], shape (K,)
    cov : NDArray[np.float64], shape (K, K)

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


def hac_pvalue(model: Design, coef: NDArray[np.float64], cand: Sequence[int],
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
    d = model.data
    ps = []
    for a in range(3):
        x = model.design(a) * d.sw[:, None]
        y = d.y[:, a] * d.sw
        keep = np.linalg.norm(x, axis=0) > 0
        idx = [i for i in cand if keep[i]]
        if not idx:
            continue
        xs = x[:, keep]
        xs = xs / np.linalg.norm(xs, axis=0)
        pos = np.cumsum(keep) - 1
        sel = [int(pos[i]) for i in idx]
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')   # near-collinear columns: the F test says so
            params, cov = ols_hac(y, xs, int(lags[a]))
        b = params[sel]
        v = cov[np.ix_(sel, sel)]
        try:
            f = float(b @ solve_normal(v, b, fallback=False)) / len(sel)
        except np.linalg.LinAlgError:
            continue
        dof = max(min(1.5 * d.K / lags[a], d.K - xs.shape[1]), 1.0)
        # scipy.stats.f.sf(f, len(sel), dof), without importing scipy.stats (~0.5 s): the
        # same function, and 1 below the distribution's support.
        ps.append(1.0 if f <= 0.0 else float(fdtrc(len(sel), dof, f)))
    return min(1.0, 3.0 * min(ps)) if ps else 1.0


def weighted_corr(a: NDArray[np.float64], b: NDArray[np.float64],
                  w: NDArray[np.float64]) -> float:
    """Return the weighted correlation of two (K, 3) contributions, flattened."""
    wa = (a * np.sqrt(w)[:, None]).ravel()
    wb = (b * np.sqrt(w)[:, None]).ravel()
    den = float(np.linalg.norm(wa) * np.linalg.norm(wb))
    return float(wa @ wb) / den if den > 0 else 0.0
