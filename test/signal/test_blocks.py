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
Block sums and means agree with a plain loop over the blocks, partial last block included.

The block grid: segments with short tails merged, rows that count, rows taken, and its sums
the same to the bit in passes of any size.
"""

import gyro_tdc.signal.blocks as blocks
from gyro_tdc.signal.blocks import (block_counts, block_length, block_mean, block_sum, block_sumsq,
                                    BlockGrid)
import numpy as np
import pytest


def _naive(a, block, reduce, partial=True):
    """Reduce each block of ``block`` rows with ``reduce`` in a Python loop."""
    stops = range(0, a.shape[0], block)
    rows = [reduce(a[i:i + block]) for i in stops if partial or i + block <= a.shape[0]]
    return np.array(rows).reshape((len(rows),) + a.shape[1:])


SHAPES = [(0,), (1,), (7,), (12,), (13,), (1000,), (13, 3), (12, 3), (5, 2, 4), (1001, 3)]


@pytest.mark.parametrize('shape', SHAPES)
@pytest.mark.parametrize('block', [1, 2, 3, 4, 7, 64])
def test_sums_means_and_squares_match_a_loop(shape, block):
    a = np.random.default_rng(3).normal(size=shape) * 10.0 + 5.0
    np.testing.assert_allclose(block_sum(a, block), _naive(a, block, lambda b: b.sum(axis=0)),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(block_mean(a, block),
                               _naive(a, block, lambda b: b.mean(axis=0)), rtol=1e-12,
                               atol=1e-12)
    np.testing.assert_allclose(block_sumsq(a, block),
                               _naive(a, block, lambda b: (b * b).sum(axis=0)), rtol=1e-12,
                               atol=1e-12)
    counts = block_counts(shape[0], block)
    np.testing.assert_array_equal(counts, _naive(np.ones(shape[0]), block, np.sum))
    assert counts.sum() == shape[0]


@pytest.mark.parametrize('shape', SHAPES)
@pytest.mark.parametrize('block', [1, 3, 4, 64])
def test_partial_false_drops_the_short_last_block(shape, block):
    a = np.random.default_rng(4).normal(size=shape)
    want = _naive(a, block, lambda b: b.mean(axis=0), partial=False)
    got = block_mean(a, block, partial=False)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(block_sum(a, block, partial=False),
                               _naive(a, block, lambda b: b.sum(axis=0), partial=False),
                               rtol=1e-12, atol=1e-12)


def test_last_partial_block_is_its_own_mean():
    a = np.arange(10.0)
    np.testing.assert_array_equal(block_mean(a, 4), [1.5, 5.5, 8.5])
    np.testing.assert_array_equal(block_sum(a, 4), [6.0, 22.0, 17.0])
    np.testing.assert_array_equal(block_counts(10, 4), [4.0, 4.0, 2.0])
    np.testing.assert_array_equal(block_sumsq(a, 4), [14.0, 126.0, 145.0])


def test_block_one_is_the_input_and_integers_become_float():
    a = np.linspace(0.0, 1.0, 5)
    assert block_mean(a, 1) is a
    out = block_mean(np.arange(6), 2)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [0.5, 2.5, 4.5])


def test_block_length_at_least_or_at_most_points():
    assert block_length(10_000, 3000) == 3 and 10_000 // 3 >= 3000
    assert block_length(10_000, 3000, at_most=True) == 4 and -(-10_000 // 4) <= 3000
    assert block_length(10, 3000) == 1 and block_length(10, 3000, at_most=True) == 1
    assert block_length(10, 0) == 10 and block_length(0, 5, at_most=True) == 1


@pytest.mark.parametrize('block', [0, -1, 2.5])
def test_bad_block_is_rejected(block):
    with pytest.raises(ValueError, match='block'):
        block_sum(np.ones(4), block)


def test_block_grid_is_block_mean_and_merges_short_tails_of_segments():
    a = np.arange(23.0)[:, None] * [1.0, -2.0]
    grid = BlockGrid(23, 5)
    np.testing.assert_array_equal(grid.mean(a), block_mean(a, 5))
    assert grid.counts.tolist() == [5, 5, 5, 5, 3]
    seg = BlockGrid(23, 5, bounds=np.array([0, 11, 23]), merge_tail=True)
    # Segment 0..11: blocks 5, 6 (a tail of 1 joins); 11..23: 5, 5, 2 (2 < 2.5 joins too).
    assert seg.counts.tolist() == [5, 6, 5, 7]
    np.testing.assert_allclose(seg.mean(a)[:, 0], [2.0, 7.5, 13.0, 19.0])
    rows = np.arange(23) % 7 != 0
    rows[5:10] = False                                # the second block has no row
    masked = BlockGrid(23, 5, rows=rows)
    assert masked.counts.tolist() == [4, 4, 5, 2]
    np.testing.assert_allclose(masked.mean(a[:, 0]), [2.5, 11.5, 17.0, 21.0])
    mean, scatter = masked.moments(a)
    np.testing.assert_array_equal(mean, masked.mean(a))
    np.testing.assert_allclose(scatter[:, 0], [5.0, 5.0, 10.0, 2.0])
    for got, want in zip(masked.moments(a + 1e3, centred=True), (mean + 1e3, scatter)):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


def _grids(n):
    rng = np.random.default_rng(4)
    take = np.sort(rng.choice(3 * n, n, replace=False))
    return [BlockGrid(n, 1), BlockGrid(n, 7), BlockGrid(n, 9, bounds=np.array([0, 40, 41, n]),
                                                        merge_tail=True),
            BlockGrid(n, 6, rows=rng.random(n) > 0.3), BlockGrid(n, 5, take=take)]


def test_block_grid_takes_rows_as_if_they_were_gathered():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(600, 3))
    take = np.sort(rng.choice(600, 200, replace=False))
    grid = BlockGrid(200, 6, take=take)
    np.testing.assert_array_equal(grid.mean(x), block_mean(x[take], 6))
    mean, ss = grid.moments(x)
    np.testing.assert_array_equal(mean, block_mean(x[take], 6))
    naive = _naive(x[take], 6, lambda b: ((b - b.mean(axis=0)) ** 2).sum(axis=0))
    np.testing.assert_allclose(ss, naive, rtol=1e-12, atol=1e-12)
    view = BlockGrid(100, 6, take=np.arange(250, 350))      # contiguous: a slice
    np.testing.assert_array_equal(view.mean(x), block_mean(x[250:350], 6))
    assert view.take is None and view.offset == 250


@pytest.mark.parametrize('pass_rows', [1, 7, 50])
def test_block_grid_sums_in_passes_of_any_size_to_the_bit(monkeypatch, pass_rows):
    # Rows taken, masked or centred are summed a pass at a time; (N, M) sums keep every bit,
    # (N,) ones their rounding (BLAS sums a row of a matrix-vector product by its position).
    x = np.random.default_rng(6).normal(size=(360, 3)) + [9.8, 0.1, -3.0]

    def sums():
        return [(g.counts, g.mean(x), g.mean(x[:, 0]), *g.moments(x), *g.moments(x, centred=True))
                for g in _grids(120)]

    before = sums()
    monkeypatch.setattr(blocks, 'PASS_ROWS', pass_rows)
    for got, ref in zip(sums(), before):
        for k, (a, b) in enumerate(zip(got, ref)):
            if k == 2:
                np.testing.assert_allclose(a, b, rtol=1e-15)
            else:
                np.testing.assert_array_equal(a, b)


def test_block_grid_moments_centred_keep_a_small_scatter_beside_a_large_mean():
    rng = np.random.default_rng(7)
    x = 1e6 + rng.normal(scale=1e-3, size=(4000, 3))
    mean, ss = BlockGrid(4000, 400).moments(x, centred=True)
    naive = _naive(x, 400, lambda b: ((b - b.mean(axis=0)) ** 2).sum(axis=0))
    np.testing.assert_allclose(ss, naive, rtol=1e-6)
    np.testing.assert_allclose(mean, block_mean(x, 400), rtol=1e-15)
    assert np.all(BlockGrid(4000, 400).moments(x)[1] >= 0.0)    # never below zero
