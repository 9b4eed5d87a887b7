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

"""The learner's arithmetic (``learn.fit``): fit, held-out rule, check, model temperature."""

from __future__ import annotations

import math

from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.fit import (at_state, correction_features, fit_points, fit_sessions,
                                grow_features, held_out, inliers, learned_model, model_of,
                                on_prior, power_up_offset, prediction_mse, prior_terms,
                                same_thermal, stream_state)
from gyro_tdc.model import MAX_EXTRAPOLATION_C
from gyro_tdc.model.compensation import CompensationModel, drift
from gyro_tdc.model.modelfile import model_from_dict, model_to_dict
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.signal import hold_readings
import numpy as np
import pytest


def _table(temps, session=0.0, shift=0.0):
    """Point-table rows of a drift 0.01 + 1e-3 dT + 2e-5 dT^2 about 20 degC (x axis)."""
    d = np.asarray(temps, dtype=np.float64) - 20.0
    b = 0.01 + shift + 1e-3 * d + 2e-5 * d ** 2
    z = np.zeros_like(d)
    return np.column_stack([np.arange(d.size) * 100.0, np.full(d.size, 500.0), d + 20.0,
                            b, z, z, np.full(d.size, session)])


def test_growth_rule():
    assert grow_features(np.array([]), 0) == ()
    assert grow_features(np.array([20.0, 21.5]), 2) == ()
    assert grow_features(np.array([20.0, 22.0]), 2) == ('dT',)
    assert grow_features(np.arange(20.0, 29.0), 4) == ('dT',)
    assert grow_features(np.arange(20.0, 29.0), 5) == ('dT', 'dT2')
    assert grow_features(np.arange(20.0, 36.0), 10) == ('dT', 'dT2', 'dT3')


def test_sessions_share_the_shape_and_an_outlier_goes():
    e = np.vstack([_table(np.arange(10.0, 30.0, 2.0)),
                   _table(np.arange(15.0, 35.0, 2.5), session=1.0, shift=3e-3)])
    coef, res = fit_sessions(e, e[:, 1], ('dT', 'dT2'), 20.0)
    np.testing.assert_allclose(coef[:, 0], [0.013, 1e-3, 2e-5], rtol=1e-9)
    coef0, _ = fit_sessions(e, e[:, 1], ('dT', 'dT2'), 20.0, session=0.0)
    assert coef0[0, 0] == pytest.approx(0.01)
    assert np.abs(res).max() < 1e-12
    e[4, 3] += 0.05                         # one entry far off
    keep = inliers(e, e[:, 1], ('dT', 'dT2'), 20.0, 1e-3)
    assert keep.tolist() == [i != 4 for i in range(e.shape[0])]
    fit = fit_points(e, ('dT', 'dT2'), e[:, 0].max(), 86400.0, 1e-3)
    assert fit['points'] == e.shape[0] - 1
    temps = np.array([12.0, 20.0, 33.0])          # the newest session's intercept
    want = 0.013 + 1e-3 * (temps - 20.0) + 2e-5 * (temps - 20.0) ** 2
    got = drift(model_of(fit), np.zeros(3), temps, clamp=False)[:, 0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_a_power_up_gets_the_power_cycles_mean_or_none_as_the_trainer_decides():
    """The first still windows of each power cycle: their mean, none where it predicts worse."""
    fit = {'features': ['dT'], 't0_c': 20.0, 'coef': [[0.1, 0.2, 0.3], [0.0, 0.0, 1e-3]],
           'range_c': [15.0, 25.0], 'resid_var': [1e-8] * 3, 'points': 9}
    # x zeroed at power-on (scattering about 0), y a repeating offset, z a curve.
    ups = [[k, 3, 300.0, temp, *np.radians([x, y, 0.0]), ] for k, (x, y, temp) in enumerate(
        ((0.010, -0.50, 18.0), (-0.010, -0.52, 20.0), (0.012, -0.49, 22.0)))]
    for u in ups:
        u[6] = 0.004 + 1e-3 * (u[3] - 20.0)       # z: an offset of 0.004 on the curve
    got = power_up_offset(fit, ups)
    assert got[0] == 0.0
    assert got[1] == pytest.approx(np.radians(-0.50333), rel=1e-4)
    assert got[2] == pytest.approx(0.004, rel=1e-9)                  # the curve's axis: mean
    assert power_up_offset(fit, []) == [0.1, 0.2, 0.3]                # none recorded: its own
    assert power_up_offset(fit, ups[:1])[1] == pytest.approx(np.radians(-0.50))   # one: it


@pytest.mark.parametrize('thermal', [None, ThermalState('none'),
                                     ThermalState('first_order', (300.0,))])
def test_learned_models_carry_the_thermal_section(thermal):
    fit = {'features': [], 't0_c': 20.0, 'coef': [[0.01, 0.0, 0.0]], 'range_c': [19.0, 21.0],
           'resid_var': [1e-8] * 3, 'points': 1}
    m = model_of(fit, thermal)
    assert m.thermal == (thermal or ThermalState()) and m.format_version == 2
    lagged = thermal is not None and thermal.kind != 'none'
    assert m.features == (('dT', 'lag') if lagged else ('dT',))
    if lagged:
        assert m.effect_params == {'lag': {'tau_s': 300.0}}
    assert model_from_dict(model_to_dict(m)) == m                 # a model file like any other
    t = np.arange(0.0, 100.0)
    np.testing.assert_allclose(drift(m, t, np.full(100, 20.0)), [[0.01, 0.0, 0.0]] * 100)


def test_prediction_check_evaluates_at_the_windows_model_temperature():
    fo = ThermalState('first_order', (300.0,))
    m = learned_model(np.array([[0.01, 0, 0], [1e-3, 0, 0]]), ('dT',), 20.0, (0.0, 40.0),
                      np.zeros(3), fo)
    # Windows at model temperatures 15 and 25 degC whose means the model predicts exactly.
    rows = [[100.0, 15.0, 0.005, 0.0, 0.0, 10.0], [100.0, 25.0, 0.015, 0.0, 0.0, 110.0]]
    assert prediction_mse(m, rows, fo) == pytest.approx(0.0, abs=1e-20)
    # Taken as thermometer readings, the lag runs over them: not exact.
    assert prediction_mse(m, rows, None) > 1e-6


def _cycles(slopes, temps=np.arange(10.0, 30.0, 2.0), seed=0):
    """Point table of one power cycle per row of ``slopes`` (rad/s/degC per axis)."""
    rng = np.random.default_rng(seed)
    rows = []
    for s, slope in enumerate(slopes):
        d = temps - 20.0
        b = 0.01 * s + np.outer(d, slope) + 1e-6 * rng.standard_normal((d.size, 3))
        rows.append(np.column_stack([1e4 * s + np.arange(d.size) * 100.0,
                                     np.full(d.size, 500.0), temps, b, np.full(d.size, s)]))
    return np.vstack(rows)


def test_a_curve_that_carries_across_power_cycles_is_kept():
    e = _cycles([(1e-3, -5e-4, 2e-4)] * 3)
    fit = fit_points(e, ('dT',), e[:, 0].max(), 86400.0, 1e-3)
    rec = fit['held_out']
    assert rec['sessions'] == 3 and rec['folds'] == 3 and rec['points'] == e.shape[0]
    assert rec['offset_only'] == []
    assert all(c < 1e-3 * o for c, o in zip(rec['curve_ms_dps2'], rec['offset_ms_dps2']))
    np.testing.assert_allclose(fit['coef'][1], [1e-3, -5e-4, 2e-4], rtol=1e-3)


def test_an_axis_whose_curve_does_not_carry_keeps_the_offset_only():
    # x turns over from one power cycle to the next, y carries, z has no curve at all.
    e = _cycles([(1e-3, 5e-4, 0.0), (-1e-3, 5e-4, 0.0), (1e-3, 5e-4, 0.0), (-1e-3, 5e-4, 0.0)])
    fit = fit_points(e, ('dT', 'dT2'), e[:, 0].max(), 86400.0, 1e-3)
    rec = fit['held_out']
    assert rec['folds'] == 4 and 'x' in rec['offset_only'] and 'y' not in rec['offset_only']
    c, o = rec['curve_ms_dps2'], rec['offset_ms_dps2']
    assert c[0] >= o[0] and c[1] < o[1]
    coef = np.asarray(fit['coef'])
    assert np.all(coef[1:, 0] == 0.0) and coef[1, 1] == pytest.approx(5e-4, rel=1e-3)
    newest = e[e[:, 6] == 3.0]        # x: the newest cycle's mean (offsets are 0.01 apart)
    assert coef[0, 0] == pytest.approx(newest[:, 3].mean(), abs=1e-4)
    model = model_of(fit)
    assert model.created['held_out'] == rec
    out = drift(model, np.zeros(2), np.array([12.0, 28.0]), clamp=False)
    assert out[0, 0] == out[1, 0] and out[0, 1] != out[1, 1]


def test_too_few_power_cycles_to_judge_keep_the_curve():
    one = _cycles([(1e-3, 0.0, 0.0)])
    rec = fit_points(one, ('dT',), one[:, 0].max(), 86400.0, 1e-3)['held_out']
    assert rec == {'sessions': 1, 'folds': 0, 'points': 0, 'curve_ms_dps2': None,
                   'offset_ms_dps2': None, 'offset_only': []}
    apart = np.vstack([_cycles([(1e-3, 0.0, 0.0)], temps=np.arange(0.0, 10.0)),
                       _cycles([(0.0, 0.0, 0.0)] * 2, temps=np.arange(30.0, 40.0))[10:]])
    fit = fit_points(apart, ('dT',), apart[:, 0].max(), 86400.0, 1e-3)
    assert fit['held_out']['folds'] == 0 and fit['coef'][1][0] != 0.0   # no overlap: kept
    assert held_out(one, one[:, 1], (), 20.0) is None                      # no curve: none


# -- the model temperature ----------------------------------------------------------------


LAGS = (ThermalState('first_order', (120.0,)), ThermalState('two_node', (30.0, 200.0)))


@pytest.mark.parametrize('thermal', LAGS)
def test_stream_state_in_any_batches_is_the_streaming_and_batch_state(thermal):
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.005, 2.0, 3000))
    temp = 20.0 + 10.0 * np.sin(t / 500.0) + rng.normal(0.0, 0.01, t.size)
    stream = thermal.stream()
    want = np.array([stream.update(a, b) for a, b in zip(t.tolist(), temp.tolist())])
    np.testing.assert_allclose(thermal.temperature(t, temp), want, rtol=0, atol=1e-9)
    cuts = np.sort(rng.choice(np.arange(1, t.size), 40, replace=False))
    carry, got = None, []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
        s, carry = stream_state(thermal, carry, t[lo:hi], temp[lo:hi])
        got.append(s)
    np.testing.assert_allclose(np.concatenate(got), want, rtol=0, atol=1e-9)
    assert carry[0] == t[-1] and len(carry[1]) == len(thermal.tau_s)


def test_stream_state_skips_missing_temperatures_and_passes_without_a_lag():
    thermal = LAGS[0]
    t = np.arange(10.0)
    temp = np.array([20.0, 21, math.nan, math.nan, 22, 22, 22, math.nan, 23, 23])
    s, carry = stream_state(thermal, None, t, temp)
    ok = np.isfinite(temp)
    assert np.isnan(s[~ok]).all()
    np.testing.assert_allclose(s[ok], thermal.temperature(t[ok], temp[ok]))
    assert carry[0] == 9.0
    for none in (None, ThermalState('none')):
        s, c = stream_state(none, None, t, temp)
        assert s is temp and c is None
    s, c = stream_state(thermal, carry, t[:2], np.full(2, math.nan))
    assert np.isnan(s).all() and c == carry


def test_hold_readings_by_stamp_with_a_timeout():
    readings = [(2.0, 21.0), (0.0, 20.0), (10.0, 22.0)]
    held, keep = hold_readings(readings, np.array([-1.0, 0.0, 1.5, 2.0, 8.0, 11.0]), 5.0)
    np.testing.assert_array_equal(held, [math.nan, 20.0, 20.0, 21.0, math.nan, 22.0])
    assert keep == [(10.0, 22.0)]
    held, keep = hold_readings([], np.array([1.0]), 5.0)
    assert np.isnan(held).all() and keep == []


def test_same_thermal_and_the_model_at_its_state():
    fo = LAGS[0]
    assert same_thermal(None, ThermalState('none')) and same_thermal(None, None)
    assert same_thermal(fo, ThermalState('first_order', (120.0,), ((100.0, 150.0),), True))
    assert not same_thermal(fo, None) and not same_thermal(fo, LAGS[1])
    assert not same_thermal(fo, ThermalState('first_order', (121.0,)))
    m = learned_model(np.array([[0.01, 0, 0], [1e-3, 0, 0], [1e-5, 0, 0]]), ('dT', 'dT2'),
                      20.0, (0.0, 40.0), np.zeros(3), fo)
    t = np.arange(0.0, 2000.0, 1.0)
    temp = 20.0 + 0.01 * t
    flat = at_state(m)
    assert flat.thermal.kind == 'none' and 'lag' not in flat.features
    np.testing.assert_allclose(drift(flat, t, fo.temperature(t, temp)), drift(m, t, temp),
                               rtol=0, atol=1e-15)
    assert at_state(flat) is flat


# -- a correction to the prior ------------------------------------------------------------


def _rbf_prior():
    """Return an RBF prior over normalised dT, dT2 (non-zero means and deviations), 14-26 degC."""
    norm = (np.array([0.5, 12.0]), np.array([3.0, 15.0]),
            np.array([[-1.0, -0.5], [0.0, 0.0], [1.0, 0.8]]), np.array([0.7, 0.9, 0.8]))
    coef = np.array([[0.01, -0.02, 0.003], [2e-3, -1e-3, 4e-4], [-5e-4, 3e-4, 1e-4],
                     [1e-3, 0.0, -2e-4], [-2e-3, 1e-3, 0.0], [5e-4, -4e-4, 3e-4]])
    return CompensationModel.network('rbf', ('dT', 'dT2'), {}, 20.0, norm, coef,
                                     temp_range_c=(14.0, 26.0), residual_var=np.full(3, 1e-8))


def test_the_correction_rule_follows_the_priors_terms():
    prior = _rbf_prior()
    assert prior_terms(None) == 0 and prior_terms(prior) == 2
    assert correction_features(None, ()) is None              # no prior: its own model
    assert correction_features(prior, ()) == ()                # the prior re-anchored
    assert correction_features(prior, ('dT',)) == ('dT',)      # with a slope
    assert correction_features(prior, ('dT', 'dT2')) is None   # as many terms: its own
    # A prior with no temperature term (a bias only) is replaced as before.
    bias = learned_model(np.array([[0.01, 0.0, 0.0]]), (), 20.0, (15.0, 25.0), np.zeros(3))
    assert prior_terms(bias) == 0 and correction_features(bias, ()) is None


def test_a_correction_keeps_the_priors_shape_inside_and_beyond_its_range():
    """The prior plus c0 + a (T - t0) wherever the node's linear policy evaluates it."""
    prior = _rbf_prior()
    c0, a = np.array([1e-3, -2e-3, 5e-4]), np.array([3e-4, 1e-4, -2e-4])
    fit = {'features': ['dT'], 't0_c': 18.5, 'coef': [c0.tolist(), a.tolist()],
           'range_c': [12.0, 24.0], 'resid_var': [1e-8] * 3, 'points': 4, 'held_out': None,
           'prior': prior.model_id}
    model = model_of(fit, None, prior)
    assert model.kind == 'rbf' and model.temp_range_c == prior.temp_range_c
    np.testing.assert_array_equal(model.centers, prior.centers)
    np.testing.assert_array_equal(model.weights, prior.weights)
    temps = np.array([14.0, 17.3, 20.0, 26.0, 10.0, 30.5, 14.0 - 20.0, 26.0 + 30.0])
    t = np.arange(temps.size) * 1e7
    got = (drift(model, t, temps, out_of_range='linear')
           - drift(prior, t, temps, out_of_range='linear'))
    held = np.clip(temps, 14.0 - MAX_EXTRAPOLATION_C, 26.0 + MAX_EXTRAPOLATION_C)
    np.testing.assert_allclose(got, c0 + (held - 18.5)[:, None] * a, rtol=0, atol=1e-12)
    # on_prior gives back exactly that correction from the corrected model's drift.
    rows = np.column_stack([np.ones(temps.size), temps,
                            drift(model, t, temps, out_of_range='linear'), t])
    seen = on_prior(prior, rows)
    np.testing.assert_array_equal(seen[:, 1], held)
    np.testing.assert_array_equal(seen[:, [0, 5]], rows[:, [0, 5]])
    np.testing.assert_allclose(seen[:, 2:5], c0 + (held - 18.5)[:, None] * a, rtol=0,
                               atol=1e-12)
    assert on_prior(prior, np.zeros((0, 6))).shape == (0, 6)      # no windows: none
    # A bias-only correction: the prior shifted.
    flat = model_of(dict(fit, features=[], coef=[c0.tolist()]), None, prior)
    np.testing.assert_allclose(flat.intercept - prior.intercept, c0, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(flat.linear, prior.linear)
    # Never over another model, or none.
    other = prior.replace(intercept=prior.intercept + 1e-3)
    for wrong in (other, None):
        with pytest.raises(ModelFileError, match='correction to model'):
            model_of(fit, None, wrong)
    # A slope where the prior has no dT input is refused, not dropped.
    dt2 = learned_model(np.array([[0.01, 0, 0], [1e-5, 0, 0]]), ('dT2',), 20.0, (10.0, 30.0),
                        np.zeros(3))
    with pytest.raises(ModelFileError, match='no dT input'):
        model_of(dict(fit, prior=dt2.model_id), None, dt2)


def test_power_cycles_apart_that_each_span_under_two_degrees_keep_the_offset_only():
    """As the trainer: a curve told only by stops of under 2 degC each is not learnt."""
    stops = np.vstack([_cycles([(1e-3, 5e-4, 2e-4)], temps=np.linspace(10.0, 11.5, 6)),
                       _cycles([(0.0, 0.0, 0.0)] * 2, temps=np.linspace(30.0, 31.5, 6))[6:]])
    rec = held_out(stops, stops[:, 1], ('dT',), 20.0)
    assert rec['folds'] == 0 and rec['sessions'] == 2 and rec['offset_only'] == ['x', 'y', 'z']
    fit = fit_points(stops, ('dT',), stops[:, 0].max(), 86400.0, 1e-3)
    assert np.all(np.asarray(fit['coef'])[1:] == 0.0)
    # One of them over 2 degC of its own: the curve is kept, unjudged, as before.
    wide = np.vstack([stops[stops[:, 6] == 0.0],
                      _cycles([(0.0, 0.0, 0.0)] * 2, temps=np.linspace(30.0, 33.0, 6))[6:]])
    assert held_out(wide, wide[:, 1], ('dT',), 20.0)['offset_only'] == []
