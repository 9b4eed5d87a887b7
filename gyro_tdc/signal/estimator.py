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
The one estimator: effect columns, one offset per session, weights, ridge, folds.

Every fit of effect columns in the package solves here (:func:`fit_columns`, :func:`solve_normal`,
:func:`pinv_fit`, :func:`hat`); sessions get their offsets as indicator columns
(:func:`session_columns`) or exactly eliminated (:func:`within`); :class:`Folds` is the one
cross-validation scheme (interleaved contiguous segments, or leave one session out),
:func:`heldout` its held-out residuals; :func:`check_offsets` judges the sessions' mean offset
against none on held-out sessions (the trainer's and the learner's rule for a power cycle whose
offset is not known yet). Its rows are block means of the one block grid,
:class:`gyro_tdc.signal.blocks.BlockGrid`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

from gyro_tdc.base import AXES, DEG2_PER_RAD2, DEG_PER_RAD
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['check_offsets', 'curve_untold', 'CURVE_SIGNIFICANCE', 'CurveVerdict', 'fit_columns',
           'Folds', 'hat', 'heldout', 'judge_curve', 'MIN_SESSION_SPAN_C', 'pinv_fit',
           'session_columns', 'solve_normal', 'within']

#: With a free offset per group (power cycle, orientation segment) a curve is told only within
#: a group: where no fold can judge it, it stands only on a group spanning this many degC.
MIN_SESSION_SPAN_C = 2.0
#: A curve is kept on an axis only where its held-out gain over the offset alone (per row, in
#: squared residual) is this many standard errors above zero: a gain inside the noise of a
#: few short still stretches is no evidence that the curve carries to the next power cycle.
CURVE_SIGNIFICANCE = 2.0


def fit_columns(x: NDArray[np.float64], y: NDArray[np.float64], *,
                weights: NDArray[np.float64] | None = None,
                penalty: NDArray[np.float64] | None = None, normalise: bool = False,
                rcond: float | None = None) -> NDArray[np.float64]:
    """
    Solve weighted, ridge-penalised linear least squares for the coefficients of ``x``.

    ``x`` (N, P) holds the effect columns (and session indicators), ``y`` (N,) or (N, M) the
    targets; the coefficients are (P,) or (P, M). ``weights`` (N,) multiply rows and targets
    by their square roots; ``penalty`` (P,) is the square root of the ridge per column (a row
    ``penalty[j] e_j`` with target 0 per non-zero entry). ``normalise`` solves on unit-norm
    columns (a zero column keeps a zero coefficient); ``rcond`` cuts small singular values
    (numpy's default when None).
    """
    if weights is not None:
        sw = np.sqrt(weights)
        x = x * sw[:, None]
        y = y * (sw[:, None] if y.ndim == 2 else sw)
    if penalty is not None:
        pen = np.asarray(penalty, dtype=np.float64)
        rows = np.diag(pen)[pen != 0.0]
        x = np.vstack([x, rows])
        y = np.concatenate([y, np.zeros((rows.shape[0],) + y.shape[1:])])
    if not normalise:
        return np.linalg.lstsq(x, y, rcond=rcond)[0]
    scale = np.linalg.norm(x, axis=0)
    scale[scale == 0] = 1.0
    beta = np.linalg.lstsq(x / scale, y, rcond=rcond)[0]
    return beta / (scale[:, None] if beta.ndim == 2 else scale)


def solve_normal(a: NDArray[np.float64], b: NDArray[np.float64], *,
                 fallback: bool = True) -> NDArray[np.float64]:
    """
    Solve normal equations ``a w = b`` (a Gram matrix plus its ridge).

    A singular ``a`` is solved by least squares with ``fallback``, else raises
    ``numpy.linalg.LinAlgError``.
    """
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        if not fallback:
            raise
        return np.linalg.lstsq(a, b, rcond=None)[0]


def pinv_fit(x: NDArray[np.float64], y: NDArray[np.float64], *, cutoff: float = 1e-15
             ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the least-squares coefficients by an SVD pseudo-inverse, and the pseudo-inverse.

    Singular values below ``cutoff`` times the largest are dropped (statsmodels'
    ``pinv_extended``, operation for operation, so a HAC covariance built on it matches).
    """
    u, s, vt = np.linalg.svd(x.conjugate(), False)
    s = np.divide(1.0, s, out=np.zeros_like(s), where=s > cutoff * np.maximum.reduce(s))
    pinv = np.dot(np.transpose(vt), np.multiply(s[:, np.newaxis], np.transpose(u)))
    return np.dot(pinv, y), pinv


def hat(x: NDArray[np.float64], w: NDArray[np.float64]
        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return ``A = pinv(x' W x)`` and the leverage of every row of a weighted fit.

    The coefficients are ``A x' W y``; a row's leave-one-out residual is ``r / (1 - h)``.
    """
    a = np.linalg.pinv((x * w[:, None]).T @ x)
    return a, np.einsum('ij,jk,ik->i', x, a, x) * w


def session_columns(groups: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """
    Return one indicator column per session (in sorted label order) and the labels.

    Parameters
    ----------
    groups : ArrayLike, shape (N,)
        Session label of every row.

    Returns
    -------
    columns : NDArray[np.float64], shape (N, G)
    labels : NDArray, shape (G,)

    """
    g = np.asarray(groups)
    labels = np.unique(g)
    return np.column_stack([(g == s).astype(np.float64) for s in labels]), labels


def curve_untold(temp: ArrayLike, groups: ArrayLike) -> float | None:
    """
    Return the widest group's span of ``temp`` (degC) where no group tells a curve, else None.

    With a free offset per group a curve is told only within one: two groups or more, none
    spanning :data:`MIN_SESSION_SPAN_C`, tell none (the rule where no fold can judge it).
    """
    g, temp = np.asarray(groups), np.asarray(temp, dtype=np.float64)
    labels = np.unique(g)
    if labels.size < 2:
        return None
    widest = max(float(np.ptp(temp[g == k])) for k in labels)
    return widest if widest < MIN_SESSION_SPAN_C else None


def within(a: NDArray[np.float64], groups: ArrayLike,
           weights: NDArray[np.float64] | None = None
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the session means of the rows of ``a`` and ``a`` minus its session's mean.

    Fitting the centred columns to the centred target solves the regression with one
    offset per session exactly, without its indicator columns; with row ``weights`` the
    means are weighted, for the weighted regression.
    """
    _, inverse, counts = np.unique(np.asarray(groups), return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    counts = counts.astype(np.float64)
    means = np.zeros((counts.size,) + a.shape[1:])
    shape = (-1,) + (1,) * (a.ndim - 1)
    np.add.at(means, inverse, a if weights is None else a * weights.reshape(shape))
    if weights is not None:
        counts = np.bincount(inverse, weights=weights, minlength=counts.size)
    means /= counts.reshape(shape)
    return means, a - means[inverse]


@dataclass(frozen=True)
class Folds:
    """
    Cross-validation folds: per fold, the held-out rows and the training rows.

    Build them with :meth:`segments` (interleaved contiguous segments, an optional buffer
    around each held-out one) or :meth:`sessions` (leave one session out).
    """

    test: tuple[NDArray[np.bool_], ...]
    train: tuple[NDArray[np.bool_], ...]

    def __iter__(self):
        """Iterate over ``(test, train)`` pairs."""
        return iter(zip(self.test, self.train))

    def __len__(self) -> int:
        """Return the number of folds."""
        return len(self.test)

    @classmethod
    def segments(cls, n: int, *, n_segments: int = 20, n_folds: int = 5, buffer: int = 0,
                 min_train: int = 0) -> 'Folds':
        """
        Return folds of ``n_segments`` contiguous segments dealt round-robin into ``n_folds``.

        Every fold is predicted by interpolation; ``buffer`` rows on each side of a held-out
        segment are left out of training (h-block), unless that leaves fewer than
        ``min_train`` rows. A fold with no held-out row, or nothing to train on, is skipped.
        """
        seg = np.minimum(np.arange(n) * n_segments // n, n_segments - 1)
        tests, trains = [], []
        for f in range(n_folds):
            test = seg % n_folds == f
            if not test.any() or test.all():
                continue
            train = ~test
            if buffer:
                near = np.convolve(test.astype(float), np.ones(2 * buffer + 1), mode='same') > 0.5
                if np.count_nonzero(~near) >= min_train:
                    train = ~near
            tests.append(test)
            trains.append(train)
        return cls(tuple(tests), tuple(trains))

    @classmethod
    def sessions(cls, groups: ArrayLike, temp: ArrayLike | None = None) -> 'Folds':
        """
        Return one fold per session: that session held out, the others trained on.

        With ``temp`` (one per row) a session is scored only inside the others' range of it
        (outside it a model is clamped or extrapolated, which says nothing of how its curve
        carries to another power cycle); a fold with fewer than two such rows is skipped.
        """
        g = np.asarray(groups)
        tests, trains = [], []
        for s in np.unique(g):
            test, train = g == s, g != s
            if temp is not None:
                x = np.asarray(temp)
                lo, hi = x[train].min(initial=np.inf), x[train].max(initial=-np.inf)
                test &= (x >= lo) & (x <= hi)
                if np.count_nonzero(test) < 2:
                    continue
            tests.append(test)
            trains.append(train)
        return cls(tuple(tests), tuple(trains))


@dataclass(frozen=True)
class CurveVerdict:
    """The held-out judgement of a curve against its offset alone, per axis."""

    ms_curve: NDArray[np.float64]
    ms_offset: NDArray[np.float64]
    worse_folds: NDArray[np.int64]
    gain_t: NDArray[np.float64]
    drop: NDArray[np.bool_]
    rows: int


def judge_curve(r_curve: NDArray[np.float64], r_offset: NDArray[np.float64], folds: Folds,
                weights: NDArray[np.float64], significance: float = CURVE_SIGNIFICANCE,
                every_fold: bool = True) -> CurveVerdict:
    """
    Judge a curve on held-out sessions against their offsets alone (the one rule).

    ``r_curve`` and ``r_offset`` are the held-out residuals (N, M) of :func:`heldout`,
    ``weights`` (N,) the rows' samples. Per axis: the weighted mean squares over the rows a
    fold scores, the folds the curve predicts no better, and the t statistic of the curve's
    per-row gain. An axis is dropped (offset only) unless the curve is better pooled, on every
    held-out power cycle (``every_fold``), and by ``significance`` standard errors (the
    trainer's rule; the learner, which judges again at every power cycle, asks the pooled
    figure only: ``significance`` 0 and not ``every_fold``).
    """
    scored = np.any(np.stack(folds.test), axis=0)
    w = weights[:, None]

    def mean_square(r: NDArray[np.float64], m: NDArray[np.bool_]) -> NDArray[np.float64]:
        return (w[m] * r[m] ** 2).sum(axis=0) / w[m].sum()

    ms_curve, ms_offset = mean_square(r_curve, scored), mean_square(r_offset, scored)
    worse = np.sum([~(mean_square(r_curve, t) < mean_square(r_offset, t)) for t in folds.test],
                   axis=0)
    gain = (w * (r_offset ** 2 - r_curve ** 2))[scored]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = gain.mean(axis=0) / (gain.std(axis=0, ddof=1) / np.sqrt(len(gain)))
    drop = ~(ms_curve < ms_offset) | (every_fold & (worse > 0)) | ~(t >= significance)
    return CurveVerdict(ms_curve, ms_offset, worse, t, drop, int(np.count_nonzero(scored)))


def heldout(residual: Callable[[NDArray[np.bool_], NDArray[np.bool_]], NDArray[np.float64]],
            folds: Folds | Sequence[tuple], shape: tuple[int, ...], *,
            groups: ArrayLike | None = None, weights: NDArray[np.float64] | None = None
            ) -> NDArray[np.float64]:
    """
    Return held-out residuals (``shape`` (N, M)): every row's from the fit without its fold.

    ``residual(test, train)`` fits on ``train`` and returns the (T, M) residuals of the
    ``test`` rows; ``folds`` are (test, train) row masks; rows in no fold are zero. With
    ``groups`` (the session of every row) a session with no training row has no fitted
    offset: its residuals are re-anchored to zero mean (weighted by ``weights``), as the
    compensator re-anchors at start-up.
    """
    out = np.zeros(shape)
    g = None if groups is None else np.asarray(groups)
    for test, train in folds:
        r = residual(test, train)
        if g is not None:
            g_test = g[test]
            for s in np.setdiff1d(g_test, g[train]):       # the sessions not trained on
                m = g_test == s
                if weights is None:
                    r[m] -= r[m].mean(axis=0)
                else:
                    w = weights[test][m]
                    r[m] -= (w[:, None] * r[m]).sum(axis=0) / w.sum()
        out[test] = r
    return out


def check_offsets(offsets: NDArray[np.float64], coef: NDArray[np.float64],
                  scale: NDArray[np.float64]) -> tuple[NDArray[np.float64], dict | None]:
    """
    Judge the offset of every offset-only axis on held-out power cycles against none.

    ``offsets`` are the sessions' turn-on offsets (S, 3), ``coef`` and ``scale`` the fit's.
    Each power cycle's offset is predicted by the mean of the others' (leave one out) and by
    none: an axis without curve whose mean does not predict better, in mean square and in
    mean absolute error (a failed boot calibration weighs on the one, far less on the other),
    gets no offset (a board that zeroes its gyro at power-on, as ArduPilot and PX4 do; re-anchoring
    still applies).
    Returns the model's intercept and the record (None: one session, or every axis a curve).
    """
    level, k = offsets.mean(axis=0), offsets.shape[0]
    flat = ~np.any(coef[1:], axis=0) & (np.asarray(scale) == 0.0)
    if k < 2 or not flat.any():
        return level, None
    err = offsets - (offsets.sum(axis=0) - offsets) / (k - 1), offsets
    ms = [(e ** 2).mean(axis=0) for e in err]
    mae = [np.abs(e).mean(axis=0) for e in err]
    none = flat & ~((ms[0] < ms[1]) & (mae[0] < mae[1]))
    return np.where(none, 0.0, level), {
        'sessions': k, 'mean_ms_dps2': (ms[0] * DEG2_PER_RAD2).tolist(),
        'none_ms_dps2': (ms[1] * DEG2_PER_RAD2).tolist(),
        'mean_mae_dps': (mae[0] * DEG_PER_RAD).tolist(),
        'none_mae_dps': (mae[1] * DEG_PER_RAD).tolist(),
        'axes': [AXES[a] for a in np.flatnonzero(flat)],
        'no_offset': [AXES[a] for a in np.flatnonzero(none)]}
