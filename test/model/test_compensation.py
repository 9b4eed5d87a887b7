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

"""Tests of gyro_tdc.model.compensation: formulas, streaming, clamping, ids, thermal state."""

import math
from pathlib import Path

from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import (compensate, CompensationModel, drift, model_temperature,
                                         predict_drift, rbf_design, static_slope,
                                         StreamingCompensator)
from gyro_tdc.model.effects import batch_features
from gyro_tdc.model.thermal_state import ThermalState
from model_summary import summary
import numpy as np
import pytest
from synth import synth_run

DEG = math.pi / 180.0


def _hand_model(features=('dT', 'dT2'), effect_params=None, **kw):
    """Poly f(dT, dT2): drift = b + a1 (T - 25) / 10 + a2 ((T - 25)^2 - 100) / 50, rad/s."""
    norm = (np.array([0.0, 100.0]), np.array([10.0, 50.0]), np.zeros((0, 2)), np.zeros(0))
    coef = [[0.01, -0.02, 0.03], [0.001, 0.002, -0.003], [0.0004, 0.0, 0.0001]]
    return CompensationModel.network('poly', features, effect_params or {}, 25.0, norm, coef,
                                     temp_range_c=(0.0, 50.0), residual_var=np.full(3, 1e-6),
                                     **kw)


def test_drift_is_the_normalised_linear_formula():
    model = _hand_model()
    temp = np.array([0.0, 10.0, 25.0, 37.5, 50.0])
    d = temp - 25.0
    want = (model.intercept + (d / 10.0)[:, None] * model.linear[0]
            + ((d ** 2 - 100.0) / 50.0)[:, None] * model.linear[1])
    np.testing.assert_allclose(drift(model, np.arange(5.0), temp), want, rtol=1e-12)


def test_network_constructor_splits_the_design_weights_and_round_trips():
    model = _hand_model()
    norm = (model.input_mean, model.input_std, model.centers, model.widths)
    built = CompensationModel.network('poly', model.features, {}, 25, norm, model.coefficients,
                                      temp_range_c=[0, 50], residual_var=[1e-6] * 3)
    assert built == model and built.model_id == model.model_id
    assert built.coefficients.shape == (3, 3) and isinstance(built.t0_c, float)
    assert built.temp_range_c == (0.0, 50.0)


def test_polynomial_constructor_is_the_cubic_in_raw_powers():
    coef = np.array([[0.01, 0.0, 0.0], [1e-3, 0.0, 0.0], [1e-4, 0.0, 0.0], [1e-5, 0.0, 0.0]])
    model = CompensationModel.polynomial(('dT', 'dT2', 'dT3'), 20.0, coef,
                                         temp_range_c=(0.0, 40.0), residual_var=np.zeros(3))
    assert model.kind == 'poly' and model.n_centers == 0 and model.effect_params == {}
    d = np.array([-10.0, 0.0, 15.0])
    want = 0.01 + 1e-3 * d + 1e-4 * d ** 2 + 1e-5 * d ** 3
    np.testing.assert_allclose(drift(model, np.arange(3.0), 20.0 + d)[:, 0], want, rtol=1e-12,
                               atol=1e-15)


def test_rbf_design_columns():
    centers = np.array([[0.0], [1.0]])
    x = np.array([[2.0], [4.0]])                       # normalised: 0 and 1 (mean 2, std 2)
    out = rbf_design((np.array([2.0]), np.array([2.0]), centers, np.array([1.0, 0.5])), x)
    np.testing.assert_allclose(out, [[1.0, 0.0, 1.0, math.exp(-2.0)],
                                     [1.0, 1.0, math.exp(-0.5), 1.0]], rtol=1e-12)


def test_compensate_inverts_predict_drift_with_a_scale_factor():
    model = _hand_model(scale=np.array([1e-3, -2e-3, 5e-4]))
    n = 200
    rng = np.random.default_rng(3)
    t = np.arange(n) * 0.1
    temp = np.linspace(5.0, 45.0, n)
    ref = rng.normal(0.0, 1.0, size=(n, 3))
    raw = predict_drift(model, t, temp, ref)
    want = (1.0 + (temp - 25.0)[:, None] * model.scale) * ref + drift(model, t, temp)
    np.testing.assert_allclose(raw, want, rtol=1e-12)
    np.testing.assert_allclose(compensate(model, t, temp, raw), ref, rtol=1e-9, atol=1e-12)


def test_drift_in_chunks_equals_one_block():
    model = fit_model([synth_run(seed=3, hours=0.2)], features='dT,dT2', n_centers=5)
    run = synth_run(seed=4, hours=0.2)
    np.testing.assert_array_equal(drift(model, run.t, run.temp, chunk=97),
                                  drift(model, run.t, run.temp))


def test_streaming_compensator_equals_batch():
    run = synth_run(seed=13, hours=0.3, tau_die=300.0, cooling=True)
    model = fit_model([run], features='dT,dT2,lag,dTdt')
    comp = StreamingCompensator(model)
    out = np.array([comp.step(t, temp, w) for t, temp, w in zip(run.t, run.temp, run.omega)])
    ref = compensate(model, run.t, run.temp, run.omega)
    # atol: 1e-12 rad/s is 6e-11 deg/s; compensated values near zero have no relative scale.
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-12)


def test_clamping_holds_the_drift_at_the_range_edge():
    run = synth_run(seed=14, hours=0.5)
    model = fit_model([run], features='dT,dT2')
    lo, hi = model.temp_range_c
    t = np.arange(3.0)
    inside = drift(model, t, np.full(3, hi))
    outside = drift(model, t, np.full(3, hi + 30.0))
    np.testing.assert_allclose(outside, inside)
    assert not np.allclose(drift(model, t, np.full(3, hi + 30.0), clamp=False), inside)


def test_streaming_range_flag_extrapolation_and_offset():
    model = _hand_model()
    clamp = StreamingCompensator(model)
    free = StreamingCompensator(model, out_of_range='extrapolate')
    w = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(clamp.step(0.0, 70.0, w),
                               w - drift(model, np.zeros(1), np.array([50.0]))[0], rtol=1e-12)
    assert not clamp.in_range
    np.testing.assert_allclose(free.step(0.0, 70.0, w),
                               w - drift(model, np.zeros(1), np.array([70.0]), clamp=False)[0],
                               rtol=1e-12)
    clamp.step(1.0, 30.0, w)
    assert clamp.in_range
    before = clamp.drift(2.0, 30.0)
    clamp.shift_offset([0.001, 0.0, -0.001])
    np.testing.assert_allclose(clamp.drift(3.0, 30.0) - before, [0.001, 0.0, -0.001],
                               atol=1e-15)
    with pytest.raises(ValueError, match="'clamp' or 'extrapolate'"):
        StreamingCompensator(model, out_of_range='wrap')


def test_model_id_covers_fitted_fields_but_not_created():
    model = _hand_model()
    assert model.model_id == _hand_model().model_id
    assert model.replace(created={'utc': 'now'}).model_id == model.model_id
    assert model.replace(intercept=model.intercept + 1e-12).model_id != model.model_id
    assert model.replace(sensor_id='imu7').model_id != model.model_id
    assert model == _hand_model() and model != model.replace(t0_c=26.0)


def test_summary_and_properties():
    model = _hand_model()
    assert model.inputs == ('dT', 'dT2') and model.n_centers == 0
    s = summary(model)
    assert s['kind'] == 'poly' and s['features'] == ['dT', 'dT2'] and s['centers'] == 0
    assert s['temp_range_c'] == [0.0, 50.0]
    np.testing.assert_allclose(s['residual_std_dps'], [1e-3 / DEG] * 3)


# ----------------------------------------------------------------------------- formats

DATA = Path(__file__).resolve().parents[1] / 'support' / 'files'


def test_format_2_state_model_drift_and_range_follow_the_state():
    thermal = ThermalState('first_order', (50.0,))
    model = _hand_model(features=('dT', 'dT2', 'lag'), effect_params={'lag': {'tau_s': 50.0}},
                        thermal=thermal)
    assert model.format_version == 2 and model.inputs == ('dT', 'dT2')
    t = np.arange(0.0, 400.0, 2.0)
    temp = np.where(t < 100.0, 20.0, 60.0)              # a step past the range end (50)
    state = thermal.temperature(t, temp)
    np.testing.assert_array_equal(model_temperature(model, t, temp), state)
    flat = _hand_model()                                # the same terms of the measured T
    np.testing.assert_allclose(drift(model, t, temp), drift(flat, t, state), rtol=1e-12)
    np.testing.assert_allclose(drift(model, t, temp, clamp=False),
                               drift(flat, t, state, clamp=False), rtol=1e-12)
    # The state reaches the range end about tau ln(4) after the step, not at the step.
    clamped = model_temperature(model, t, temp, clamp=True)
    assert clamped[t == 102.0][0] < 50.0 and clamped[-1] == 50.0
    s = summary(model)
    assert s['format_version'] == 2 and s['thermal']['tau_s'] == [50.0]


def test_static_slope_is_the_settled_drift_change_over_the_range_per_degc():
    # (f(50) - f(0)) / 50: the dT term gives linear[0] / 10, the even dT2 term nothing.
    flat = _hand_model()
    np.testing.assert_allclose(static_slope(flat), flat.linear[0] / 10.0, rtol=1e-12)
    lagged = _hand_model(features=('dT', 'dT2', 'lag'), effect_params={'lag': {'tau_s': 50.0}},
                         thermal=ThermalState('first_order', (50.0,)))
    np.testing.assert_allclose(static_slope(lagged), static_slope(flat), rtol=1e-12)
    assert np.all(np.isnan(static_slope(flat.replace(temp_range_c=(30.0, 30.0)))))


def test_kind_none_evaluates_every_term_of_the_measured_temperature():
    # A static model: the state is the measured temperature, each term of it (clamped).
    run = synth_run(seed=3, hours=0.2)
    model = fit_model([run], features='dT,dT2', n_centers=5)
    assert model.thermal == ThermalState() and model.format_version == 2
    np.testing.assert_array_equal(model_temperature(model, run.t, run.temp), run.temp)
    s = np.clip(run.temp, *model.temp_range_c)
    x = batch_features(model.features, run.t, s, t0=model.t0_c, params=model.effect_params)
    np.testing.assert_array_equal(compensate(model, run.t, run.temp, run.omega),
                                  run.omega - rbf_design(model, x) @ model.coefficients)


def test_linear_policy_continues_the_hand_model_along_its_tangent():
    model = _hand_model()              # quadratic in dT, range 0..50 degC, T0 = 25
    t = np.zeros(1)
    lin = StreamingCompensator(model, out_of_range='linear', max_extrapolation_c=15.0)
    w = np.zeros(3)
    # d b / d T at 50 degC: a1 / 10 + a2 * 2 (T - 25) / 50.
    slope = model.linear[0] / 10.0 + model.linear[1] * 2.0 * 25.0 / 50.0
    for temp, reach in ((58.0, 8.0), (80.0, 15.0)):
        want = drift(model, t, np.array([50.0]))[0] + reach * slope
        np.testing.assert_allclose(-lin.step(0.0, temp, w), want, rtol=1e-9)
        np.testing.assert_allclose(drift(model, t, np.array([temp]), out_of_range='linear')[0],
                                   want, rtol=1e-9)
        assert not lin.in_range and lin.range_distance_c == pytest.approx(temp - 50.0)
        assert lin.model_temp == pytest.approx(50.0 + reach)
    with pytest.raises(ValueError, match="'linear', 'clamp' or 'extrapolate'"):
        StreamingCompensator(model, out_of_range='tangent')
