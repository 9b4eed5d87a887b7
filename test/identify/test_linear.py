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


"""Tests of gyro_tdc.identify.linear: the drift network's linear stage, ridge, groups."""

from __future__ import annotations

from gyro_tdc.identify import fit_linear, LinearFit, RIDGE_GRID
import numpy as np
import pytest


def test_fit_linear_recovers_a_linear_law_and_its_scale_term():
    rng = np.random.default_rng(2)
    x = rng.uniform(-20.0, 30.0, size=(400, 2))
    w = np.array([[0.1, -0.2, 0.3], [0.01, 0.02, -0.03], [1e-3, 0.0, 2e-3]])
    cols = rng.normal(size=(400, 3))
    s = np.array([1e-3, -2e-3, 5e-4])
    y = np.column_stack([np.ones(400), x]) @ w + cols * s
    fit = fit_linear(x, y, scale_cols=cols, kind='poly', ridge=1e-12)
    assert isinstance(fit, LinearFit) and fit.centers.shape == (0, 2)
    np.testing.assert_allclose(fit.scale, s, atol=1e-9)
    np.testing.assert_allclose(fit.predict(x, cols), y, atol=1e-9)
    np.testing.assert_allclose(fit.resid, fit.predict(x, cols) - y, atol=1e-12)
    assert fit.sse == pytest.approx(float((fit.resid ** 2).sum()))
    assert fit.design(x).shape == (400, 3) and fit.coef.shape == (3, 3)


def test_fit_linear_rbf_auto_ridge_is_from_the_grid_and_beats_poly_on_a_bump():
    x = np.linspace(-1.0, 1.0, 300)[:, None]
    y = np.repeat(np.exp(-(x / 0.3) ** 2), 3, axis=1)
    rbf = fit_linear(x, y, kind='rbf', n_centers=8, ridge='auto', seed=0)
    poly = fit_linear(x, y, kind='poly')
    assert rbf.ridge in RIDGE_GRID and rbf.centers.shape[0] >= 2
    assert rbf.sse < 0.01 * poly.sse
    assert fit_linear(x, y, kind='rbf', n_centers=8, seed=0).sse == rbf.sse  # seeded


def test_fit_linear_groups_is_the_regression_with_one_constant_per_group():
    rng = np.random.default_rng(7)
    n = 400
    x = rng.uniform(-10.0, 10.0, (n, 2))
    groups = np.repeat([5, 2, 9], [100, 150, 150])
    const = {5: [1.0, 2.0, 3.0], 2: [-4.0, 0.0, 1.0], 9: [0.5, 0.5, 0.5]}
    y = (np.array([const[g] for g in groups]) + x @ np.array([[0.3, -0.2, 0.1], [0.05, 0.0, 2.0]])
         + rng.standard_normal((n, 3)) * 0.01)
    fit = fit_linear(x, y, kind='poly', groups=groups)
    dummies = (groups[:, None] == np.array([2, 5, 9])[None, :]).astype(float)
    sol = np.linalg.lstsq(np.column_stack([dummies, x]), y, rcond=None)[0]
    design = fit.design(x)
    np.testing.assert_allclose(fit.coef[0], 0.0)
    np.testing.assert_allclose(design[:, 1:] @ fit.coef[1:] + fit.offsets[np.searchsorted(
        [2, 5, 9], groups)], np.column_stack([dummies, x]) @ sol, atol=1e-6)
