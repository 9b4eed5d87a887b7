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

"""Re-anchoring on bursty logs: the real PAN recording, bursts that are power cycles, batch."""

from __future__ import annotations

import math

from gyro_tdc.data import Run
from gyro_tdc.data.realdata import default_pan_csv, read_pan_cubesat_csv
from gyro_tdc.identify import fit_model
from gyro_tdc.model import compensate
from gyro_tdc.runtime.blockstats import block_length, EARLY_BLOCKS, window_stats
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.reanchor import reanchor_shift, StillnessDetector
from gyro_tdc.signal import STILL_WINDOW_S
import numpy as np
import pytest

DEG = math.pi / 180.0
#: A turn-on offset no model knows, rad/s.
OFFSET = np.array([0.3, -0.2, 0.25]) * DEG


@pytest.fixture(scope='module')
def pan():
    """Return the PAN recording (25 bursts of 5 s at 50 Hz, 300 s apart) and a model of it."""
    rec = read_pan_cubesat_csv(default_pan_csv())
    run = Run(rec.t, rec.temp_c, rec.gyro, np.zeros_like(rec.gyro), 'pan')
    return rec, fit_model([run], kind='poly', features=('dT', 'dT2'), t0=20.0)


def _stream(model, t, temp, raw):
    """Stream samples through a core with the node's defaults; return it and every anchor."""
    core = CompensatorCore(Policy(), model)
    anchors, prev, out = [], None, np.empty_like(raw)
    for i, (ts, tc, w) in enumerate(zip(t.tolist(), temp.tolist(), raw.tolist())):
        core.add_temperature(ts, tc)
        out[i] = core.process(ts, *w)[:3]
        a = core.anchor
        if a is not None and a is not prev:
            anchors.append((i, core.reanchoring.sessions.session, a))
        prev = a
    return core, anchors, out


def test_pan_recording_reanchors_on_its_first_burst(pan):
    """The real recording: one power cycle, anchored on its first 5 s burst, at the pause."""
    rec, model = pan
    raw = rec.gyro + OFFSET
    core, anchors, _ = _stream(model, rec.t, rec.temp_c, raw)
    assert core.reanchoring.sessions.session == 1            # 300 s pauses: no power cycle
    assert len(anchors) == 1
    i, _, a = anchors[0]
    # The window: the first burst (250 samples), ended by the pause, judged when the next
    # burst's first sample comes (i: the shift is in force from the one after it).
    assert a.reason == 'precision' and a.samples == 250 and i == 250
    assert rec.t[250] - rec.t[249] > 290.0
    assert a.t == rec.t[249] and a.duration_s == pytest.approx(rec.t[249] - rec.t[0])
    assert all(s <= v for s, v in zip(a.se, a.tolerance))
    # The shift is the mean of the model's output over those samples, its SE their blocks'.
    comp = compensate(model, rec.t[:250], rec.temp_c[:250], raw[:250])
    np.testing.assert_allclose(a.delta, comp.mean(axis=0), rtol=0, atol=1e-12)
    bs = block_length(STILL_WINDOW_S)
    assert window_stats(rec.t[:250], comp, comp[0], bs).m > 20
    k = np.floor((rec.t[:250] - rec.t[0]) / bs)
    means = [comp[k == v].mean(axis=0) for v in np.unique(k)]
    counts = np.array([np.count_nonzero(k == v) for v in np.unique(k)])
    mu = comp.mean(axis=0)
    m = len(means)
    se = np.sqrt(m / (m - 1) * sum(n ** 2 * (b - mu) ** 2 for n, b in zip(counts, means))) / 250
    np.testing.assert_allclose(a.se, se, rtol=1e-9)
    # The turn-on offset is found, up to the model's error over the burst.
    resid = compensate(model, rec.t[:250], rec.temp_c[:250], rec.gyro[:250]).mean(axis=0)
    np.testing.assert_allclose(np.asarray(a.delta) - OFFSET, resid, rtol=0, atol=1e-12)
    # The batch rule (evaluate --reanchor auto) takes the same samples.
    shift = reanchor_shift(rec.t, compensate(model, rec.t, rec.temp_c, raw),
                           tolerance=a.tolerance)
    assert (shift.samples, shift.reason) == (250, 'precision')
    np.testing.assert_allclose(shift.delta, a.delta, rtol=0, atol=1e-12)


@pytest.mark.parametrize('seed', range(8))
def test_pan_bursts_offset_within_its_standard_error(pan, seed):
    """
    The recording's stamps, thermometer and noise level, a drift the model knows.

    The truth is then the turn-on offset itself: the anchor finds it within 4 of its own SE.
    """
    rec, model = pan
    rng = np.random.default_rng(seed)
    drift = -compensate(model, rec.t, rec.temp_c, np.zeros_like(rec.gyro))
    sigma = np.sqrt(model.residual_var)
    raw = drift + OFFSET + rng.normal(0.0, 1.0, rec.gyro.shape) * sigma
    core, anchors, _ = _stream(model, rec.t, rec.temp_c, raw)
    assert len(anchors) == 1 and anchors[0][2].reason == 'precision'
    a = anchors[0][2]
    err = np.abs(np.asarray(a.delta) - OFFSET)
    assert np.all(err <= 4.0 * np.asarray(a.se)), err / np.asarray(a.se)


def _bursts(pause_s, n_bursts=6, burst_s=5.0, rate_hz=50.0, sigma=1e-3, seed=5,
            turn_on=True):
    """Return bursts (stamps, temperature, raw, noise-free raw, burst index) of a sensor."""
    rng = np.random.default_rng(seed)
    per = int(burst_s * rate_hz)
    t = np.concatenate([1000.0 + b * (burst_s + pause_s) + np.arange(per) / rate_hz
                        for b in range(n_bursts)])
    burst = np.repeat(np.arange(n_bursts), per)
    temp = np.round((30.0 - 0.5 * burst - 0.01 * (t - t[0]) / 3600.0) / 0.01) * 0.01
    offsets = rng.uniform(-0.4, 0.4, (n_bursts if turn_on else 1, 3)) * DEG
    if not turn_on:
        offsets = np.repeat(offsets, n_bursts, axis=0)
    clean = 2e-4 * (temp - 25.0)[:, None] + offsets[burst]      # a turn-on offset each
    return t, temp, clean + rng.normal(0.0, sigma, (t.size, 3)), clean, burst


@pytest.fixture(scope='module')
def line():
    """Return a line fitted on a continuous run of the bursts' sensor (no turn-on offset)."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 3600.0, 0.5)
    temp = 15.0 + 20.0 * t / t[-1]
    om = 2e-4 * (temp - 25.0)[:, None] + rng.normal(0.0, 1e-3, (t.size, 3))
    return fit_model([Run(t, temp, om, np.zeros_like(om), 'train')], kind='poly',
                     features=('dT',), t0=25.0)


def test_every_burst_a_power_cycle_anchors_within_the_burst(line):
    """
    Anchor each 5 s burst on its own samples when every burst is a power cycle.

    Pauses over BURST_MAX_S: from the second burst on (the stream has paused), each anchors
    before the burst ends (precision) and finds its own turn-on offset.
    """
    t, temp, raw, clean, burst = _bursts(pause_s=4000.0)
    core, anchors, out = _stream(line, t, temp, raw)
    truth = compensate(line, t, temp, clean)
    assert core.reanchoring.sessions.session == 6
    sessions = [s for _, s, _ in anchors]
    # The first burst: the stream has not paused yet, its window would span 10 s.
    assert sessions == [2, 3, 4, 5, 6]
    for i, s, a in anchors:
        b = s - 1
        assert burst[i] == b and a.reason == 'precision'
        assert a.duration_s < 5.0 and a.t < t[burst == b][-1]
        span = (t >= a.t - a.duration_s) & (t <= a.t)
        assert np.count_nonzero(span) == a.samples
        err = np.abs(np.asarray(a.delta) - truth[span].mean(axis=0))
        assert np.all(err <= 4.0 * np.asarray(a.se)), err / np.asarray(a.se)
        # After the anchor, the burst's output averages zero within the noise.
        after = (burst == b) & (np.arange(t.size) > i)
        assert np.count_nonzero(after) > 50
        assert np.all(np.abs(out[after].mean(axis=0)) < 4e-4)


def test_bursts_within_a_session_end_their_windows_early_once_paused():
    """300 s pauses (one session): windows end at the pause, then early, mid-burst."""
    t, _, raw, _, burst = _bursts(pause_s=300.0, seed=7, turn_on=False)
    det = StillnessDetector(STILL_WINDOW_S, window_max=600.0, tolerance=5e-5)
    found = [det.update(ts, w, w, None, 20.0) for ts, w in zip(t.tolist(), raw.tolist())]
    anchors = [(i, a) for i, a in enumerate(found) if a is not None]
    assert anchors and det.paused
    i, a = anchors[0]
    # Not precise over the first window (the first burst, ended by the pause): the next,
    # after the pause, ends once the two are, inside the second burst.
    assert a.reason == 'precision' and a.duration_s > 300.0 and a.samples > 250
    assert burst[i] == 1 and burst[i - 1] == 1 and burst[i + 1] == 1
    start = np.flatnonzero(burst == 1)[0]
    assert t[i - 1] - t[start + 1] >= (EARLY_BLOCKS - 1) * block_length(STILL_WINDOW_S)
    # The batch rule on the same samples (the stream is still throughout) agrees.
    shift = reanchor_shift(t, raw, tolerance=(5e-5,) * 3)
    assert (shift.samples, shift.reason) == (a.samples, 'precision')
    np.testing.assert_allclose(shift.delta, a.delta, rtol=0, atol=1e-12)


def test_a_continuous_stream_keeps_its_span_windows():
    """No pause, no early end: at 2 kHz the first anchor is still a whole 10 s window."""
    rng = np.random.default_rng(3)
    det = StillnessDetector(STILL_WINDOW_S, window_max=600.0, tolerance=1e-3)
    found = None
    for k in range(25000):
        w = (rng.normal(0.0, 1e-3, 3) + 0.002).tolist()
        found = det.update(k / 2000.0, w, w, None, 20.0)
        if found is not None:
            break
    assert found is not None and not det.paused
    assert found.duration_s >= STILL_WINDOW_S and found.samples == 20001


@pytest.mark.parametrize('shape', ['pause inside', 'paused before', 'continuous'])
def test_the_batch_rule_takes_the_samples_the_stream_does(shape):
    """reanchor_shift (evaluate --reanchor auto) and the streaming detector agree on bursts."""
    rng = np.random.default_rng(11)
    if shape == 'continuous':
        t = np.arange(6000) / 100.0
    else:
        one = np.arange(300) / 100.0               # 3 s bursts at 100 Hz, 60 s apart
        t = np.concatenate([k * 63.0 + one for k in range(8)])
    x = 0.001 + rng.normal(0.0, 2e-3, (t.size, 3))
    det = StillnessDetector(STILL_WINDOW_S, gyro_std=1.0, window_max=600.0,
                            tolerance=1e-4)
    if shape == 'paused before':                  # an earlier session of the logger
        for k in range(200):
            det.update(-5000.0 + k / 100.0, (0.0,) * 3, (0.0,) * 3, None, 20.0)
        det.reset()
    found = None
    for k, (ts, w) in enumerate(zip(t.tolist(), x.tolist())):
        found = det.update(ts, w, w, None, 20.0)
        if found is not None:
            break
    assert found is not None
    shift = reanchor_shift(t, x, tolerance=(1e-4,) * 3, paused=shape == 'paused before')
    assert (shift.samples, shift.reason) == (found.samples, found.reason) == (
        shift.samples, 'precision')
    assert shift.duration_s == pytest.approx(found.duration_s, abs=1e-9)
    np.testing.assert_allclose(shift.delta, found.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(shift.se, found.se, rtol=1e-9)
    assert det.paused == (shape != 'continuous')
    if shape == 'continuous':                      # whole windows only
        assert found.duration_s >= STILL_WINDOW_S and found.samples % 1001 == 0
    else:                                          # ended inside a burst
        k = int(np.searchsorted(t, found.t))
        assert t[k] == found.t and t[k + 1] - t[k] < 0.011 and t[k] - t[k - 1] < 0.011


def test_a_new_power_cycle_of_2khz_bursts_anchors_in_its_first_burst():
    """2 s bursts at 2 kHz every 2 min, then a power cycle: its first burst is anchored."""
    rng = np.random.default_rng(21)
    sigma = 0.02                                  # per sample (0.03 deg/s/sqrt(Hz) at 2 kHz)
    one = np.arange(4000) / 2000.0
    first = np.concatenate([k * 120.0 + one for k in range(6)])
    t = np.concatenate([first, first[-1] + 3600.0 + np.concatenate(
        [k * 120.0 + one for k in range(3)])])
    cycle = np.r_[np.zeros(first.size, int), np.ones(t.size - first.size, int)]
    temp = np.round((25.0 - 2.0 * (t - t[0]) / 3600.0) / 0.25) * 0.25
    offsets = np.array([[0.2, -0.3, 0.1], [-0.25, 0.15, 0.3]]) * DEG
    clean = 2e-4 * (temp - 25.0)[:, None] + offsets[cycle]
    train_t = np.arange(0.0, 3600.0, 0.01)
    train_temp = 30.0 - 20.0 * train_t / train_t[-1]
    om = 2e-4 * (train_temp - 25.0)[:, None] + rng.normal(0.0, sigma, (train_t.size, 3))
    model = fit_model([Run(train_t, train_temp, om, np.zeros_like(om), 'train')], kind='poly',
                      features=('dT',), t0=25.0)
    core, anchors, _ = _stream(model, t, temp, clean + rng.normal(0.0, sigma, clean.shape))
    assert core.reanchoring.sessions.session == 2
    truth = compensate(model, t, temp, clean)
    (i1, s1, a1), (i2, s2, a2) = anchors
    # The first cycle: its first burst, judged at the pause (the stream had not paused).
    assert s1 == 1 and i1 == 4000 and a1.samples == 4000
    # The new cycle: within its first burst, after EARLY_BLOCKS blocks.
    start = first.size
    assert s2 == 2 and start < i2 < start + 4000 and a2.reason == 'precision'
    assert a2.samples < 4000 and a2.duration_s < 2.0
    for i, a in ((i1, a1), (i2, a2)):
        span = (t >= a.t - a.duration_s) & (t <= a.t)
        err = np.abs(np.asarray(a.delta) - truth[span].mean(axis=0))
        assert np.all(err <= 4.0 * np.asarray(a.se)), err / np.asarray(a.se)
