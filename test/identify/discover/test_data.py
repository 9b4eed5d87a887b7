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
The measured runs on the block grid, and what they can excite before any fit.

:class:`~gyro_tdc.identify.discover.data.BlockData` groups samples into blocks per
contiguous segment; :func:`~gyro_tdc.identify.discover.data.excitation` names the effects
the data cannot excite, with the experiment that would.
"""

from __future__ import annotations

from discover_cases import DEG
from gyro_tdc.data.runs import Run
from gyro_tdc.identify.discover import discover
from gyro_tdc.identify.discover.data import BlockData
import numpy as np


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
