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


"""Tests of gyro_tdc.identify.tau: the one grid-then-Brent search of a time constant."""

from __future__ import annotations

import math

from gyro_tdc.errors import FitError
from gyro_tdc.identify import fit_time_constant, TimeConstantFit
import numpy as np
import pytest


def test_fit_time_constant_finds_the_minimum_and_keeps_the_profile():
    calls = []

    def sse(tau):
        calls.append(tau)
        return (math.log(tau) - math.log(173.0)) ** 2 + 2.0

    res = fit_time_constant(sse, (1.0, 20000.0), n_grid=13)
    assert isinstance(res, TimeConstantFit)
    assert res.tau == pytest.approx(173.0, rel=2e-3) and res.sse == pytest.approx(2.0)
    assert res.grid_tau.shape == res.grid_sse.shape == (13,)
    np.testing.assert_allclose(res.grid_tau[[0, -1]], [1.0, 20000.0])
    np.testing.assert_allclose(res.grid_sse, [sse(v) for v in res.grid_tau])
    assert res.sse <= res.grid_sse.min()
    assert all(1.0 <= c <= 20000.0 for c in calls)
    lin = fit_time_constant(lambda tau: (tau - 7.3) ** 2, (0.0, 20.0), n_grid=5, log=False,
                            xatol=1e-6)
    assert lin.tau == pytest.approx(7.3, abs=1e-4)
    np.testing.assert_allclose(lin.grid_tau, [0.0, 5.0, 10.0, 15.0, 20.0])


def test_fit_time_constant_keeps_the_grid_point_at_an_edge_and_on_a_single_point():
    res = fit_time_constant(lambda tau: tau, (2.0, 50.0), n_grid=6)
    assert res.tau == pytest.approx(2.0, rel=1e-3)
    one = fit_time_constant(lambda tau: 1.0, (30.0, 30.0), n_grid=1)
    assert one.tau == pytest.approx(30.0) and one.grid_tau.shape == (1,)


@pytest.mark.parametrize('bounds, n_grid, log', [((0.0, 10.0), 5, True), ((5.0, 1.0), 5, True),
                                                 ((-1.0, 1.0), 5, False),
                                                 ((1.0, math.inf), 5, True),
                                                 ((1.0, 2.0), 0, True)])
def test_fit_time_constant_rejects_bad_bounds(bounds, n_grid, log):
    with pytest.raises(FitError, match='bounds|n_grid'):
        fit_time_constant(lambda tau: tau, bounds, n_grid=n_grid, log=log)


@pytest.mark.parametrize('n_grid, xatol', [(13, 1e-3), (14, 0.01), (25, 1e-3)])
def test_fit_time_constant_equals_the_grid_then_brent_search_it_replaced(n_grid, xatol):
    # The search formerly written inline in fitting (13 points), discover (14, xatol 0.01)
    # and realdata_eval (25): log grid, bounded Brent between the best point's neighbours.
    from scipy.optimize import minimize_scalar
    rng = np.random.default_rng(n_grid)
    bumps = rng.normal(size=8) * 0.05

    def sse_log(v):
        return (v - 5.1) ** 2 + float(bumps @ np.sin(np.arange(1, 9) * v))

    grid = np.linspace(math.log(1.0), math.log(20000.0), n_grid)
    vals = [sse_log(g) for g in grid]
    i = int(np.argmin(vals))
    best = minimize_scalar(sse_log, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, n_grid - 1)]),
                           method='bounded', options={'xatol': xatol})
    want = float(math.exp(best.x if best.fun <= vals[i] else grid[i]))
    got = fit_time_constant(lambda tau: sse_log(math.log(tau)), (1.0, 20000.0), n_grid=n_grid,
                            xatol=xatol)
    assert got.tau == pytest.approx(want, rel=1e-9)
