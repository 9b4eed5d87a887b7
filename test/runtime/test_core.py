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

"""The compensator's pure decision logic (no rclpy): hold, staleness, re-anchoring, policies."""

from __future__ import annotations

from dataclasses import fields, replace
import math

from gyro_tdc.identify import fit_model
from gyro_tdc.learn.learner import learned_model, Learner
from gyro_tdc.model.compensation import compensate, model_temperature, StreamingCompensator
from gyro_tdc.model.effects import batch_features, EFFECTS, STATIC_EFFECTS
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.flags import (describe_flags, NO_MODEL, NO_TEMPERATURE, NON_FINITE,
                                    OUT_OF_RANGE, PASSTHROUGH, STALE)
from gyro_tdc.runtime.health import health
from gyro_tdc.runtime.policy import PARAMS, Policy
from gyro_tdc.runtime.priming import prepare
import numpy as np
import pytest
from synth import synth_run

DEG = math.pi / 180.0


@pytest.fixture(scope='module')
def model():
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)
    return fit_model([run], features=('dT', 'dT2', 'dTdt', 'lag', 'warmup'), n_centers=10,
                     fit_params=False)


def stream(n=3000, rate_hz=100.0, temp_hz=1.0, seed=0, t_lo=0.0, t_hi=40.0):
    """Return IMU stamps, raw rates and thermometer samples of a short warming run."""
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(n) / rate_hz
    tt = 1000.0 + np.arange(0.0, n / rate_hz + 1.0, 1.0 / temp_hz) - 0.25
    tc = np.linspace(t_lo, t_hi, tt.size) + rng.normal(0, 0.01, tt.size)
    omega = rng.normal(0.0, 1e-3, (n, 3)) + 0.01
    return t, omega, tt, tc


def zoh(t, tt, tc):
    """Return the thermometer reading held at each IMU stamp (latest at or before)."""
    idx = np.searchsorted(tt, t, side='right') - 1
    assert np.all(idx >= 0)
    return tc[idx]


def run_core(core, t, omega, tt, tc):
    """Feed temperatures and samples in stamp order; return outputs, variances, flags."""
    out, var, flags = [], [], []
    j = 0
    for i in range(t.size):
        while j < tt.size and tt[j] <= t[i]:
            core.add_temperature(tt[j], tc[j])
            j += 1
        ox, oy, oz, v, f, _, _ = core.process(t[i], *omega[i])
        out.append((ox, oy, oz))
        var.append(v)
        flags.append(f)
    return np.array(out), np.array(var), np.array(flags)


def test_policy_checks_choices_and_ranges():
    with pytest.raises(ValueError, match='stale_policy'):
        Policy(stale_policy='drop')
    with pytest.raises(ValueError, match='out_of_range'):
        Policy(out_of_range='wrap')
    with pytest.raises(ValueError, match='temperature_timeout'):
        Policy(temperature_timeout=0.0)
    with pytest.raises(ValueError, match='passthrough_variance'):
        Policy(passthrough_variance=-1.0)


def test_policy_is_built_from_the_parameter_table():
    rows = [s for s in PARAMS if s.policy]
    assert [f.name for f in fields(Policy)] == [s.name for s in rows]
    assert Policy() == Policy(**{s.name: s.default for s in rows})
    assert len(rows) == 18 and {'model_file', 'queue_depth', 'raw_cdr', 'executor'}.isdisjoint(
        f.name for f in fields(Policy))
    with pytest.raises(ValueError, match='still_window'):
        Policy(still_window=math.nan)
    with pytest.raises(ValueError, match='still_accel_std'):
        Policy(still_accel_std=math.inf)
    assert Policy(stale_variance=0.0, still_window=1e9).still_window == 1e9  # sign only
    with pytest.raises(AttributeError):
        Policy().stale_policy = 'passthrough'  # frozen


def test_stream_equals_offline_compensation(model):
    t, omega, tt, tc = stream()
    core = CompensatorCore(Policy(reanchor_on_start=False), model)   # the arithmetic alone
    out, var, flags = run_core(core, t, omega, tt, tc)
    ref = compensate(model, t, zoh(t, tt, tc), omega)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    assert not flags.any()
    np.testing.assert_array_equal(var, np.tile(model.residual_var, (t.size, 1)))
    assert core.counts == {'in': t.size, 'out': t.size, 'compensated': t.size}


def test_static_effects_depend_on_temperature_only():
    rng = np.random.default_rng(7)
    temp = rng.uniform(-20, 60, 200)
    t1 = np.sort(rng.uniform(0, 1e4, 200))
    t2 = np.sort(rng.uniform(5e4, 9e4, 200))
    ids = sorted(STATIC_EFFECTS)
    assert set(ids) <= set(EFFECTS)
    np.testing.assert_array_equal(batch_features(ids, t1, temp, t0=25.0),
                                  batch_features(ids, t2, temp, t0=25.0))
    for dynamic in set(EFFECTS) - STATIC_EFFECTS:
        assert not np.array_equal(batch_features([dynamic], t1, temp, t0=25.0),
                                  batch_features([dynamic], t2, temp, t0=25.0)), dynamic


@pytest.mark.parametrize('mode', ['clamp', 'extrapolate'])
def test_static_model_fast_path_is_bit_identical_to_step(mode):
    run = synth_run(hours=1.0, rate_hz=2.0, ref_dps=(20.0, -10.0, 5.0), ref_period_s=300.0,
                    scale=(1e-3, -2e-3, 5e-4), seed=9)
    static = fit_model([run], features=('dT', 'dT2', 'scale'), n_centers=8)
    assert np.any(static.scale != 0.0)
    lo, hi = static.temp_range_c
    t, omega, tt, tc = stream(n=2000, rate_hz=50.0, t_lo=lo - 5.0, t_hi=hi + 5.0)
    core = CompensatorCore(Policy(out_of_range=mode, reanchor_on_start=False), static)
    out, _, flags = run_core(core, t, omega, tt, tc)
    step = StreamingCompensator(static, out_of_range=mode)
    temp = zoh(t, tt, tc)
    ref = np.array([step.step(t[i], temp[i], omega[i]) for i in range(t.size)])
    np.testing.assert_array_equal(out, ref)
    assert (flags == OUT_OF_RANGE).any() and (flags == 0).any()


def test_no_model_and_no_temperature_pass_through(model):
    core = CompensatorCore(Policy(passthrough_variance=0.5))
    assert core.process(1.0, 0.1, 0.2, 0.3) == (0.1, 0.2, 0.3, (0.5, 0.5, 0.5),
                                                NO_MODEL | PASSTHROUGH, None, None)
    core.set_model(model)
    r = core.process(2.0, 0.1, 0.2, 0.3)
    assert r[:3] == (0.1, 0.2, 0.3) and r[4] == NO_TEMPERATURE | PASSTHROUGH
    core.add_temperature(5.0, 20.0)
    # A thermometer sample stamped after the IMU sample is not used for it.
    assert core.process(4.0, 0.1, 0.2, 0.3)[4] == NO_TEMPERATURE | PASSTHROUGH
    assert core.process(5.0, 0.1, 0.2, 0.3)[4] == 0
    assert core.counts == {'in': 4, 'out': 4, 'compensated': 1}
    assert describe_flags(NO_TEMPERATURE | PASSTHROUGH) == \
        'no temperature yet, raw rate passed through'


def test_non_finite_passes_through_flagged(model):
    core = CompensatorCore(Policy(), model)
    core.add_temperature(0.0, 20.0)
    for bad in (math.nan, math.inf, -math.inf):
        r = core.process(1.0, 0.1, bad, 0.3)
        assert r[0] == 0.1 and r[2] == 0.3 and (r[1] == bad or math.isnan(bad))
        assert r[4] == NON_FINITE | PASSTHROUGH
    assert core.process(math.nan, 0.1, 0.2, 0.3)[4] == NON_FINITE | PASSTHROUGH
    assert core.flag_counts[NON_FINITE] == 4
    assert core.process(1.0, 0.1, 0.2, 0.3)[4] == 0


@pytest.mark.parametrize('learn', [False, True])
def test_a_stamp_that_is_no_time_passes_through_and_changes_nothing(model, learn):
    # An infinite stamp was a session break (the held temperature dropped: the next samples
    # said "no temperature yet"); while learning it reached the install of a model not
    # queued (+inf >= +inf, AttributeError) and set the learner's hand-off clock to +inf.
    from gyro_tdc.learn.learner import Learner
    core = CompensatorCore(Policy(), model)
    core.learner = Learner(prior=model) if learn else None
    core.add_temperature(0.0, 20.0)
    assert core.process(0.5, 0.1, 0.2, 0.3)[4] == 0
    for bad in (math.inf, math.nan, -math.inf):
        assert core.process(bad, 0.1, 0.2, 0.3)[4] == NON_FINITE | PASSTHROUGH
    assert core.process(1.0, 0.1, 0.2, 0.3)[4] == 0
    assert core.flag_counts[NON_FINITE] == 3 and core.reanchoring.sessions.session == 1
    if learn:                         # the hand-off still runs by the stamps' clock
        assert core.learning.next < math.inf


@pytest.mark.parametrize('policy', ['hold', 'passthrough'])
def test_stale_temperature(model, policy):
    core = CompensatorCore(Policy(temperature_timeout=2.0, stale_policy=policy,
                                  stale_variance=0.25, passthrough_variance=0.5), model)
    core.add_temperature(10.0, 20.0)
    assert core.process(12.0, 0.1, 0.2, 0.3)[4] == 0
    fresh = CompensatorCore(Policy(), model)
    fresh.add_temperature(10.0, 20.0)
    fresh.process(12.0, 0.1, 0.2, 0.3)
    expect = fresh.process(12.5, 0.1, 0.2, 0.3)
    r = core.process(12.5, 0.1, 0.2, 0.3)
    assert core.temperature_age() == pytest.approx(2.5)
    if policy == 'hold':
        assert r[4] == STALE
        assert r[:3] == pytest.approx(expect[:3], abs=1e-15)
        assert r[3] == pytest.approx(tuple(v + 0.25 for v in model.residual_var))
    else:
        assert r == (0.1, 0.2, 0.3, (0.5, 0.5, 0.5), STALE | PASSTHROUGH, None, None)
    core.add_temperature(12.6, 21.0)
    assert core.process(12.7, 0.1, 0.2, 0.3)[4] == 0
    assert core.flag_counts[STALE] == 1


@pytest.mark.parametrize('mode', ['clamp', 'extrapolate'])
def test_out_of_range(model, mode):
    lo, hi = model.temp_range_c
    # The range is the model temperature's (the lagged state, tau = 120 s): 1000 s of data.
    t, omega, tt, tc = stream(n=500, rate_hz=0.5, t_lo=hi - 5.0, t_hi=hi + 10.0)
    core = CompensatorCore(Policy(out_of_range=mode, out_of_range_variance=0.125,
                                  reanchor_on_start=False), model)
    out, var, flags = run_core(core, t, omega, tt, tc)
    temp = zoh(t, tt, tc)
    outside = model_temperature(model, t, temp) > hi
    assert outside.any() and (~outside).any()
    np.testing.assert_array_equal(flags == OUT_OF_RANGE, outside)
    ref = compensate(model, t, temp, omega, clamp=mode == 'clamp')
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(var[outside], np.tile(model.residual_var + 0.125,
                                                     (outside.sum(), 1)))


def test_reload_same_model_mid_stream_carries_filters_on(model):
    t, omega, tt, tc = stream(n=4000, rate_hz=10.0, temp_hz=1.0)
    core = CompensatorCore(Policy(reanchor_on_start=False), model)
    half = t.size // 2
    first, _, _ = run_core(core, t[:half], omega[:half], tt[tt <= t[half - 1]],
                           tc[tt <= t[half - 1]])
    core.set_model(model)  # reload: primed from the temperature history
    later = tt > t[half - 1]
    second, _, _ = run_core(core, t[half:], omega[half:], tt[later], tc[later])
    ref = compensate(model, t, zoh(t, tt, tc), omega)
    np.testing.assert_allclose(first, ref[:half], rtol=0, atol=1e-12)
    # Warm-up restarts nowhere; the lag filters resume from a 1 s decimated replay.
    np.testing.assert_allclose(second, ref[half:], rtol=0, atol=2e-4 * DEG)
    unprimed = CompensatorCore(Policy(reanchor_on_start=False), model)
    cold, _, _ = run_core(unprimed, t[half:], omega[half:], tt[tt > t[half] - 1.0],
                          tc[tt > t[half] - 1.0])
    assert np.abs(cold - ref[half:]).max() > 10 * np.abs(second - ref[half:]).max()


def test_reanchor_on_start(model):
    t, omega, tt, tc = stream(n=3000, rate_hz=100.0, t_lo=20.0, t_hi=20.5)
    omega = omega - 0.01  # zero mean around the true rate ...
    offset = np.array([0.9e-3, -0.5e-3, 0.3e-3])  # ... plus a session bias offset
    temp = zoh(t, tt, tc)
    drift = -compensate(model, t, temp, np.zeros_like(omega))  # the model has no scale
    raw = omega + drift + offset
    core = CompensatorCore(Policy(reanchor_on_start=True, still_window=5.0), model)
    out, _, _ = run_core(core, t, raw, tt, tc)
    assert core.anchor is not None
    assert core.anchor.t == pytest.approx(t[0] + 5.0, abs=0.011)
    after = t > core.anchor.t
    assert np.abs(out[after].mean(axis=0)).max() < 2e-4
    assert np.abs(out[~after].mean(axis=0) - offset).max() < 2e-4
    # Without re-anchoring the offset stays.
    plain = CompensatorCore(Policy(reanchor_on_start=False), model)
    kept, _, _ = run_core(plain, t, raw, tt, tc)
    np.testing.assert_allclose(kept.mean(axis=0), offset, atol=2e-4)
    assert plain.anchor is None


def test_prepare_off_thread_then_install_equals_an_install_in_place(model):
    """prepare() on a copy while samples keep coming, install() later: the same bits."""
    t, omega, tt, tc = stream(n=6000, rate_hz=10.0, temp_hz=1.0, seed=6)
    third = t.size // 3

    def run_until(core, k0, k1):
        sel = (tt > (t[k0 - 1] if k0 else -np.inf)) & (tt <= t[k1 - 1])
        return run_core(core, t[k0:k1], omega[k0:k1], tt[sel], tc[sel])[0]

    split, whole = CompensatorCore(Policy(), model), CompensatorCore(Policy(), model)
    run_until(split, 0, third)
    run_until(whole, 0, third)
    prepared = prepare(model, split.policy, split.priming())  # the worker's part
    run_until(split, third, 2 * third)  # the stream goes on while the file is read
    run_until(whole, third, 2 * third)
    split.install(prepared)
    whole.set_model(model)
    np.testing.assert_array_equal(run_until(split, 2 * third, t.size),
                                  run_until(whole, 2 * third, t.size))


def test_reinstalling_the_same_model_keeps_the_reanchoring(model):
    t, omega, tt, tc = stream(n=1000, rate_hz=100.0, t_lo=20.0, t_hi=20.2)
    raw = omega - 0.01 + [0.9e-3, -0.5e-3, 0.3e-3] - compensate(
        model, t, zoh(t, tt, tc), np.zeros_like(omega))
    core = CompensatorCore(Policy(reanchor_on_start=True, still_window=5.0), model)
    out, _, _ = run_core(core, t, raw, tt, tc)
    anchor = core.anchor
    assert anchor is not None
    core.set_model(model)
    assert core.anchor is anchor
    again = core.process(t[-1], *raw[-1])
    # The shift (~1e-3 rad/s) is still applied; the dynamic filters resume from the replay.
    assert np.abs(anchor.delta).min() > 2e-4
    np.testing.assert_allclose(again[:3], out[-1], rtol=0, atol=1e-6)
    other = fit_model([synth_run(hours=1.0, rate_hz=2.0, seed=8)], features=('dT',),
                      n_centers=4)
    core.set_model(other)
    assert core.anchor is None
    run_core(core, t + 20.0, raw, tt + 20.0, tc)
    assert core.anchor is not None and core.anchor.t > t[-1] + 20.0 - 15.0


def test_motion_reports_by_threshold_and_only_changes_passed_on():
    """CompensatorCore.motion: any component above motion_threshold (or NaN) is motion."""
    core = CompensatorCore(Policy(motion_threshold=0.01))
    core.learner = learner = Learner()
    assert core.moving is None
    assert core.motion(1.0, (0.0, 0.0, 0.0, 0.0, 0.0, 0.005)) is False
    assert core.motion(2.0, (0.0, 0.0, 0.0, 0.0, 0.0, -0.02)) is True
    assert core.motion(3.0, (0.5, 0.0, 0.0, 0.0, 0.0, 0.0)) is True
    assert core.motion(4.0, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)) is False
    assert core.motion(5.0, (math.nan, 0.0, 0.0, 0.0, 0.0, 0.0)) is True
    assert learner.motion == [(1.0, False), (2.0, True), (4.0, False), (5.0, True)]
    assert core.motion_reports == 5 and core.moving is True


def test_a_scheduled_model_is_installed_at_its_stamp_a_late_one_at_once(model):
    """CompensatorCore.schedule: the first message stamped at or after ``due`` uses it."""
    other = learned_model(np.array([[0.01, 0.0, 0.0], [1e-3, 0.0, 0.0]]), ('dT',), 20.0,
                          (0.0, 40.0), np.full(3, 1e-8))
    t, omega, tt, tc = stream(n=600, rate_hz=10.0)
    ref = CompensatorCore(Policy(), model)
    a = run_core(ref, t[:300], omega[:300], tt, tc)
    ref.set_model(other)                   # in place, just before sample 300
    b = run_core(ref, t[300:], omega[300:], tt, tc)
    core = CompensatorCore(Policy(), model)
    c = run_core(core, t[:100], omega[:100], tt, tc)
    core.schedule(other, float(t[300]))    # made ready at sample 100, due at 300
    assert core.model_id == model.model_id
    d = run_core(core, t[100:], omega[100:], tt, tc)
    assert core.model_id == other.model_id and core.learned_installs == 1
    for x, y in zip(a + b, (np.vstack([c[0], d[0][:200]]), np.vstack([c[1], d[1][:200]]),
                            np.r_[c[2], d[2][:200]], d[0][200:], d[1][200:], d[2][200:])):
        np.testing.assert_array_equal(x, y)
    # Late (its stamp already passed): installed at once; cancelled: never.
    core.schedule(model, float(t[50]))
    assert core.model_id == model.model_id and core.learned_installs == 2
    core.schedule(other, float(t[-1]) + 1.0)
    core.learning.cancel()
    core.process(float(t[-1]) + 2.0, *omega[-1])
    assert core.model_id == model.model_id and core.learned_installs == 2


def _session(model, t0, offset, seed, n=1500, rate_hz=100.0):
    """Return stamps, raw rates (still, the model's drift plus ``offset``) and temperatures."""
    t, omega, tt, tc = stream(n=n, rate_hz=rate_hz, seed=seed, t_lo=20.0, t_hi=20.3)
    t, tt = t - 1000.0 + t0, tt - 1000.0 + t0
    drift = -compensate(model, t, zoh(t, tt, tc), np.zeros_like(omega))
    return t, omega - 0.01 + drift + offset, tt, tc


@pytest.fixture(scope='module')
def static_model():
    return fit_model([synth_run(hours=1.0, rate_hz=2.0, seed=3)], features=('dT', 'dT2'),
                     n_centers=6)


@pytest.mark.parametrize('second_t0', [1000.0 + 15.0 + 3600.0, 10.0])
def test_a_power_cycle_starts_a_new_reanchoring(static_model, second_t0):
    """A 1 h pause, or stamps stepping back: the new session's offset is anchored anew."""
    policy = Policy(reanchor_on_start=True, still_window=5.0)
    core = CompensatorCore(policy, static_model)
    off1, off2 = np.array([0.9e-3, -0.5e-3, 0.3e-3]), np.array([-0.7e-3, 0.8e-3, -0.4e-3])
    t1, raw1, tt1, tc1 = _session(static_model, 1000.0, off1, seed=1)
    out1, _, _ = run_core(core, t1, raw1, tt1, tc1)
    first = core.anchor
    assert first is not None and core.reanchoring.sessions.session == 1
    np.testing.assert_allclose(first.delta, off1, atol=2e-4)
    assert health(core).values['reanchor'] == f'done at t={first.t:.3f} s'
    t2, raw2, tt2, tc2 = _session(static_model, second_t0, off2, seed=2)
    core.add_temperature(tt2[0], tc2[0])
    core.process(t2[0], *raw2[0])
    assert core.anchor is None and core.reanchoring.sessions.session == 2 and core.needs_accel
    why = 'gap of 3600 s' if second_t0 > 1000.0 else 'restart (stamps back by 1005 s)'
    assert health(core).values['reanchor'] == (
        f'waiting for stillness (session 2 from t={t2[0]:.3f} s, after a {why})')
    out2, _, _ = run_core(core, t2[1:], raw2[1:], tt2[1:], tc2[1:])
    second = core.anchor
    assert second is not None and second.t == pytest.approx(t2[0] + 5.0, abs=0.011)
    np.testing.assert_allclose(second.delta, off2, atol=2e-4)   # dropped the old shift
    after = t2[1:] > second.t
    assert np.abs(out2[after].mean(axis=0)).max() < 2e-4
    # Before the new anchor the model's own offset (no old shift) is what is left.
    assert np.abs(out2[~after].mean(axis=0) - off2).max() < 2e-4
    assert health(core).values['reanchor'].startswith(f'done at t={second.t:.3f} s (session 2')


def test_a_short_gap_or_reanchoring_off_keeps_the_session(static_model):
    off = np.array([0.9e-3, -0.5e-3, 0.3e-3])
    t1, raw1, tt1, tc1 = _session(static_model, 1000.0, off, seed=1)
    t2, raw2, tt2, tc2 = _session(static_model, 1000.0 + 15.0 + 590.0, off, seed=2)
    core = CompensatorCore(Policy(reanchor_on_start=True, still_window=5.0), static_model)
    run_core(core, t1, raw1, tt1, tc1)
    anchor = core.anchor
    out2, _, _ = run_core(core, t2, raw2, tt2, tc2)     # 590 s: the same power cycle
    assert core.anchor is anchor and core.reanchoring.sessions.session == 1
    assert np.abs(out2.mean(axis=0)).max() < 2e-4
    # A slow stream (10 s a sample): 100 periods (1000 s) is the gap, 700 s is no break.
    slow = CompensatorCore(Policy(reanchor_on_start=True, still_window=50.0), static_model)
    ts, raws, tts, tcs = _session(static_model, 0.0, off, seed=3, n=20, rate_hz=0.1)
    run_core(slow, ts, raws, tts, tcs)
    slow.process(ts[-1] + 700.0, *raws[-1])
    assert slow.reanchoring.sessions.session == 1
    slow.process(ts[-1] + 700.0 + 1100.0, *raws[-1])
    assert slow.reanchoring.sessions.session == 2
    # reanchor_on_start off: the sessions are counted, nothing is ever shifted.
    off_core = CompensatorCore(Policy(reanchor_on_start=False), static_model)
    run_core(off_core, t1, raw1, tt1, tc1)
    t3, raw3, tt3, tc3 = _session(static_model, 1000.0 + 15.0 + 3600.0, off, seed=2)
    out3, _, _ = run_core(off_core, t3, raw3, tt3, tc3)
    assert off_core.anchor is None and off_core.reanchoring.sessions.session == 2
    np.testing.assert_allclose(out3.mean(axis=0), off, atol=2e-4)
    assert health(off_core).values['reanchor'].startswith('off (session 2')


def test_a_model_of_the_offset_only_is_re_anchored_out_of_its_range(static_model):
    """Out of range a curve's shift would take in its extrapolation error; an offset has none."""
    flat = fit_model([synth_run(hours=1.0, rate_hz=2.0, seed=3)], features=())
    assert flat.features == () and flat.temp_range_c[1] < 55.0
    # The trainer's check keeps the features with zero shape terms where no axis's curve
    # carries: the same offset only.
    zeroed = replace(static_model, linear=np.zeros_like(static_model.linear),
                     weights=np.zeros_like(static_model.weights))
    offset = np.array([0.9e-3, -0.5e-3, 0.3e-3])
    for model, anchored in ((flat, True), (zeroed, True), (static_model, False)):
        t, omega, tt, tc = stream(n=1500, rate_hz=100.0, t_lo=60.0, t_hi=60.3)
        raw = omega - 0.01 - compensate(model, t, zoh(t, tt, tc), np.zeros_like(omega)) + offset
        core = CompensatorCore(Policy(reanchor_on_start=True, still_window=5.0), model)
        out, _, flags = run_core(core, t, raw, tt, tc)
        assert np.all(flags == OUT_OF_RANGE)            # flagged (and widened) either way
        assert (core.anchor is not None) is anchored
        if anchored:
            np.testing.assert_allclose(core.anchor.delta, offset, atol=2e-4)
            assert np.abs(out[t > core.anchor.t].mean(axis=0)).max() < 2e-4
        else:       # the curve's output is the same as without re-anchoring
            plain = CompensatorCore(Policy(reanchor_on_start=False), model)
            np.testing.assert_array_equal(out, run_core(plain, t, raw, tt, tc)[0])
