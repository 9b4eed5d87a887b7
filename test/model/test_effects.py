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


"""Effect library: ids, parameters, flags, batch == streaming for every entry, one lag."""

import math

from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FeatureError
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate, StreamingCompensator
from gyro_tdc.model.effects import (batch_features, Effect, EFFECT_IDS, EFFECTS, first_order_lag,
                                    input_ids, INPUT_ORDER, NONLINEAR_EFFECTS, normalise_ids,
                                    REFERENCE_EFFECTS, resolve_params, STATE_TERMS, STATIC_EFFECTS,
                                    StreamingFeatures, TEMPERATURE_EFFECTS, THERMAL_EFFECTS,
                                    with_implied)
from gyro_tdc.model.modelfile import load_model, save_model
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from synth import synth_run

DESIGN_IDS = ['bias', 'dT', 'dT2', 'dT3', 'dTdt', 'lag', 'scale', 'warmup']
#: Column layout of existing model files: new effects must not reorder it.
LAYOUT = ('dT', 'dT2', 'dT3', 'dTdt', 'lag', 'warmup')
INPUTS = [e for e in EFFECTS if EFFECTS[e].is_input]
#: Non-default parameters so that a parameter that is ignored would show.
PARAMS = {'lag': {'tau_s': 7.5}, 'dTdt': {'tau_s': 3.0}, 'warmup': {'tau_s': 20.0}}


def test_catalog_has_the_design_ids_with_physics():
    assert list(EFFECTS) == DESIGN_IDS
    for eff in EFFECTS.values():
        assert len(eff.description) > 30 and eff.excited_by
        for name in eff.fitted:
            lo, hi = eff.bounds[name]
            assert 0 < lo < eff.params[name] < hi


def test_derived_sets_come_from_the_entries_flags():
    assert EFFECT_IDS == tuple(DESIGN_IDS)
    assert INPUT_ORDER == LAYOUT
    assert STATIC_EFFECTS == {'bias', 'dT', 'dT2', 'dT3', 'scale'}
    assert NONLINEAR_EFFECTS == {'lag', 'warmup'}
    assert TEMPERATURE_EFFECTS == {'dT', 'dT2', 'dT3', 'dTdt', 'lag', 'scale'}
    assert REFERENCE_EFFECTS == {'scale'}
    assert THERMAL_EFFECTS == {'lag'} and STATE_TERMS == {'dT', 'dT2', 'dT3'}
    for eff in EFFECTS.values():
        assert (eff.id in THERMAL_EFFECTS) == eff.thermal
        assert (eff.id in STATIC_EFFECTS) == eff.static
        assert (eff.id in NONLINEAR_EFFECTS) == bool(eff.fitted)
        assert (eff.batch is not None) == (eff.stream is not None) == eff.is_input


def test_an_incomplete_entry_is_rejected():
    with pytest.raises(FeatureError, match='batch and a streaming'):
        Effect('half', 'd', 'f', 'e', batch=lambda s, p: s.d)
    with pytest.raises(FeatureError, match='batch and a streaming'):
        Effect('odd', 'd', 'f', 'e', is_input=False, batch=lambda s, p: s.d,
               stream=lambda p, t0: None)
    with pytest.raises(FeatureError, match='default and bounds'):
        Effect('tau', 'd', 'f', 'e', params={'tau_s': 1.0}, fitted=('tau_s',),
               batch=lambda s, p: s.d, stream=lambda p, t0: None)


def test_ids_parse_and_reject_unknown():
    assert normalise_ids('dT2, dT ,lag') == ('dT', 'dT2', 'lag')
    assert input_ids(['bias', 'scale', 'warmup', 'dT']) == ('dT', 'warmup')
    with pytest.raises(FeatureError, match=r"Unknown effect id\(s\) 'dT4'"):
        normalise_ids('dT,dT4')
    with pytest.raises(FeatureError, match=r'lag.tau_s must be a positive'):
        resolve_params(['lag'], {'lag': {'tau_s': -1.0}})
    with pytest.raises(FeatureError, match=r"'lag' has no parameter"):
        resolve_params(['lag'], {'lag': {'tau': 3.0}})


def _irregular(seed, n=6000):
    rng = np.random.default_rng(seed)
    t = 100.0 + np.cumsum(rng.uniform(0.005, 0.05, n))
    temp = 20.0 + 8.0 * np.sin(t / 40.0) + rng.normal(0.0, 0.02, n)
    return t, temp


def _streamed(ids, t, temp, t0, params=None, state=None):
    if state is None:
        s = StreamingFeatures(ids, t0=t0, params=params)
        return np.array([s.update(a, b) for a, b in zip(t, temp)]).reshape(t.size, -1)
    s = StreamingFeatures(ids, t0=t0, params=params, state=True)
    return np.array([s.update(a, b, c) for a, b, c in zip(t, temp, state)]).reshape(t.size, -1)


def test_with_a_state_lag_is_no_column_and_the_temperature_terms_follow_the_state():
    assert input_ids(['dT', 'dT2', 'lag', 'dTdt'], state=True) == ('dT', 'dT2', 'dTdt')
    assert input_ids(['dT', 'lag'], state=False) == ('dT', 'lag')
    assert with_implied('lag') == ('dT', 'lag') and with_implied('lag,dT2') == ('dT2', 'lag')
    assert with_implied('dTdt,lag') == ('dT', 'dTdt', 'lag')
    assert with_implied('dTdt,warmup') == ('dTdt', 'warmup')
    t, temp = _irregular(4, 2000)
    state = first_order_lag(t, temp, 30.0)
    x = batch_features(['dT', 'dT2', 'dT3', 'dTdt', 'lag'], t, temp, t0=18.0, state=state)
    d = state - 18.0
    np.testing.assert_array_equal(x[:, :3], np.column_stack([d, d * d, d * d * d]))
    # The gradient is of the measured temperature, as without a state.
    np.testing.assert_array_equal(x[:, 3], batch_features(['dTdt'], t, temp, t0=18.0)[:, 0])
    assert batch_features(['lag'], t, temp, t0=18.0, state=state).shape == (t.size, 0)
    with pytest.raises(ValueError, match='Expected `state` of shape'):
        batch_features(['dT'], t, temp, t0=18.0, state=state[:-1])
    with pytest.raises(ValueError, match='thermal `state`'):
        StreamingFeatures(['dT'], t0=18.0, state=True).update(1.0, 20.0)


@pytest.mark.parametrize('thermal', [ThermalState('first_order', (25.0,)),
                                     ThermalState('two_node', (3.0, 40.0))])
@pytest.mark.parametrize('seed', [0, 1])
def test_streaming_equals_batch_for_every_effect_of_a_state(thermal, seed):
    t, temp = _irregular(seed)
    t[3000:] += 600.0                     # a gap
    t[200:210] = t[200]                   # repeated stamps
    state = thermal.temperature(t, temp)
    cols = input_ids(INPUTS, state=True)
    assert cols == tuple(e for e in LAYOUT if e != 'lag')
    x = batch_features(INPUTS, t, temp, t0=18.0, params=PARAMS, state=state)
    stream = thermal.stream()
    s = np.array([stream.update(a, b) for a, b in zip(t, temp)])
    np.testing.assert_allclose(s, state, rtol=1e-12, atol=1e-9)
    y = _streamed(INPUTS, t, temp, 18.0, PARAMS, state=s)
    assert x.shape == y.shape == (t.size, len(cols))
    np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-12 * np.max(np.abs(x)))
    for eid in cols:
        one = batch_features([eid], t, temp, t0=18.0, params=PARAMS, state=state)
        np.testing.assert_array_equal(one[:, 0], x[:, cols.index(eid)])


@pytest.mark.parametrize('eid', INPUTS)
@pytest.mark.parametrize('seed', [0, 1])
def test_streaming_equals_batch_for_every_effect(eid, seed):
    t, temp = _irregular(seed)
    params = {k: v for k, v in PARAMS.items() if k == eid}
    x = batch_features([eid], t, temp, t0=18.0, params=params)
    y = _streamed([eid], t, temp, 18.0, params)
    assert x.shape == y.shape == (t.size, 1)
    scale = np.max(np.abs(x))
    np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-12 * scale)


def test_streaming_equals_batch_for_all_inputs_together_with_repeated_stamps():
    t, temp = _irregular(2, 3000)
    t[100:110] = t[100]            # a stamp not after the previous one holds the filters
    x = batch_features(INPUTS, t, temp, t0=21.0, params=PARAMS)
    y = _streamed(INPUTS, t, temp, 21.0, PARAMS)
    assert x.shape == (t.size, len(LAYOUT))
    np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-12 * np.max(np.abs(x)))


@pytest.mark.parametrize('eid', INPUTS)
def test_static_flag_means_no_time_memory(eid):
    # A static feature depends on the current temperature only: the same temperatures at
    # other stamps give the same column. Every other input has a memory that shows.
    rng = np.random.default_rng(7)
    temp = rng.uniform(-20, 60, 200)
    t1 = np.sort(rng.uniform(0, 1e4, 200))
    t2 = np.sort(rng.uniform(5e4, 9e4, 200))
    same = np.array_equal(batch_features([eid], t1, temp, t0=25.0),
                          batch_features([eid], t2, temp, t0=25.0))
    assert same == EFFECTS[eid].static


def test_streaming_reset_starts_a_new_run():
    t, temp = _irregular(3, 500)
    s = StreamingFeatures(['lag', 'warmup'], t0=0.0)
    first = np.array([s.update(a, b) for a, b in zip(t, temp)])
    s.reset()
    again = np.array([s.update(a, b) for a, b in zip(t, temp)])
    np.testing.assert_array_equal(first, again)


def test_first_order_lag_matches_step_response():
    t = np.arange(0.0, 50.0, 0.01)
    u = np.where(t > 0, 1.0, 0.0)
    u[0] = 0.0
    y = first_order_lag(t, u, 5.0)
    i = np.searchsorted(t, 5.0)
    assert y[i] == pytest.approx(1 - np.exp(-1), abs=2e-3)
    assert y[-1] == pytest.approx(1.0, abs=1e-4)


def _lag_loop(t, u, tau, hold, y0=None):
    """Run the recursion of first_order_lag as a plain loop."""
    y = np.empty(u.size)
    y[0] = u[0] if y0 is None else y0
    for k in range(1, u.size):
        h = max(t[k] - t[k - 1], 0.0)
        a = math.exp(-h / tau)
        if hold == 'step':
            y[k] = a * y[k - 1] + (1.0 - a) * u[k]
        else:
            c = tau * (1.0 - a) / h if h > 0 else 1.0
            y[k] = a * y[k - 1] + (1.0 - c) * u[k] + (c - a) * u[k - 1]
    return y


@pytest.mark.parametrize('hold', ['step', 'linear'])
@pytest.mark.parametrize('y0', [None, -3.0])
def test_first_order_lag_scan_equals_the_recursion_on_irregular_stamps(hold, y0):
    t, u = _irregular(4, 3000)
    t[50:55] = t[50]
    for tau in (0.01, 2.0, 500.0):
        np.testing.assert_allclose(first_order_lag(t, u, tau, hold=hold, y0=y0),
                                   _lag_loop(t, u, tau, hold, y0), rtol=1e-11, atol=1e-9)


def test_linear_hold_on_a_uniform_step_equals_the_same_on_its_stamps():
    t, u = _irregular(5, 2000)
    step = 0.25
    stamps = np.arange(u.size) * step
    np.testing.assert_allclose(first_order_lag(step, u, 30.0, hold='linear'),
                               first_order_lag(stamps, u, 30.0, hold='linear'),
                               rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(first_order_lag(step, u, 30.0),
                               first_order_lag(stamps, u, 30.0), rtol=1e-12, atol=1e-10)


def test_lag_is_exact_for_a_ramp():
    dt, tau, rate = 0.5, 37.0, 0.02
    t = np.arange(2000) * dt
    y = first_order_lag(dt, rate * t, tau, hold='linear')
    exact = rate * (t - tau * (1.0 - np.exp(-t / tau)))
    np.testing.assert_allclose(y, exact, atol=1e-10)
    np.testing.assert_allclose(first_order_lag(t, rate * t, tau, hold='linear'), exact,
                               atol=1e-10)


def test_lag_with_zero_tau_passes_through_and_starts_settled():
    u = np.array([1.0, 2.0, 5.0])
    np.testing.assert_array_equal(first_order_lag(1.0, u, 0.0, hold='linear'), u)
    assert first_order_lag(1.0, u, 10.0, hold='linear')[0] == 1.0
    assert first_order_lag(1.0, u, 10.0, hold='linear', y0=-3.0)[0] == -3.0
    assert first_order_lag(np.arange(3.0), u, 10.0, y0=-3.0)[0] == -3.0
    assert first_order_lag(np.zeros(0), np.zeros(0), 10.0).shape == (0,)


@pytest.mark.parametrize('args, kwargs, name', [
    ((0.0, np.zeros(3), 1.0), {}, 'dt'),
    ((1.0, np.zeros(3), -1.0), {}, 'tau'),
    ((1.0, np.zeros(3), math.nan), {}, 'tau'),
    ((np.arange(2.0), np.zeros(3), 1.0), {}, '`t` of shape'),
    ((1.0, np.zeros((3, 2)), 1.0), {}, '`u` to have shape'),
    ((1.0, np.zeros(3), 1.0), {'hold': 'cubic'}, 'hold')])
def test_lag_rejects_bad_arguments(args, kwargs, name):
    with pytest.raises(ValueError, match=name):
        first_order_lag(*args, **kwargs)


def test_dtdt_feature_is_the_smoothed_derivative():
    t = np.arange(0.0, 3000.0, 0.5)
    temp = 10.0 + 0.01 * t  # 0.01 degC/s ramp
    x = batch_features(['dTdt'], t, temp, t0=10.0, params={'dTdt': {'tau_s': 30.0}})
    # The discrete filter lags a ramp by tau - dt/2, hence the 1 % tolerance.
    assert x[-1, 0] == pytest.approx(0.01, rel=1e-2)


def test_a_new_effect_is_one_catalog_entry(monkeypatch, tmp_path):
    # A contributor adds one entry (here a quartic term); ids, layout, fit, model file and
    # the streaming compensator follow without another change.
    quartic = Effect('dT4', 'Quartic curvature of the zero-rate level (a toy for this test).',
                     'dT^4', 'a wide temperature span',
                     batch=lambda s, p: s.d * s.d * s.d * s.d,
                     stream=lambda p, t0: lambda t, dt_s, temp, d, first: d * d * d * d,
                     static=True)
    monkeypatch.setitem(EFFECTS, 'dT4', quartic)
    assert normalise_ids('dT4, dT') == ('dT', 'dT4')
    assert input_ids(['dT4', 'lag', 'dT']) == ('dT', 'lag', 'dT4')
    t, temp = _irregular(6, 500)
    np.testing.assert_allclose(_streamed(['dT4'], t, temp, 18.0),
                               batch_features(['dT4'], t, temp, t0=18.0), rtol=1e-12)

    def with_quartic(seed):
        run = synth_run(seed=seed, hours=1.0, t_lo=-20.0, t_hi=60.0, t_ref=25.0)
        q = (run.temp - 25.0)[:, None] ** 4 * np.array([4e-7, -3e-7, 3e-7]) * math.pi / 180.0
        return Run(run.t, run.temp, run.omega + q, run.omega_ref, f'quartic{seed}')

    train, test = with_quartic(1), with_quartic(2)
    model = fit_model([train], kind='poly', features='dT,dT2,dT4', t0=25.0)
    without = fit_model([train], kind='poly', features='dT,dT2', t0=25.0)
    bs = bias_stability(compensate(model, test.t, test.temp, test.omega), test.omega_ref)
    bs_without = bias_stability(compensate(without, test.t, test.temp, test.omega),
                                test.omega_ref)
    floor = 0.05 ** 2                     # white noise of synth_run, (deg/s)^2
    assert np.all(bs < 1.1 * floor) and np.all(bs_without > 2.0 * floor), (bs, bs_without)
    loaded = load_model(save_model(model, tmp_path / 'quartic.yaml'))
    assert loaded.features == ('dT', 'dT2', 'dT4') and loaded.model_id == model.model_id
    comp = StreamingCompensator(loaded)
    n = 300
    batch = compensate(loaded, test.t[:n], test.temp[:n], test.omega[:n])
    stream = np.array([comp.step(a, b, c) for a, b, c in
                       zip(test.t[:n], test.temp[:n], test.omega[:n])])
    np.testing.assert_allclose(stream, batch, rtol=1e-9, atol=1e-12)


def test_the_lag_needs_no_scipy_and_the_uniform_linear_hold_equals_lfilter():
    """No lag imports scipy; the uniform linear hold equals scipy's lfilter to rounding."""
    import subprocess
    import sys
    code = (
        'import math, sys, numpy as np\n'
        'from gyro_tdc.model.effects import first_order_lag\n'
        'rng = np.random.default_rng(3)\n'
        'u = np.cumsum(rng.normal(size=50000))\n'
        'first_order_lag(np.arange(50000) * 0.01, u, 7.5, hold="linear")\n'
        'first_order_lag(0.01, u, 7.5, hold="step")\n'
        'ys = {tau: first_order_lag(0.01, u, tau, hold="linear", y0=u[0] + 0.3)\n'
        '      for tau in (0.02, 7.5, 600.0, 1e6)}\n'
        'assert "scipy" not in sys.modules, "scipy was imported"\n'
        'from scipy.signal import lfilter\n'
        'for tau, y in ys.items():\n'
        '    a = math.exp(-0.01 / tau); c = tau * -math.expm1(-0.01 / tau) / 0.01\n'
        '    b0, b1 = 1.0 - c, c - a\n'
        '    zi = np.array([b1 * u[0] + a * (u[0] + 0.3)])\n'
        '    ref, _ = lfilter([b0, b1], [1.0, -a], u[1:], zi=zi)\n'
        '    scale = np.abs(u).max()\n'
        '    assert np.abs(y[1:] - ref).max() <= 1e-13 * scale, (tau, np.abs(y[1:] - ref).max())\n'
        '    assert y[0] == u[0] + 0.3\n'
        'print("ok")\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'


@pytest.mark.parametrize('tau', [1e-3, 0.05, 0.3, 7.0, 1e3, 1e18])
def test_the_uniform_linear_hold_matches_the_sequential_recursion(tau):
    """Every regime of the constant-factor scan (fast decay, rows, no decay) is the recursion."""
    rng = np.random.default_rng(6)
    dt = 0.1
    a = math.exp(-dt / tau)
    c = tau * -math.expm1(-dt / tau) / dt
    for n in (2, 3, 17, 1000, 4099):
        u = rng.normal(size=n)
        y = first_order_lag(dt, u, tau, hold='linear', y0=0.4)
        ref = np.empty(n)
        ref[0] = 0.4
        for k in range(1, n):
            ref[k] = a * ref[k - 1] + (1.0 - c) * u[k] + (c - a) * u[k - 1]
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)


def test_the_step_hold_scan_matches_the_sequential_recursion():
    """The prefix scan (in place, spare buffer) equals y[k] = a_k y[k-1] + (1 - a_k) u[k]."""
    rng = np.random.default_rng(5)
    for n in (2, 3, 17, 1000, 4099):
        t = np.cumsum(rng.uniform(0.0, 0.2, n))
        u = rng.normal(size=n)
        y = first_order_lag(t, u, 0.7)
        ref = np.empty(n)
        ref[0] = u[0]
        for k in range(1, n):
            a = np.exp(-(t[k] - t[k - 1]) / 0.7)
            ref[k] = a * ref[k - 1] + (1.0 - a) * u[k]
        np.testing.assert_allclose(y, ref, rtol=1e-12, atol=1e-12)
