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

"""The one still test (gyro_tdc.signal): still, driving, slow constant turns, motion veto."""

from __future__ import annotations

import math

from gyro_tdc.runtime.reanchor import StillnessDetector
from gyro_tdc.signal import (detect_still, judge_windows, MAX_RATE, motion_veto, NOISE_FACTOR,
                             noise_floor, noise_thresholds, StillWindows, StreamingStill,
                             windows_moving)
import numpy as np
import pytest

RATE_HZ = 20.0
DEG = math.pi / 180.0
G = np.array([0.0, 0.0, 9.80665])


def _rest(seconds: float, seed: int = 0, *, bias=(0.06, -0.07, 0.02)):
    """Return stamps, gyro and accel of a still IMU (L3GD20-like noise at 20 Hz)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    gyro = np.asarray(bias) + rng.normal(0.0, 0.03 * DEG * math.sqrt(RATE_HZ), (t.size, 3))
    accel = G + rng.normal(0.0, 0.0015 * math.sqrt(RATE_HZ), (t.size, 3))
    return t, gyro, accel


def _drive(t, gyro, accel, a: float, b: float, seed: int = 1):
    """Add driving (manoeuvres plus vibration) between a and b seconds, in place."""
    rng = np.random.default_rng(seed)
    on = (t >= a) & (t < b)
    gyro[on] += rng.normal(0.0, 0.5 * DEG, (on.sum(), 3)) + [0, 0, 10 * DEG]
    accel[on] += rng.normal(0.0, 0.8, (on.sum(), 3))
    return on


def test_a_still_run_is_still_and_driving_splits_it():
    t, gyro, accel = _rest(1800.0)
    st = detect_still(t, gyro, accel)
    assert st.reason == '' and st.fraction > 0.99 and len(st.segments) == 1
    assert st.still_s == pytest.approx(1800.0, abs=1.0)
    # The auto thresholds sit at NOISE_FACTOR times the quietest window, near the noise.
    sd = 0.03 * DEG * math.sqrt(RATE_HZ)
    assert np.all(st.gyro_threshold > 2.5 * sd) and np.all(st.gyro_threshold < NOISE_FACTOR * sd)
    on = _drive(t, gyro, accel, 600.0, 1200.0)
    st = detect_still(t, gyro, accel)
    assert len(st.segments) == 2 and not np.any(st.mask & on)
    assert st.rejected()['gyro'] >= 59
    assert st.still_s == pytest.approx(1200.0, abs=20.0)
    # Without the accelerometer the gyro's scatter alone sees the drive.
    st = detect_still(t, gyro)
    assert st.accel_std is None and not np.any(st.mask & on) and len(st.segments) == 2


def test_short_stops_are_dropped_below_the_minimum_duration():
    t, gyro, accel = _rest(900.0)
    _drive(t, gyro, accel, 100.0, 400.0)
    _drive(t, gyro, accel, 440.0, 800.0, seed=2)      # a 40 s stop between two drives
    st = detect_still(t, gyro, accel, min_still_s=60.0)
    assert [round(float(t[a])) for a, _ in st.segments] == [0, 800]
    assert st.rejected().get('brief', 0) >= 3
    st = detect_still(t, gyro, accel, min_still_s=0.0)
    assert len(st.segments) == 3
    # A run that never stops looks still to itself (auto thresholds take its quietest
    # window as the noise); the floor of a run of the same sensor that stops refuses it.
    floors = detect_still(t, gyro, accel)
    _drive(t, gyro, accel, 0.0, 900.0, seed=3)
    assert detect_still(t, gyro, accel).fraction > 0.9
    st = detect_still(t, gyro, accel, gyro_floor=floors.gyro_floor,
                      accel_floor=floors.accel_floor)
    assert not st.mask.any() and st.reason.startswith('no still')


@pytest.mark.parametrize('turn_dps', [0.5, 2.0, 5.0])
def test_slow_constant_yaw_turn_what_rejects_it(turn_dps):
    """A slow constant turn has no scatter: what tells it from a bias, and the honest limit."""
    t, gyro, accel = _rest(1200.0, seed=4)
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
    t, gyro, accel = _rest(1200.0, seed=5)
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
    t, gyro, accel = _rest(60.0, seed=6)
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


def _stream(det, t, gyro, accel=None, rate=None, moving=None, temp=None):
    segs = []
    for k in range(t.size):
        s = det.update(float(t[k]), gyro[k].tolist(),
                       None if accel is None else accel[k].tolist(),
                       rate=None if rate is None else rate[k].tolist(),
                       temp_c=math.nan if temp is None else float(temp[k]),
                       moving=False if moving is None else bool(moving[k]))
        if s is not None:
            segs.append(s)
    last = det.flush()
    return segs + ([last] if last is not None else [])


@pytest.mark.parametrize('fixed', [True, False])
def test_streaming_still_equals_the_batch_form(fixed):
    t, gyro, accel = _rest(2400.0, seed=7)
    _drive(t, gyro, accel, 300.0, 700.0)
    _drive(t, gyro, accel, 1000.0, 1045.0, seed=8)     # a stop of 5 min, then a short drive
    _drive(t, gyro, accel, 1345.0, 1380.0, seed=9)     # a 25 s drive ...
    _drive(t, gyro, accel, 1405.0, 1900.0, seed=10)    # ... a 25 s stop (too brief)
    temp = 20.0 + t / 600.0
    opts = {'gyro_std': 0.01, 'accel_std': 0.2} if fixed else {}
    batch = detect_still(t, gyro, accel, **opts)
    segs = _stream(StreamingStill(**opts), t, gyro, accel, temp=temp)
    assert [(s.t0_s, s.t1_s) for s in segs] == [(t[a], t[b - 1]) for a, b in batch.segments]
    assert len(segs) == 4
    for s, (a, b) in zip(segs, batch.segments):
        assert s.samples == b - a
        np.testing.assert_allclose(s.gyro_mean, gyro[a:b].mean(axis=0), rtol=0, atol=1e-12)
        assert s.temp_c == pytest.approx(temp[a:b].mean())
        assert s.rate_mean is None


def test_streaming_still_veto_prior_and_rate():
    t, gyro, accel = _rest(1200.0, seed=11)
    turn = (t >= 400.0) & (t < 800.0)
    gyro[turn, 2] += 2.0 * DEG
    # The motion veto splits the stretch; the rate test (a prior) too; without either the
    # smooth turn passes (the limit of the test).
    assert len(_stream(StreamingStill(), t, gyro, accel)) == 1
    det = StreamingStill()
    segs = _stream(det, t, gyro, accel, moving=turn)
    assert len(segs) == 2 and det.rejected['motion'] == 40
    comp = gyro - [0.06, -0.07, 0.02]
    segs = _stream(StreamingStill(), t, gyro, accel, rate=comp)
    assert len(segs) == 2 and segs[0].rate_mean is not None
    assert max(abs(v) for v in segs[0].rate_mean) < 1e-3
    # A prior holds the first windows' threshold: moving from the start is not the floor.
    t2, g2, a2 = _rest(300.0, seed=12)
    _drive(t2, g2, a2, 0.0, 120.0)
    det = StreamingStill(prior_std=[0.03 * DEG * math.sqrt(RATE_HZ)] * 3)
    segs = _stream(det, t2, g2, a2)
    assert len(segs) == 1 and segs[0].t0_s >= 120.0
    # A NaN sample spoils its window only.
    gyro[6000, 0] = np.nan
    det = StreamingStill()
    assert len(_stream(det, t, gyro, accel, moving=turn)) == 3 and det.rejected['non-finite'] == 1
    with pytest.raises(ValueError, match='window_s'):
        StreamingStill(0.0)


def test_window_statistics_over_several_passes_are_each_windows_own():
    # 2 h at 20 Hz with a drive, a NaN and a motion report: 144,000 samples, more than one
    # pass of the window sums; every window's mean and std (ddof 1) is its own, a row with a
    # NaN counting as zeros and flagging its window.
    t, gyro, accel = _rest(7200.0)
    _drive(t, gyro, accel, 3000.0, 3600.0)
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


def _windows_one_by_one(det, t, gyro, accel, temp):
    out = []
    for k in range(t.size):
        w = det.add(float(t[k]), gyro[k].tolist(), accel[k].tolist(), temp_c=float(temp[k]))
        if w is not None:
            out.append(w)
    return out


def _key(w):
    return (w.t0, w.t1, w.n, w.gyro_mean, w.gyro_std, w.accel_std, w.temp_c, w.why,
            w.thresholds, w.t_next)


@pytest.mark.parametrize('cut', ['grid', 'span'])
def test_still_windows_sample_by_sample_equal_chunk_by_chunk(cut):
    """One sample at a time (the compensator) or in chunks (the learner): the same bits."""
    t, gyro, accel = _rest(900.0, seed=13)
    _drive(t, gyro, accel, 300.0, 420.0)
    temp = 20.0 + t / 600.0
    one = _windows_one_by_one(StillWindows(10.0, cut=cut), t, gyro, accel, temp)
    det = StillWindows(10.0, cut=cut)
    chunks = []
    for lo, hi in ((0, 7), (7, 4000), (4000, 4001), (4001, t.size)):
        chunks += det.extend(t[lo:hi], gyro[lo:hi], accel[lo:hi], temp[lo:hi])
    assert len(one) == len(chunks) > 80
    assert [_key(w) for w in one] == [_key(w) for w in chunks]
    assert {w.why for w in one[30:42]} <= {'gyro', 'accel'} and one[0].why == ''
    # 'span' windows end with their first sample window_s after the first one (201 at 20 Hz).
    assert one[0].n == (201 if cut == 'span' else 200)


def test_still_windows_are_the_batch_forms_windows():
    """The streaming windows on the grid are detect_still's: statistics and verdict."""
    t, gyro, accel = _rest(1200.0, seed=14)
    _drive(t, gyro, accel, 500.0, 700.0)
    opts = {'gyro_std': 0.01, 'accel_std': 0.2}
    batch = detect_still(t, gyro, accel, window_s=10.0, min_still_s=0.0, **opts)
    det = StillWindows(10.0, **opts)
    wins = det.extend(t, gyro, accel)
    last = det.flush()
    wins.append(last)
    assert [w.n for w in wins] == batch.counts.tolist()
    assert [w.t0 for w in wins] == t[batch.starts].tolist()
    np.testing.assert_allclose([w.gyro_mean for w in wins], batch.gyro_mean, rtol=0, atol=1e-15)
    np.testing.assert_allclose([w.gyro_std for w in wins], batch.gyro_std, rtol=1e-9)
    np.testing.assert_allclose([w.accel_std for w in wins], batch.accel_std, rtol=1e-9)
    assert [w.why for w in wins] == batch.why.tolist()
    assert det.flush() is None and det.window_end is None


def test_still_windows_floor_prior_motion_and_samples():
    t, gyro, accel = _rest(200.0, seed=15)
    det = StillWindows(10.0, prior_std=[1e-6] * 3)
    wins = det.extend(t, gyro, accel)
    # The prior holds the first NOISE_WINDOWS - 1 windows below 4e-6 rad/s: refused.
    assert [w.why for w in wins[:3]] == ['gyro', 'gyro', '']
    np.testing.assert_array_equal(det.gyro_floor, np.min([w.gyro_std for w in wins], axis=0))
    # A report holds until the next; a window overlapping motion is vetoed (the first
    # window judged here is the one in progress before, 190 .. 200 s).
    det.observe_motion(205.0, True)
    det.observe_motion(212.0, False)
    t2 = 200.0 + t[:800]
    wins = det.extend(t2, gyro[:800], accel[:800])
    assert [(w.t0, w.why) for w in wins] == [(190.0, ''), (200.0, 'motion'), (210.0, 'motion'),
                                             (220.0, '')]
    assert det.motion.reports == [(212.0, False)]
    # Too few samples (below min_samples) is never still; a NaN spoils its window only.
    few = StillWindows(10.0, min_samples=50)
    assert {w.why for w in few.extend(t[::10], gyro[::10])} == {'samples'}
    g = gyro.copy()
    g[250, 1] = np.nan
    assert [w.why for w in StillWindows(10.0).extend(t, g)][:3] == ['', 'non-finite', '']
    with pytest.raises(ValueError, match='cut'):
        StillWindows(10.0, cut='other')


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
