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

"""compensator_node with a learn_file as model_file: it compensates with the learned model."""

from __future__ import annotations

from compensator_rig import rates, to_ns
from gyro_tdc.learn.learner import Learner
from gyro_tdc.model.compensation import compensate
from learn_states import BIAS, learned
import numpy as np
from rosutil import spin_until


def test_model_file_may_be_a_learn_file(rig_factory, tmp_path):
    learner = learned()
    path = tmp_path / 'learn.json'
    learner.save(path)
    rig = rig_factory(model_file=str(path))
    assert rig.node.core.model_id == learner.model.model_id
    assert rig.node.loading.last_reload == f'loaded {learner.model.model_id}'
    t0 = 1_700_000_000.0
    n = 200
    imu_ns = np.array([to_ns(t0 + k / 50.0) for k in range(n)])
    omega = np.array(BIAS) + np.random.default_rng(1).normal(0, 1e-4, (n, 3))
    temp_ns = np.array([to_ns(t0 - 0.5 + k) for k in range(6)])
    temp_c = np.full(6, 21.0)
    sent = rig.feed(imu_ns, omega, temp_ns, temp_c)
    spin_until(rig.executor, lambda: len(rig.out) >= len(sent), 5.0)
    want = compensate(learner.model, imu_ns * 1e-9, np.full(n, 21.0), omega)
    np.testing.assert_allclose(rates(rig.out), want, rtol=0, atol=1e-9)
    assert np.abs(rates(rig.out).mean(axis=0)).max() < 1e-4     # the bias is removed


def test_a_learn_file_without_a_model_passes_through_with_the_reason(rig_factory, tmp_path):
    path = tmp_path / 'empty.json'
    Learner().save(path)
    rig = rig_factory(model_file=str(path))
    assert rig.node.core.model is None
    assert rig.node.loading.last_reload.startswith('failed:')
    assert 'no accepted model yet' in rig.node.loading.last_reload
