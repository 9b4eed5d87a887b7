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

"""The gyro model: configured effects are in the output, noise and digits are as specified."""

from __future__ import annotations

import math

from gyro_tdc.data.runs import Run
from gyro_tdc.sim import EFFECT_IDS, Scenario, simulate_run, simulate_scenario, to_run
import numpy as np
import pytest

DEG = math.pi / 180.0

# Heating and cooling at different rates with soaks, rate-table steps: every effect excited.
RICH = {
    'name': 'rich',
    'imu_rate_hz': 5.0,
    'profile': {'start_c': 0.0, 'segments': [
        {'kind': 'hold', 'duration_s': 1200.0},
        {'kind': 'ramp', 'to_c': 60.0, 'rate_c_per_h': 120.0},
        {'kind': 'hold', 'duration_s': 600.0},
        {'kind': 'ramp', 'to_c': -10.0, 'rate_c_per_h': 60.0},
    ]},
    'thermal': {'tau_package_s': 60.0},
    'gyro': {
        'effects': ['bias', 'dT', 'dT2', 'dT3', 'dTdt', 'scale', 'warmup'],
        't_ref_c': 25.0,
        'bias_dps': [1.5, -2.0, 0.5],
        'dT_dps_per_c': [0.03, -0.02, 0.01],
        'dT2_dps_per_c2': [8e-4, 5e-4, -3e-4],
        'dT3_dps_per_c3': [4e-6, -3e-6, 2e-6],
        'dTdt_dps_per_c_per_s': [6.0, -4.0, 3.0],
        'scale_ppm_per_c': [160.0, -120.0, 90.0],
        'warmup_dps': [0.3, -0.2, 0.15],
        'warmup_tau_s': 240.0,
        'sensitivity_mdps_per_digit': 8.75,
        'range_dps': 250.0,
    },
    'noise': {'arw_dps_per_rt_hz': 0.03},
    'rate_table': [{'t_s': 200.0 * k, 'rate_dps': [40.0 * (-1) ** k, 20.0 * (k % 3 - 1),
                                                   -30.0 * (-1) ** (k // 2)]}
                   for k in range(45)],
}
COEFFS = ('bias', 'dT', 'dT2', 'dT3', 'dTdt', 'scale', 'warmup')
UNITS = {'bias': DEG, 'dT': DEG, 'dT2': DEG, 'dT3': DEG, 'dTdt': DEG, 'scale': 1e-6,
         'warmup': DEG}
KEYS = {'bias': 'bias_dps', 'dT': 'dT_dps_per_c', 'dT2': 'dT2_dps_per_c2',
        'dT3': 'dT3_dps_per_c3', 'dTdt': 'dTdt_dps_per_c_per_s', 'scale': 'scale_ppm_per_c',
        'warmup': 'warmup_dps'}


def _design(run, axis: int, t_ref: float, tau_w: float) -> np.ndarray:
    """Regressors of one axis on the true die temperature (rad/s model, per coefficient)."""
    d_t = run.truth.die_c - t_ref
    ref = run.ref_at(run.imu_t)[:, axis]
    return np.column_stack([np.ones_like(d_t), d_t, d_t ** 2, d_t ** 3,
                            run.truth.die_rate_c_per_s, ref * d_t,
                            np.exp(-run.imu_t / tau_w)])


def _fit(run, t_ref=25.0, tau_w=240.0) -> dict[str, np.ndarray]:
    err = run.gyro - run.ref_at(run.imu_t)
    out = np.zeros((len(COEFFS), 3))
    for axis in range(3):
        x = _design(run, axis, t_ref, tau_w)
        out[:, axis] = np.linalg.lstsq(x, err[:, axis], rcond=None)[0]
    return dict(zip(COEFFS, out))


def test_noise_free_output_is_exactly_the_model():
    sc = Scenario.from_dict(RICH).with_overrides({'noise.enabled': False,
                                                  'gyro.quantise': False})
    run = simulate_run(sc, seed=0)
    fitted = _fit(run)
    for name in COEFFS:
        expected = np.asarray(RICH['gyro'][KEYS[name]]) * UNITS[name]
        np.testing.assert_allclose(fitted[name], expected, rtol=1e-6, atol=1e-12,
                                   err_msg=name)
        np.testing.assert_allclose(run.truth.coefficients[name], expected, rtol=1e-12)
    np.testing.assert_allclose(run.gyro - run.ref_at(run.imu_t), run.truth.drift, atol=1e-15)


def test_least_squares_recovers_every_effect_from_noisy_quantised_output():
    run = simulate_run(Scenario.from_dict(RICH), seed=11)
    fitted = _fit(run)
    # Tolerances: a few standard errors at 0.067 deg/s white noise over 46,800 samples.
    tolerances = {'bias': 0.002 * DEG, 'dT': 1e-4 * DEG, 'dT2': 5e-6 * DEG,
                  'dT3': 2e-7 * DEG, 'dTdt': 0.2 * DEG, 'scale': 3e-6, 'warmup': 0.01 * DEG}
    for name in COEFFS:
        expected = np.asarray(RICH['gyro'][KEYS[name]]) * UNITS[name]
        np.testing.assert_allclose(fitted[name], expected, rtol=0, atol=tolerances[name],
                                   err_msg=name)


def test_switched_off_effect_contributes_nothing_and_leaves_noise_alone():
    sc = Scenario.from_dict(RICH).with_overrides({'gyro.quantise': False})
    full = simulate_run(sc, seed=4)
    no_dt2 = simulate_run(sc.with_overrides({'gyro.effects.dT2': False}), seed=4)
    d_t = full.truth.die_c - 25.0
    a2 = np.asarray(RICH['gyro']['dT2_dps_per_c2']) * DEG
    np.testing.assert_allclose(full.gyro - no_dt2.gyro, np.outer(d_t ** 2, a2), atol=1e-12)
    assert 'dT2' not in no_dt2.truth.effects
    np.testing.assert_array_equal(no_dt2.truth.coefficients['dT2'], 0.0)


def test_all_effects_off_leaves_only_the_reference_and_noise():
    sc = Scenario.from_dict(RICH).with_overrides({'gyro.effects': {k: False
                                                                   for k in EFFECT_IDS}})
    run = simulate_run(sc, seed=1)
    np.testing.assert_array_equal(run.truth.drift, 0.0)
    resid = run.gyro - run.ref_at(run.imu_t)
    assert np.std(resid) == pytest.approx(run.truth.noise_std[0], rel=0.03)


@pytest.mark.parametrize('rate_hz', [10.0, 200.0])
def test_white_noise_std_is_density_times_root_rate(rate_hz):
    sc = Scenario.from_dict({
        'imu_rate_hz': rate_hz,
        'profile': {'start_c': 25.0, 'segments': [{'kind': 'hold',
                                                   'duration_s': 40000.0 / rate_hz}]},
        'gyro': {'effects': [], 'quantise': False},
        'noise': {'arw_dps_per_rt_hz': [0.03, 0.01, 0.05]}})
    run = simulate_run(sc, seed=7)
    expected = np.array([0.03, 0.01, 0.05]) * DEG * math.sqrt(rate_hz)
    np.testing.assert_allclose(run.truth.white_std, expected)
    np.testing.assert_allclose(run.gyro.std(axis=0), expected, rtol=0.02)
    assert np.all(np.abs(run.gyro.mean(axis=0)) < 4.0 * expected / math.sqrt(len(run)))
    lag1 = [np.corrcoef(run.gyro[:-1, i], run.gyro[1:, i])[0, 1] for i in range(3)]
    np.testing.assert_allclose(lag1, 0.0, atol=0.02)


def test_bias_instability_and_rate_random_walk_statistics():
    base = {
        'imu_rate_hz': 10.0,
        'profile': {'start_c': 25.0, 'segments': [{'kind': 'hold', 'duration_s': 20000.0}]},
        'gyro': {'effects': [], 'quantise': False}}
    gm = simulate_run(Scenario.from_dict(dict(base, noise={
        'bias_instability_dps': 0.01, 'bias_instability_tau_s': [5.0, 20.0]})), seed=2)
    assert np.std(gm.gyro) == pytest.approx(0.01 * DEG, rel=0.1)
    rrw = simulate_scenario(Scenario.from_dict(dict(base, noise={'rrw_dps_per_rt_s': 1e-3})),
                            seed=0)[0]
    # Increments over 100 s have std K sqrt(100 s).
    inc = rrw.gyro[1000:] - rrw.gyro[:-1000]
    assert np.std(inc) == pytest.approx(1e-3 * DEG * 10.0, rel=0.1)
    assert np.all(rrw.gyro[0] == 0.0)


def test_output_is_quantised_to_the_sensitivity_and_saturates():
    sc = Scenario.from_dict(RICH).with_overrides({
        'rate_table': [{'t_s': 0.0, 'rate_dps': [300.0, -20.0, 0.0]}]})
    run = simulate_run(sc, seed=0, rate_hz=1.0)
    step = 8.75e-3 * DEG
    assert run.truth.quant_step == pytest.approx(step)
    digits = run.gyro / step
    np.testing.assert_allclose(digits, np.round(digits), atol=1e-6)
    assert np.all(np.abs(run.gyro) <= 250.0 * DEG + step)
    np.testing.assert_allclose(run.gyro[:, 0], round(250.0 * DEG / step) * step)
    assert len(np.unique(np.round(digits[:, 1]))) > 100


def test_lag_effect_makes_the_die_trail_the_package():
    sc = Scenario.from_dict(dict(RICH, thermal={'tau_package_s': 60.0, 'tau_die_s': 200.0}))
    off = simulate_run(sc, seed=0, rate_hz=1.0)
    on = simulate_run(sc.with_overrides({'gyro.effects.lag': True}), seed=0, rate_hz=1.0)
    np.testing.assert_allclose(off.truth.die_c, off.truth.package_c)
    assert off.truth.params['tau_die_s'] == 0.0 and on.truth.params['tau_die_s'] == 200.0
    k = np.searchsorted(on.imu_t, 2900.0)                  # heating at 120 degC/h, settled
    assert on.truth.package_c[k] - on.truth.die_c[k] == pytest.approx(200.0 / 30.0, rel=1e-2)
    # The thermometer reads the package in both: the die is what lags it.
    np.testing.assert_allclose(on.temp_c, off.temp_c)


def test_warmup_decays_from_power_on():
    sc = Scenario.from_dict(RICH).with_overrides({
        'noise.enabled': False, 'gyro.quantise': False,
        'gyro.effects': ['warmup'], 'gyro.power_on_s': -120.0})
    run = simulate_run(sc, seed=0)
    w = np.asarray(RICH['gyro']['warmup_dps']) * DEG
    np.testing.assert_allclose(run.truth.drift[0], w * math.exp(-120.0 / 240.0))
    k = np.searchsorted(run.imu_t, 120.0)
    np.testing.assert_allclose(run.truth.drift[k], w * math.exp(-1.0), rtol=1e-9)


def test_accelerometer_reads_gravity_on_z():
    run = simulate_run(Scenario.from_dict(RICH).with_overrides(
        {'accel.noise_mps2_per_rt_hz': 0.002}), seed=0)
    np.testing.assert_allclose(run.accel.mean(axis=0), [0.0, 0.0, 9.80665], atol=1e-3)
    np.testing.assert_allclose(run.accel.std(axis=0), 0.002 * math.sqrt(5.0), rtol=0.03)


def test_runs_differ_by_seed_and_offset_and_reproduce():
    sc = Scenario.from_dict(RICH).with_overrides({'runs.count': 3,
                                                  'runs.bias_offset_dps_std': 0.03})
    runs = simulate_scenario(sc, seed=5, rate_hz=1.0)
    assert [r.name for r in runs] == ['rich/run1', 'rich/run2', 'rich/run3']
    offsets = np.array([r.truth.bias_offset for r in runs])
    assert np.all(np.abs(offsets) < 0.2 * DEG) and len(np.unique(offsets[:, 0])) == 3
    again = simulate_scenario(sc, seed=5, rate_hz=1.0, runs=[1])[0]
    np.testing.assert_array_equal(again.gyro, runs[1].gyro)
    other = simulate_scenario(sc, seed=6, rate_hz=1.0, runs=[1])[0]
    assert not np.array_equal(other.gyro, runs[1].gyro)


def test_to_run_holds_the_latest_thermometer_reading():
    sc = Scenario.from_dict(RICH).with_overrides({'thermometer.rate_hz': 0.5})
    sim = simulate_run(sc, seed=0)
    run = to_run(sim)
    assert isinstance(run, Run) and len(run) == len(sim)
    # IMU at 5 Hz, thermometer every 2 s: stamps 0..1.8 s read the t=0 sample, etc.
    np.testing.assert_array_equal(run.temp[:10], sim.temp_c[0])
    np.testing.assert_array_equal(run.temp[10:20], sim.temp_c[1])
    idx = np.searchsorted(sim.temp_t, sim.imu_t, side='right') - 1
    np.testing.assert_array_equal(run.temp, sim.temp_c[idx])
    np.testing.assert_array_equal(run.omega_ref, sim.ref_at(sim.imu_t))
    np.testing.assert_array_equal(run.omega_ref[1000], np.asarray(
        RICH['rate_table'][1000 // (200 * 5)]['rate_dps']) * DEG)
    assert run.info['truth'] is sim.truth and run.info['source'] == 'sim'
