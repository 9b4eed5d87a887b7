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


"""Tests of gyro_tdc.identify.tau: the one time-constant search, the thermal state's search."""

from __future__ import annotations

import math

from gyro_tdc.errors import FitError
from gyro_tdc.identify import fit_time_constant, TimeConstantFit
from gyro_tdc.identify.tau import (choose_state, ParamSearch, run_state, RunBlocks,
                                   TAU_BOUNDS)
from gyro_tdc.model import input_ids, resolve_params, ThermalState
import numpy as np
import pytest
from synth import synth_run


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


TAU_DIE = 300.0


@pytest.fixture(scope='module')
def lagged():
    """Return a heating and a cooling run of a die lagging the thermometer by 300 s."""
    return [synth_run(seed=s, hours=1.0, rate_hz=2.0, tau_die=TAU_DIE, cooling=bool(s % 2),
                      noise_dps=0.01, name=f'r{s}') for s in (1, 2)]


def test_the_state_of_a_run_is_computed_once_per_front_end_and_read_only(lagged):
    run = lagged[0]
    a, b = ThermalState('first_order', (120.0,)), ThermalState('first_order', (240.0,))
    s = run_state(a, run)
    assert run_state(a, run) is s and not s.flags.writeable
    np.testing.assert_array_equal(s, a.temperature(run.t, run.temp))
    assert run_state(b, run) is not s
    np.testing.assert_array_equal(run_state(b, run), b.temperature(run.t, run.temp))


def test_run_blocks_average_only_the_rows_that_count(lagged):
    run = lagged[0]
    rows = (np.arange(len(run)) // 100) % 3 != 1          # every third block has no row
    b = RunBlocks(run, 100, rows)
    kept = [k for k in range(-(-len(run) // 100)) if k % 3 != 1]
    assert b.y.shape == (len(kept), 3) and b.counts.sum() == rows.sum()
    err = run.omega - run.omega_ref
    np.testing.assert_allclose(b.y[1], err[200:300].mean(axis=0), rtol=1e-12)   # block 2
    np.testing.assert_allclose(b.ss_raw, (err[rows] ** 2).sum(axis=0), rtol=1e-12)
    within = sum(((err[k * 100:(k + 1) * 100] - err[k * 100:(k + 1) * 100].mean(axis=0)) ** 2)
                 .sum(axis=0) for k in kept)
    np.testing.assert_allclose(b.ss_within.sum(axis=0), within, rtol=1e-9)


def test_the_first_order_search_finds_the_lag_and_its_interval(lagged):
    ids = ('dT', 'dT2', 'lag')
    par = resolve_params(ids, None)
    search = ParamSearch(lagged, input_ids(ids, state=True), 25.0, inner='poly', n_centers=0,
                         ridge=1e-6, seed=0, scale=False, labels=[0, 1])
    tau, seen = search.first_order(par, TAU_BOUNDS)
    assert abs(tau - TAU_DIE) < 0.05 * TAU_DIE and len(seen) >= 13
    state, info = choose_state(search, 'first_order', par, tau, seen)
    lo, hi = state.tau_interval_s[0]
    assert state.kind == 'first_order' and lo < TAU_DIE < hi and state.identifiable
    assert info['chosen'] == 'first_order' and info['profiles'][0]['tau_s'] == tau
    a, b = search.two_node(par, tau, TAU_BOUNDS)
    assert 0 < a <= b and tau / 4.0 <= a + b <= tau * 4.0
