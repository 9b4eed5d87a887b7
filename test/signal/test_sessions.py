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

"""The one session-break rule: batch and streaming forms agree."""

from __future__ import annotations

from gyro_tdc.base import SESSION_GAP_S
from gyro_tdc.signal import (BURST_MAX_S, BURST_PAUSES, gap_breaks, gap_limit, session_gap,
                             SessionTracker)
import numpy as np


def _bursts(n_bursts, pause_s, rate_hz=10.0, burst_s=20.0, t0=0.0):
    one = np.arange(0.0, burst_s, 1.0 / rate_hz)
    return np.concatenate([t0 + k * (burst_s + pause_s) + one for k in range(n_bursts)])


def _stream(t, rule):
    """Judge every step over SESSION_GAP_S (the core's gate); return the break indices."""
    dt = np.diff(t)
    period = float(np.median(dt))
    return [i + 1 for i in np.flatnonzero(dt > SESSION_GAP_S) if rule.judge(dt[i], period)]


def test_the_rule():
    assert gap_limit(0.01, []) == SESSION_GAP_S
    assert gap_limit(10.0, []) == 1000.0                        # 100 periods
    assert gap_limit(0.01, [900.0] * (BURST_PAUSES - 1)) == SESSION_GAP_S
    assert gap_limit(0.01, [900.0] * BURST_PAUSES) == 2700.0    # 3 x the median pause
    assert gap_limit(0.01, [2000.0] * BURST_PAUSES) == BURST_MAX_S
    assert session_gap(np.array([0.0])) == np.inf
    assert session_gap(np.arange(10.0), gap_s=42.0) == 42.0


def test_batch_and_streaming_agree_on_a_bursty_log_and_a_night_off():
    # A logger recording 20 s every 15 min, then off for 2 h, then on again.
    t = np.concatenate([_bursts(12, 900.0), _bursts(12, 900.0, t0=12 * 920.0 + 7200.0)])
    batch = [i for i, _ in gap_breaks(t)]
    night = int(np.flatnonzero(np.diff(t) > 7000.0)[0]) + 1
    assert batch == [night]                                     # the rhythm is no restart
    rule = SessionTracker()
    stream = _stream(t, rule)
    # Streaming cannot know the rhythm before it has seen it: the first pauses break.
    assert stream[-1] == night
    assert len(stream) == BURST_PAUSES - 1 + 1
    # A stream of steady 900 s pauses from the start: the same after the rule has its rhythm.
    again = SessionTracker()
    again.rhythm = list(rule.rhythm)
    assert _stream(_bursts(12, 900.0), again) == []


def test_a_restart_and_a_nan_step():
    rule = SessionTracker()
    assert rule.judge(-5.0, 0.01) == 'restart (stamps back by 5 s)'
    assert rule.judge(-0.5, 0.01) == ''                         # within RESTART_BACK_S
    assert rule.judge(float('nan'), 0.01) == ''
    assert rule.judge(3600.5, 0.01) == 'gap of 3600 s' and rule.rhythm == []
    assert rule.pauses == 2                                     # the two steps no break


def test_the_tracker_counts_sessions_and_their_mean_period():
    tracker = SessionTracker(first=1)
    tracker.begin(0.0, 1)
    # 101 samples at 0.1 s, then a 700 s step: a break (over SESSION_GAP_S).
    assert tracker.period(10.0, 102) == 0.1
    assert tracker.judge(700.0, tracker.period(10.0, 102)) == 'gap of 700 s'
    assert tracker.start(710.0, 'gap of 700 s', 102) == 2
    assert (tracker.t0, tracker.k0, tracker.pauses) == (710.0, 102, 0)
    # A pause judged no break is left out of the session's mean period.
    assert tracker.judge(-0.5, 0.1) == '' and tracker.pauses == 1
    assert tracker.period(720.5, 204) == (720.5 - 710.0 + 0.5) / (204 - 102 - 1 - 1)


def test_the_tracker_merges_sessions_once_the_rhythm_shows():
    tracker = SessionTracker()
    for k in range(BURST_PAUSES):
        why = tracker.judge(900.0, 0.1)
        relabel = tracker.merges(0.1)
        if why:
            tracker.start(920.0 * (k + 1), why, gap=900.0)
    # The first pauses broke; the fifth shows the rhythm and merges them all back.
    assert relabel == {k: 0 for k in range(BURST_PAUSES)}
    assert tracker.session == 0 and tracker.gaps == []
    assert tracker.judge(7200.0, 0.1) == 'gap of 7200 s'


def test_the_tracker_says_which_steps_to_show_it():
    """The gap until the median period is known, then 100 periods, at most the gap."""
    fast, slow = SessionTracker(), SessionTracker()
    assert fast.pause_s() == SESSION_GAP_S == slow.pause_s()
    fast.median_period(np.full(64, 0.01))
    slow.median_period(np.full(64, 10.0))
    assert fast.pause_s() == 1.0                     # 100 periods of 10 ms
    assert slow.pause_s() == SESSION_GAP_S           # 100 periods of 10 s would be 1000 s
