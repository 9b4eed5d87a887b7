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

"""The stillness test (no rclpy): still, moving, shaken and slowly turning windows; the gate."""

from __future__ import annotations

import math

from gyro_tdc.base.limits import MAX_DRIFT_RAD_S
from gyro_tdc.identify import fit_model
from gyro_tdc.model import compensate
from gyro_tdc.runtime.blockstats import (block_length, BlockStats, default_tolerance, max_windows,
                                         standard_error, window_stats)
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.flags import PASSTHROUGH
from gyro_tdc.runtime.health import health
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.reanchor import (gated_shift, PROVISIONAL, REANCHOR_KEY, reanchor_shift,
                                       shift_gate, StillnessDetector)
from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run


def test_stillness_detector():
    rng = np.random.default_rng(1)
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    found = None
    for k in range(200):
        raw = 0.003 + rng.normal(0, 0.002, 3)
        found = det.update(k * 0.01, raw, raw - 0.001, (0.0, 0.0, 9.81), 20.0) or found
    assert found is not None and found.samples == 101
    assert found.delta == pytest.approx((0.002,) * 3, abs=1e-3)
    # Moving (a rate swing) or shaken (accelerometer spread) is not still.
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    for k in range(300):
        raw = (0.1 * math.sin(k / 10.0), 0.0, 0.0)
        assert det.update(k * 0.01, raw, raw, None, 20.0) is None
    for k in range(300, 600):
        acc = (rng.normal(0, 0.5), 0.0, 9.81)
        assert det.update(k * 0.01, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), acc, 20.0) is None
    assert det.windows_rejected >= 4
    # A slow constant turn has no spread but a mean above max_rate.
    det = StillnessDetector(window=1.0, gyro_std=0.01, max_rate=0.02, accel_std=0.05)
    for k in range(300):
        assert det.update(k * 0.01, (0.05, 0, 0), (0.05, 0, 0), None, 20.0) is None


def test_block_standard_error_is_the_cluster_formula():
    rng = np.random.default_rng(6)
    t = np.sort(rng.uniform(0.0, 3.0, 200))
    x = rng.normal(0.0, 1.0, (200, 3)) + [5.0, -2.0, 0.0]
    st = window_stats(t, x, (1.0, 1.0, 1.0), 0.25)
    k = np.floor((t - t[0]) / 0.25)
    blocks = [x[k == v] for v in np.unique(k)]
    mu = x.mean(axis=0)
    m = len(blocks)
    want = np.sqrt(m / (m - 1) * sum(len(b) ** 2 * (b.mean(axis=0) - mu) ** 2
                                     for b in blocks)) / len(x)
    np.testing.assert_allclose(standard_error(st), want, rtol=1e-10)
    assert (st.n, st.m) == (200, m)
    halves = window_stats(t[:90], x[:90], (1.0,) * 3, 0.25) + window_stats(
        t[90:], x[90:], (1.0,) * 3, 0.25)
    assert halves.n == 200
    assert standard_error(window_stats(t[:1], x[:1], (0.0,) * 3, 0.25)) == (math.inf,) * 3


def test_default_tolerance_and_window_counts():
    assert default_tolerance([4e-6, 1e-12, 0.0]) == pytest.approx((2e-4, 1e-5, 1e-5))
    assert max_windows(10.0, 600.0) == 60 and max_windows(10.0, 5.0) == 1
    assert block_length(10.0) == pytest.approx(0.2) and block_length(600.0) == 1.0
    with pytest.raises(ValueError, match='shape'):
        reanchor_shift(np.zeros(3), np.zeros((3, 2)), tolerance=[1.0] * 3)
    # Shorter than one window: every sample, said so.
    r = reanchor_shift(np.arange(5.0), np.ones((5, 3)), tolerance=[1.0] * 3)
    assert (r.samples, r.reason, r.delta) == (5, 'end of data', (1.0, 1.0, 1.0))


def _turn(det, t0, n, rate=0.01, seed=3):
    """Feed a slow constant-rate turn (noise-floor scatter, no accelerometer); anchors."""
    rng = np.random.default_rng(seed)
    anchors = []
    for k in range(n):
        raw = (rate + rng.normal(0, 1e-3), rng.normal(0, 1e-3), rng.normal(0, 1e-3))
        a = det.update(t0 + k * 0.01, raw, raw, None, 20.0)
        if a is not None:
            anchors.append(a)
    return anchors


def test_motion_reports_veto_a_slow_constant_turn():
    """A 0.01 rad/s turn has only the noise's scatter: only a motion report tells it."""
    # Without motion reports the detector alone sees stillness (false: the turn rate
    # becomes the anchor), which is what the veto is for.
    det = StillnessDetector(window=1.0, max_rate=0.02)
    anchors = _turn(det, 0.0, 500)
    assert anchors and anchors[0].delta[0] == pytest.approx(0.01, abs=1e-3)
    # Reported moving: no window is still, no anchor.
    det = StillnessDetector(window=1.0, max_rate=0.02)
    det.observe_motion(0.0, True)
    assert _turn(det, 0.0, 500) == [] and det.windows_rejected >= 4
    # Stopped at 5 s (the report holds until the next): anchors again after it only.
    det.observe_motion(5.0, False)
    anchors = _turn(det, 5.0, 300, rate=0.0)
    assert anchors and all(a.t - a.duration_s >= 5.0 for a in anchors)
    # A brief motion report inside a window vetoes that window only; reset keeps reports.
    det.reset()
    det.observe_motion(8.5, True)
    det.observe_motion(8.6, False)
    anchors = _turn(det, 8.0, 300, rate=0.0, seed=4)
    assert anchors and all(not (a.t - a.duration_s <= 8.5 <= a.t) for a in anchors)


def test_anchor_is_the_block_sums_of_its_windows_bit_for_bit():
    """The shift is the block sums of its windows: the batch rule's, exactly."""
    rng = np.random.default_rng(8)
    det = StillnessDetector(window=10.0, window_max=30.0, tolerance=1e-9)
    t = np.arange(3500) / 100.0 + 0.003 * rng.random(3500)
    out = 1e-3 * rng.standard_normal((3500, 3)) + 0.004
    found = None
    for k in range(3500):
        found = det.update(float(t[k]), (0.0, 0.0, 0.0), out[k].tolist(), None, 20.0) or found
    assert found is not None and found.reason == 'longest'
    # By hand: windows of 10 s from their first sample (that sample included), blocks of
    # block_length(10.0) (20 samples) from each window's start, sums in sample order around
    # out[0].
    c, i0, windows = out[0].tolist(), 0, []
    while len(windows) < 3:
        i1 = i0 + 1 + int(np.flatnonzero(t[i0 + 1:] - t[i0] >= 10.0)[0])
        windows.append((i0, i1 + 1))
        i0 = i1 + 1
    s, n = [0.0] * 3, 0
    for a, b in windows:                 # each window's sum of block sums, then the windows
        block, bs, ws = None, [0.0] * 3, [0.0] * 3
        for k in range(a, b):
            kb = math.floor((t[k] - t[a]) / block_length(10.0))
            if kb != block:
                ws = [u + v for u, v in zip(ws, bs)]
                block, bs = kb, [0.0] * 3
            bs = [u + (o - ci) for u, o, ci in zip(bs, out[k].tolist(), c)]
            n += 1
        s = [u + v for u, v in zip(s, [u + v for u, v in zip(ws, bs)])]
    assert found.samples == n
    assert found.delta == pytest.approx(tuple(ci + si / n for ci, si in zip(c, s)), rel=1e-12)
    st = sum((window_stats(t[a:b], out[a:b], c, block_length(10.0)) for a, b in windows),
             BlockStats())
    assert found.delta == tuple(ci + si / st.n for ci, si in zip(c, st.s))


def test_motion_that_ends_a_still_run_before_its_precision_gives_its_anchor():
    # 25 s still (two whole 10 s windows, the third cut by motion) with a tolerance never
    # met, then moving: the still windows' mean is the anchor ('motion'), not thrown away.
    rng = np.random.default_rng(4)
    det = StillnessDetector(window=10.0, window_max=60.0, gyro_std=0.01, max_rate=0.02,
                            tolerance=1e-9)
    t = np.arange(4000) / 100.0
    out = 1e-3 * rng.standard_normal((4000, 3)) + 0.004
    moving = t >= 25.0
    out[moving, 0] += 0.3 * np.sin(t[moving] * 5.0)
    found = [a for k in range(4000)
             if (a := det.update(float(t[k]), out[k].tolist(), out[k].tolist(), None, 20.0))]
    assert len(found) == 1 and found[0].reason == 'motion'
    a = found[0]
    # The two whole windows (each from its first sample to the first 10 s after it).
    i1 = int(np.flatnonzero(t >= 10.0)[0])
    n = i1 + 2 + int(np.flatnonzero(t[i1 + 1:] - t[i1 + 1] >= 10.0)[0])
    assert a.samples == n and t[n - 1] < 25.0          # still samples only
    assert a.delta == pytest.approx(out[:n].mean(axis=0), abs=1e-12)
    assert 20.0 <= a.t <= 25.0 and a.duration_s == pytest.approx(a.t, abs=0.02)
    # No still window before the motion: nothing to take.
    det = StillnessDetector(window=10.0, window_max=60.0, gyro_std=0.01, max_rate=0.02,
                            tolerance=1e-9)
    assert not any(det.update(float(t[k]), out[k].tolist(), out[k].tolist(), None, 20.0)
                   for k in range(4000) if t[k] >= 25.0)


def test_a_still_run_gives_its_shift_so_far_on_the_axes_already_known_to_be_off():
    """
    Until its anchor a still run offers its mean so far where it is 3 SE off zero.

    x is 4 mrad/s off, y and z on zero, 1 mrad/s noise at 100 Hz, a tolerance met after 60 s
    (window_max): after each 10 s window ``provisional`` holds the run's x mean so far and 0 on
    y and z (0.1 mrad/s SE), ``update`` returns nothing until the anchor, which clears it.
    """
    rng = np.random.default_rng(5)
    det = StillnessDetector(window=10.0, window_max=60.0, gyro_std=0.01, max_rate=0.02,
                            tolerance=1e-9)
    t = np.arange(7000) / 100.0
    out = 1e-3 * rng.standard_normal((7000, 3)) + [0.004, 0.0, 0.0]
    seen, found = [], []
    for k in range(7000):
        if (a := det.update(float(t[k]), out[k].tolist(), out[k].tolist(), None, 20.0)):
            found.append((k, a))
        if det.provisional is not None and (not seen or det.provisional is not seen[-1][1]):
            seen.append((k, det.provisional))
    assert [a.reason for _, a in found] == ['longest']
    assert len(seen) == 5 and all(p.reason == PROVISIONAL for _, p in seen)
    for k, p in seen:                    # each window's end: the run's mean so far
        assert 10.0 <= t[k] < found[0][0] / 100.0
        assert p.delta[0] == pytest.approx(out[:p.samples, 0].mean(), abs=1e-12)
        assert p.delta[1:] == (0.0, 0.0) and p.samples < found[0][1].samples
    assert det.provisional is None


@pytest.mark.parametrize('step', [0.0, 0.02])
def test_a_run_resumed_after_a_pause_keeps_what_came_before_only_where_it_agrees(step):
    """
    Keep a still run across a pause only while its mean agrees with the first window after.

    12 s still at 25 Hz, 30 s without samples (a logger that stopped), then 20 s still, a
    tolerance the first 12 s do not meet. With the same bias on both sides the first anchor
    averages both (a bursty logger's run goes on); with the bias stepped by 0.02 rad/s in the
    pause (a board warming after a cold start: over 100 standard errors) it is the second
    stretch's alone (before: the run mixed both, whose scatter kept it above the tolerance:
    no anchor; on a short run, a mix of both).
    """
    rng = np.random.default_rng(7)
    det = StillnessDetector(window=10.0, window_max=60.0, gyro_std=0.02, max_rate=0.05,
                            tolerance=1e-4)      # 12 s are not enough, 20 s are
    t = np.r_[np.arange(300) / 25.0, 42.0 + np.arange(500) / 25.0]
    out = 2e-3 * rng.standard_normal((t.size, 3)) + 0.004
    after = t > 40.0
    out[after] += step
    found = [a for k in range(t.size)
             if (a := det.update(float(t[k]), out[k].tolist(), out[k].tolist(), None, 20.0))]
    a = found[0]
    assert a.t > 42.0                                     # taken after the pause
    if step:
        assert a.delta == pytest.approx((0.004 + step,) * 3, abs=5e-4)
        assert a.duration_s < 20.0                        # the second stretch alone
    else:
        assert a.delta == pytest.approx((0.004,) * 3, abs=5e-4)
        assert a.duration_s > 42.0                        # from the first stretch on
    # The batch form (evaluate --reanchor auto) keeps the same rule.
    shift = reanchor_shift(t, out, tolerance=(1e-4,) * 3)
    assert shift.delta == pytest.approx(a.delta, abs=3e-4)
    assert (shift.duration_s < 20.0) == bool(step)
    # Data that end 4 s after the pause, inside the window after it: the windows before.
    cut = reanchor_shift(t[:400], out[:400], tolerance=(1e-4,) * 3)
    assert cut.reason == 'end of data' and cut.samples == 300
    assert cut.delta == pytest.approx((0.004,) * 3, abs=5e-4)


def _gated(model, gate_dps):
    """Return ``model`` carrying the trainer's gate (deg/s per axis)."""
    return model.replace(metrics={**model.metrics, REANCHOR_KEY: {'min_shift_dps': gate_dps}})


def test_the_gate_is_the_models_and_any_shift_without_one():
    model = fit_model([synth_run(hours=0.5, rate_hz=2.0, seed=2)], kind='poly', features='dT')
    assert shift_gate(None).tolist() == shift_gate(model).tolist() == [0.0, 0.0, 0.0]
    gated = _gated(model, [0.1, 0.0, float('nan')])
    np.testing.assert_allclose(shift_gate(gated), [math.radians(0.1), 0.0, 0.0])
    np.testing.assert_allclose(gated_shift(gated, [1e-3, 1e-3, -1e-3]), [0.0, 1e-3, -1e-3])
    np.testing.assert_allclose(gated_shift(gated, [3e-3, 0.0, 0.0]), [3e-3, 0.0, 0.0])
    for bad in ({}, {'min_shift_dps': [0.1, 0.2]}, {'min_shift_dps': 'x'}, [1, 2, 3]):
        broken = model.replace(metrics={REANCHOR_KEY: bad})
        assert shift_gate(broken).tolist() == [0.0, 0.0, 0.0]


def test_the_core_takes_no_shift_within_the_models_gate():
    """A start-up shift below an axis's gate is no evidence of a turn-on offset: not taken."""
    model = fit_model([synth_run(hours=0.5, rate_hz=2.0, seed=2, noise_dps=0.01)],
                      kind='poly', features='dT')
    rng = np.random.default_rng(4)
    t = 100.0 + np.arange(2000) / 100.0
    offset = np.array([0.9e-3, -0.5e-3, 0.3e-3])          # rad/s: 0.052, -0.029, 0.017 deg/s
    raw = (rng.normal(0.0, 1e-4, (t.size, 3)) + offset
           + compensate_zero(model, t, np.full(t.size, 25.0)))

    def anchor(m, **policy):
        core = CompensatorCore(Policy(**policy), m)
        for k in range(t.size):
            if k % 100 == 0:
                core.add_temperature(t[k], 25.0)
            core.process(t[k], *raw[k])
        return core.anchor

    free = anchor(model)
    np.testing.assert_allclose(free.delta, offset, atol=1e-4)
    gated = _gated(model, [0.1, 0.01, 0.1])                  # x and z within their gate
    held = anchor(gated)
    assert held.delta[0] == held.delta[2] == 0.0
    assert held.delta[1] == pytest.approx(free.delta[1], abs=1e-12)
    # Another averaging than the one the trainer measured: its gate does not apply.
    for policy in ({'reanchor_tolerance': 1e-5}, {'still_window': 5.0}):
        np.testing.assert_allclose(anchor(gated, **policy).delta, offset, atol=1e-4)


def compensate_zero(model, t, temp):
    """Return the model's drift (rad/s) along ``temp``: what the sensor adds to a zero rate."""
    return -compensate(model, t, temp, np.zeros((t.size, 3)))


def test_the_core_shifts_by_the_run_so_far_until_its_anchor():
    """
    Correct an offset known to 3 SE at the first still window, not only at the anchor.

    x 0.2 deg/s off, y and z on the model, 0.03 deg/s noise at 25 Hz (a flight controller's
    rest), a tolerance of 2e-5 rad/s (30 s of averaging): from the first window's end
    the x output is the offset minus the run's mean so far (within 4 SE of a window),
    y and z untouched; health says so. The anchor then averages the output as it was before
    the provisional shift: its shift is the offset, not a rest of it.
    """
    model = fit_model([synth_run(hours=0.5, rate_hz=2.0, seed=2, noise_dps=0.01)],
                      kind='poly', features='dT')
    rng = np.random.default_rng(6)
    t = 100.0 + np.arange(3000) / 25.0
    offset = np.radians([0.2, 0.0, 0.0])
    raw = (rng.normal(0.0, math.radians(0.03), (t.size, 3)) + offset
           + compensate_zero(model, t, np.full(t.size, 25.0)))
    core = CompensatorCore(Policy(reanchor_tolerance=2e-5), model)
    out, states = np.empty_like(raw), []
    for k in range(t.size):
        if k % 25 == 0:
            core.add_temperature(t[k], 25.0)
        out[k] = core.process(t[k], *raw[k])[:3]
        states.append(health(core).values['reanchor'])
    first = int(np.flatnonzero([s.startswith('averaging') for s in states])[0])
    final = int(np.flatnonzero([s.startswith('done') for s in states])[0])
    assert 9.9 < t[first] - t[0] < 10.5 and t[final] - t[first] > 15.0
    se = math.radians(0.03) / math.sqrt(250)
    mid = slice(first + 1, final)
    assert abs(out[mid, 0].mean()) < 4 * se < offset[0]
    np.testing.assert_allclose(out[:final, 1:], (raw - compensate_zero(
        model, t, np.full(t.size, 25.0)))[:final, 1:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(core.anchor.delta, offset, atol=4 * se)
    assert core.reanchoring.settled and core.anchor.reason == 'precision'


@settings(max_examples=12, deadline=None)
@given(offset=st.lists(st.floats(-0.015, 0.015), min_size=3, max_size=3),
       noise=st.floats(1e-5, 0.05), rate=st.sampled_from([1.0, 25.0, 200.0]),
       glitch=st.floats(0.0, 0.05), seed=st.integers(0, 2 ** 16))
@example(offset=[0.01, -0.005, 0.0], noise=0.01, rate=25.0, glitch=0.02, seed=1)  # shifts early
def test_provisional_shifts_on_hostile_still_streams_keep_the_output_finite_and_plausible(
        offset, noise, rate, glitch, seed):
    """
    Offsets up to still_max_rate, any noise, non-finite and implausible samples in a still run.

    Whatever the run's shift so far, every output is finite and corrected by at most
    MAX_DRIFT_RAD_S, a provisional or final shift is finite, and a shift in force is undone
    when the run restarts at a power cycle.
    """
    model = fit_model([synth_run(hours=0.5, rate_hz=2.0, seed=2, noise_dps=0.01)],
                      kind='poly', features='dT')
    rng = np.random.default_rng(seed)
    n = int(40.0 * rate)
    t = 100.0 + np.arange(n) / rate
    raw = rng.normal(0.0, noise, (n, 3)) + offset + compensate_zero(model, t,
                                                                    np.full(n, 25.0))
    bad = rng.random(n) < glitch
    raw[bad] = rng.choice([math.nan, math.inf, 1e6], size=(int(bad.sum()), 3))
    core = CompensatorCore(Policy(), model)
    shifts = []
    for k in range(n):
        core.add_temperature(t[k], 25.0)
        ox, oy, oz, _, flags, _, _ = core.process(t[k], *raw[k])
        if not flags & PASSTHROUGH:
            out = np.array([ox, oy, oz])
            assert np.all(np.isfinite(out))
            assert np.all(np.abs(out - raw[k]) <= MAX_DRIFT_RAD_S)
        if core.anchor is not None:
            shifts.append(core.anchor.delta)
    assert np.all(np.isfinite(np.asarray(shifts, dtype=float)))
    core.process(t[-1] + 7200.0, *offset)             # a power cycle: the shift undone
    assert core.anchor is None and not core.reanchoring.settled
