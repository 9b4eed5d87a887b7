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

"""A core with a learner: a new power cycle re-anchored at once, learned installs kept."""

from __future__ import annotations

from array import array
import math
from pathlib import Path
import sys
from types import SimpleNamespace

from gyro_tdc.learn.fit import learned_model
from gyro_tdc.learn.learner import LearnConfig, Learner
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.health import health
from gyro_tdc.runtime.policy import Policy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'support'))
from still_logs import DEG, still_log  # noqa: E402


class _Front:
    """The node's front of the learner: appends only, handed over before each step."""

    def __init__(self, config):
        self.config = config
        self.buf = array('d')
        self.temps = []

    def add_temperature(self, t, temp_c):
        self.temps.append((t, temp_c))

    def observe_motion(self, t, moving):
        pass

    def hand_over(self, learner):
        learner.buf.extend(self.buf)
        del self.buf[:]
        for t, temp_c in self.temps:
            learner.add_temperature(t, temp_c)
        self.temps = []


def _stream(log):
    """
    Stream ``log`` through a core and a learner from nothing as compensator_node does.

    The core's learner is a front that only appends (no learner attribute but those); the
    learner is handed its samples and stepped every second of stamps and what it swapped in
    is scheduled. Returns the outputs, the anchors (session, stamp), the core and the
    learner.
    """
    policy = Policy()
    core = CompensatorCore(policy)
    learner = Learner(LearnConfig(temperature_timeout=policy.temperature_timeout))
    front = _Front(learner.config)
    core.learner = front

    def step():
        front.hand_over(learner)
        learner.step()
        for due, model in learner.take_swaps(core.last_t):
            core.schedule(model, due)

    out = np.empty((log.t.size, 3))
    anchors, seen = [], None
    j, m = 0, log.temp_t.size
    next_step = float(log.t[0]) + 1.0
    blocks = 0
    # The order messages arrive in (by default their stamps).
    imu_at, temp_at = (log.info.get(k, v) for k, v in (('imu_at', log.t), ('temp_at', log.temp_t)))
    for k in range(log.t.size):
        ts = float(log.t[k])
        while j < m and temp_at[j] <= imu_at[k]:
            core.add_temperature(float(log.temp_t[j]), float(log.temp_c[j]))
            j += 1
        out[k] = core.process(ts, *log.gyro[k].tolist(), log.accel[k].tolist())[:3]
        if core.anchor is not seen:
            seen = core.anchor
            if seen is not None:
                anchors.append((core.reanchoring.sessions.session, ts))
        if not ts < next_step:           # every second of stamps (a restart: at once)
            step()
            next_step = ts + 1.0
        elif ts < next_step - 2.0:
            next_step = ts
        blocks = max(blocks, len(core.learning.block))
    core.largest_block = blocks
    return out, anchors, core, learner


def test_a_new_power_cycle_of_2khz_bursts_takes_its_offset_in_its_first_burst():
    """
    Correct a new power cycle's first bursts to its own offset, learned from nothing.

    2 s bursts at 2 kHz every 2 min, an L3GD20's noise, cooling (the second cycle below the
    range learned on the first: out of range), two power cycles an hour apart with turn-on
    offsets of 0.2 deg/s. The learner's models carry the first cycle's offset (no
    re-anchoring there); the second cycle is re-anchored 1 s into its first burst (before:
    never: out of range, a tolerance of 1e-5 rad/s, and the detector restarted by every
    learned install), so its first two bursts (second half of the first, all of the
    second) are corrected to within a few SE of a burst mean, not left at the old offset;
    the learner's own offset for the cycle then replaces the shift.
    """
    log = still_log(rate_hz=2000.0, days=2.0, day_s=1800.0, profile='cooling', t_lo=10.0,
                    t_hi=20.0, arw_dps=0.03, power_cycles=2, bursts=(2.0, 120.0), seed=3)
    out, anchors, core, _ = _stream(log)
    second = log.session == 1
    t2, out2 = log.t[second], out[second]
    burst = np.r_[0, np.cumsum(np.diff(t2) > 2.0)]
    # The turn-on offsets differ: the first cycle's offset is far off on some axis.
    change = np.abs(log.truth[second][:4000].mean(axis=0)
                    - log.truth[log.session == 0][-4000:].mean(axis=0))
    assert change.max() > 0.1 * DEG
    # The second cycle anchored within its first burst (1 s in), the first never.
    assert [s for s, _ in anchors] == [2]
    assert anchors[0][1] - t2[0] < 1.5
    # From the anchor on, its first two bursts' output (the reference is zero) is within
    # 4 SE of a 1 s mean at 2 kHz (0.03 deg/s/sqrt(Hz): 0.03 deg/s) of zero on every
    # axis, as is the fifth's (the learner's own offset then).
    se = 0.03 * DEG
    late = (burst == 0) & (t2 > anchors[0][1])
    for sel in (late, burst == 1, burst == 4):
        mean = out2[sel].mean(axis=0)
        assert np.all(np.abs(mean) < 4 * se), (mean / DEG, change / DEG)
    # By then a learned model carrying this cycle's offset is in use: the shift dropped.
    assert core.reanchoring.learned and core.anchor is None


def test_a_power_cycle_whose_stamps_restart_is_learned_at_once():
    """
    Learn a power cycle whose stamps start again near 0, as a flight controller's boot clock.

    Two power cycles of a 10 Hz still logger, turn-on offsets of 0.2 deg/s, the second's
    stamps (IMU and thermometer) restarting at 5 s, below the first's. The core hands the
    learner the second cycle's samples from its first one (before: none until its stamps
    passed the first cycle's last hand-off stamp, which they never do, while the hand-off
    block grew by every sample), the learner counts the new power cycle, learns it, and a
    model carrying its own offset is installed: its second half's output is within 4 SE of
    a 10 min mean of zero.
    """
    log = still_log(rate_hz=10.0, days=1.0, day_s=14400.0, profile='daily', t_lo=15.0,
                    t_hi=25.0, power_cycles=2, gap_s=600.0, seed=5)
    t0 = log.t[log.session == 1][0]
    keep = log.t < t0 + 5400.0                        # the second cycle 90 min, the first 2 h
    for name in ('t', 'gyro', 'accel', 'truth', 'session'):
        setattr(log, name, getattr(log, name)[keep])
    kt = log.temp_t < t0 + 5400.0
    log.temp_t, log.temp_c = log.temp_t[kt], log.temp_c[kt]
    second = log.session == 1
    log.info.update(imu_at=log.t, temp_at=log.temp_t)
    log.t = np.where(second, log.t - t0 + 5.0, log.t)
    log.temp_t = np.where(log.temp_t >= t0, log.temp_t - t0 + 5.0, log.temp_t)
    assert log.t[second][-1] < log.t[~second][-1]
    out, anchors, core, learner = _stream(log)
    assert core.reanchoring.sessions.session == 2 and learner.session == 1
    assert core.largest_block < 7 * 100              # a second of samples at the most
    # Every sample reached the learner (the window in progress waits for its end).
    assert learner.last_t > log.t[-1] - 2 * learner.config.window_s
    assert core.reanchoring.learned                  # the second cycle's own offset in use
    t2, out2 = log.t[second], out[second]
    late = t2 > t2[0] + 0.5 * (t2[-1] - t2[0])
    tail = late & (t2 > t2[-1] - 600.0)
    se = 0.03 * DEG / math.sqrt(600.0)
    assert np.all(np.abs(out2[tail].mean(axis=0)) < 4 * se + 0.004 * DEG), out2[tail].mean(0)


class _Learner:
    """The learner's face the core uses: a buffer, a thermometer, motion, a floor."""

    def __init__(self):
        self.config = SimpleNamespace(max_rate_hz=100.0)
        self.buf = array('d')
        self.gyro_floor = np.full(3, math.inf)

    def add_temperature(self, t, temp_c):
        pass

    def observe_motion(self, t, moving):
        pass


def _bias(b, until):
    """Return a learned bias-only model (offset ``b`` rad/s) whose offset is of ``until``."""
    m = learned_model(np.array([b, [0.0] * 3]), ('dT',), 20.0, (0.0, 40.0), np.full(3, 1e-6))
    m.created['offset_until'] = until
    return m


def _feeder(core, rng, noise):
    """Return ``feed(t0, n, offset)``: n samples at 100 Hz at 20 degC, still; the outputs."""
    def feed(t0, n, offset):
        t = t0 + np.arange(n) / 100.0
        out = np.empty((n, 3))
        for k in range(n):
            core.add_temperature(float(t[k]), 20.0)
            w = offset + rng.normal(0.0, noise, 3)
            out[k] = core.process(float(t[k]), *w.tolist(), (0.0, 0.0, 9.81))[:3]
        return out
    return feed


def test_a_learned_model_of_this_session_ends_its_reanchoring_an_older_one_keeps_the_shift():
    """
    Keep or drop the shift by whose offset a learned install carries; restart at a break.

    A learned model of an older session (before this one's first stamp) after a learned one
    keeps the shift (the output moves by the two models' difference only); one of this
    session's still time drops it and ends re-anchoring for the session (no new anchor
    however long it is still); a power cycle starts re-anchoring again.
    """
    core = CompensatorCore(Policy(still_window=5.0))
    core.learner = _Learner()
    feed = _feeder(core, np.random.default_rng(1), 1e-3)
    core.add_temperature(0.0, 20.0)
    a, b1, b2 = np.full(3, 1e-3), np.array([3e-3, -2e-3, 1e-3]), np.array([-1e-3, 2e-3, 0.0])

    core.schedule(_bias(a, -1.0), None)           # a learned model from before the stream
    feed(1.0, 3000, b1)
    first = core.anchor
    assert first is not None and np.allclose(first.delta, b1 - a, atol=3e-4)
    core.schedule(_bias(a + 1e-4, -1.0), None)    # an older session's offset: shift kept
    out = feed(31.0, 500, b1)
    assert core.anchor is first
    assert np.allclose(out.mean(axis=0), b1 - a - 1e-4 - np.asarray(first.delta), atol=2e-4)
    core.schedule(_bias(b1, 30.0), None)          # this session's offset: shift dropped
    assert core.anchor is None and core.reanchoring.learned
    out = feed(36.0, 3000, b1)
    assert core.anchor is None and not core.needs_accel     # no re-anchoring any more
    assert np.allclose(out.mean(axis=0), 0.0, atol=2e-4)
    assert health(core).values['reanchor'] == 'offset from the learner'
    feed(5000.0, 3000, b2)                        # a power cycle: re-anchored again
    assert core.reanchoring.sessions.session == 2 and core.anchor is not None
    assert health(core).values['reanchor'].startswith('done at t=')
    assert np.allclose(core.anchor.delta, b2 - b1, atol=3e-4)


def test_a_new_power_cycle_starts_on_the_learners_power_up_intercept_at_once():
    """
    Start a power cycle on the intercept the learner gave an unknown offset, not the last one.

    A learned model carries its session's offset ``b1`` and the learner's intercept for a
    power cycle whose offset is not known yet (``created['power_up_intercept']``). At a
    pause of an hour, and again at stamps stepping back (a boot clock), the first samples of
    the new cycle (0.2 s: before any still window ends) are corrected by that intercept at
    once (before: by ``b1``, until the learner saw the break), and re-anchoring goes on.
    """
    core = CompensatorCore(Policy(still_window=5.0))
    core.learner = _Learner()
    feed = _feeder(core, np.random.default_rng(2), 1e-4)
    b1, up = np.array([3e-3, -2e-3, 1e-3]), np.array([0.0, -1e-3, 5e-4])

    model = _bias(b1, 30.0)
    model.created['power_up_intercept'] = up.tolist()
    core.add_temperature(0.0, 20.0)
    core.schedule(model, None)
    assert np.allclose(feed(1.0, 3000, b1).mean(axis=0), 0.0, atol=5e-5)
    for t0, session in ((3700.0, 2), (1.0, 3)):     # a pause, then the stamps stepping back
        b = np.array([1e-3, 1e-3, 1e-3])
        out = feed(t0, 20, b)
        assert core.reanchoring.sessions.session == session
        np.testing.assert_allclose(out.mean(axis=0), b - up, atol=1e-4)   # b1: 5e-4 off
        np.testing.assert_array_equal(core.slot.model.intercept, up)
        assert core.reanchoring.waiting and core.slot.model.created['offset_until'] is None
        out = feed(t0 + 0.2, 1500, b)                # anchored on its own still time
        assert core.anchor is not None
        np.testing.assert_allclose(out[-300:].mean(axis=0), 0.0, atol=5e-5)
