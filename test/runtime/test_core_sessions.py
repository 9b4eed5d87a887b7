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

"""The core across power cycles: the model's time terms restart with the session."""

from __future__ import annotations

from gyro_tdc.identify import fit_model
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.health import health
from gyro_tdc.runtime.policy import Policy
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def timed_model():
    """Return a model with warm-up and a lagged thermal state (time terms)."""
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)
    return fit_model([run], features=('dT', 'dT2', 'lag', 'warmup'), n_centers=6,
                     fit_params=False)


def _session(t0, t_lo, t_hi, seed, n=1200, rate_hz=10.0):
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(n) / rate_hz
    tt = t0 - 0.25 + np.arange(0.0, n / rate_hz + 1.0)
    tc = np.linspace(t_lo, t_hi, tt.size)
    return t, rng.normal(0.01, 1e-3, (n, 3)), tt, tc


def _feed(core, t, omega, tt, tc):
    out, j = [], 0
    for i in range(t.size):
        while j < tt.size and tt[j] <= t[i]:
            core.add_temperature(tt[j], tc[j])
            j += 1
        out.append(core.process(t[i], *omega[i])[:3])
    return np.asarray(out)


@pytest.mark.parametrize('second_t0', [5000.0 + 120.0 + 3600.0, 100.0])
def test_a_power_cycle_restarts_warmup_and_thermal_state(timed_model, second_t0):
    """After a gap or a clock restart the output is a fresh core's on the new session."""
    first = _session(5000.0, 10.0, 40.0, seed=1)
    second = _session(second_t0, 25.0, 15.0, seed=2)
    core = CompensatorCore(Policy(reanchor_on_start=False), timed_model)
    _feed(core, *first)
    assert core.slot.comp.thermal_progress > 0.0
    after = _feed(core, *second)
    assert core.reanchoring.sessions.session == 2
    fresh = _feed(CompensatorCore(Policy(reanchor_on_start=False), timed_model), *second)
    np.testing.assert_allclose(after, fresh, rtol=0, atol=1e-12)
    # A model installed after the break is primed over the new session only.
    core.set_model(timed_model)
    other = CompensatorCore(Policy(reanchor_on_start=False), timed_model)
    _feed(other, *second)
    other.set_model(timed_model)
    t, w = second[0][-1] + 0.1, second[1][-1]
    assert core.process(t, *w)[:3] == pytest.approx(other.process(t, *w)[:3], abs=1e-12)


def test_a_bursty_logger_is_one_power_cycle_once_its_rhythm_shows():
    """20 s every 15 min: the shared rule's rhythm; then a 2 h pause is a power cycle."""
    from gyro_tdc.signal import BURST_PAUSES
    core = CompensatorCore(Policy(reanchor_on_start=True))
    one = np.arange(0.0, 20.0, 0.1)
    t = np.concatenate([k * 920.0 + one for k in range(12)])
    for ts in t:
        core.process(float(ts), 0.0, 0.0, 0.0)
    assert core.reanchoring.sessions.session == BURST_PAUSES      # the first four pauses only
    for ts in t[-1] + 7200.0 + one:
        core.process(float(ts), 0.0, 0.0, 0.0)
    assert core.reanchoring.sessions.session == BURST_PAUSES + 1
    assert health(core).values['reanchor'].endswith('after a gap of 7200 s)')


def test_pauses_shorter_than_the_gap_teach_the_rhythm_as_the_learner_and_batch_see_it():
    """1 Hz bursts 300 s apart: a 700 s pause is no power cycle, for every user of the rule."""
    from gyro_tdc.signal import session_gap
    t, t0 = [], 0.0
    for pause in [300.0] * 8 + [700.0] + [300.0] * 3 + [0.0]:
        t += list(t0 + np.arange(100.0))
        t0 = t[-1] + pause
    t = np.array(t)
    assert session_gap(t) > 700.0                   # the batch session cutter: one session
    core = CompensatorCore(Policy(reanchor_on_start=True))
    for ts in t:
        core.process(float(ts), 0.0, 0.0, 0.0)
    assert core.reanchoring.sessions.session == 1
    assert len(core.reanchoring.sessions.rhythm) > 0
    # A longer pause than the rhythm allows is still a power cycle.
    for ts in t[-1] + 7200.0 + np.arange(100.0):
        core.process(float(ts), 0.0, 0.0, 0.0)
    assert core.reanchoring.sessions.session == 2


def test_a_clock_restart_forgets_the_old_sessions_temperatures(timed_model):
    """After the stamps step back, the held readings and their age are the new session's."""
    first = _session(5000.0, 10.0, 40.0, seed=1)
    second = _session(100.0, 25.0, 15.0, seed=2, n=50)
    core = CompensatorCore(Policy(reanchor_on_start=False), timed_model)
    _feed(core, *first)
    assert core.temps.latest[1] > 5000.0
    _feed(core, *second)
    assert core.reanchoring.sessions.session == 2
    temp, stamp = core.temps.latest
    assert stamp < 110.0 and 15.0 <= temp <= 25.0          # not the old session's 40 degC
    assert 0.0 <= core.temperature_age() <= 1.0             # it was about -5020 s
    assert core.temps.at(5120.0)[1] < 110.0                 # no old reading left to look up


def test_the_core_and_the_learner_cut_a_slow_stream_alike():
    """A 0.1 Hz stream: 700 s pauses are no power cycle, a 3 h one is, for both users."""
    from gyro_tdc.learn import Learner
    t, t0 = [], 0.0
    for pause in [700.0] * 4 + [10800.0] + [700.0] * 2 + [0.0]:
        t += list(t0 + 10.0 * np.arange(100.0))
        t0 = t[-1] + pause
    core = CompensatorCore(Policy(reanchor_on_start=True))
    learner = Learner()
    for k, ts in enumerate(t):
        core.process(float(ts), 0.0, 0.0, 0.0)
        learner.observe(float(ts), 0.0, 0.0, 0.0)
        if k % 50 == 49:
            learner.step(force=True)
    learner.step(force=True)
    assert core.reanchoring.sessions.session - 1 == learner.session == 1
    assert core.reanchoring.sessions.pause_s() == learner.sessions.pause_s() == 600.0
