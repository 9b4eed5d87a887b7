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

"""The compensator's backlog meter (pure): queue age, callback time, samples missing."""

from __future__ import annotations

from gyro_tdc.nodes.compensator_backlog import (Backlog, BASELINE_DRIFT, MIN_STEPS, PAUSE_S,
                                                QUEUE_AGE_WARN_S, STAMP_JUMP_S)
import pytest

T0 = 1_700_000_000.0
P = 5e-4                                  # 2 kHz


def feed(backlog, stamps, starts, cost=30e-6):
    """Record samples as the callbacks do: (stamp, start, end)."""
    for t, s in zip(stamps, starts):
        backlog.record((t, s, s + cost))


def test_keeping_up_is_ok_with_the_callback_figures():
    bl = Backlog(2000.0)
    n = 2000
    stamps = [T0 + k * P for k in range(n)]
    starts = [100.0 + k * P + 1e-4 * (k % 3) for k in range(n)]   # 0..0.2 ms of jitter
    feed(bl, stamps, starts, cost=40e-6)
    r = bl.report(101.0)
    assert r.level == 0 and r.message == ''
    assert float(r.values['queue age max s']) <= 2.1e-4
    assert r.values['callback median us'] == '40' and r.values['callback max us'] == '40'
    assert r.values['input missing'] == '0' and r.values['input period ms'] == \
        '0.5 (expected_rate_hz)'
    feed(bl, [T0 + n * P], [100.0 + n * P])
    r = bl.report(102.0)
    assert r.values['callback load %'] == '0'            # 40 us in one second


def test_falling_behind_warns_with_the_age_and_counts_the_queue_overwrites():
    """A node at half the input rate behind a 2000-sample keep-last queue."""
    bl = Backlog(0.0)                     # the period learnt from the stamps
    stamps, starts = [], []
    # 1 s fresh, then the queue is full: every sample taken is the oldest of the last 2000,
    # one in two arrivals overwritten (steps of two periods), each 1 s old.
    for k in range(2000):
        stamps.append(T0 + k * P)
        starts.append(50.0 + k * P)
    for j in range(1000):
        stamps.append(T0 + 1.0 + 2 * j * P)
        starts.append(50.0 + 2.0 + 2 * j * P)
    feed(bl, stamps, starts)
    r = bl.report(53.0)
    assert r.level == 1 and 'falling behind: a sample waited 1.000 s' in r.message
    assert 'input samples missing by stamp (999 in 999 gaps at the 0.5 ms' in r.message
    assert r.values['input missing'] == '999' and r.values['input period ms'] == '0.5 (learnt)'
    # 1 s, less the baseline's allowed drift over the 2 s since the freshest sample.
    assert float(r.values['queue age s']) == pytest.approx(1.0 - 2.0 * BASELINE_DRIFT,
                                                           abs=1e-4)
    r = bl.report(54.0)                  # nothing new: OK, the totals stay
    assert r.level == 0 and r.values['input missing'] == '999'


def test_a_pause_of_the_imu_is_no_loss_and_stamps_stepping_back_restart_the_baseline():
    bl = Backlog(2000.0)
    feed(bl, [T0 + k * P for k in range(100)], [10.0 + k * P for k in range(100)])
    later = T0 + 100 * P + 5.0            # the IMU paused 5 s: its next sample comes fresh
    feed(bl, [later], [10.0 + 100 * P + 5.0])
    # A new stream stamped an hour earlier (a restarted clock): no queue age from it.
    feed(bl, [T0 - 3600.0 + k * P for k in range(10)], [20.0 + k * P for k in range(10)])
    r = bl.report(21.0)
    assert r.level == 0, r.message
    assert r.values['input pauses'] == '1' and r.values['input missing'] == '0'
    assert float(r.values['queue age max s']) < 1e-9 and r.values['input stamp jumps'] == '1'


@pytest.mark.parametrize('stray', [-2.0 ** 31, 2.0 ** 31 - 1, T0 - 3.0, T0 + 3600.0])
def test_one_hostile_stamp_is_a_jump_not_a_loss_nor_an_age(stray):
    """A sample stamped far before, far after or a little before the stream costs nothing."""
    bl = Backlog(2000.0)
    stamps = [T0 + k * P for k in range(50)] + [stray] + [T0 + k * P for k in range(50, 100)]
    feed(bl, stamps, [10.0 + k * P for k in range(101)])
    r = bl.report(11.0)
    assert r.level == 0, r.message
    assert r.values['input missing'] == '0' and float(r.values['queue age max s']) < 1e-3
    far = abs(stray - T0) > STAMP_JUMP_S
    assert r.values['input stamp jumps'] == ('1' if far else '0')   # and back to the stream


def test_an_interleaved_second_stream_hides_no_gap_of_the_first():
    """Another publisher 10 s behind on the topic: the first stream's gap is still counted."""
    bl = Backlog(2000.0)
    stamps = []
    for k in list(range(100)) + list(range(110, 200)):     # 10 samples of the first lost
        stamps += [T0 + k * P, T0 - 10.0 + k * P]
    feed(bl, stamps, [10.0 + j * P / 2 for j in range(len(stamps))])
    assert bl.report(11.0).values['input missing'] == '10'


def test_a_stall_longer_than_the_queue_is_a_loss_not_a_pause():
    """Held up 3 s behind a 1 s queue: the next sample is 1 s old and 2 s of stamps gone."""
    bl = Backlog(2000.0)
    feed(bl, [T0 + k * P for k in range(10)], [10.0 + k * P for k in range(10)])
    t = T0 + 10 * P + 2.0                 # the oldest sample the queue still holds
    feed(bl, [t + k * P for k in range(5)], [10.0 + 10 * P + 3.0 + k * 1e-5 for k in range(5)])
    r = bl.report(14.0)
    assert 2.0 > PAUSE_S and r.level == 1
    assert r.values['input pauses'] == '0'
    assert r.values['input missing'] == str(round(2.0 / P))     # one gap of 4001 steps - 1
    assert float(r.values['queue age max s']) == pytest.approx(1.0, abs=1e-3)


def test_a_replay_faster_than_real_time_counts_what_its_queue_dropped():
    """5 Hz stamps at 2,000 msg/s: the node busy throughout, 500 samples gone at once."""
    bl = Backlog()
    stamps = [T0 + k * 0.2 for k in range(100)] + [T0 + k * 0.2 for k in range(600, 700)]
    feed(bl, stamps, [7.0 + k * P for k in range(200)])
    r = bl.report(8.0)
    assert r.level == 1 and r.values['input missing'] == '500'
    assert r.values['input pauses'] == '0' and r.values['input period ms'] == '200 (learnt)'


def test_the_baseline_follows_a_slow_clock_drift():
    """An IMU clock 50 ppm slow: no queue age accumulates over an hour (10 Hz here)."""
    bl = Backlog(10.0)
    for minute in range(60):
        ks = range(minute * 6000, (minute + 1) * 6000, 10)
        feed(bl, [T0 + k * 0.01 * (1 - 50e-6) for k in ks], [5.0 + k * 0.01 for k in ks])
        r = bl.report(5.0 + (minute + 1) * 60.0)
    assert 50e-6 < BASELINE_DRIFT
    assert r.level == 0 and float(r.values['queue age max s']) < 1e-4


def test_the_period_is_learnt_from_enough_steps_only():
    bl = Backlog()
    feed(bl, [T0 + k * 0.01 for k in range(MIN_STEPS // 2)],
         [1.0 + k * 0.01 for k in range(MIN_STEPS // 2)])
    assert bl.report(2.0).values['input period ms'] == 'learning'
    feed(bl, [T0 + k * 0.01 for k in range(MIN_STEPS // 2, MIN_STEPS + 5)],
         [1.0 + k * 0.01 for k in range(MIN_STEPS // 2, MIN_STEPS + 5)])
    assert bl.report(3.0).values['input period ms'] == '10 (learnt)'


def test_the_period_is_learnt_right_by_a_node_behind_from_its_start():
    """Three samples in four lost from the first one on: the period is still 0.5 ms."""
    bl = Backlog()
    ks = [k for k in range(400) if k % 4 == 0 or k % 20 == 1]
    feed(bl, [T0 + k * P for k in ks], [3.0 + j * 1e-3 for j in range(len(ks))])
    r = bl.report(4.0)
    assert r.values['input period ms'] == '0.5 (learnt)'
    assert r.values['input missing'] == str(ks[-1] + 1 - len(ks))


def test_no_samples_reports_empty_figures():
    r = Backlog().report(1.0)
    assert r.level == 0 and r.values['queue age s'] == '' and r.values['input missing'] == '0'
    assert QUEUE_AGE_WARN_S == 0.25
