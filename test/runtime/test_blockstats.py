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

"""Re-anchoring's block statistics: sums that add up, the block-means SE, tolerances."""

from __future__ import annotations

import math

from gyro_tdc.runtime.blockstats import (block_length, BlockStats, default_tolerance,
                                         max_windows, standard_error, TOLERANCE_FLOOR,
                                         window_stats)
import numpy as np
import pytest


def test_window_statistics_add_up_and_give_the_block_means_standard_error():
    rng = np.random.default_rng(1)
    t = np.arange(400) * 0.125                         # 1 s blocks of 8 samples, exact
    x = rng.normal(0.0, 1e-3, (400, 3))
    c = (0.0, 0.0, 0.0)
    first, second = window_stats(t[:200], x[:200], c, 1.0), window_stats(t[200:], x[200:], c, 1.0)
    whole = first + second
    assert whole.n == 400 and whole.m == 50
    assert whole.s == pytest.approx(tuple(x.sum(axis=0)))
    means = x.reshape(50, 8, 3).mean(axis=1)
    expected = means.std(axis=0, ddof=1) / math.sqrt(50)
    assert standard_error(whole) == pytest.approx(tuple(expected), rel=1e-9)


def test_the_standard_error_is_infinite_below_two_blocks():
    one = window_stats(np.arange(5) * 0.01, np.ones((5, 3)), (0.0, 0.0, 0.0), 1.0)
    assert one.m == 1 and standard_error(one) == (math.inf,) * 3
    assert standard_error(BlockStats()) == (math.inf,) * 3


def test_tolerances_and_window_counts():
    assert default_tolerance((1e-4, 0.0, -1.0)) == pytest.approx((1e-3, TOLERANCE_FLOOR,
                                                                  TOLERANCE_FLOOR))
    assert block_length(10.0) == pytest.approx(0.2) and block_length(600.0) == 1.0
    assert max_windows(10.0, 600.0) == 60 and max_windows(10.0, 5.0) == 1
