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

"""The still test (gyro_tdc.signal.still): the rule, the noise floor and the batch form."""

from __future__ import annotations

import math

from gyro_tdc.runtime.reanchor import StillnessDetector
from gyro_tdc.signal import (detect_still, judge_windows, MAX_RATE, motion_veto, NOISE_FACTOR,
                             noise_floor, noise_thresholds, stretch_edges, windows_moving)
from gyro_tdc.signal.still import NoiseFloor
import numpy as np
import pytest
from still_data import DEG, drive, RATE_HZ, rest


def test_a_still_run_is_still_and_driving_splits_it():
    t, gyro, accel = rest(1800.0)
    st = detect_still(t, gyro, accel)
    assert st.reason == '' and st.fraction > 0.99 and len(st.segments) == 1
    assert st.still_s == pytest.approx(1800.0, abs=1.0)
    # The auto thresholds sit at NOISE_FACTOR times the quietest window, near the noise.
    sd = 0.03 * DEG * math.sqrt(RATE_HZ)
    assert np.all(st.gyro_threshold > 2.5 * sd) and np.all(st.gyro_threshold < NOISE_FACTOR * sd)
    on = drive(t, gyro, accel, 600.0, 1200.0)
    st = detect_still(t, gyro, accel)
    assert len(st.segments) == 2 and not np.any(st.mask & on)
    assert st.rejected()['gyro'] >= 59
    assert st.still_s == pytest.approx(1200.0, abs=20.0)
    # Without the accelerometer the gyro's scatter alone sees the drive.
    st = detect_still(t, gyro)
    assert st.accel_std is None and not np.any(st.mask & on) and len(st.segments) == 2


def test_short_stops_are_dropped_below_the_minimum_duration():
    t, gyro, accel = rest(900.0)
    drive(t, gyro, accel, 100.0, 400.0)
    drive(t, gyro, accel, 440.0, 800.0, seed=2)      # a 40 s stop between two drives
    st = detect_still(t, gyro, accel, min_still_s=60.0)
    assert [round(float(t[a])) for a, _ in st.segments] == [0, 800]
    assert st.rejected().get('brief', 0) >= 3
    st = detect_still(t, gyro, accel, min_still_s=0.0)
    assert len(st.segments) == 3
    # A run that never stops looks still to itself (auto thresholds take its quietest
    # window as the noise); the floor of a run of the same sensor that stops refuses it.
    floors = detect_still(t, gyro, accel)
    drive(t, gyro, accel, 0.0, 900.0, seed=3)
    assert detect_still(t, gyro, accel).fraction > 0.9
    st = detect_still(t, gyro, accel, gyro_floor=floors.gyro_floor,
                      accel_floor=floors.accel_floor)
    assert not st.mask.any() and st.reason.startswith('no still')


def test_judging_again_reuses_the_windows_and_gives_a_fresh_verdict():
    """``again`` judges a result's windows with other floors and veto as a fresh call does."""
    t, gyro, accel = rest(900.0)
    drive(t, gyro, accel, 100.0, 400.0)
    gyro[5000] = np.nan
    first = detect_still(t, gyro, accel, window_s=2.5)
    moving = (t > 600.0) & (t < 650.0)
    for kw in ({'gyro_floor': 3.0 * first.gyro_floor, 'accel_floor': first.accel_floor},
               {'moving': moving, 'min_still_s': 0.0}):
        fresh = detect_still(t, gyro, accel, window_s=2.5, **kw)
        again = detect_still(t, gyro, accel, window_s=2.5, again=first, **kw)
        assert again.gyro_mean is first.gyro_mean and again.segments == fresh.segments
        for name in ('mask', 'why', 'gyro_threshold', 'accel_threshold', 'durations_s'):
            np.testing.assert_array_equal(getattr(again, name), getattr(fresh, name))
    assert not np.array_equal(again.mask, first.mask) and again.reason == fresh.reason
    # Another run's result (other samples) is not reused.
    other = detect_still(t[:-10], gyro[:-10], accel[:-10], window_s=2.5, again=first)
    assert other.gyro_mean is not first.gyro_mean and other.starts.size == first.starts.size
    # Nor one of other windows, or of the other sensors: a fresh call's result instead.
    for kw, acc in (({'window_s': 5.0}, accel), ({'window_s': 2.5}, None)):
        reused = detect_still(t, gyro, acc, again=first, **kw)
        fresh = detect_still(t, gyro, acc, **kw)
        assert reused.gyro_mean is not first.gyro_mean
        np.testing.assert_array_equal(reused.mask, fresh.mask)
        np.testing.assert_array_equal(reused.starts, fresh.starts)


@pytest.mark.parametrize('turn_dps', [0.5, 2.0, 5.0])
def test_slow_constant_yaw_turn_what_rejects_it(turn_dps):
    """A slow constant turn has no scatter: what tells it from a bias, and the honest limit."""
    t, gyro, accel = rest(1200.0, seed=4)
    turn = (t >= 400.0) & (t < 800.0)
    gyro[turn, 2] += turn_dps * DEG
    # 1. The limit: a smooth turn about the vertical leaves the accelerometer unchanged and
    # adds no scatter: with no prior and no motion topic it passes as still.
    st = detect_still(t, gyro, accel)
    assert st.mask[turn].mean() > 0.9
    # 2. The motion veto (cmd_vel angular.z) rejects it.
    cmd_t = np.arange(0.0, 1200.0, 0.2)
    cmd = np.zeros((cmd_t.size, 6))
    cmd[(cmd_t >= 400.0) & (cmd_t < 800.0), 5] = turn_dps * DEG
    moving = motion_veto(t, cmd_t, cmd)
    st = detect_still(t, gyro, accel, moving=moving)
    assert not np.any(st.mask & turn) and st.rejected()['motion'] >= 39
    assert st.mask[~turn].mean() > 0.95
    # 3. A prior (the rate compensated by a model) rejects a turn above max_rate only.
    comp = gyro - [0.06, -0.07, 0.02]
    st = detect_still(t, gyro, accel, rate=comp)
    if turn_dps * DEG > MAX_RATE:
        assert not np.any(st.mask & turn) and st.rejected()['rate'] >= 39
    else:
        assert st.mask[turn].mean() > 0.9


def test_a_slow_turn_about_a_horizontal_axis_shows_in_the_accelerometer():
    t, gyro, accel = rest(1200.0, seed=5)
    turn = (t >= 400.0) & (t < 800.0)
    w = 0.5 * DEG
    gyro[turn, 1] += w
    # Gravity turns in the sensor frame as the IMU pitches at 0.5 deg/s.
    th = np.clip(t - 400.0, 0.0, 400.0) * w
    accel[:, 0] += -9.80665 * np.sin(th)
    accel[:, 2] += 9.80665 * (np.cos(th) - 1.0)
    st = detect_still(t, gyro, accel)
    assert not np.any(st.mask & turn) and st.rejected()['accel'] >= 39
    # The gyro alone cannot see it.
    assert detect_still(t, gyro).mask[turn].mean() > 0.9


def test_motion_veto_holds_the_latest_report():
    t = np.arange(0.0, 10.0, 0.5)
    mt = np.array([2.0, 5.0, 7.0])
    # Twist-like rows (linear x, y, z, angular x, y, z): moving from 5 s to 7 s.
    rows = np.zeros((3, 6))
    rows[1, 0] = 0.3
    v = motion_veto(t, mt, rows)
    assert v[t < 2.0].all()                       # no report yet: vetoed
    assert not v[(t >= 2.0) & (t < 5.0)].any()
    assert v[(t >= 5.0) & (t < 7.0)].all() and not v[t >= 7.0].any()
    np.testing.assert_array_equal(motion_veto(t, mt[::-1], rows[::-1]), v)   # any order
    np.testing.assert_array_equal(motion_veto(t, mt, np.array([False, True, False])), v)
    assert motion_veto(t, [], np.zeros((0, 6))).all()
    nan = rows.copy()
    nan[2, 0] = np.nan                            # a NaN report is not a report of rest
    assert motion_veto(t, mt, nan)[t >= 7.0].all()


def test_judge_and_thresholds_are_the_streaming_detectors_too():
    g_std = np.array([[1.0, 1.0, 1.0], [5.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]]) * 1e-3
    a_std = np.array([[1, 1, 1], [1, 1, 1], [9, 1, 1], [1, 1, 1]]) * 1e-2
    g_thr, a_thr = noise_thresholds(noise_floor(g_std), noise_floor(a_std))
    np.testing.assert_allclose(g_thr, [4e-3] * 3)
    why = judge_windows(g_std, a_std, g_thr, a_thr, mean_rate=[[0, 0, 0], [0, 0, 0],
                                                               [0, 0, 0], [0, 0, 0.5]],
                        moving=[False, False, False, False])
    assert why.tolist() == ['', 'gyro', 'accel', 'rate']
    assert judge_windows(g_std, None, g_thr, a_thr, moving=[True] * 4).tolist() == ['motion'] * 4
    g_thr, _ = noise_thresholds([1e-3] * 3, None, prior_std=[1e-4] * 3)
    np.testing.assert_allclose(g_thr, [4e-4] * 3)
    g_thr, a_thr = noise_thresholds([1e-3] * 3, [1.0] * 3, gyro_std=0.01, accel_std=0.2)
    assert g_thr.tolist() == [0.01] * 3 and a_thr.tolist() == [0.2] * 3
    # The streaming detector takes the same verdict on a slow turn (mean above max_rate).
    t, gyro, accel = rest(60.0, seed=6)
    det = StillnessDetector(10.0)
    out = gyro - [0.06, -0.07, 0.02] + [0.0, 0.0, 2.0 * DEG]
    assert all(det.update(float(a), g, o, c, 20.0) is None
               for a, g, o, c in zip(t, gyro, out, accel))
    assert det.windows_rejected >= 4


def test_bad_input_is_named():
    with pytest.raises(ValueError, match='gyro'):
        detect_still(np.arange(5.0), np.zeros((4, 3)))
    st = detect_still(np.arange(2.0), np.zeros((2, 3)))
    assert not st.mask.any() and 'too few' in st.reason


def test_window_statistics_over_several_passes_are_each_windows_own():
    # 2 h at 20 Hz with a drive, a NaN and a motion report: 144,000 samples, more than one
    # pass of the window sums; every window's mean and std (ddof 1) is its own, a row with a
    # NaN counting as zeros and flagging its window.
    t, gyro, accel = rest(7200.0)
    drive(t, gyro, accel, 3000.0, 3600.0)
    gyro[100_000, 1] = math.nan
    moving = np.zeros(t.size, dtype=bool)
    moving[50_000] = True
    st = detect_still(t, gyro, accel, moving=moving)
    assert t.size > 1 << 17 and st.starts.size == 720
    finite = (np.isfinite(gyro) & np.isfinite(accel)).all(axis=1)[:, None]
    g, a = np.where(finite, gyro, 0.0), np.where(finite, accel, 0.0)
    for j in (0, 300, 400, 500, 719):
        rows = slice(st.starts[j], st.starts[j] + st.counts[j])
        np.testing.assert_allclose(st.gyro_mean[j], g[rows].mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(st.gyro_std[j], g[rows].std(axis=0, ddof=1), rtol=1e-9)
        np.testing.assert_allclose(st.accel_std[j], a[rows].std(axis=0, ddof=1), rtol=1e-9)
    assert st.why[100_000 // 200] == 'non-finite' and st.why[50_000 // 200] == 'motion'
    assert set(st.why[3000 // 10:3600 // 10]) <= {'gyro', 'accel'}


def test_windows_moving_holds_each_report_until_the_next():
    mt, mv = [1.0, 2.0, 4.0], [False, True, False]
    got = windows_moving([0.0, 1.0, 2.5, 3.9, 4.0, 0.0], [0.9, 1.9, 3.0, 4.5, 5.0, 1.5],
                         mt, mv)
    # Before the first report: no veto; [2, 4) moving.
    assert got.tolist() == [False, False, True, True, False, False]
    assert not windows_moving([0.0], [9.0], [], []).any()


def test_the_auto_still_test_judges_a_stretch_by_its_samples_and_its_noise():
    from gyro_tdc.signal import auto_window, MAX_STILL_SE, MIN_STILL_SAMPLES
    rng = np.random.default_rng(7)
    rate = 25.0
    t = np.arange(int(95 * rate)) / rate
    gyro = rng.normal(0.0, 0.05 * DEG, (t.size, 3))
    moves = (t >= 15.0) & (t < 80.0)          # still 15 s, flying 65 s, still 15 s
    gyro[moves] += rng.normal(0.0, 20.0 * DEG, (int(moves.sum()), 3))
    window = auto_window(t)
    assert window == pytest.approx(2.5)
    auto = detect_still(t, gyro, window_s=window, min_still_s=None)
    assert len(auto.segments) == 2
    # window_s None: the same auto window, from the median step detect_still takes anyway.
    again = detect_still(t, gyro, window_s=None, min_still_s=None)
    assert again.window_s == window and again.segments == auto.segments
    assert all(b - a >= MIN_STILL_SAMPLES for a, b in auto.segments)   # 15 s: 375 samples
    assert 25.0 <= auto.still_s <= 30.0
    assert not auto.mask[moves].any()
    fixed = detect_still(t, gyro, window_s=window, min_still_s=60.0)
    assert fixed.segments == () and 'no still stretch of 60 s' in fixed.reason
    # The same stretches with 20 times the noise: their means are not known well enough.
    noisy = gyro.copy()
    noisy[~moves] *= 20.0
    se = 20.0 * 0.05 * DEG / math.sqrt(375)
    assert se > MAX_STILL_SE
    loud = detect_still(t, noisy, window_s=window, min_still_s=None)
    assert loud.segments == () and 'samples with a mean known to' in loud.reason
    # At 1 Hz the window holds 20 samples and a stretch needs 60 s (as before).
    assert auto_window(np.arange(100.0)) == pytest.approx(20.0)
    assert detect_still(np.arange(100.0), np.zeros((100, 3)), window_s=None).window_s == 20.0


def test_a_logging_gap_ends_a_still_stretch_and_low_rate_stops_count():
    from gyro_tdc.signal import MIN_STILL_SAMPLES
    rng = np.random.default_rng(11)
    rate = 25.0
    # An SD-card logger that stops for 290 s inside a stop: two stretches, not one of 310 s.
    t = np.r_[np.arange(250) / rate, 300.0 + np.arange(250) / rate]
    gyro = rng.normal(0.0, 0.05 * DEG, (t.size, 3))
    st = detect_still(t, gyro, window_s=None, min_still_s=None)
    assert st.segments == ((0, 250), (250, 500))
    assert st.still_s == pytest.approx(20.0, abs=0.1)
    # A 15 s stop of an 8 Hz log (120 samples) is kept when its mean is known well enough.
    assert MIN_STILL_SAMPLES <= 120
    t8 = np.arange(120) / 8.0
    st8 = detect_still(t8, rng.normal(0.0, 0.05 * DEG, (120, 3)), window_s=None, min_still_s=None)
    assert st8.segments == ((0, 120),)


def test_noise_floor_pools_to_the_degrees_of_freedom():
    f = NoiseFloor()
    f.add(9, np.full(3, 1.0), np.full(3, math.inf))
    assert np.isinf(f.floor).all()            # 9 degrees of freedom: not yet
    for _ in range(4):
        f.add(9, np.full(3, 1.0), np.full(3, math.inf))
    np.testing.assert_allclose(f.floor, 1.0)
    f.add(9, np.zeros(3), np.array([0.5, math.inf, 0.5]))   # a constant window pooled
    assert f.floor[0] == f.floor[2] < 1.0 and f.floor[0] >= 0.5 / math.sqrt(12.0)


def test_a_long_step_or_a_cut_ends_a_stretch():
    still = np.array([1, 1, 0, 1, 1, 1, 1, 1], dtype=bool)
    steps = np.array([1.0, 1.0, 1.0, 1.0, 9.0, 1.0, 1.0])     # a gap between items 4 and 5
    starts, stops = stretch_edges(still, steps, 2.0)
    assert starts.tolist() == [0, 3, 5] and stops.tolist() == [2, 5, 8]
    starts, stops = stretch_edges(still, steps, 2.0, [5])    # cut between items 5 and 6
    assert starts.tolist() == [0, 3, 5, 6] and stops.tolist() == [2, 5, 6, 8]
    assert stretch_edges(still, steps, 10.0)[0].tolist() == [0, 3]
