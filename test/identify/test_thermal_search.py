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


"""Tests of gyro_tdc.identify.thermal_search: the runs on the block grid, the time constants."""

from __future__ import annotations

from gyro_tdc.identify.thermal_search import (choose_state, ParamSearch, run_state, RunBlocks,
                                              TAU_BOUNDS)
from gyro_tdc.model import input_ids, resolve_params, ThermalState
import numpy as np
import pytest
from synth import synth_run

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
                         ridge=1e-6, seed=0, scale=False, n_total=sum(map(len, lagged)),
                         labels=[0, 1])
    tau, seen = search.first_order(par, TAU_BOUNDS)
    assert abs(tau - TAU_DIE) < 0.05 * TAU_DIE and len(seen) >= 13
    state, info = choose_state(search, 'first_order', par, tau, seen)
    lo, hi = state.tau_interval_s[0]
    assert state.kind == 'first_order' and lo < TAU_DIE < hi and state.identifiable
    assert info['chosen'] == 'first_order' and info['profiles'][0]['tau_s'] == tau
    a, b = search.two_node(par, tau, TAU_BOUNDS)
    assert 0 < a <= b and tau / 4.0 <= a + b <= tau * 4.0
