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

"""The accelerometer physics: tilted gravity, a thermal offset of the die, noise and digits."""

from __future__ import annotations

import math

from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import load_scenario, Scenario, simulate_run, simulate_scenario, to_run
from gyro_tdc.sim.noise import white_noise
from gyro_tdc.sim.simulator import G0, gravity_vector
import numpy as np
import pytest

BASE = {
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


def _run(overrides: dict, seed: int = 0):
    return simulate_run(Scenario.from_dict(BASE).with_overrides(overrides), seed=seed)


def test_defaults_keep_gravity_on_z_and_the_old_output():
    # No tilt, offset or digits: the output of the accelerometer before its physics existed.
    run = _run({'accel.noise_mps2_per_rt_hz': 0.002})
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
    run = _run({'accel.tilt_deg': [20.0, -10.0]})
    np.testing.assert_allclose(run.accel, np.broadcast_to(gravity_vector(9.80665, 20.0, -10.0),
                                                          run.accel.shape), rtol=0, atol=1e-12)


def test_random_tilt_is_drawn_per_run_and_reproducible():
    sc = Scenario.from_dict(BASE).with_overrides({'accel.tilt_std_deg': 5.0, 'runs.count': 3})
    a = simulate_scenario(sc, seed=3)
    b = simulate_scenario(sc, seed=3)
    tilts = np.array([r.truth.accel_tilt_deg for r in a])
    assert len({tuple(t) for t in tilts}) == 3
    assert np.all(np.abs(tilts) < 25.0)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.accel, y.accel)
    # The gyro of each run does not depend on the tilt stream.
    c = simulate_scenario(Scenario.from_dict(BASE).with_overrides({'runs.count': 3}), seed=3)
    for x, y in zip(a, c):
        np.testing.assert_array_equal(x.gyro, y.gyro)


def test_thermal_offset_is_curved_in_the_die_temperature():
    coef = {'accel.bias_mg': [10.0, -5.0, 0.0], 'accel.dT_mg_per_c': [0.3, -0.2, 0.1],
            'accel.dT2_mg_per_c2': [2e-3, 1e-3, -3e-3]}
    run = _run(coef)
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
    run = _run({'accel.noise_mps2_per_rt_hz': 0.003, 'accel.sensitivity_mg_per_digit': 1.0,
                'profile.segments': [{'kind': 'hold', 'duration_s': 4000.0}]})
    step = G0 * 1e-3
    assert run.truth.accel_quant_step == pytest.approx(step)
    np.testing.assert_allclose(np.round(run.accel / step), run.accel / step, atol=1e-9)
    floor = math.sqrt((0.003 * math.sqrt(5.0)) ** 2 + step ** 2 / 12.0)
    np.testing.assert_allclose(run.truth.accel_noise_std, floor)
    np.testing.assert_allclose(run.accel.std(axis=0), floor, rtol=0.05)


def test_range_saturates():
    run = _run({'accel.range_g': 0.5})
    assert np.max(np.abs(run.accel)) == pytest.approx(0.5 * G0)


def test_mid_run_reorientation_steps_gravity():
    run = _run({'accel.reorient_at_s': 1000.0, 'accel.reorient_tilt_deg': [15.0, 0.0]})
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
        Scenario.from_dict(BASE).with_overrides({key: value})


def test_accel_chamber_scenario_ships_and_to_run_carries_the_accelerometer():
    sc = load_scenario('accel_chamber')
    assert sc.runs.count == 2 and sc.accel.thermal
    run = to_run(simulate_run(sc, seed=0, rate_hz=0.2))
    assert run.accel is not None and run.accel.shape == (len(run), 3)
    assert run.slice(5, 10).accel.shape == (5, 3)
