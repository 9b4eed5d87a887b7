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

"""
The thermal state: front end, identification of tau with its interval, format 2, streaming.

Scenarios from ``thermal_synth`` (a die lagging the thermometer, drift quadratic in the die
temperature, white noise 0.05 deg/s so the floor is 0.0025 (deg/s)^2); ``bench/
bench_thermal_state.py`` runs the full sweep of time constants and curvatures.
"""

import math

from gyro_tdc.errors import FeatureError, FitError, ModelFileError
from gyro_tdc.identify import (effective_samples, fit_model, profile_interval, TAU_BOUNDS,
                               THERMAL_CHOICES)
from gyro_tdc.model.compensation import (compensate, CompensationModel, drift, model_temperature,
                                         StreamingCompensator)
from gyro_tdc.model.modelfile import load_model, model_to_dict, save_model
from gyro_tdc.model.thermal_state import (SETTLE_TAUS, StreamingThermalState, THERMAL_KINDS,
                                          ThermalState)
from gyro_tdc.runtime import CompensatorCore, Policy
from gyro_tdc.runtime.health import health
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from thermal_synth import lag_run, OTHER
import yaml

FLOOR = 0.05 ** 2


def _bs(model, run):
    """Held-out BS per axis in units of the white-noise floor."""
    return bias_stability(compensate(model, run.t, run.temp, run.omega), run.omega_ref) / FLOOR


def _irregular(seed, n=2000):
    """Irregular stamps with repeats and a long gap, and a wandering temperature."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.05, 3.0, n))
    t[n // 3:] += 900.0                       # a gap of 15 min
    t[50:60] = t[50]                          # repeated stamps hold the state
    temp = 20.0 + np.cumsum(rng.normal(0.0, 0.3, n))
    return t, temp


# ----------------------------------------------------------------------------- front end

def test_kinds_fields_and_validation():
    assert THERMAL_KINDS == ('none', 'first_order', 'two_node')
    assert ThermalState().tau_s == () and ThermalState().tau_total_s == 0.0
    th = ThermalState('two_node', [30, 400.0], [[20, 40], [350, 480.0]], True)
    assert th.tau_s == (30.0, 400.0) and th.tau_total_s == 430.0
    assert th.tau_interval_s == ((20.0, 40.0), (350.0, 480.0))
    s = th.stream()                                    # settled SETTLE_TAUS x 430 s after
    s.update(0.0, 20.0)
    s.update(SETTLE_TAUS * 430.0, 20.0)
    assert s.settled and s.progress == SETTLE_TAUS
    for kw, msg in [({'kind': 'three_node'}, '`kind` must be one of none, first_order'),
                    ({'kind': []}, '`kind` must be one of none, first_order'),
                    ({'kind': {'a': 1}}, '`kind` must be one of none, first_order'),
                    ({'kind': 'first_order'}, r'`tau_s` must hold 1 time constant'),
                    ({'kind': 'none', 'tau_s': (5.0,)}, r'`tau_s` must hold 0'),
                    ({'kind': 'first_order', 'tau_s': (-1.0,)}, 'positive finite'),
                    ({'kind': 'first_order', 'tau_s': (math.inf,)}, 'positive finite'),
                    ({'kind': 'first_order', 'tau_s': (100.0,),
                      'tau_interval_s': ((110.0, 120.0),)}, 'must contain its time constant'),
                    ({'kind': 'first_order', 'tau_s': (100.0,), 'tau_interval_s': ((90,),)},
                     'one \\[lo, hi\\] per time constant'),
                    ({'kind': 'first_order', 'tau_s': (100.0,), 'identifiable': 'yes'},
                     '`identifiable` must be true, false or null')]:
        with pytest.raises(FeatureError, match=msg):
            ThermalState(**kw)


def test_dict_round_trip_and_describe():
    fitted = ThermalState('first_order', (417.2,), ((415.1, 420.1),), True)
    assert ThermalState.from_dict(fitted.to_dict()) == fitted
    assert fitted.to_dict() == {'kind': 'first_order', 'tau_s': [417.2],
                                'tau_interval_s': [[415.1, 420.1]], 'identifiable': True}
    assert fitted.describe() == ('thermal state: first-order lag, tau = 417.2 s '
                                 '(95 % interval 415.1..420.1 s)')
    flat = ThermalState('first_order', (42.5,), ((1.0, 83.5),), False)
    assert 'tau not identifiable from these data: profile flat over 1..83.5 s' in \
        flat.describe()
    assert 'given, not fitted' in ThermalState('first_order', (60.0,)).describe()
    assert 'no lag' in ThermalState().describe()
    with pytest.raises(FeatureError, match='missing field `tau_s`'):
        ThermalState.from_dict({'kind': 'none'})
    with pytest.raises(FeatureError, match=r"unknown field\(s\) \['tau'\]"):
        ThermalState.from_dict({'kind': 'none', 'tau_s': [], 'tau': 3})


@pytest.mark.parametrize('thermal', [ThermalState('first_order', (45.0,)),
                                     ThermalState('two_node', (12.0, 300.0)), ThermalState()])
@pytest.mark.parametrize('seed', [0, 1])
def test_streaming_state_equals_batch_on_irregular_stamps_with_a_gap(thermal, seed):
    t, temp = _irregular(seed)
    batch = thermal.temperature(t, temp)
    s = thermal.stream()
    stream = np.array([s.update(a, b) for a, b in zip(t, temp)])
    assert batch[0] == temp[0] == stream[0]            # starts at the first measurement
    np.testing.assert_allclose(stream, batch, rtol=1e-9, atol=1e-9)
    s.reset()
    assert s.value is None and s.update(t[5], temp[5]) == temp[5]


def test_settled_by_stamps_after_three_tau():
    s = StreamingThermalState(ThermalState('two_node', (20.0, 80.0)))
    assert not s.settled and s.progress == 0.0
    s.update(1000.0, 25.0)
    s.update(1299.0, 25.0)
    assert s.progress == pytest.approx(2.99) and not s.settled
    s.update(1290.0, 25.0)                             # an older stamp: no time passes
    assert s.progress * 100.0 == pytest.approx(299.0)
    s.update(1300.0, 25.0)
    assert s.settled and s.progress == pytest.approx(3.0)
    none = ThermalState().stream()
    none.update(5.0, 20.0)
    assert none.settled and none.progress == math.inf


# ----------------------------------------------------------------------------- identification

def test_effective_samples_counts_memory():
    rng = np.random.default_rng(0)
    white = rng.normal(size=(4096, 2))
    assert np.all(effective_samples(white) > 0.6 * 4096)
    ar = np.zeros(4096)
    e = rng.normal(size=4096)
    for k in range(1, 4096):
        ar[k] = 0.9 * ar[k - 1] + e[k]
    n_eff = effective_samples(ar)[0]
    assert 4096 * 0.02 < n_eff < 4096 * 0.1        # AR(1) 0.9: (1 - rho) / (1 + rho) = 0.053


def test_profile_interval_of_a_parabola_and_of_a_flat_profile():
    # SSE = n (1 + ((ln tau - ln 100) / 0.1)^2 / n): stat = n ln(SSE / SSE_min) ~ u^2 / 0.01,
    # so the 95 % interval is ln tau = ln 100 +- 0.1 sqrt(3.841).
    n = 1e6

    def sse(tau):
        u = math.log(tau / 100.0) / 0.1
        return np.array([n + u * u])

    prof = profile_interval(sse, 100.0, (1.0, 1e4), np.array([n]))
    half = 0.1 * math.sqrt(3.841)
    assert prof.interval[0] == pytest.approx(100 * math.exp(-half), rel=2e-3)
    assert prof.interval[1] == pytest.approx(100 * math.exp(half), rel=2e-3)
    assert prof.identifiable and prof.stat.min() == 0.0
    assert np.all(np.diff(prof.grid_tau) > 0)
    flat = profile_interval(lambda tau: np.array([1.0 + 1e-9 * tau]), 1.0, (1.0, 1e4),
                            np.array([100.0]))
    assert not flat.identifiable and flat.interval == (1.0, 1e4)
    wide = profile_interval(lambda tau: np.array([n + (math.log(tau / 100.0) / 2) ** 2]), 100.0,
                            (1.0, 1e4), np.array([n]))
    assert not wide.identifiable and wide.interval[1] / wide.interval[0] > 3.0
    with pytest.raises(FitError, match='0 < lo <= tau <= hi'):
        profile_interval(sse, 0.5, (1.0, 10.0), np.array([n]))


# (tau_die s, curvature): none, moderate and dominant curvature in die temperature.
SCENARIOS = [(60.0, 0.0), (420.0, 5.0), (900.0, 1.0)]


@pytest.fixture(scope='module', params=SCENARIOS, ids=lambda p: f'tau{p[0]:.0f}-c{p[1]:g}')
def scenario(request):
    tau, curvature = request.param
    train = lag_run(seed=11, tau_die=tau, curvature=curvature, rate_hz=5.0)
    test = lag_run(seed=12, tau_die=tau, curvature=curvature, segments=OTHER, rate_hz=5.0)
    return tau, curvature, train, test


@pytest.mark.parametrize('kind', ['poly', 'rbf'])
def test_tau_recovered_with_interval_and_held_out_at_the_floor(scenario, kind):
    tau, curvature, train, test = scenario
    model = fit_model([train], kind=kind, features=('dT', 'dT2', 'lag'))
    th = model.thermal
    assert model.format_version == 2 and th.kind == 'first_order'
    assert th.tau_s[0] == pytest.approx(tau, rel=0.1)
    lo, hi = th.tau_interval_s[0]
    assert lo <= tau <= hi and th.identifiable
    assert model.effect_params['lag'] == {'tau_s': th.tau_s[0]}
    assert model.inputs == ('dT', 'dT2')
    bs = _bs(model, test)
    assert np.all(bs <= 1.1), bs
    # The valid range is the state's, over the training data.
    s = th.temperature(train.t, train.temp)
    assert model.temp_range_c == (s.min(), s.max())
    prof = model.metrics['thermal']['profiles'][0]
    assert prof['interval_s'] == [lo, hi] and len(prof['profile_tau_s']) >= 20


def test_the_measured_temperature_model_misses_a_lagging_die():
    train = lag_run(seed=11, tau_die=420.0, curvature=5.0, rate_hz=2.0)
    test = lag_run(seed=12, tau_die=420.0, curvature=5.0, segments=OTHER, rate_hz=2.0)
    static = fit_model([train], kind='poly', features=('dT', 'dT2'))
    assert static.format_version == 2 and static.thermal == ThermalState()
    assert np.all(_bs(static, test) > 1.5)


def test_a_constant_ramp_or_no_lag_cannot_pin_tau():
    # The whole run on one ramp with the die already lagging: any tau fits but the start-up.
    ramp = lag_run(seed=3, tau_die=300.0, segments=(('ramp', 60.0, 20.0),), start_c=-10.0,
                   skip_s=3000.0)
    no_lag = lag_run(seed=3, tau_die=0.0)
    for run in (ramp, no_lag):
        th = fit_model([run], kind='poly', features='dT,dT2,lag').thermal
        assert th.identifiable is False
        lo, hi = th.tau_interval_s[0]
        assert lo == TAU_BOUNDS[0] or hi == TAU_BOUNDS[1] or hi / lo > 3
        assert 'tau not identifiable from these data: profile flat over' in th.describe()


def test_lag_alone_implies_dt_and_given_tau_is_not_assessed():
    run = lag_run(seed=4, tau_die=200.0, curvature=0.0, rate_hz=2.0)
    model = fit_model([run], kind='poly', features='lag')
    assert model.features == ('dT', 'lag') and model.inputs == ('dT',)
    assert model.thermal.tau_s[0] == pytest.approx(200.0, rel=0.1)
    fixed = fit_model([run], kind='poly', features='dT,lag', fit_params=False,
                      params={'lag': {'tau_s': 150.0}})
    assert fixed.thermal == ThermalState('first_order', (150.0,))
    assert fixed.thermal.identifiable is None and 'thermal' not in fixed.metrics
    given = ThermalState('two_node', (20.0, 180.0))
    by_state = fit_model([run], kind='poly', features='dT', thermal=given)
    assert by_state.thermal == given and by_state.features == ('dT', 'lag')
    assert by_state.effect_params['lag']['tau_s'] == 200.0
    implied = fit_model([run], kind='poly', features='dT', thermal='first_order')
    assert implied.features == ('dT', 'lag') and implied.thermal.identifiable


@pytest.mark.parametrize('thermal, message', [
    ('none', "thermal='none' contradicts it"),
    (ThermalState(), "kind 'none' contradicts it"),
    ('three_node', 'Expected `thermal` to be one of none, first_order, two_node, auto or a '
                   "ThermalState, got 'three_node'"),
])
def test_contradictory_or_unknown_front_end_is_refused(thermal, message):
    run = lag_run(seed=4, tau_die=200.0, rate_hz=1.0)
    with pytest.raises(FitError, match=message):
        fit_model([run], kind='poly', features='dT,lag', thermal=thermal)
    assert 'auto' in THERMAL_CHOICES


def test_auto_keeps_one_node_unless_two_nodes_lower_the_cv_error():
    one = lag_run(seed=5, tau_die=420.0, rate_hz=2.0)
    m1 = fit_model([one], kind='poly', features='dT,dT2,lag', thermal='auto')
    info = m1.metrics['thermal']
    assert m1.thermal.kind == 'first_order' and info['chosen'] == 'first_order'
    assert info['cv_sse']['two_node'] > 0.95 * info['cv_sse']['first_order']
    two = lag_run(seed=5, tau_die=400.0, tau_package=400.0, rate_hz=2.0)
    m2 = fit_model([two], kind='poly', features='dT,dT2,lag', thermal='auto')
    assert m2.thermal.kind == 'two_node' and len(m2.thermal.tau_interval_s) == 2
    assert m2.thermal.tau_total_s == pytest.approx(800.0, rel=0.1)
    assert m2.metrics['thermal']['cv_sse']['two_node'] < \
        0.95 * m2.metrics['thermal']['cv_sse']['first_order']
    test = lag_run(seed=6, tau_die=400.0, tau_package=400.0, segments=OTHER, rate_hz=2.0)
    fo = fit_model([two], kind='poly', features='dT,dT2,lag')
    assert np.all(_bs(m2, test) <= 1.1) and np.mean(_bs(fo, test)) > np.mean(_bs(m2, test))


# ----------------------------------------------------------------------------- model, file

@pytest.fixture(scope='module')
def lag_model():
    run = lag_run(seed=7, tau_die=300.0, curvature=2.0, rate_hz=2.0)
    return fit_model([run], kind='rbf', features='dT,dT2,dTdt,lag', n_centers=6)


def test_streaming_compensator_equals_batch_with_clamping_gaps_and_irregular_stamps(lag_model):
    lo, hi = lag_model.temp_range_c
    rng = np.random.default_rng(3)
    t, temp = _irregular(4, 1500)
    temp = np.interp(t, [t[0], t[700], t[-1]], [lo - 8.0, hi + 10.0, lo + 5.0])
    temp += rng.normal(0, 0.05, t.size)
    omega = rng.normal(0, 0.01, (t.size, 3))
    state = model_temperature(lag_model, t, temp)
    assert np.any(state > hi) and np.any(state < lo)
    np.testing.assert_array_equal(model_temperature(lag_model, t, temp, clamp=True),
                                  np.clip(state, lo, hi))
    for policy, clamp in (('clamp', True), ('extrapolate', False)):
        batch = compensate(lag_model, t, temp, omega, clamp=clamp)
        comp = StreamingCompensator(lag_model, out_of_range=policy)
        out, flags = [], []
        for a, b, c in zip(t, temp, omega):
            out.append(comp.step(a, b, c))
            flags.append(comp.in_range)
        np.testing.assert_allclose(np.array(out), batch, rtol=1e-9, atol=1e-12)
        # The range flag is the state's, not the thermometer's.
        np.testing.assert_array_equal(flags, (state >= lo) & (state <= hi))
        assert comp.model_temp == pytest.approx(np.clip(state, lo, hi)[-1] if clamp
                                                else state[-1], abs=1e-9)


def test_streaming_compensator_reports_the_settling_state(lag_model):
    comp = StreamingCompensator(lag_model)
    tau = lag_model.thermal.tau_total_s
    comp.drift(100.0, 20.0)
    comp.drift(100.0 + tau, 21.0)
    assert comp.thermal_progress == pytest.approx(1.0) and not comp.thermal.settled
    comp.drift(100.0 + 3 * tau, 21.0)
    assert comp.thermal.settled and comp.thermal_progress >= SETTLE_TAUS
    comp.reset()
    assert comp.model_temp is None and comp.thermal_progress == 0.0
    static = lag_model.replace(features=('dT', 'dT2', 'dTdt'), effect_params={
        'dTdt': lag_model.effect_params['dTdt']}, thermal=ThermalState())
    assert StreamingCompensator(static).thermal_progress is None


def test_health_says_the_state_is_settling_until_three_tau(lag_model):
    core = CompensatorCore(Policy(), lag_model)
    tau = lag_model.thermal.tau_total_s
    core.add_temperature(0.0, 20.0)
    core.process(0.0, 0.0, 0.0, 0.0)
    core.add_temperature(1.5 * tau, 20.5)
    core.process(1.5 * tau, 0.0, 0.0, 0.0)
    h = health(core)
    assert h.values['thermal state'] == 'settling (1.5 of 3 tau)'
    core.add_temperature(3.0 * tau, 21.0)
    core.process(3.0 * tau, 0.0, 0.0, 0.0)
    assert health(core, h.mark).values['thermal state'] == 'settled'
    still = CompensatorCore(Policy(), lag_model.replace(
        features=('dT', 'dT2', 'dTdt'), effect_params={'dTdt': {'tau_s': 60.0}},
        thermal=ThermalState()))
    still.add_temperature(0.0, 20.0)
    still.process(0.0, 0.0, 0.0, 0.0)
    assert 'thermal state' not in health(still).values


def test_format_2_file_round_trip_is_exact(tmp_path, lag_model):
    path = save_model(lag_model, tmp_path / 'm.yaml')
    text = path.read_text()
    assert 'format_version: 2\n' in text
    data = yaml.safe_load(text)
    assert data['thermal'] == lag_model.thermal.to_dict()
    assert data['effect_params']['lag'] == {'tau_s': lag_model.thermal.tau_s[0]}
    back = load_model(path)
    assert back == lag_model and back.model_id == lag_model.model_id
    assert back.thermal == lag_model.thermal
    run = lag_run(seed=8, tau_die=300.0, rate_hz=0.5)
    np.testing.assert_array_equal(drift(back, run.t, run.temp),
                                  drift(lag_model, run.t, run.temp))
    # The thermal front end is part of the content hash.
    other = lag_model.replace(thermal=ThermalState(
        'first_order', lag_model.thermal.tau_s, lag_model.thermal.tau_interval_s, False))
    assert other.model_id != lag_model.model_id


def _broken(model, **edit):
    d = model_to_dict(model)
    d.update(edit)
    return d


@pytest.mark.parametrize('edit, message', [
    ({'format_version': 3}, r'`format_version` must be 2 \(the format this gyro_tdc reads\), '
                            r'got 3'),
    ({'thermal': None}, r'format_version 2 model: field `thermal` must be a mapping'),
    ({'thermal': {'kind': 'first_order', 'tau_s': []}},
     r'format_version 2 model: field `thermal`: `tau_s` must hold 1 time constant'),
    ({'thermal': {'kind': 'none', 'tau_s': [], 'tau_interval_s': None,
                  'identifiable': None}},
     'format_version 2 model: fields `thermal`/`features`/`effect_params`: thermal kind '
     "'none' does not match"),
    ({'effect_params': {'dTdt': {'tau_s': 60.0}, 'lag': {'tau_s': 5.0}}},
     r"effect_params lag.tau_s \(5.0\) must equal the thermal state's total time constant"),
    ({'widths': [1.0]}, r'format_version 2 model: field `widths` must have shape \(6,\)'),
])
def test_format_2_errors_name_the_version_and_the_field(tmp_path, lag_model, edit, message):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(_broken(lag_model, **edit)))
    with pytest.raises(ModelFileError, match=message) as info:
        load_model(path)
    assert str(path) in str(info.value) and '\n' not in str(info.value)


def test_a_format_1_file_is_refused(tmp_path, lag_model):
    d = _broken(lag_model, format_version=1)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ModelFileError, match=r'`format_version` must be 2 \(the format this '
                       r'gyro_tdc reads\), got 1'):
        load_model(path)


def test_hand_built_models_have_kind_none_and_lag_needs_a_lagged_state():
    coef = np.vstack([np.zeros(3), np.ones(3)])
    m = CompensationModel.polynomial(('dT',), 20.0, coef, temp_range_c=(0.0, 40.0),
                                     residual_var=np.zeros(3))
    assert m.thermal == ThermalState() and m.format_version == 2 and m.inputs == ('dT',)
    with pytest.raises(FeatureError, match='thermal kind'):
        CompensationModel.polynomial(('dT', 'lag'), 20.0, coef, temp_range_c=(0.0, 40.0),
                                     residual_var=np.zeros(3),
                                     effect_params={'lag': {'tau_s': 50.0}})
    with pytest.raises(FeatureError, match='`thermal` must be a ThermalState, got NoneType'):
        m.replace(thermal=None)


def test_training_report_prints_tau_with_its_interval_or_that_it_is_not_pinned():
    from gyro_tdc.data.coverage import coverage
    from gyro_tdc.evaluate.report import format_training
    from gyro_tdc.identify.train import TrainResult

    ramp = lag_run(seed=3, tau_die=300.0, segments=(('ramp', 60.0, 20.0),), start_c=-10.0,
                   skip_s=3000.0, rate_hz=1.0)
    rich = lag_run(seed=3, tau_die=300.0, rate_hz=1.0)
    for run, pinned in ((rich, True), (ramp, False)):
        model = fit_model([run], kind='poly', features='dT,dT2,lag')
        text, warns = format_training(TrainResult(model=model, path=None,
                                                  coverage=coverage([run]), bags=['run'],
                                                  samples=len(run)))
        head = text.splitlines()[0]
        lo, hi = model.thermal.tau_interval_s[0]
        if pinned:
            assert f'lag.tau_s = {model.thermal.tau_s[0]:.4g} (95 % interval {lo:.4g}..' \
                   f'{hi:.4g})' in head
            assert not any('not identifiable' in w for w in warns)
        else:
            assert 'lag.tau_s = ' not in head
            assert f'lag.tau_s not identifiable (profile flat over {lo:.4g}..{hi:.4g} s)' in head
            assert any(w.startswith('tau not identifiable from these data') for w in warns)
