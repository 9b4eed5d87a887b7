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

from gyro_tdc.errors import FitError
from gyro_tdc.fitting import estimate_t0, fit_model, fit_px4_cubic
from gyro_tdc.metrics import bias_stability
from gyro_tdc.model import compensate, drift, predict_drift, StreamingCompensator
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
