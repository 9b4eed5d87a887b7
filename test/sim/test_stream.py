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

"""SimStream hands out a run in time order, in chunks, identical to the batch run."""

from __future__ import annotations

from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import load_scenario, SimStream, simulate_scenario
import numpy as np
import pytest


@pytest.fixture(scope='module')
def scenario():
    return load_scenario('rate_steps').with_overrides({'duration_s': 900.0})


def test_chunks_concatenate_to_the_batch_run(scenario):
    batch = simulate_scenario(scenario, seed=3, rate_hz=10.0)[1]
    stream = SimStream(scenario, seed=3, run_index=1, rate_hz=10.0)
    imu, temp, ref = [], [], []
    t = 0.0
    while not stream.done:
        chunk_imu, chunk_temp, chunk_ref = stream.next_until(t)
        assert np.all(chunk_imu.t <= t) and np.all(chunk_temp.t <= t)
        imu.append(chunk_imu)
        temp.append(chunk_temp)
        ref.append(chunk_ref)
        t += 0.73
    assert stream.position >= stream.t_end
    np.testing.assert_array_equal(np.concatenate([c.t for c in imu]), batch.imu_t)
    np.testing.assert_array_equal(np.concatenate([c.gyro for c in imu]), batch.gyro)
    np.testing.assert_array_equal(np.concatenate([c.accel for c in imu]), batch.accel)
    np.testing.assert_array_equal(np.concatenate([c.temp_c for c in temp]), batch.temp_c)
    np.testing.assert_array_equal(np.concatenate([c.t for c in ref]), batch.ref_t)
    np.testing.assert_array_equal(np.concatenate([c.ref for c in ref]), batch.ref)
    assert stream.run.temp_var == batch.temp_var


def test_going_back_in_time_returns_nothing(scenario):
    stream = SimStream(scenario, seed=0, rate_hz=10.0)
    first, _, _ = stream.next_until(10.0)
    assert first.t.size == 101 and first.gyro.shape == (101, 3)
    again, temp, ref = stream.next_until(5.0)
    assert again.t.size == 0 and temp.t.size == 0 and ref.t.size == 0
    assert stream.position == 10.0
    with pytest.raises(ScenarioError, match='`t`'):
        stream.next_until(float('nan'))
