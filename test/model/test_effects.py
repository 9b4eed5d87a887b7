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


"""Effect library: ids, parameters, flags, batch == streaming for every entry."""

import math

from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FeatureError
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate, StreamingCompensator
from gyro_tdc.model.effects import (batch_features, Effect, EFFECT_IDS, EFFECTS,
                                    input_ids, INPUT_ORDER, NONLINEAR_EFFECTS, normalise_ids,
                                    REFERENCE_EFFECTS, resolve_params, STATE_TERMS, STATIC_EFFECTS,
                                    StreamingFeatures, TEMPERATURE_EFFECTS, THERMAL_EFFECTS,
                                    with_implied)
from gyro_tdc.model.lag import first_order_lag
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
