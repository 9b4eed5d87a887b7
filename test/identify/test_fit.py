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


"""Tests of gyro_tdc.identify.fit: a known drift recovered, checks, metrics, session offsets."""

from __future__ import annotations

from dataclasses import replace
import math

from gyro_tdc.errors import FitError
from gyro_tdc.identify import (estimate_t0, fit_model, fit_px4_cubic, FitOptions,
                               session_check_lines)
from gyro_tdc.model import ThermalState
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
    with pytest.raises(FitError, match='Expected `kind` to be one of rbf, poly'):
        fit_model([run], opts, kind='spline')


def test_fit_options_refuse_an_unknown_kind_or_front_end_when_built():
    """One check of the choices, shared by FitOptions, TrainOptions and the accelerometer."""
    with pytest.raises(FitError, match="Expected `kind` to be one of rbf, poly, got 'mlp'."):
        FitOptions(kind='mlp')
    with pytest.raises(FitError, match="two_node, auto or a ThermalState, got 'hot'."):
        FitOptions(thermal='hot')
    for thermal in (None, 'auto', ThermalState('first_order', (60.0,))):
        assert FitOptions(thermal=thermal).thermal == thermal


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
    with pytest.raises(FitError, match='Expected `kind` to be one of rbf, poly'):
        fit_model([run], kind='mlp')
    with pytest.raises(FitError, match='No training runs'):
        fit_model([])


def test_a_lagged_die_that_barely_moves_is_refused_in_one_line():
    """The thermometer spans 1 degC in the last 30 s; a die lagging it by 1500 s does not."""
    run = synth_run(seed=16, hours=0.2, t_lo=20.0, t_hi=20.0)
    t = run.t - run.t[0]
    late = replace(run, temp=20.0 + np.clip((t - (t[-1] - 30.0)) / 30.0, 0.0, 1.0))
    with pytest.raises(FitError, match=r'^The lagged die temperature \(tau 1500 s\) spans '
                                       r'0\.0[0-9]+ degC only .*the thermometer 1\.00 degC.*'
                                       'give --features without lag\\.$'):
        fit_model([late], features='dT,dT2', thermal=ThermalState('first_order', (1500.0,)))
    assert fit_model([late], features='dT,dT2').temp_range_c == (20.0, 21.0)   # no lag: fits


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


DEG = math.pi / 180.0
OFFSETS = ((0.4, -0.3, 0.1), (-0.5, 0.2, 0.45), (0.05, 0.5, -0.35))


def _runs(noise=0.0, offsets=OFFSETS[:2], ranges=((-10.0, 30.0), (15.0, 50.0)), **kw):
    return [synth_run(seed=i, hours=1.0, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=noise,
                      offset_dps=off, name=f'run{i}', **kw)
            for i, (off, (lo, hi)) in enumerate(zip(offsets, ranges))]


@pytest.mark.parametrize('kind', ['poly', 'rbf'])
def test_known_offsets_are_recovered_exactly_on_noise_free_data(kind):
    runs = _runs()
    m = fit_model(runs, kind=kind, features='dT,dT2', t0=25.0, sessions=[0, 1])
    info = m.metrics['sessions']
    off = np.array(OFFSETS[:2])
    assert info['count'] == 2 and info['names'] == ['run0', 'run1']
    np.testing.assert_allclose(info['offset_dps'], off - off.mean(axis=0), atol=1e-9)
    np.testing.assert_allclose(info['spread_dps'], np.abs(off[0] - off[1]), atol=1e-9)
    # The curve: the drift of the mean session, exactly (b0 + mean offset at T0 = 25 degC).
    truth = synth_run(hours=1.0, rate_hz=2.0, t_lo=-10.0, t_hi=50.0, noise_dps=0.0,
                      offset_dps=tuple(off.mean(axis=0)))
    pred = predict_drift(m, truth.t, truth.temp, truth.omega_ref)
    np.testing.assert_allclose(pred, truth.omega, atol=1e-9 if kind == 'poly' else 2e-6)
    assert max(m.metrics['train_rms_dps']) < (1e-9 if kind == 'poly' else 2e-6)


def test_a_curve_that_carries_across_power_cycles_is_kept_with_its_figures():
    m = fit_model(_runs(noise=0.02), kind='poly', features='dT,dT2', t0=25.0, sessions=[0, 1])
    check = m.metrics['sessions']['heldout']
    assert check['folds'] == 2 and check['offset_only'] == []
    assert all(c < o for c, o in zip(check['curve_ms_dps2'], check['offset_ms_dps2']))
    assert np.all(m.linear != 0.0)
    unchecked = fit_model(_runs(noise=0.02), kind='poly', features='dT,dT2', t0=25.0,
                          sessions=[0, 1], check_sessions=False)
    assert 'heldout' not in unchecked.metrics['sessions']
    np.testing.assert_array_equal(unchecked.linear, m.linear)
    bias = fit_model(_runs(noise=0.02), kind='poly', features='bias', sessions=[0, 1])
    assert 'heldout' not in bias.metrics['sessions']      # no curve: nothing to judge


def test_an_axis_whose_curve_does_not_carry_keeps_the_offset_only():
    # x: the slope flips from one power cycle to the next (no curve carries); y, z: shared.
    runs = [synth_run(seed=i, hours=1.0, rate_hz=2.0, t_lo=0.0, t_hi=40.0, noise_dps=0.02,
                      a1=(a, -0.015, 0.01), a2=(0.0, 1.5e-4, -1e-4), offset_dps=OFFSETS[i],
                      name=f'run{i}') for i, a in enumerate((0.02, -0.02))]
    m = fit_model(runs, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1])
    check = m.metrics['sessions']['heldout']
    assert check['offset_only'] == ['x']
    assert check['curve_ms_dps2'][0] >= check['offset_ms_dps2'][0]
    np.testing.assert_array_equal(m.linear[:, 0], 0.0)
    assert np.all(m.linear[:, 1:] != 0.0) and m.scale[0] == 0.0
    # The offset of each session on x is its mean; the model's none: +0.4 and -0.5 deg/s
    # (and the curve's level) do not predict each other better than no offset.
    means = [float(np.mean(r.omega[:, 0] - r.omega_ref[:, 0])) for r in runs]
    assert m.metrics['sessions']['turn_on']['no_offset'] == ['x'] and m.intercept[0] == 0.0
    assert m.metrics['sessions']['offset_dps'][0][0] == pytest.approx(np.degrees(means[0]),
                                                                      rel=1e-3)
    # The training residual on x is the scatter around each session's mean.
    var = np.mean([np.var(r.omega[:, 0]) for r in runs])
    assert m.residual_var[0] == pytest.approx(var, rel=0.02)


def test_a_curve_that_misses_one_held_out_power_cycle_keeps_the_offset_only():
    # x: three power cycles share a slope, the fourth flips: the curve wins on the pooled
    # held-out mean square but predicts that power cycle worse; y, z carry on every one.
    runs = [synth_run(seed=i, hours=1.0, rate_hz=2.0, t_lo=0.0, t_hi=40.0, noise_dps=0.02,
                      a1=(a, -0.015, 0.01), a2=(0.0, 1.5e-4, -1e-4), offset_dps=OFFSETS[i % 3],
                      name=f'run{i}') for i, a in enumerate((0.03, 0.025, 0.02, -0.01))]
    m = fit_model(runs, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1, 2, 3])
    check = m.metrics['sessions']['heldout']
    assert check['curve_ms_dps2'][0] < check['offset_ms_dps2'][0]
    assert check['worse_folds'] == [1, 0, 0] and check['offset_only'] == ['x']
    np.testing.assert_array_equal(m.linear[:, 0], 0.0)
    assert np.all(m.linear[:, 1:] != 0.0)
    lines = session_check_lines(check)
    assert '  power cycles predicted worse by the curve: 1  0  0' in lines
    assert lines[-1].startswith('axes x: the curve does not predict every held-out power')


def test_one_intercept_bends_the_curve_per_session_offsets_do_not():
    runs = _runs(noise=0.02)
    third = synth_run(seed=7, hours=1.0, rate_hz=2.0, t_lo=0.0, t_hi=40.0, noise_dps=0.02,
                      offset_dps=OFFSETS[2])
    errors = {}
    for label, sessions in (('one', None), ('per session', [0, 1])):
        m = fit_model(runs, kind='poly', features='dT,dT2,dT3', t0=25.0, sessions=sessions)
        comp = compensate(m, third.t, third.temp, third.omega)
        head = third.t <= third.t[0] + 600.0
        comp = comp - comp[head].mean(axis=0)           # re-anchored on its first 10 min
        errors[label] = np.sqrt(np.mean(comp ** 2, axis=0)) / DEG
    assert np.all(errors['per session'] < 0.021)        # the noise: 0.02 deg/s
    assert np.all(errors['one'] > 0.05)                 # bent by the two offsets


def test_one_session_label_is_the_model_without_sessions():
    runs = _runs(noise=0.02)
    ref = fit_model(runs, kind='rbf', features='dT,dT2', t0=25.0, seed=1)
    same = fit_model(runs, kind='rbf', features='dT,dT2', t0=25.0, seed=1,
                     sessions=['a', 'a'])
    assert same.model_id == ref.model_id and 'sessions' not in same.metrics


def test_sessions_with_a_thermal_state_and_still_rows():
    runs = _runs(noise=0.0, tau_die=300.0)
    rows = [np.arange(len(r)) % 3 != 0 for r in runs]
    m = fit_model(runs, kind='poly', features='dT,dT2,lag', t0=25.0, sessions=[0, 1],
                  rows=rows)
    off = np.array(OFFSETS[:2])
    assert m.thermal.tau_s[0] == pytest.approx(300.0, rel=0.02)
    np.testing.assert_allclose(m.metrics['sessions']['offset_dps'], off - off.mean(axis=0),
                               atol=2e-3)
    assert m.metrics['sessions']['samples'] == [int(np.count_nonzero(r)) for r in rows]


def test_session_labels_must_match_the_runs():
    with pytest.raises(FitError, match='one session label per run'):
        fit_model(_runs(), features='dT', sessions=[0])
