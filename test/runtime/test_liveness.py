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

"""Input liveness (no rclpy): FrequencyStatus's judgement on counted arrivals, on a fake clock."""

from __future__ import annotations

from gyro_tdc.runtime.liveness import ERROR, InputRate, LEARN_S, OK, WARN, WINDOW_S
import pytest

START = 1000.0


def reports(rate, seconds, hz, *, t0=START, n0=0, step=1.0):
    """Run ``rate`` once per ``step`` for ``seconds`` of an input arriving at ``hz``."""
    out = []
    t, n = t0, n0
    for _ in range(int(round(seconds / step))):
        t += step
        n += int(round(hz * step))
        out.append(rate.run(t, n))
    return out, t, n


def test_an_expected_rate_met_is_ok_and_slowing_warns_then_silence_is_an_error():
    rate = InputRate('imu/data_raw', START, 200.0)
    steady, t, n = reports(rate, 10.0, 200.0)
    assert all(r.level == OK and r.message == '' for r in steady)
    assert steady[-1].hz == pytest.approx(200.0) and steady[-1].expected_hz == 200.0
    assert steady[-1].window_s == pytest.approx(WINDOW_S)
    slow, t, n = reports(rate, 10.0, 150.0, t0=t, n0=n)
    assert slow[-1].level == WARN and 'too slow: 150.00 Hz' in slow[-1].message
    stopped, t, n = reports(rate, 10.0, 0.0, t0=t, n0=n)
    levels = [r.level for r in stopped]
    # Within the window the rate falls (WARN), once the window saw nothing: ERROR.
    assert levels[0] == WARN and levels[-1] == ERROR
    assert stopped[-1].message == 'no imu/data_raw for 10.0 s' and stopped[-1].silent_s == 10.0
    assert levels.index(ERROR) == int(WINDOW_S) - 1
    back, t, n = reports(rate, 10.0, 200.0, t0=t, n0=n)
    assert back[-1].level == OK


def test_an_expected_rate_exceeded_warns():
    rate = InputRate('imu/data_raw', START, 100.0)
    fast, _, _ = reports(rate, 6.0, 250.0)      # two drivers on one topic, say
    assert fast[-1].level == WARN and 'too fast' in fast[-1].message


def test_a_rate_of_zero_is_learnt_then_only_slowing_warns():
    rate = InputRate('imu/data_raw', START, 0.0)
    first, t, n = reports(rate, LEARN_S + 0.5, 400.0, step=0.5)   # from the first seen
    assert all(r.level == OK for r in first)
    assert first[0].expected_hz is None and first[-1].expected_hz == pytest.approx(400.0)
    faster, t, n = reports(rate, 10.0, 800.0, t0=t, n0=n)
    assert all(r.level == OK for r in faster)       # learnt: no upper bound
    slower, t, n = reports(rate, 10.0, 300.0, t0=t, n0=n)
    assert slower[-1].level == WARN


def test_no_message_yet_warns_then_errors_and_a_late_start_is_not_slow():
    rate = InputRate('imu/data_raw', START, 100.0)
    assert rate.run(START + 1.0, 0).level == WARN
    late = rate.run(START + 30.0, 0)
    assert late.level == ERROR and late.message == 'no imu/data_raw yet (30.0 s since start)'
    # The window starts at the first message seen, not at start-up: a 30 s late start is
    # not reported as a slow rate.
    steady, _, _ = reports(rate, 6.0, 100.0, t0=START + 30.0)
    assert [r.level for r in steady[1:]] == [OK] * 5


def test_a_slow_input_is_judged_over_enough_messages():
    rate = InputRate('imu/data_raw', START, 1.0)
    steady, _, _ = reports(rate, 60.0, 1.0)
    assert all(r.level == OK for r in steady)
    assert steady[-1].window_s == pytest.approx(20.0)


def test_an_input_not_judged_only_shows_its_figures():
    rate = InputRate('imu/temperature', START, None)
    out, t, n = reports(rate, 3.0, 2.0)
    silent = rate.run(t + 100.0, n)
    assert out[-1].level == silent.level == OK and silent.message == ''
    assert silent.silent_s == pytest.approx(100.0) and silent.expected_hz is None
    v = silent.values('temperature')
    assert v['temperature silent s'] == '100.000' and v['temperature expected rate Hz'] == ''
