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

"""Chamber profiles, the paper's precise test method (eqs. 20, 24, 25), heat conduction."""

from __future__ import annotations

import math

from gyro_tdc.sim import (heat_conduction_time_s, load_scenario, max_temperature_step_c, nice_ceil,
                          nice_floor, Profile, Scenario, simulate_run, simulate_thermal,
                          staircase_plan)
from gyro_tdc.sim.chamber import (hold_segment, points_segment, ramp_segment, staircase_segment,
                                  step_segment)
import numpy as np
import pytest


def test_eq20_temperature_step_of_the_l3gd20():
    bound = max_temperature_step_c(sensitivity_dps=8.75e-3, alpha_dps_per_c=0.03,
                                   beta_dps_per_c=-0.04)
    assert bound == pytest.approx(0.125, rel=1e-12)
    assert nice_floor(bound) == pytest.approx(0.1)


def test_eq24_hold_time_of_the_set_z_021_chamber():
    t_s = heat_conduction_time_s(specific_heat_kj_per_kg_k=1.005, density_kg_per_m3=1.293,
                                 length_m=0.6, conductivity_w_per_m_k=0.0267)
    assert t_s == pytest.approx(17.5209, abs=1e-4)
    assert nice_ceil(t_s) == pytest.approx(20.0)


def test_staircase_plan_gives_18_degc_per_hour():
    plan = staircase_plan()
    assert plan.step_c == pytest.approx(0.1)
    assert plan.hold_s == pytest.approx(20.0)
    assert plan.min_hold_s <= plan.hold_s
    assert plan.rate_c_per_h == pytest.approx(18.0)


@pytest.mark.parametrize('x, down, up', [(0.125, 0.1, 0.2), (17.52, 10.0, 20.0),
                                         (0.1, 0.1, 0.1), (20.0, 20.0, 20.0),
                                         (3.0, 2.0, 5.0), (0.7, 0.5, 1.0)])
def test_nice_numbers_follow_the_1_2_5_series(x, down, up):
    assert nice_floor(x) == pytest.approx(down)
    assert nice_ceil(x) == pytest.approx(up)


@pytest.mark.parametrize('kwargs, name', [
    ({'sensitivity_dps': 0.0, 'alpha_dps_per_c': 0.03, 'beta_dps_per_c': 0.04},
     'sensitivity_dps'),
    ({'sensitivity_dps': 8.75e-3, 'alpha_dps_per_c': float('nan'), 'beta_dps_per_c': 0.04},
     'alpha_dps_per_c'),
])
def test_eq20_rejects_bad_input_naming_it(kwargs, name):
    with pytest.raises(ValueError, match=name):
        max_temperature_step_c(**kwargs)


def test_paper_profile_matches_section_3_1():
    profile = load_scenario('l3gd20_paper').profile
    t, temp = profile.t, profile.temp_c
    assert temp[0] == -40.0 and temp[-1] == 85.0
    assert (temp.min(), temp.max()) == (-40.0, 85.0)
    jumps = np.flatnonzero(np.diff(t) == 0.0)
    assert jumps.size == 1250                               # 125 degC in 0.1 degC steps
    np.testing.assert_allclose(temp[jumps + 1] - temp[jumps], 0.1, atol=1e-9)
    np.testing.assert_allclose(np.diff(t[jumps]), 20.0)     # one step every 20 s
    start, end = t[jumps[0]], t[jumps[-1]] + 20.0
    assert start == 600.0                                   # stable soak at -40 degC first
    assert 3600.0 * 125.0 / (end - start) == pytest.approx(18.0)
    assert profile.duration_s - end == pytest.approx(3600.0)  # then stable for 1 h
    # Right-continuous: the value at a jump is the level after it, held for 20 s.
    assert profile.value([start])[0] == pytest.approx(-39.9)
    assert profile.value([start + 19.999])[0] == pytest.approx(-39.9)
    assert profile.value([start - 1e-6])[0] == pytest.approx(-40.0)


def test_staircase_cools_too_and_lands_on_the_target():
    profile = Profile.from_segments(20.0, [staircase_segment(19.25, 0.1, 20.0)])
    assert profile.temp_c[-1] == 19.25
    assert profile.duration_s == pytest.approx(8 * 20.0)    # 7 whole steps + 1 partial
    assert np.all(np.diff(profile.temp_c) <= 0.0)


def test_ramp_hold_step_and_points_segments_chain():
    profile = Profile.from_segments(10.0, [
        hold_segment(100.0), ramp_segment(40.0, 36.0), step_segment(30.0),
        points_segment([0.0, 50.0, 100.0], [30.0, 35.0, 35.0]), ramp_segment(10.0, 72.0)])
    assert profile.duration_s == pytest.approx(100.0 + 3000.0 + 100.0 + 1250.0)
    q = np.array([50.0, 1600.0, 3100.0, 3150.0, 3200.0, 4450.0])
    np.testing.assert_allclose(profile.value(q), [10.0, 25.0, 30.0, 35.0, 35.0, 10.0])
    np.testing.assert_allclose(profile.slope([50.0, 1600.0, 3300.0]),
                               [0.0, 0.01, -0.02])


def test_a_segment_with_nothing_to_do_keeps_the_chain_going():
    # A ramp or staircase to the temperature already reached adds no breakpoint; the next
    # segment starts from the last one there is.
    profile = Profile.from_segments(20.0, [
        ramp_segment(20.0, 10.0), staircase_segment(20.0, 0.1, 20.0), hold_segment(5.0),
        ramp_segment(30.0, 36.0)])
    np.testing.assert_allclose(profile.t, [0.0, 5.0, 1005.0])
    np.testing.assert_allclose(profile.temp_c, [20.0, 20.0, 30.0])


def test_profile_rejects_decreasing_time():
    with pytest.raises(ValueError, match='`t`'):
        Profile(np.array([0.0, 10.0, 5.0]), np.zeros(3))


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
