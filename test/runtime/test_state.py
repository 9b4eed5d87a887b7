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

"""The core's state groups: the stream restart at a power cycle, the re-anchoring, its variance."""

from __future__ import annotations

from collections import deque

from gyro_tdc.runtime.handoff import LearningGate
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.state import detector_for, reanchor_var, Reanchoring, StreamState, Tally
from gyro_tdc.signal import TemperatureHold
import numpy as np
import pytest


def _hold(*samples):
    hold = TemperatureHold()
    for t, c in samples:
        hold.add(t, c)
    return hold


def test_tally_counts_start_at_zero_and_are_not_shared():
    a, b = Tally(), Tally()
    a.counts['in'] += 1
    assert b.counts == {'in': 0, 'out': 0, 'compensated': 0}
    assert set(a.accel) == {'compensated', 'passed through', 'missing'}
    assert all(v == 0 for v in a.flags.values())


def test_a_restart_replays_from_the_reading_held_at_the_break():
    s = StreamState(history=deque([(1.0, 20.0), (2.0, 21.0)]), first=(1.0, 20.0), t=10.0)
    temps = _hold((9.5, 25.0), (10.5, 26.0))
    s.restart(10.6, 0.6, temps, timeout=1.0)
    assert s.first is None
    assert list(s.history) == [(10.5, 26.0)]


def test_a_restart_keeps_no_reading_older_than_the_timeout_or_the_last_sample():
    s = StreamState(history=deque(), t=10.0)
    s.restart(20.0, 10.0, _hold((9.0, 25.0)), timeout=1.0)       # 11 s old
    assert not s.history
    s = StreamState(history=deque(), t=10.0)
    s.restart(10.4, 0.4, _hold((9.9, 25.0)), timeout=1.0)        # before the last sample
    assert not s.history


def test_a_clock_that_restarted_drops_the_old_sessions_later_readings():
    temps = _hold((1.0, 20.0), (50.0, 30.0), (51.0, 31.0))
    s = StreamState(history=deque(), t=51.0)
    s.restart(1.5, -49.5, temps, timeout=1.0)
    assert temps.at(100.0) == (20.0, 1.0)
    assert list(s.history) == [(1.0, 20.0)]


def test_the_detector_takes_the_policys_thresholds():
    p = Policy(still_window=2.5, reanchor_tolerance=0.0)
    det = detector_for(p)
    assert det.window == pytest.approx(2.5)
    assert detector_for(Policy()).default_rule


def test_rethreshold_keeps_the_detector_unless_a_still_threshold_changed():
    r = Reanchoring(detector_for(Policy()))
    before = r.detector
    r.rethreshold(Policy(), Policy(), None, None)
    assert r.detector is before
    r.rethreshold(Policy(), Policy(still_window=3.0), None, None)
    assert r.detector is not before and r.detector.window == pytest.approx(3.0)


def test_sessions_count_from_one():
    r = Reanchoring(detector_for(Policy()))
    assert r.sessions.session == 1 and r.sessions.t0 is None


class _Model:
    def __init__(self, var, created):
        self.residual_var = np.asarray(var)
        self.created = created


def test_reanchor_var_is_the_models_unless_a_learner_floor_is_larger():
    var = [1e-8, 2e-8, 3e-8]
    learning, idle = LearningGate(extend=[].extend, block_n=10), LearningGate(block_n=10)
    assert reanchor_var(None, learning) is None
    np.testing.assert_array_equal(reanchor_var(_Model(var, {}), learning), var)
    floored = _Model(var, {'gyro_floor': [1e-4, 1e-5, 1e-6]})
    np.testing.assert_array_equal(reanchor_var(floored, idle), var)
    np.testing.assert_allclose(reanchor_var(floored, learning), [1e-7, 2e-8, 3e-8])
    bad = _Model(var, {'gyro_floor': [float('nan'), 1.0, 1.0]})
    np.testing.assert_array_equal(reanchor_var(bad, learning), var)
