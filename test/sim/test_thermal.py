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

"""Heat conduction: first-order lags of air, package, die and thermometer."""

from __future__ import annotations

import math

from gyro_tdc.sim import Profile, Scenario, simulate_run, simulate_thermal
from gyro_tdc.sim.chamber import hold_segment, ramp_segment, step_segment
import numpy as np
import pytest


def test_step_response_reaches_63_percent_at_tau():
    profile = Profile.from_segments(20.0, [hold_segment(100.0), step_segment(30.0),
                                           hold_segment(1000.0)])
    hist = simulate_thermal(profile, duration_s=1100.0, dt=0.1, tau_package_s=50.0)
    package = hist.at('package_c', [100.0, 150.0, 200.0, 350.0])
    expected = 20.0 + 10.0 * (1.0 - np.exp(-np.array([0.0, 50.0, 100.0, 250.0]) / 50.0))
    # The jump is spread over one 0.1 s grid interval: at most a 0.05 s shift.
    np.testing.assert_allclose(package, expected, atol=10.0 * 0.1 / 50.0)
    assert (package[1] - 20.0) / 10.0 == pytest.approx(1.0 - math.exp(-1.0), abs=2e-3)


def test_cascade_die_trails_package_by_rate_times_tau_on_a_ramp():
    rate = 60.0 / 3600.0
    profile = Profile.from_segments(0.0, [ramp_segment(50.0, 60.0), hold_segment(3000.0)])
    hist = simulate_thermal(profile, duration_s=profile.duration_s, tau_package_s=60.0,
                            tau_die_s=180.0)
    mid = hist.t.searchsorted(2000.0)
    assert hist.package_c[mid] - hist.die_c[mid] == pytest.approx(rate * 180.0, rel=1e-3)
    assert hist.air_c[mid] - hist.package_c[mid] == pytest.approx(rate * 60.0, rel=1e-3)
    assert hist.die_c[-1] == pytest.approx(50.0, abs=1e-3)   # settled after the soak
    # The die's rate is the exact derivative of its temperature.
    numeric = np.gradient(hist.die_c, hist.t)
    np.testing.assert_allclose(hist.die_rate_c_per_s[10:-10], numeric[10:-10], atol=1e-6)
    assert hist.die_rate_c_per_s[mid] == pytest.approx(rate, rel=1e-3)


def test_thermometer_reads_package_or_die_with_its_own_lag():
    profile = Profile.from_segments(0.0, [ramp_segment(10.0, 36.0)])
    common = {'duration_s': 1000.0, 'tau_package_s': 10.0, 'tau_die_s': 30.0}
    probe = simulate_thermal(profile, thermometer_location='package', thermometer_tau_s=5.0,
                             **common)
    register = simulate_thermal(profile, thermometer_location='die', **common)
    np.testing.assert_array_equal(register.thermometer_c, register.die_c)
    lag = probe.package_c[5000] - probe.thermometer_c[5000]
    assert lag == pytest.approx(0.01 * 5.0, rel=1e-3)


def _scenario(**thermometer) -> Scenario:
    return Scenario.from_dict({
        'imu_rate_hz': 10.0,
        'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 30.0},
                                                  {'kind': 'ramp', 'to_c': 30.0,
                                                   'rate_c_per_h': 360.0}]},
        'thermometer': dict({'rate_hz': 2.0}, **thermometer)})


def test_external_probe_resolution_and_rate():
    run = simulate_run(_scenario(resolution_c=0.03, noise_c=0.01), seed=3)
    np.testing.assert_allclose(np.diff(run.temp_t), 0.5)
    steps = run.temp_c / 0.03
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert run.temp_var == pytest.approx(0.01 ** 2 + 0.03 ** 2 / 12.0)
    assert np.max(np.abs(run.temp_c - (run.truth.thermal.at('package_c', run.temp_t)))) < 0.1


@pytest.mark.parametrize('resolution', [1.0, 1.0 / 256.0])
def test_on_die_register_resolution(resolution):
    run = simulate_run(_scenario(location='die', resolution_c=resolution), seed=0)
    steps = run.temp_c / resolution
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.max(np.abs(run.temp_c - run.truth.thermal.at('die_c', run.temp_t))) \
        <= resolution / 2.0 + 1e-12
