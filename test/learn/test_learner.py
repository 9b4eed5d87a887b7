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

"""Online learning: vehicle day 1 then day 2, restart, growth, swap check."""

from __future__ import annotations

import json
import math

from gyro_tdc.learn.learner import LearnConfig, learned_model, Learner
from gyro_tdc.model.compensation import drift
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.runtime import CompensatorCore, Policy
from gyro_tdc.sim import simulate_run
from learning_days import BOUND, day_offset, DEG2, floor_ratio, stream
import numpy as np
import pytest
from thermal_synth import lag_run, OTHER


@pytest.fixture(scope='module')
def days():
    """Vehicle day 1 (seed 1) and day 2 (seed 2, hotter), 6 h each at 10 Hz."""
    return simulate_run('vehicle_day1', seed=1), simulate_run('vehicle_day2', seed=2)


def _new():
    core = CompensatorCore(Policy())
    learner = Learner()
    core.learner = learner
    return core, learner


@pytest.fixture(scope='module')
def uninterrupted(days):
    """Learn from nothing over day 1 then day 2; the day-2 output and the learner."""
    core, learner = _new()
    d1, d2 = days
    stream(core, learner, d1, 0.0)
    out, ok = stream(core, learner, d2, day_offset(days))
    return out, ok, learner


def test_no_model_day1_then_day2_within_the_noise_floor(days, uninterrupted):
    """Learn:=true, no model, fed day 1 then day 2: day 2 is within 1.3x the floor."""
    out, ok, learner = uninterrupted
    assert ok.all()                      # learned on day 1: day 2 is compensated throughout
    ratio = floor_ratio(days, out, ok)
    assert np.all(ratio <= BOUND), ratio
    s = learner.summary()
    assert s['features'] == ['dT', 'dT2', 'dT3'] and learner.session == 1
    lo, hi = s['covered_c']
    assert lo < 10.0 and hi > 30.0 and s['still_s'] > 0.45 * 2 * 21600.0
    assert s['swaps'] > 10 and s['check'].startswith('candidate')
    # Still time while heating and while cooling both made points (the morning, the stops).
    e = learner.entries()
    assert e.shape[0] > 40 and np.unique(e[:, 6]).tolist() == [0.0, 1.0]
    # Raw (no learning) is far off: the learning does the work.
    raw_ratio = ((days[1].gyro - days[1].ref) ** 2).mean(axis=0) * DEG2 / (
        days[1].truth.noise_std ** 2 * DEG2)
    assert np.all(raw_ratio > 20.0 * BOUND)


def test_restart_mid_day2_resumes_from_learn_file(days, uninterrupted, tmp_path):
    """Killed mid day 2 after a save: the restart resumes the saved state, nothing lost."""
    d1, d2 = days
    off = day_offset(days)
    path = tmp_path / 'learn.json'
    core, learner = _new()
    stream(core, learner, d1, 0.0)
    half = len(d2.imu_t) // 2
    saved = {}

    def save(k):
        if learner.save_due():
            learner.save(path)
            saved['state'] = json.loads(json.dumps(learner.state()))
            saved['k'] = k

    stream(core, learner, d2, off, stop=half, on_poll=save)
    kill = half                       # killed here: what came after the last save is lost
    assert saved['k'] < kill
    core2, learner2 = _new()
    assert learner2.load(path)
    assert json.loads(json.dumps(learner2.state())) == saved['state']
    model = learner2.take_model()
    assert model is not None
    core2.set_model(model)
    out2, ok2 = stream(core2, learner2, d2, off, start=kill)
    full_out, full_ok, full = uninterrupted
    r_full = floor_ratio(days, full_out[kill:], full_ok[kill:], kill)
    r_restart = floor_ratio(days, out2, ok2, kill)
    assert ok2.all()
    np.testing.assert_allclose(r_restart, r_full, rtol=0.03)
    assert np.all(r_restart <= BOUND)
    assert learner2.summary()['points'] >= full.summary()['points'] - 3


def test_poll_rate_does_not_change_what_is_learned(days):
    """All timing is by stamp: polling every 37 or 600 messages learns the same points."""
    d1 = days[0]
    a_core, a = _new()
    b_core, b = _new()
    stream(a_core, a, d1, 0.0, stop=40000)
    stream(b_core, b, d1, 0.0, stop=40000, poll=37)
    a.step()
    b.step()
    sa, sb = a.state(), b.state()
    assert sa['bins'] and sa['bins'] == sb['bins'] and sa['fit'] == sb['fit']
    assert sa['still_s'] == sb['still_s']


def _still(learner, t0, secs, bias, temp, rate=100.0, seed=0, moving_s=30.0):
    """Feed a still stretch (white noise around ``bias``) then some motion."""
    rng = np.random.default_rng(seed)
    n = int(secs * rate)
    t = t0 + np.arange(n) / rate
    learner.add_temperature(t[0], temp)
    noisy = np.asarray(bias) + 1e-4 * rng.standard_normal((n, 3))
    for ti, w in zip(t.tolist(), noisy.tolist()):
        learner.observe(ti, *w)
    m = int(moving_s * rate)
    tm = t[-1] + (1 + np.arange(m)) / rate
    for ti, w in zip(tm.tolist(), (0.3 * rng.standard_normal((m, 3))).tolist()):
        learner.observe(ti, *w)
    learner.step()
    return tm[-1] + 1.0 / rate


def test_growth_bias_then_dt_then_dt2():
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    t = 0.0
    t = _still(learner, t, 120.0, [0.01, -0.02, 0.005], 20.2)
    m = learner.take_model()
    assert m is not None and learner.fit['features'] == []      # bias only
    np.testing.assert_allclose(m.intercept, [0.01, -0.02, 0.005], atol=3e-5)
    np.testing.assert_allclose(m.linear, 0.0)
    for i, temp in enumerate((21.7, 23.4)):
        t = _still(learner, t, 120.0, [0.01 + 1e-3 * (temp - 20.2), -0.02, 0.005], temp,
                   seed=i + 1)
    assert learner.fit['features'] == ['dT']
    assert learner.fit['coef'][1][0] == pytest.approx(1e-3, rel=0.05)
    for i, temp in enumerate((25.0, 27.0, 29.5)):
        t = _still(learner, t, 120.0, [0.01 + 1e-3 * (temp - 20.2), -0.02, 0.005], temp,
                   seed=i + 5)
    assert learner.fit['features'] == ['dT', 'dT2']


def test_the_priors_offset_only_axes_stay_offset_only():
    """What train found to do harm across power cycles (y's curve) the learner never installs."""
    prior = learned_model(np.zeros((2, 3)), ('dT',), 20.2, (0.0, 40.0), np.full(3, 1e-6))
    prior = prior.replace(metrics={'held_out': {'curve': [True, False, True]}})
    learner = Learner(LearnConfig(temperature_timeout=1e9), prior=prior)
    t = 0.0
    for i, temp in enumerate((20.2, 21.7, 23.4, 25.0)):
        t = _still(learner, t, 120.0, [0.01 + 1e-3 * (temp - 20.2), 1e-3 * (temp - 20.2),
                                       0.005], temp, seed=i + 1)
    assert learner.fit['features'] == ['dT']
    assert learner.fit['coef'][1][0] == pytest.approx(1e-3, rel=0.05)
    m = learner.model
    assert m.linear[0, 1] == 0.0 and m.linear[0, 0] == pytest.approx(1e-3, rel=0.05)
    # y compensates a constant: the offset of the newest still time (its last stretches).
    recent = np.mean([1e-3 * (temp - 20.2) for temp in (21.7, 23.4, 25.0)])
    assert m.intercept[1] == pytest.approx(recent, abs=3e-4)


def test_a_better_prior_is_kept_and_an_outlier_is_dropped():
    truth = learned_model(np.array([[0.01, 0.0, 0.0], [1e-3, 0.0, 0.0]]), ('dT',), 20.0,
                          (0.0, 40.0), np.zeros(3))
    learner = Learner(LearnConfig(temperature_timeout=1e9), prior=truth)
    t = 0.0
    for i, temp in enumerate((18.0, 21.0, 24.0, 27.0)):
        t = _still(learner, t, 70.0, [0.01 + 1e-3 * (temp - 20.0), 0.0, 0.0], temp, seed=i)
    # The first candidate (one stretch, a bias only) may beat the prior only where the
    # prior is as good: the learned model is always as good on the recent stretches.
    c = learner.check
    assert c is not None and c['current_mse'] is not None
    # An outlier stretch (a slow constant turn that passed the still test) is dropped.
    t = _still(learner, t, 300.0, [0.2, 0.0, 0.0], 22.5, seed=9)
    for i, temp in enumerate((19.5, 25.5, 28.0)):
        t = _still(learner, t, 70.0, [0.01 + 1e-3 * (temp - 20.0), 0.0, 0.0], temp,
                   seed=20 + i)
    m = learner.model
    np.testing.assert_allclose(m.intercept[0] + m.linear[0, 0] * (25.0 - m.t0_c),
                               0.015, atol=5e-4)


def test_reset_and_bad_file(tmp_path):
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    _still(learner, 0.0, 120.0, [0.01, 0.0, 0.0], 20.0)
    assert learner.summary()['points'] == 1
    learner.reset()
    assert learner.summary()['points'] == 0 and learner.model is None
    bad = tmp_path / 'bad.json'
    bad.write_text('{"format": "other"}')
    with pytest.raises(ValueError, match='not a learner state'):
        learner.load(bad)
    assert not learner.load(tmp_path / 'missing.json')


def test_motion_reports_veto_a_slow_constant_turn(tmp_path):
    """A constant-rate turn has only noise-floor scatter: a motion report keeps it out."""
    turn = [0.05, 0.0, 0.0]          # rad/s, constant: passes the noise test alone
    # Without motion reports the (false) stillness is what the still test alone sees.
    alone = Learner(LearnConfig(temperature_timeout=1e9))
    _still(alone, 0.0, 300.0, turn, 20.0)
    assert alone.summary()['points'] == 1
    np.testing.assert_allclose(alone.model.intercept, turn, atol=3e-5)
    # Reported moving: nothing learned; the state (reports included) survives a restart.
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    learner.observe_motion(0.0, True)
    t = _still(learner, 0.0, 300.0, turn, 20.0)
    assert learner.summary()['points'] == 0 and learner.model is None
    path = tmp_path / 'learn.json'
    learner.save(path)
    again = Learner(LearnConfig(temperature_timeout=1e9))
    assert again.load(path) and again.motion == learner.motion == [(0.0, True)]
    t = _still(again, t, 120.0, turn, 20.0, seed=1)
    assert again.summary()['points'] == 0
    # Stopped: still time counts again, from the report on.
    again.observe_motion(t, False)
    _still(again, t, 120.0, [0.01, 0.0, 0.0], 20.0, seed=2)
    assert again.summary()['points'] == 1
    np.testing.assert_allclose(again.model.intercept, [0.01, 0.0, 0.0], atol=3e-5)


TAU_DIE = 300.0


def _feed(learner, run, start=0, stop=None, poll=600):
    """Feed a chamber run (10 Hz IMU, thermometer at 1 Hz), stepping every ``poll``."""
    stop = run.t.size if stop is None else stop
    for k in range(start, stop):
        if k % 10 == 0:
            learner.add_temperature(run.t[k], run.temp[k])
        learner.observe(run.t[k], *run.omega[k])
        if k % poll == poll - 1:
            learner.step()


def _lag_prior(thermal):
    """Return a prior that knows nothing of the drift (zero), with ``thermal``."""
    return learned_model(np.zeros((2, 3)), ('dT',), 20.0, (0.0, 60.0), np.full(3, 1e-6),
                         thermal)


@pytest.fixture(scope='module')
def lag_runs():
    """Return a chamber run to learn and one held out, the die 300 s behind the thermometer."""
    return (lag_run(seed=1, tau_die=TAU_DIE),
            lag_run(seed=2, tau_die=TAU_DIE, segments=OTHER))


def test_binning_at_the_model_temperature_removes_the_hysteresis(lag_runs):
    """Binned at the thermometer, heating and cooling disagree; at the prior's state, not."""
    train, held = lag_runs
    floor = (0.05 * math.pi / 180.0) ** 2
    heating = np.gradient(held.temp, held.t) > 5e-3
    cooling = np.gradient(held.temp, held.t) < -5e-3
    got = {}
    for name, thermal in (('state', ThermalState('first_order', (TAU_DIE,))),
                          ('thermometer', None)):
        learner = Learner(prior=_lag_prior(thermal))
        _feed(learner, train)
        learner.flush()
        m = learner.model
        assert m.thermal == thermal and learner.fit['features'] == ['dT', 'dT2', 'dT3']
        err = held.omega - drift(m, held.t, held.temp, out_of_range='linear')
        # Hysteresis: the mean error while heating minus that while cooling (x axis), deg/s.
        hyst = (err[heating, 0].mean() - err[cooling, 0].mean()) * 180.0 / math.pi
        got[name] = ((err ** 2).mean(axis=0) / floor, hyst)
    (with_state, hyst_state), (without, hyst_thermo) = got['state'], got['thermometer']
    assert np.all(with_state < 1.05), with_state          # measured 1.00 / 1.00 / 1.00
    assert without[0] > 1.8 and np.all(without > with_state + 0.2), without   # 2.08/1.61/1.28
    # Measured -0.00008 vs -0.0111 deg/s.
    assert abs(hyst_state) < 0.002 and abs(hyst_thermo) > 0.008, (hyst_state, hyst_thermo)


def test_thermal_state_persists_across_steps_and_a_restart(lag_runs, tmp_path):
    """The state streams across steps (any poll) and resumes from the learn file exactly."""
    train = lag_runs[0]
    thermal = ThermalState('two_node', (60.0, TAU_DIE))
    a, b = Learner(prior=_lag_prior(thermal)), Learner(prior=_lag_prior(thermal))
    half = 40000
    _feed(a, train, stop=half)
    _feed(b, train, stop=half, poll=37)
    a.step(force=True)
    b.step(force=True)
    want = thermal.temperature(train.t[:half], np.repeat(train.temp[:half:10], 10)[:half])
    for learner in (a, b):
        t_last, ys = learner.thermal_state
        assert t_last == train.t[half - 1]
        assert ys[-1] == pytest.approx(want[-1], abs=1e-9)
    # The same points whatever the poll (to rounding: the filter runs per batch).
    ba, bb = a.state()['bins'], b.state()['bins']
    assert ba.keys() == bb.keys() and len(ba) > 3
    for k in ba:
        np.testing.assert_allclose([e[2] for e in ba[k]], [e[2] for e in bb[k]], atol=1e-9)
        assert [e[:2] + e[3:] for e in ba[k]] == [e[:2] + e[3:] for e in bb[k]]
    path = tmp_path / 'learn.json'
    a.save(path)
    again = Learner(prior=_lag_prior(thermal))
    assert again.load(path) and again.thermal_state == a.thermal_state
    assert again.model.thermal == thermal and json.loads(path.read_text())['thermal'] == \
        thermal.to_dict()
    _feed(a, train, start=half, stop=half + 3000)
    _feed(again, train, start=half, stop=half + 3000)
    a.step(force=True)
    again.step(force=True)
    np.testing.assert_allclose(again.thermal_state[1], a.thermal_state[1], rtol=0, atol=1e-9)


def test_set_prior_keeps_points_of_the_same_thermal_section_only(lag_runs, tmp_path):
    train = lag_runs[0]
    lag = ThermalState('first_order', (TAU_DIE,))
    learner = Learner(prior=_lag_prior(lag))
    _feed(learner, train, stop=30000)
    learner.step()
    points = learner.summary()['points']
    assert points > 3 and learner.fit is not None
    path = tmp_path / 'learn.json'
    learner.save(path)
    # The same thermal section (a refitted model_file): points and state kept; the new
    # prior is current until a learned candidate predicts better.
    new = learned_model(np.array([[1e-3, 0, 0], [1e-4, 0, 0]]), ('dT',), 20.0, (0.0, 60.0),
                        np.full(3, 1e-6), ThermalState('first_order', (TAU_DIE,), ((200.0,
                                                                                   400.0),)))
    learner.set_prior(new)
    assert learner.summary()['points'] == points and learner.thermal_state is not None
    assert learner.model is new and learner.fit is None and learner.take_model() is None
    # Another thermal section: the points were binned at another temperature: dropped.
    other = _lag_prior(ThermalState('first_order', (100.0,)))
    learner.set_prior(other)
    assert learner.summary()['points'] == 0 and learner.thermal_state is None
    assert learner.model is other and learner.thermal == other.thermal
    _feed(learner, train, start=30000, stop=40000)
    learner.step()
    assert learner.summary()['points'] > 0 and learner.model.thermal == other.thermal
    # The same rule at load: restarted with a lag-free model_file, the saved points go.
    restarted = Learner(prior=_lag_prior(None))
    assert restarted.load(path) and restarted.summary()['points'] == 0
    assert restarted.model.thermal is None and restarted.take_model() is None
    # No prior and kind none are the same model temperature: nothing is dropped.
    plain = Learner(LearnConfig(temperature_timeout=1e9))
    _still(plain, 0.0, 120.0, [0.01, 0.0, 0.0], 20.0)
    plain.set_prior(_lag_prior(ThermalState('none')))
    assert plain.summary()['points'] == 1


def test_a_gap_inside_one_step_starts_a_new_session():
    """The night between two days starts a session even when one step spans it."""
    rng = np.random.default_rng(7)
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    for t0, bias, temp in ((0.0, 0.01, 20.0), (5000.0, 0.02, 20.2)):
        learner.add_temperature(t0, temp)
        t = t0 + np.arange(12000) / 100.0
        for ti, w in zip(t.tolist(), (bias + 1e-4 * rng.standard_normal((t.size, 3))).tolist()):
            learner.observe(ti, *w)
    learner.step()                       # one step over both days
    learner.flush()
    assert learner.session == 1
    e = learner.entries()
    assert sorted(set(e[:, 6].tolist())) == [0.0, 1.0]
    np.testing.assert_allclose(learner.model.intercept, [0.02] * 3, atol=3e-5)
