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

"""The streaming still test: windows one sample or one chunk at a time, the running floor."""

from __future__ import annotations

import math

from gyro_tdc.signal import detect_still, NOISE_FACTOR, StillWindows
import numpy as np
import pytest
from still_data import DEG, drive, RATE_HZ, rest
from streaming_still import StreamingStill

SIGMA = 5e-4


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
    t, gyro, accel = rest(2400.0, seed=7)
    drive(t, gyro, accel, 300.0, 700.0)
    drive(t, gyro, accel, 1000.0, 1045.0, seed=8)     # a stop of 5 min, then a short drive
    drive(t, gyro, accel, 1345.0, 1380.0, seed=9)     # a 25 s drive ...
    drive(t, gyro, accel, 1405.0, 1900.0, seed=10)    # ... a 25 s stop (too brief)
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
    t, gyro, accel = rest(1200.0, seed=11)
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
    t2, g2, a2 = rest(300.0, seed=12)
    drive(t2, g2, a2, 0.0, 120.0)
    det = StreamingStill(prior_std=[0.03 * DEG * math.sqrt(RATE_HZ)] * 3)
    segs = _stream(det, t2, g2, a2)
    assert len(segs) == 1 and segs[0].t0_s >= 120.0
    # A NaN sample spoils its window only.
    gyro[6000, 0] = np.nan
    det = StreamingStill()
    assert len(_stream(det, t, gyro, accel, moving=turn)) == 3 and det.rejected['non-finite'] == 1
    with pytest.raises(ValueError, match='window_s'):
        StreamingStill(0.0)


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
    t, gyro, accel = rest(900.0, seed=13)
    drive(t, gyro, accel, 300.0, 420.0)
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
    t, gyro, accel = rest(1200.0, seed=14)
    drive(t, gyro, accel, 500.0, 700.0)
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
    t, gyro, accel = rest(200.0, seed=15)
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


def _feed(still, t, gyro, accel=None, chunk=600):
    out = []
    for k in range(0, t.size, chunk):
        out += still.extend(t[k:k + chunk], gyro[k:k + chunk],
                            None if accel is None else accel[k:k + chunk])
    return out


def test_a_day_at_1hz_keeps_the_floor_near_the_noise_and_every_window_still():
    rng = np.random.default_rng(0)
    t = np.arange(86400.0)
    gyro = 0.01 + SIGMA * rng.standard_normal((t.size, 3))
    still = StillWindows(10.0, min_samples=3)
    wins = _feed(still, t, gyro)
    assert 0.5 * SIGMA < still.gyro_floor.min() and still.gyro_floor.max() < SIGMA
    assert np.mean([w.why == '' for w in wins]) > 0.999
    # The quietest single window of ten samples, the floor of old, sinks far below.
    lowest = np.min([min(w.gyro_std) for w in wins])
    assert lowest < 0.3 * SIGMA
    assert NOISE_FACTOR * lowest < SIGMA        # which refused most windows


def test_a_quantised_accelerometer_below_its_step_is_still():
    """Readings on few levels: the floor is the step's noise, not the mean's rounding."""
    rng = np.random.default_rng(1)
    t = np.arange(20000.0)
    gyro = SIGMA * rng.standard_normal((t.size, 3))
    accel = np.array([0.02, -0.03, 9.80665]) + 0.0015 * rng.standard_normal((t.size, 3))
    accel = np.round(accel / 0.0024) * 0.0024
    still = StillWindows(10.0, min_samples=3)
    wins = _feed(still, t, gyro, accel)
    assert np.all(still.accel_floor >= 0.0024 / math.sqrt(12.0) - 1e-12)
    assert np.mean([w.why == '' for w in wins]) > 0.99


def test_a_constant_axis_has_zero_scatter_and_no_floor():
    rng = np.random.default_rng(2)
    t = np.arange(2000.0) / 10.0
    gyro = SIGMA * rng.standard_normal((t.size, 3))
    gyro[:, 2] = 0.1 + 0.2                     # exactly one value (not exact in binary)
    still = StillWindows(10.0)
    wins = _feed(still, t, gyro)
    assert all(w.gyro_std[2] == 0.0 for w in wins)
    assert math.isinf(still.gyro_floor[2]) and np.isfinite(still.gyro_floor[:2]).all()
