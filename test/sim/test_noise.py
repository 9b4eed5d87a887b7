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

"""Noise processes: white noise, bias instability, rate random walk, digits and range."""

from __future__ import annotations

import math

from gyro_tdc.sim import Scenario, simulate_run, simulate_scenario
from gyro_tdc.sim.noise import gauss_markov, quantise, random_walk, white_noise
import numpy as np
import pytest

DEG = math.pi / 180.0


def test_processes_are_zero_where_their_coefficient_is_and_shaped_n_by_3():
    rng = np.random.default_rng(0)
    assert white_noise(rng, 5, density=[0.0, 0.0, 0.0], rate_hz=100.0).shape == (5, 3)
    np.testing.assert_array_equal(gauss_markov(rng, 4, sigma=[0.0] * 3, tau_s=[1.0], dt=0.1), 0.0)
    np.testing.assert_array_equal(gauss_markov(rng, 4, sigma=[1.0] * 3, tau_s=[], dt=0.1), 0.0)
    walk = random_walk(rng, 6, k=[1.0, 2.0, 3.0], dt=0.1)
    assert walk.shape == (6, 3) and np.all(walk[0] == 0.0) and np.all(walk[1:] != 0.0)


def test_quantise_rounds_to_the_step_and_clips_in_place():
    x = np.array([0.26, -0.74, 5.0, -9.0])
    assert quantise(x, 0.5, limit=2.0) is x
    np.testing.assert_array_equal(x, [0.5, -0.5, 2.0, -2.0])
    y = np.array([0.26, 7.0])
    quantise(y, 0.0)                      # no step, no limit: unchanged
    np.testing.assert_array_equal(y, [0.26, 7.0])


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
