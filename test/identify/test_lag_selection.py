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

"""
``--features auto`` on a lagging die trained on heating only, at one rate (issue 27).

Two power cycles of the simulator's L3GD20 (cubic drift in the die temperature, the die
90 s behind the package thermometer), each a 5 min soak, a 1 degC/min ramp up and a 5 min
soak, over 7..33 and 20..55 degC; a third cycle over 46..11 degC *cooling* is held out. The
soaks at the ends of the ramps show the die catching up, so the lag is identifiable from
heating alone: the choice must name ``lag`` with tau near 90 s, not ``warmup`` (a decay
since power-on that a cooling cycle does not follow), and the held-out cooling cycle must
come within 1.2 x the floor on every axis.
"""

from __future__ import annotations

import math

from gyro_tdc.identify import estimate_t0, fit_model
from gyro_tdc.identify.features import choose_features, features_for_fit
from gyro_tdc.model import compensate
from gyro_tdc.sim import load_scenario, simulate_run
from gyro_tdc.sim.simulator import to_run
import numpy as np

DEG = math.pi / 180.0
TAU_DIE_S = 90.0


def _cycle(lo: float, hi: float, heating: bool, seed: int):
    """Simulate one power cycle: soak, ramp at 60 degC/h, soak; 2 Hz, die lag 90 s."""
    a, b = (lo, hi) if heating else (hi, lo)
    sc = {'format_version': 1, 'name': f'cycle{seed}', 'sensor': 'l3gd20', 'imu_rate_hz': 2.0,
          'profile': {'start_c': a, 'segments': [
              {'kind': 'hold', 'duration_s': 300.0},
              {'kind': 'ramp', 'to_c': b, 'rate_c_per_h': 60.0},
              {'kind': 'hold', 'duration_s': 300.0}]},
          'thermal': {'tau_package_s': 30.0, 'tau_die_s': TAU_DIE_S},
          'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.004},
          'gyro': {'effects': ['bias', 'dT', 'dT2', 'dT3', 'lag'],
                   'dT2_dps_per_c2': [8.0e-4, 6.0e-4, -2.5e-4],
                   'dT3_dps_per_c3': [4.0e-6, -3.0e-6, 2.0e-6]},
          'runs': {'count': 1, 'bias_offset_dps_std': 0.2}}
    sim = simulate_run(load_scenario(sc), seed=seed)
    return to_run(sim), sim.truth.noise_std


def test_heating_only_names_lag_and_holds_on_cooling():
    """Name lag (not warmup) from heating-only cycles with soaks; hold on a cooling cycle."""
    train = [_cycle(7.0, 33.0, True, 1001)[0], _cycle(20.0, 55.0, True, 1002)[0]]
    held, noise = _cycle(11.0, 46.0, False, 1003)
    t0 = estimate_t0(train[0])
    choice = choose_features(train, t0=t0)
    verdict = {d.effect: d.verdict for d in choice.decisions}
    assert 'lag' in choice.features and 'warmup' not in choice.features, choice.lines()
    assert verdict['lag'] == 'added'
    tau = choice.discovery.thermal.tau_s[0]
    assert 0.8 * TAU_DIE_S < tau < 1.2 * TAU_DIE_S
    # The report says what heating-only data cannot test.
    assert any('only heat' in line and 'hysteresis' in line for line in choice.lines())
    ids, params, _ = features_for_fit(train, 'auto', t0=t0)
    model = fit_model(train, features=ids, params=params or None, t0=t0, sessions=[0, 1])
    err = compensate(model, held.t, held.temp, held.omega) - held.omega_ref
    err -= err.mean(axis=0)                     # re-anchored: its own turn-on offset
    ratio = np.mean(err ** 2, axis=0) / noise ** 2
    assert np.all(ratio <= 1.2), ratio
