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
The learner on slow still logs: 1 Hz, power cycles, bursts, a wandering offset.

Days are compressed to 3 h so each test takes seconds; ``bench/bench_learning_field.py``
runs the three-day logs and the sweep.
"""

from __future__ import annotations

import math

from gyro_tdc.learn.learner import LearnConfig, Learner
from gyro_tdc.model import drift
import numpy as np
from still_logs import DEG, judge, learn_through_core, still_log

DAY_S = 3 * 3600.0


def test_a_1hz_still_log_is_learned_throughout():
    """Every window of a motionless 1 Hz logger is still: learned to the end, beats batch."""
    log = still_log(rate_hz=1.0, days=2.0, day_s=DAY_S, seed=5)
    out, passed, learner = learn_through_core(log)
    s = learner.summary()
    span = log.t[-1] - log.t[0]
    assert s['still_s'] > 0.98 * span and s['last_update_t'] > log.t[-1] - 900.0
    assert s['features'] == ['dT', 'dT2', 'dT3'] and learner.session == 0
    r = judge(log, out, passed)
    assert r['passed'] == 0.0
    assert np.all(r['vs_raw'] < 0.1), r['vs_raw']
    assert np.all(r['vs_batch'] <= 1.05), r['vs_batch']


def _learn_directly(log, chunk_s=10.0):
    """Feed a log to a learner alone (no core), stepped every ``chunk_s`` of stamps."""
    learner = Learner(LearnConfig(temperature_timeout=5.0))
    j = 0
    edges = np.searchsorted(log.t, np.arange(log.t[0], log.t[-1] + chunk_s, chunk_s))
    for a, b in zip(edges[:-1], edges[1:]):
        while j < log.temp_t.size and log.temp_t[j] <= log.t[max(b - 1, a)]:
            learner.add_temperature(float(log.temp_t[j]), float(log.temp_c[j]))
            j += 1
        for k in range(a, b):
            learner.observe(float(log.t[k]), *log.gyro[k].tolist())
        learner.step()
    return learner


def test_each_power_cycle_gets_its_own_offset():
    """Three power cycles an hour apart, each its turn-on offset: the last one re-learned."""
    log = still_log(rate_hz=1.0, days=3.0, day_s=DAY_S / 2, seed=6, power_cycles=3,
                    turn_on_dps=0.3, accel=False)
    learner = _learn_directly(log)
    assert learner.session == 2
    assert sorted(np.unique(learner.entries()[:, 6]).tolist()) == [0.0, 1.0, 2.0]
    last = log.session == 2
    jump = np.abs(log.truth[last][0] - log.truth[log.session == 1][-1])
    assert jump.max() > 0.1 * DEG                    # the offsets differ by tenths of deg/s
    end = last & (log.t > log.t[-1] - 1800.0)
    temp = np.interp(log.t[end], log.temp_t, log.temp_c)
    err = log.truth[end] - drift(learner.model, log.t[end], temp)
    assert np.abs(err.mean(axis=0)).max() < 0.003 * DEG


def _bursts(learner, t0, n, period, rate=10.0, burst=5.0, bias=(0.01, -0.02, 0.005),
            temp=20.0, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        t = t0 + k * period + np.arange(int(burst * rate)) / rate
        learner.add_temperature(t[0], temp + 0.01 * k)
        for ti, w in zip(t.tolist(), (np.asarray(bias) + 1e-4 * rng.standard_normal(
                (t.size, 3))).tolist()):
            learner.observe(ti, *w)
        learner.step()
    return t0 + n * period


def test_a_burst_logger_is_one_power_cycle_and_a_night_off_another():
    """Pauses of 15 min, the logger's rhythm, are no restarts; a 3 h pause is."""
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    t = _bursts(learner, 0.0, 12, 900.0)
    assert learner.session == 0                       # merged once the rhythm is known
    assert 2600.0 < learner.session_gap() <= 2700.0   # 3 x the median pause
    _bursts(learner, t + 3 * 3600.0, 3, 900.0, seed=1)
    assert learner.session == 1


def test_grid_slivers_do_not_break_a_stretch():
    """Bursts that the 10 s grid cuts into a sliver and the rest are one still stretch."""
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    _bursts(learner, 0.0, 12, 305.0, rate=50.0, burst=5.0)
    learner.flush()
    assert learner.stretches == 1 and 55.0 < learner.still_s < 60.1   # the bursts' time


def test_the_offset_follows_the_newest_still_time():
    """A bias walking away at constant temperature: the model's offset is the newest."""
    def run(offset_s):
        learner = Learner(LearnConfig(temperature_timeout=1e9, offset_s=offset_s))
        rng = np.random.default_rng(3)
        t = np.arange(0.0, 8 * 3600.0)
        bias = 0.01 + 2e-5 * t / 3600.0               # 2e-5 rad/s an hour
        learner.add_temperature(0.0, 20.0)
        for k in range(0, t.size, 600):
            sl = slice(k, k + 600)
            for ti, b, w in zip(t[sl].tolist(), bias[sl].tolist(),
                                (5e-4 * rng.standard_normal((600, 3))).tolist()):
                learner.observe(ti, b + w[0], b + w[1], b + w[2])
            learner.step()
        return float(np.abs(learner.model.intercept - bias[-1]).max())
    assert run(1800.0) < 2e-5                       # about half the window's walk
    assert run(0.0) > 5e-5                          # the session's average lags
    assert math.isfinite(run(600.0))


def test_a_device_clock_restart_is_a_new_session():
    """Stamps stepping back (the IMU restarted, its clock from zero) start a new session."""
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    _bursts(learner, 1000.0, 1, 10.0, burst=200.0)
    assert learner.session == 0
    _bursts(learner, 5.0, 1, 10.0, burst=100.0, seed=1)
    assert learner.session == 1
