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

"""Identification: a known drift is recovered; conventional vs modified; lag tau; errors."""

import math

from gyro_tdc.errors import FitError
from gyro_tdc.identify import (estimate_t0, fit_linear, fit_model, fit_px4_cubic,
                               fit_time_constant, FitOptions, LinearFit, RIDGE_GRID,
                               TimeConstantFit)
from gyro_tdc.model.compensation import compensate, predict_drift
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from synth import synth_run


def _bs(model, run):
    return bias_stability(compensate(model, run.t, run.temp, run.omega), run.omega_ref)


@pytest.mark.parametrize('seed', [1, 5])
def test_known_drift_recovered_to_noise_floor_on_held_out_run(seed):
    train, test = synth_run(seed=seed), synth_run(seed=seed + 100)
    floor = test.info['noise_dps'] ** 2
    for kind in ('rbf', 'poly'):
        model = fit_model([train], kind=kind, features='dT,dT2')
        bs = _bs(model, test)
        assert np.all(bs < 1.1 * floor), (kind, bs, floor)
    assert np.all(bias_stability(test.omega, test.omega_ref) > 10 * floor)


def test_fit_options_are_the_keywords_and_a_keyword_overrides_them():
    run = synth_run(seed=2, hours=0.5)
    opts = FitOptions(kind='poly', features=('dT', 'dT2', 'dT3'), sensor_id='s1')
    model = fit_model([run], opts)
    assert model.model_id == fit_model([run], kind='poly', features='dT,dT2,dT3',
                                       sensor_id='s1').model_id
    assert model.kind == 'poly' and model.sensor_id == 's1'
    other = fit_model([run], opts, sensor_id='s2')
    assert other.sensor_id == 's2' and other.model_id != model.model_id
    assert opts.sensor_id == 's1'        # the options object is not changed
    with pytest.raises(FitError, match='Unknown model kind'):
        fit_model([run], opts, kind='spline')


def test_modified_beats_conventional_only_when_dt2_present():
    # With a dT^2 term, the conventional linear model f(dT) is left with curvature ...
    train, test = synth_run(seed=2), synth_run(seed=3)
    conv = fit_model([train], kind='poly', features='dT')
    modi = fit_model([train], kind='poly', features='dT,dT2')
    p3 = _bs(modi, test) / _bs(conv, test)
    assert np.all(p3 < 0.8), p3
    # ... without one, both reach the floor and P3 is about 1.
    train, test = synth_run(seed=2, a2=(0, 0, 0)), synth_run(seed=3, a2=(0, 0, 0))
    conv = fit_model([train], kind='poly', features='dT')
    modi = fit_model([train], kind='poly', features='dT,dT2')
    p3 = _bs(modi, test) / _bs(conv, test)
    assert np.all(np.abs(p3 - 1) < 0.02), p3


def test_flexible_rbf_in_dt_alone_absorbs_static_curvature():
    train, test = synth_run(seed=4), synth_run(seed=6)
    rbf_dt = fit_model([train], kind='rbf', features='dT')
    assert np.all(_bs(rbf_dt, test) < 1.1 * test.info['noise_dps'] ** 2)


def test_lag_feature_recovers_tau_and_reaches_floor_where_static_models_cannot():
    kw = dict(tau_die=600.0, cooling=True)
    train, test = synth_run(seed=7, a2=(0, 0, 0), **kw), synth_run(seed=8, **kw)
    lag_only = fit_model([train], kind='poly', features='lag')
    assert lag_only.effect_params['lag']['tau_s'] == pytest.approx(600.0, rel=0.05)
    train = synth_run(seed=7, **kw)
    floor = test.info['noise_dps'] ** 2
    lag = fit_model([train], features='lag')
    static = fit_model([train], features='dT,dT2')
    px4 = fit_px4_cubic([train])
    assert np.all(_bs(lag, test) < 1.2 * floor)
    assert np.all(_bs(static, test) > 2 * floor)
    assert np.all(_bs(px4, test) > 2 * floor)


def test_scale_effect_identified_with_rate_table_and_removed_from_measured_rate():
    # Sensitivity relative to the soak temperature (T0): a constant scale-factor error is a
    # calibration matter, not a thermal one.
    kw = dict(scale=(2e-3, -1e-3, 1.5e-3), ref_dps=(10.0, 5.0, 20.0), ref_period_s=300.0,
              t_ref=-10.0)
    train, test = synth_run(seed=9, **kw), synth_run(seed=10, **kw)
    model = fit_model([train], features='dT,dT2,scale')
    np.testing.assert_allclose(model.scale, [2e-3, -1e-3, 1.5e-3], rtol=0.05)
    assert np.all(_bs(model, test) < 1.1 * test.info['noise_dps'] ** 2)
    pred = predict_drift(model, test.t, test.temp, test.omega_ref)
    resid = (test.omega - pred) * 180 / np.pi
    assert np.all(np.sqrt(np.mean(resid ** 2, axis=0)) < 1.05 * test.info['noise_dps'])


def test_refinement_does_not_hurt():
    train, test = synth_run(seed=11, hours=1.0), synth_run(seed=12, hours=1.0)
    plain = fit_model([train], features='dT,dT2', n_centers=6)
    refined = fit_model([train], features='dT,dT2', n_centers=6, refine=True)
    assert np.all(_bs(refined, test) <= 1.02 * _bs(plain, test))


def test_t0_is_the_stable_initial_temperature():
    run = synth_run(seed=15, t_lo=-40.0, t_hi=85.0)
    assert estimate_t0(run) == pytest.approx(-40.0, abs=1e-9)


def test_bad_training_data_raise_clear_errors():
    run = synth_run(seed=16, hours=0.2)
    with pytest.raises(FitError, match='Too few samples'):
        fit_model([run.slice(0, 10)])
    flat = synth_run(seed=16, hours=0.2, t_lo=20.0, t_hi=20.1)
    with pytest.raises(FitError, match='Temperature span too small'):
        fit_model([flat])
    with pytest.raises(FitError, match='non-zero reference rate'):
        fit_model([run], features='dT,scale')
    with pytest.raises(FitError, match='Unknown model kind'):
        fit_model([run], kind='mlp')
    with pytest.raises(FitError, match='No training runs'):
        fit_model([])


@pytest.mark.parametrize('features', ['dT,dT2', 'dT,dT2,scale'])
def test_training_metrics_equal_the_full_rate_residual(features):
    # The metrics come from block sums, not a second full-rate pass: check they agree.
    run = synth_run(seed=17, hours=6.0, rate_hz=10.0, ref_dps=(10.0, 5.0, 20.0),
                    ref_period_s=300.0, scale=(1e-3, 0.0, 2e-3), t_ref=-10.0)
    model = fit_model([run], features=features, max_rows=20_000)
    full = bias_stability(compensate(model, run.t, run.temp, run.omega), run.omega_ref)
    np.testing.assert_allclose(model.metrics['train_bs_dps2'], full, rtol=1e-3)
    np.testing.assert_allclose(model.residual_var, np.radians(np.sqrt(full)) ** 2, rtol=1e-3)
    np.testing.assert_allclose(model.metrics['raw_bs_dps2'],
                               bias_stability(run.omega, run.omega_ref), rtol=1e-9)


def test_fit_linear_recovers_a_linear_law_and_its_scale_term():
    rng = np.random.default_rng(2)
    x = rng.uniform(-20.0, 30.0, size=(400, 2))
    w = np.array([[0.1, -0.2, 0.3], [0.01, 0.02, -0.03], [1e-3, 0.0, 2e-3]])
    cols = rng.normal(size=(400, 3))
    s = np.array([1e-3, -2e-3, 5e-4])
    y = np.column_stack([np.ones(400), x]) @ w + cols * s
    fit = fit_linear(x, y, scale_cols=cols, kind='poly', ridge=1e-12)
    assert isinstance(fit, LinearFit) and fit.centers.shape == (0, 2)
    np.testing.assert_allclose(fit.scale, s, atol=1e-9)
    np.testing.assert_allclose(fit.predict(x, cols), y, atol=1e-9)
    np.testing.assert_allclose(fit.resid, fit.predict(x, cols) - y, atol=1e-12)
    assert fit.sse == pytest.approx(float((fit.resid ** 2).sum()))
    assert fit.design(x).shape == (400, 3) and fit.coef.shape == (3, 3)


def test_fit_linear_rbf_auto_ridge_is_from_the_grid_and_beats_poly_on_a_bump():
    x = np.linspace(-1.0, 1.0, 300)[:, None]
    y = np.repeat(np.exp(-(x / 0.3) ** 2), 3, axis=1)
    rbf = fit_linear(x, y, kind='rbf', n_centers=8, ridge='auto', seed=0)
    poly = fit_linear(x, y, kind='poly')
    assert rbf.ridge in RIDGE_GRID and rbf.centers.shape[0] >= 2
    assert rbf.sse < 0.01 * poly.sse
    assert fit_linear(x, y, kind='rbf', n_centers=8, seed=0).sse == rbf.sse  # seeded


def test_fit_time_constant_finds_the_minimum_and_keeps_the_profile():
    calls = []

    def sse(tau):
        calls.append(tau)
        return (math.log(tau) - math.log(173.0)) ** 2 + 2.0

    res = fit_time_constant(sse, (1.0, 20000.0), n_grid=13)
    assert isinstance(res, TimeConstantFit)
    assert res.tau == pytest.approx(173.0, rel=2e-3) and res.sse == pytest.approx(2.0)
    assert res.grid_tau.shape == res.grid_sse.shape == (13,)
    np.testing.assert_allclose(res.grid_tau[[0, -1]], [1.0, 20000.0])
    np.testing.assert_allclose(res.grid_sse, [sse(v) for v in res.grid_tau])
    assert res.sse <= res.grid_sse.min()
    assert all(1.0 <= c <= 20000.0 for c in calls)
    lin = fit_time_constant(lambda tau: (tau - 7.3) ** 2, (0.0, 20.0), n_grid=5, log=False,
                            xatol=1e-6)
    assert lin.tau == pytest.approx(7.3, abs=1e-4)
    np.testing.assert_allclose(lin.grid_tau, [0.0, 5.0, 10.0, 15.0, 20.0])


def test_fit_time_constant_keeps_the_grid_point_at_an_edge_and_on_a_single_point():
    res = fit_time_constant(lambda tau: tau, (2.0, 50.0), n_grid=6)
    assert res.tau == pytest.approx(2.0, rel=1e-3)
    one = fit_time_constant(lambda tau: 1.0, (30.0, 30.0), n_grid=1)
    assert one.tau == pytest.approx(30.0) and one.grid_tau.shape == (1,)


@pytest.mark.parametrize('bounds, n_grid, log', [((0.0, 10.0), 5, True), ((5.0, 1.0), 5, True),
                                                 ((-1.0, 1.0), 5, False),
                                                 ((1.0, math.inf), 5, True),
                                                 ((1.0, 2.0), 0, True)])
def test_fit_time_constant_rejects_bad_bounds(bounds, n_grid, log):
    with pytest.raises(FitError, match='bounds|n_grid'):
        fit_time_constant(lambda tau: tau, bounds, n_grid=n_grid, log=log)


@pytest.mark.parametrize('n_grid, xatol', [(13, 1e-3), (14, 0.01), (25, 1e-3)])
def test_fit_time_constant_equals_the_grid_then_brent_search_it_replaced(n_grid, xatol):
    # The search formerly written inline in fitting (13 points), discover (14, xatol 0.01)
    # and realdata_eval (25): log grid, bounded Brent between the best point's neighbours.
    from scipy.optimize import minimize_scalar
    rng = np.random.default_rng(n_grid)
    bumps = rng.normal(size=8) * 0.05

    def sse_log(v):
        return (v - 5.1) ** 2 + float(bumps @ np.sin(np.arange(1, 9) * v))

    grid = np.linspace(math.log(1.0), math.log(20000.0), n_grid)
    vals = [sse_log(g) for g in grid]
    i = int(np.argmin(vals))
    best = minimize_scalar(sse_log, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, n_grid - 1)]),
                           method='bounded', options={'xatol': xatol})
    want = float(math.exp(best.x if best.fun <= vals[i] else grid[i]))
    got = fit_time_constant(lambda tau: sse_log(math.log(tau)), (1.0, 20000.0), n_grid=n_grid,
                            xatol=xatol)
    assert got.tau == pytest.approx(want, rel=1e-9)
