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

"""The one estimator: known coefficients recovered, sessions and folds as specified."""

from gyro_tdc.signal.estimator import (CURVE_SIGNIFICANCE, curve_untold, fit_columns, Folds, hat,
                                       heldout, judge_curve, pinv_fit, session_columns,
                                       solve_normal, within)
import numpy as np
import pytest


def _data(seed=0, n=200):
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.ones(n), rng.normal(size=n), rng.normal(size=n)])
    coef = np.array([[0.5, -1.0], [2.0, 0.25], [-0.75, 3.0]])
    return x, coef, x @ coef, rng


def test_fit_columns_recovers_known_coefficients_with_weights_and_scaling():
    x, coef, y, rng = _data()
    np.testing.assert_allclose(fit_columns(x, y), coef, rtol=1e-12)
    w = rng.uniform(0.1, 3.0, size=x.shape[0])
    np.testing.assert_allclose(fit_columns(x, y, weights=w), coef, rtol=1e-12)
    scaled = x * np.array([1e6, 1.0, 1e-6])          # badly scaled columns, and a zero one
    got = fit_columns(np.column_stack([scaled, np.zeros(x.shape[0])]), y[:, 0],
                      normalise=True, rcond=1e-12)
    np.testing.assert_allclose(got[:3] * [1e6, 1.0, 1e-6], coef[:, 0], rtol=1e-9)
    assert got[3] == 0.0


def test_weights_are_rows_repeated_and_the_penalty_is_a_ridge():
    x, _, y, rng = _data(1, 60)
    y = y + rng.normal(size=y.shape)
    w = rng.integers(1, 4, size=x.shape[0]).astype(float)
    rep = np.repeat(np.arange(x.shape[0]), w.astype(int))
    np.testing.assert_allclose(fit_columns(x, y, weights=w), fit_columns(x[rep], y[rep]),
                               rtol=1e-10)
    pen = np.array([0.0, 3.0, 3.0])                  # no penalty on the constant
    ridge = np.linalg.solve(x.T @ x + np.diag(pen ** 2), x.T @ y)
    np.testing.assert_allclose(fit_columns(x, y, penalty=pen), ridge, rtol=1e-10)
    np.testing.assert_allclose(solve_normal(x.T @ x + np.diag(pen ** 2), x.T @ y), ridge,
                               rtol=1e-10)


def test_a_singular_system_falls_back_or_raises_as_asked():
    a = np.array([[1.0, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(solve_normal(a, np.array([2.0, 2.0])), [1.0, 1.0])
    with pytest.raises(np.linalg.LinAlgError):
        solve_normal(a, np.array([2.0, 2.0]), fallback=False)


def test_pinv_fit_and_the_leverage_give_the_leave_one_out_residuals():
    x, _, y, rng = _data(2, 40)
    y = y[:, 0] + rng.normal(size=x.shape[0])
    params, pinv = pinv_fit(x, y)
    np.testing.assert_allclose(params, fit_columns(x, y), rtol=1e-10)
    assert pinv.shape == (3, 40)
    w = rng.uniform(0.5, 2.0, size=x.shape[0])
    a, h = hat(x, w)
    r = y - x @ (a @ ((x * w[:, None]).T @ y))
    keep = np.arange(x.shape[0]) != 7
    refit = fit_columns(x[keep], y[keep], weights=w[keep])
    assert r[7] / (1.0 - h[7]) == pytest.approx(y[7] - x[7] @ refit, rel=1e-9)


def test_one_offset_per_session_as_columns_or_eliminated_is_one_regression():
    x, coef, _, rng = _data(3, 90)
    groups = np.repeat([5, 2, 9], 30)
    offsets = np.array([1.0, -2.0, 0.5])                 # for labels 2, 5, 9 (sorted)
    cols, labels = session_columns(groups)
    assert labels.tolist() == [2, 5, 9] and cols.shape == (90, 3)
    y = x[:, 1:] @ coef[1:, 0] + cols @ offsets + 0.01 * rng.normal(size=90)
    full = fit_columns(np.column_stack([cols, x[:, 1:]]), y)
    xm, xc = within(x[:, 1:], groups)
    ym, yc = within(y, groups)
    slope = fit_columns(xc, yc)
    np.testing.assert_allclose(slope, full[3:], rtol=1e-10)
    np.testing.assert_allclose(ym - xm @ slope, full[:3], rtol=1e-10)
    np.testing.assert_allclose(full[:3], offsets, atol=0.01)


def test_folds_segments_interleave_and_sessions_leave_one_out():
    folds = Folds.segments(100, n_segments=20, n_folds=5)
    assert len(folds) == 5
    cover = sum(t.astype(int) for t, _ in folds)
    assert np.all(cover == 1)
    test, train = next(iter(folds))
    assert np.flatnonzero(test)[:5].tolist() == [0, 1, 2, 3, 4] and test[25] and not test[5]
    assert np.array_equal(train, ~test)
    buffered = Folds.segments(100, n_segments=20, n_folds=5, buffer=2)
    for t, tr in buffered:
        ti, ri = np.flatnonzero(t), np.flatnonzero(tr)
        assert np.min(np.abs(ti[:, None] - ri[None, :])) > 2
    groups = np.array([3, 3, 1, 1, 1, 7])
    loso = Folds.sessions(groups)
    assert [t.tolist() for t, _ in loso][0] == [False, False, True, True, True, False]
    assert all(np.array_equal(tr, ~t) for t, tr in loso)
    # Scored inside the others' temperatures only; a fold with under two such rows skipped.
    temp = np.array([10.0, 30.0, 12.0, 20.0, 40.0, 25.0])
    inside = Folds.sessions(groups, temp)
    assert [t.tolist() for t in inside.test] == [[False, False, True, True, False, False]]
    assert np.array_equal(inside.train[0], groups != 1)
    assert not len(Folds.sessions(np.zeros(4), np.arange(4.0)))      # one session: none


def test_heldout_reanchors_a_session_seen_nowhere_in_training():
    y = np.array([[1.0], [3.0], [10.0], [14.0]])
    groups = np.array([0, 0, 1, 1])
    w = np.array([1.0, 3.0, 1.0, 1.0])

    def residual(test, train):
        return y[test] - y[train].mean()       # a 'fit' that predicts the training mean

    out = heldout(residual, Folds.sessions(groups), (4, 1), groups=groups, weights=w)
    # Each held-out session re-anchored to zero (weighted) mean: only its own scatter is left.
    np.testing.assert_allclose(out[:, 0], [-1.5, 0.5, -2.0, 2.0])
    plain = heldout(residual, Folds.sessions(groups), (4, 1), groups=groups)
    np.testing.assert_allclose(plain[:, 0], [-1.0, 1.0, -2.0, 2.0])
    none = heldout(residual, Folds.sessions(groups), (4, 1))
    np.testing.assert_allclose(none[:, 0], [-11.0, -9.0, 8.0, 12.0])


def test_a_curve_is_untold_by_groups_that_each_span_under_two_degrees():
    temp = np.array([10.0, 11.5, 30.0, 31.0, 31.2])
    assert curve_untold(temp, [0, 0, 1, 1, 1]) == 1.5            # the widest, under 2 degC
    assert curve_untold(temp, [0, 0, 0, 0, 0]) is None            # one group: its own rule
    assert curve_untold(np.r_[temp, 33.0], [0, 0, 1, 1, 1, 1]) is None   # 3 degC of one


def test_judge_curve_keeps_a_significant_gain_on_every_fold_only():
    rng = np.random.default_rng(3)
    groups = np.repeat([0, 1, 2, 3], 200)
    folds = Folds.sessions(groups)
    w = np.full(groups.size, 25.0)
    r_offset = rng.normal(0.0, 1.0, (groups.size, 3))
    r_curve = r_offset.copy()
    r_curve[:, 0] *= 0.8                        # x: a clear gain on every row
    # y: better on every power cycle by 0.01 per row, in a gain of +-0.5 per row: no evidence
    r_offset[:, 1] = rng.choice([-1.0, 1.0], groups.size)
    r_curve[:, 1] = np.sqrt(1.0 - 0.01 - 0.5 * (-1.0) ** np.arange(groups.size))
    r_curve[groups == 2, 2] *= 1.5              # z: a gain, but worse on one power cycle
    r_curve[groups != 2, 2] *= 0.5
    v = judge_curve(r_curve, r_offset, folds, w)
    assert v.rows == groups.size and v.worse_folds[2] == 1 and v.worse_folds[0] == 0
    assert v.gain_t[0] > CURVE_SIGNIFICANCE > abs(v.gain_t[1])
    assert v.drop.tolist() == [False, True, True]
    assert v.ms_curve[0] == pytest.approx(0.64 * v.ms_offset[0])
    # the gain on y alone, made consistent, is kept
    r_curve[:, 1] = 0.9 * r_offset[:, 1]
    assert not judge_curve(r_curve, r_offset, folds, w).drop[1]
    # the learner's pooled figure only: z's pooled gain keeps it, y's hair too
    assert judge_curve(r_curve, r_offset, folds, w, significance=0.0,
                       every_fold=False).drop.tolist() == [False, False, False]
    r_curve[:, 2] = 1.01 * r_offset[:, 2]
    assert judge_curve(r_curve, r_offset, folds, w, significance=0.0,
                       every_fold=False).drop.tolist() == [False, False, True]
