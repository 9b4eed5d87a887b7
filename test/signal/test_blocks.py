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

"""Block sums and means agree with a plain loop over the blocks, partial last block included."""

from gyro_tdc.signal.blocks import block_counts, block_length, block_mean, block_sum, block_sumsq
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
