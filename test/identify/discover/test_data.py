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
The measured runs on the block grid, what they can excite, and the linear model's statistics.

:class:`~gyro_tdc.identify.discover.data.BlockData` groups samples into blocks per
contiguous segment; :func:`~gyro_tdc.identify.discover.data.excitation` names the effects
the data cannot excite, with the experiment that would. The statistics the false-discovery
guard is built on (folds, noise memory, the HAC test) are each checked against a known answer
on seeded synthetic data.
"""

from __future__ import annotations

import math
import warnings

from discover_cases import DEG
from gyro_tdc.data.runs import Run
from gyro_tdc.identify.discover import discover
from gyro_tdc.identify.discover.data import (ar1, bandwidth, BlockData, corr, hac_pvalue,
                                             LinearModel, make_folds, ols_hac, rel_residual)
import numpy as np
import pytest
from synth import synth_run


def gapped_run(seed: int = 0) -> Run:
    """Return a 1 Hz run of 125 samples, a 100 s gap, then 103 samples."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([np.arange(125.0), 225.0 + np.arange(103.0)])
    temp = 20.0 + 0.01 * t
    omega = rng.normal(0.0, 1e-3, size=(t.size, 3))
    return Run(t, temp, omega, np.zeros((t.size, 3)), 'gapped')


def test_blocks_follow_segments_and_short_tails_join():
    run = gapped_run()
    data = BlockData([run], block_s=10.0, t0=20.0)
    # Segment 1: 12 blocks of 10 and a tail of 5 (half a block: its own block).
    # Segment 2: 10 blocks, the tail of 3 joins the last one (13 samples).
    expected = [10] * 12 + [5] + [10] * 9 + [13]
    assert data.n.tolist() == expected
    edges = np.concatenate([[0], np.cumsum(expected)])
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        assert data.tfirst[k] == run.t[a] and data.tlast[k] == run.t[b - 1]
        np.testing.assert_allclose(data.y[k], run.omega[a:b].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(data.column('dT2', {}),
                               [((run.temp[a:b] - 20.0) ** 2).mean()
                                for a, b in zip(edges[:-1], edges[1:])], rtol=1e-12)
    assert data.tfirst[13] == 225.0   # no block spans the gap


def test_unidentifiable_without_soak_or_rate_steps():
    # Constant non-zero rate, a ramp from the first sample (no soak): scale and warm-up
    # cannot be excited; the reason and the experiment name what is missing.
    n = 2 * 3600 * 2
    t = np.arange(n) / 2.0
    temp = 10.0 + 30.0 * t / t[-1]
    ref = np.tile([0.1, 0.0, 0.0], (n, 1))
    omega = ref + (0.01 + 0.002 * (temp - 10.0))[:, None] * DEG
    omega = omega + np.random.default_rng(0).normal(0.0, 0.05 * DEG, (n, 3))
    res = discover([Run(t, temp, omega, ref)], allan=False)
    why = {u.effect: u for u in res.unidentifiable}
    assert 'constant' in why['scale'].reason
    assert 'soak' in why['warmup'].reason and 'soak' in why['warmup'].experiment
    # One rate, no soak: the rate effects are scored (only the ramp's start could show
    # them), nothing is named, and a note says what the data cannot test.
    assert not {'dTdt', 'lag'} & set(why)
    assert any('one rate' in n and 'no soak' in n and 'mid-ramp' in n for n in res.notes)
    assert res.steps == ()


def test_folds_one_run_blocked_with_buffer_and_several_runs_leave_one_out():
    data = BlockData([synth_run(seed=1, hours=1.0, rate_hz=2.0)], block_s=10.0, t0=25.0)
    folds, buffer = make_folds(data, memory=4, n_folds=5)
    assert len(folds) == 5 and buffer == 4
    tested = np.zeros(data.K, dtype=int)
    for test, train in folds:
        tested += test
        assert not np.any(test & train)
        # Every training row is more than `buffer` blocks from every held-out row.
        ti, tr = np.flatnonzero(test), np.flatnonzero(train)
        assert np.min(np.abs(ti[:, None] - tr[None, :])) > buffer
    assert np.all(tested == 1)

    two = BlockData([synth_run(seed=2, hours=0.5, rate_hz=2.0, name='a'),
                     synth_run(seed=3, hours=0.5, rate_hz=2.0, name='b')],
                    block_s=10.0, t0=25.0)
    folds, buffer = make_folds(two, memory=4)
    assert buffer == 0 and len(folds) == 2
    for r, (test, train) in enumerate(folds):
        assert np.array_equal(test, two.run == r) and np.array_equal(train, two.run != r)


def test_ar1_and_bandwidth_see_the_memory_of_the_noise():
    rng = np.random.default_rng(0)
    e = rng.normal(size=20000)
    x = np.empty_like(e)
    x[0] = e[0]
    for i in range(1, e.size):
        x[i] = 0.6 * x[i - 1] + e[i]
    assert ar1(x) == pytest.approx(0.6, abs=0.02)
    assert abs(ar1(e)) < 0.02
    assert ar1(e[:2]) == 0.0
    white = bandwidth(e[:1000], floor=False)
    assert white <= 8
    assert bandwidth(x[:1000], floor=False) > 2 * white
    # A slow wander under white noise: a long memory, at most a third of the record.
    slow = e[:1000] + 0.05 * np.cumsum(rng.normal(size=1000))
    assert 100 < bandwidth(slow, floor=False) <= 333
    # The test's bandwidth never goes below 1.3 sqrt(K).
    assert bandwidth(e[:1000]) >= math.ceil(1.3 * math.sqrt(1000))


def test_rel_residual_and_weighted_corr():
    # The weighted correlation of two (K, 3) contributions: corr of both scaled by sqrt(w).
    rng = np.random.default_rng(4)
    x = rng.normal(size=(200, 3))
    assert rel_residual(x, x @ np.array([1.0, -2.0, 0.5])) < 1e-12
    assert rel_residual(x, np.full(200, 3.0)) == 0.0
    assert rel_residual(np.zeros((200, 0)), rng.normal(size=200)) == 1.0
    assert 0.9 < rel_residual(x, rng.normal(size=200)) <= 1.0
    a = rng.normal(size=(50, 3))
    sw = np.sqrt(rng.uniform(0.5, 2.0, size=50))[:, None]
    assert corr(a * sw, 2.0 * a * sw) == pytest.approx(1.0)
    assert corr(a * sw, -a * sw) == pytest.approx(-1.0)
    assert corr(a * sw, np.zeros_like(a) * sw) == 0.0


@pytest.mark.parametrize('a2, significant', [((2e-4, 1.5e-4, -1e-4), True), ((0, 0, 0), False)])
def test_hac_pvalue_of_a_present_and_an_absent_curvature(a2, significant):
    data = BlockData([synth_run(seed=0, a2=a2, hours=2.0, rate_hz=2.0)], block_s=10.0, t0=25.0)
    model = LinearModel(data, ('bias', 'dT', 'dT2'), {})
    coef = model.fit()
    r = (data.y - model.predict(coef)) * data.sw[:, None]
    lags = [bandwidth(r[:, a]) for a in range(3)]
    p = hac_pvalue(model, model.columns_of('dT2'), lags)
    assert 0.0 <= p <= 1.0
    assert (p < 1e-20) if significant else (p > 0.1)


@pytest.mark.parametrize('seed', range(6))
def test_ols_hac_is_statsmodels_bit_for_bit(seed):
    # The HAC test's OLS without statsmodels' import: the same numbers, to the last bit,
    # also for near-collinear columns (rank-deficient designs keep the pseudo-inverse's).
    from statsmodels.regression.linear_model import OLS

    rng = np.random.default_rng(seed)
    for _ in range(25):
        n, k = int(rng.integers(20, 2000)), int(rng.integers(1, 8))
        lags = int(rng.integers(1, 50))
        x = rng.normal(size=(n, k))
        if seed % 2:
            x[:, -1] = 2.0 * x[:, 0] + 1e-12 * rng.normal(size=n)
        x = x / np.linalg.norm(x, axis=0)
        y = rng.normal(size=n) + x @ rng.normal(size=k)
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            ref = OLS(y, x).fit(cov_type='HAC', cov_kwds={'maxlags': lags,
                                                          'use_correction': True})
            params, cov = ols_hac(y, x, lags)
        assert np.asarray(ref.params).tobytes() == params.tobytes()
        assert np.asarray(ref.cov_params()).tobytes() == cov.tobytes()
