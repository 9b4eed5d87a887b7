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

"""The simulator: the gyro model (effects, noise, digits), the accelerometer, SimStream."""

from __future__ import annotations

import math

from gyro_tdc.data.runs import Run
from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import (EFFECT_IDS, load_scenario, Scenario, SimStream, simulate_run,
                          simulate_scenario, to_run)
from gyro_tdc.sim.noise import white_noise
from gyro_tdc.sim.simulator import G0
import numpy as np
import pytest
from scenarios import accel_thermal, gravity_vector

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


# The accelerometer physics: tilted gravity, a thermal offset of the die, noise and digits.

ACCEL_BASE = {
    'name': 'acc',
    'imu_rate_hz': 5.0,
    'profile': {'start_c': 0.0, 'segments': [
        {'kind': 'hold', 'duration_s': 300.0},
        {'kind': 'ramp', 'to_c': 60.0, 'rate_c_per_h': 120.0},
        {'kind': 'hold', 'duration_s': 300.0},
    ]},
    'thermal': {'tau_package_s': 60.0, 'tau_die_s': 120.0},
    'gyro': {'effects': ['bias', 'dT', 'lag'], 't_ref_c': 25.0},
    'accel': {'noise_mps2_per_rt_hz': 0.0},
}


def _accel_run(overrides: dict, seed: int = 0):
    return simulate_run(Scenario.from_dict(ACCEL_BASE).with_overrides(overrides), seed=seed)


def test_defaults_keep_gravity_on_z_and_the_old_output():
    # No tilt, offset or digits: the output of the accelerometer before its physics existed.
    run = _accel_run({'accel.noise_mps2_per_rt_hz': 0.002})
    old = np.random.default_rng(np.random.SeedSequence(0, spawn_key=(0,)).spawn(6)[4])
    expected = white_noise(old, len(run), density=(0.002,) * 3, rate_hz=5.0)
    expected[:, 2] += 9.80665
    np.testing.assert_array_equal(run.accel, expected)
    np.testing.assert_array_equal(run.truth.accel_gravity, [[0.0, 0.0, 9.80665]] * 2)


@pytest.mark.parametrize('roll, pitch', [(0.0, 0.0), (30.0, 0.0), (0.0, -20.0), (10.0, 45.0)])
def test_gravity_vector_has_the_magnitude_and_points_up(roll, pitch):
    g = gravity_vector(9.81, roll, pitch)
    assert np.linalg.norm(g) == pytest.approx(9.81, rel=1e-12)
    assert g[2] == pytest.approx(9.81 * math.cos(math.radians(roll)) * math.cos(
        math.radians(pitch)))
    assert g[0] == pytest.approx(-9.81 * math.sin(math.radians(pitch)))


def test_fixed_tilt_puts_gravity_in_the_sensor_frame():
    run = _accel_run({'accel.tilt_deg': [20.0, -10.0]})
    np.testing.assert_allclose(run.accel, np.broadcast_to(gravity_vector(9.80665, 20.0, -10.0),
                                                          run.accel.shape), rtol=0, atol=1e-12)


def test_random_tilt_is_drawn_per_run_and_reproducible():
    sc = Scenario.from_dict(ACCEL_BASE).with_overrides({'accel.tilt_std_deg': 5.0,
                                                        'runs.count': 3})
    a = simulate_scenario(sc, seed=3)
    b = simulate_scenario(sc, seed=3)
    tilts = np.array([r.truth.accel_tilt_deg for r in a])
    assert len({tuple(t) for t in tilts}) == 3
    assert np.all(np.abs(tilts) < 25.0)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.accel, y.accel)
    # The gyro of each run does not depend on the tilt stream.
    c = simulate_scenario(Scenario.from_dict(ACCEL_BASE).with_overrides({'runs.count': 3}), seed=3)
    for x, y in zip(a, c):
        np.testing.assert_array_equal(x.gyro, y.gyro)


def test_thermal_offset_is_curved_in_the_die_temperature():
    coef = {'accel.bias_mg': [10.0, -5.0, 0.0], 'accel.dT_mg_per_c': [0.3, -0.2, 0.1],
            'accel.dT2_mg_per_c2': [2e-3, 1e-3, -3e-3]}
    run = _accel_run(coef)
    d = run.truth.die_c - 25.0
    mg = G0 * 1e-3
    for a in range(3):
        want = (coef['accel.bias_mg'][a] + coef['accel.dT_mg_per_c'][a] * d
                + coef['accel.dT2_mg_per_c2'][a] * d * d) * mg
        np.testing.assert_allclose(run.truth.accel_offset[:, a], want, atol=1e-12)
        np.testing.assert_allclose(run.truth.accel_thermal[:, a],
                                   want - coef['accel.bias_mg'][a] * mg, atol=1e-12)
    g = run.truth.accel_gravity[0]
    np.testing.assert_allclose(run.accel, g + run.truth.accel_offset, atol=1e-12)
    # The die lags the package: the offset follows the die, not the thermometer.
    assert np.max(np.abs(run.truth.die_c - run.truth.package_c)) > 1.0


def test_noise_and_digits_set_the_floor():
    run = _accel_run({'accel.noise_mps2_per_rt_hz': 0.003,
                      'accel.sensitivity_mg_per_digit': 1.0,
                      'profile.segments': [{'kind': 'hold', 'duration_s': 4000.0}]})
    step = G0 * 1e-3
    assert run.truth.accel_quant_step == pytest.approx(step)
    np.testing.assert_allclose(np.round(run.accel / step), run.accel / step, atol=1e-9)
    floor = math.sqrt((0.003 * math.sqrt(5.0)) ** 2 + step ** 2 / 12.0)
    np.testing.assert_allclose(run.truth.accel_noise_std, floor)
    np.testing.assert_allclose(run.accel.std(axis=0), floor, rtol=0.05)


def test_range_saturates():
    run = _accel_run({'accel.range_g': 0.5})
    assert np.max(np.abs(run.accel)) == pytest.approx(0.5 * G0)


def test_mid_run_reorientation_steps_gravity():
    run = _accel_run({'accel.reorient_at_s': 1000.0, 'accel.reorient_tilt_deg': [15.0, 0.0]})
    k = int(np.searchsorted(run.imu_t, 1000.0))
    np.testing.assert_allclose(run.accel[:k], np.broadcast_to(
        gravity_vector(9.80665, 0.0, 0.0), (k, 3)), atol=1e-12)
    np.testing.assert_allclose(run.accel[k:], np.broadcast_to(
        gravity_vector(9.80665, 15.0, 0.0), (len(run) - k, 3)), atol=1e-12)
    assert run.truth.accel_reorient_s == 1000.0


@pytest.mark.parametrize('key, value, match', [
    ('accel.tilt_deg', [1.0], 'roll and pitch'),
    ('accel.tilt_deg', [0.0, 200.0], 'roll and pitch'),
    ('accel.tilt_std_deg', -1.0, 'tilt_std_deg'),
    ('accel.dT_mg_per_c', 'x', 'dT_mg_per_c'),
    ('accel.sensitivity_mg_per_digit', -0.1, 'sensitivity_mg_per_digit'),
])
def test_bad_accel_fields_are_named(key, value, match):
    with pytest.raises(ScenarioError, match=match):
        Scenario.from_dict(ACCEL_BASE).with_overrides({key: value})


def test_accel_chamber_scenario_ships_and_to_run_carries_the_accelerometer():
    sc = load_scenario('accel_chamber')
    assert sc.runs.count == 2 and accel_thermal(sc.accel)
    run = to_run(simulate_run(sc, seed=0, rate_hz=0.2))
    assert run.accel is not None and run.accel.shape == (len(run), 3)
    assert run.slice(5, 10).accel.shape == (5, 3)


MINIMAL = {'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 10.0}]}}


def test_simulate_rejects_bad_seed_rate_and_run_index():
    sc = Scenario.from_dict(MINIMAL)
    with pytest.raises(ScenarioError, match='seed'):
        simulate_run(sc, seed=-1)
    with pytest.raises(ScenarioError, match='rate_hz'):
        simulate_run(sc, rate_hz=0.0)
    with pytest.raises(ScenarioError, match='run_index'):
        simulate_run(sc, run_index=1)


@pytest.fixture(scope='module')
def scenario():
    return load_scenario('rate_steps').with_overrides({'duration_s': 900.0})


def test_chunks_concatenate_to_the_batch_run(scenario):
    batch = simulate_scenario(scenario, seed=3, rate_hz=10.0)[1]
    stream = SimStream(scenario, seed=3, run_index=1, rate_hz=10.0)
    imu, temp, ref = [], [], []
    t = 0.0
    while not stream.done:
        chunk_imu, chunk_temp, chunk_ref = stream.next_until(t)
        assert np.all(chunk_imu.t <= t) and np.all(chunk_temp.t <= t)
        imu.append(chunk_imu)
        temp.append(chunk_temp)
        ref.append(chunk_ref)
        t += 0.73
    assert stream.position >= max(batch.imu_t[-1], batch.temp_t[-1], batch.ref_t[-1])
    np.testing.assert_array_equal(np.concatenate([c.t for c in imu]), batch.imu_t)
    np.testing.assert_array_equal(np.concatenate([c.gyro for c in imu]), batch.gyro)
    np.testing.assert_array_equal(np.concatenate([c.accel for c in imu]), batch.accel)
    np.testing.assert_array_equal(np.concatenate([c.temp_c for c in temp]), batch.temp_c)
    np.testing.assert_array_equal(np.concatenate([c.t for c in ref]), batch.ref_t)
    np.testing.assert_array_equal(np.concatenate([c.ref for c in ref]), batch.ref)
    assert stream.run.temp_var == batch.temp_var


def test_going_back_in_time_returns_nothing(scenario):
    stream = SimStream(scenario, seed=0, rate_hz=10.0)
    first, _, _ = stream.next_until(10.0)
    assert first.t.size == 101 and first.gyro.shape == (101, 3)
    again, temp, ref = stream.next_until(5.0)
    assert again.t.size == 0 and temp.t.size == 0 and ref.t.size == 0
    assert stream.position == 10.0
    with pytest.raises(ScenarioError, match='`t`'):
        stream.next_until(float('nan'))
