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

"""Model swaps: a model without time terms is installed without replaying the history."""

from __future__ import annotations

from gyro_tdc.identify import fit_model
from gyro_tdc.learn.learner import learned_model
from gyro_tdc.runtime import priming as priming_mod
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.drift import timeless
from gyro_tdc.runtime.policy import Policy
import numpy as np
import pytest
from synth import synth_run

STATIC = learned_model(np.array([[0.01, -0.02, 0.005], [1e-3, 2e-4, -1e-4], [1e-6, 0, 0]]),
                       ('dT', 'dT2'), 20.0, (0.0, 60.0), np.full(3, 1e-6))
OTHER = learned_model(np.array([[0.02, -0.01, 0.004], [9e-4, 1e-4, -2e-4], [2e-6, 0, 0]]),
                      ('dT', 'dT2'), 20.0, (0.0, 60.0), np.full(3, 1e-6))


@pytest.fixture(scope='module')
def timed_model():
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)
    return fit_model([run], features=('dT', 'dT2', 'lag', 'warmup'), n_centers=6,
                     fit_params=False)


def _long_core(model):
    """Return a core that has seen 3 h of 1 Hz thermometer (a full history) and IMU samples."""
    core = CompensatorCore(Policy(reanchor_on_start=False), model)
    w = (0.011, -0.019, 0.006)
    for k in range(3 * 3600):
        t = 1000.0 + k
        core.add_temperature(t - 0.25, 15.0 + 10.0 * k / 10800.0)
        core.process(t, *w)
    assert len(core.stream.history) == core.HISTORY_LENGTH
    return core, w


def _count_advances(monkeypatch):
    calls = [0]
    real = priming_mod.advance

    def counting(comp, t, temp):
        calls[0] += 1
        real(comp, t, temp)
    monkeypatch.setattr(priming_mod, 'advance', counting)
    return calls


def test_a_static_model_swap_replays_no_history(monkeypatch):
    assert timeless(STATIC) and timeless(OTHER)
    core, w = _long_core(STATIC)
    calls = _count_advances(monkeypatch)
    core.schedule(OTHER, None)                 # a learned model, installed at once
    assert core.model_id == OTHER.model_id
    assert calls[0] <= 2                       # the first sample and the last: no history
    # The same output as a core that had the model from the start.
    ref, _ = _long_core(OTHER)
    t = core.last_t + 1.0
    core.add_temperature(t - 0.25, 25.5)
    ref.add_temperature(t - 0.25, 25.5)
    assert core.process(t, *w)[:3] == ref.process(t, *w)[:3]


def test_a_model_with_time_terms_replays_at_most_the_history(monkeypatch, timed_model):
    assert not timeless(timed_model)
    core, w = _long_core(STATIC)
    calls = _count_advances(monkeypatch)
    core.schedule(timed_model, None)
    assert core.model_id == timed_model.model_id
    assert core.HISTORY_LENGTH <= calls[0] <= core.HISTORY_LENGTH + 2
