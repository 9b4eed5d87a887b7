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

"""Runs with gyro axes made constant (within one quantum), and the hypothesis draws of them."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import strategies as st
import numpy as np

#: One or two of the axes x, y, z (0, 1, 2), in order.
axis_sets = st.sets(st.sampled_from(range(3)), min_size=1, max_size=2).map(sorted)
#: What a constant axis reads, rad/s.
values = st.floats(-5.0, 5.0, allow_nan=False)
#: Its quantum (0: exactly one value).
quanta = st.one_of(st.just(0.0), st.floats(1e-9, 1e-2))


def with_constant(run, axes, value, quantum, seed=0):
    """Return ``run`` with ``axes`` reading ``value`` within one quantum."""
    rng = np.random.default_rng(seed)
    omega = run.omega.copy()
    for i in axes:
        omega[:, i] = value + quantum * rng.integers(0, 2, len(run))
    return replace(run, omega=omega)
