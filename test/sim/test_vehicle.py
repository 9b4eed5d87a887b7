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

"""Vehicle days: the section's checks, the schedule, the heated set point and the motion."""

from __future__ import annotations

from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import Profile, Scenario
from gyro_tdc.sim.vehicle import (heated_profile, plan_legs, VEHICLE_DEFAULTS, vehicle_motion,
                                  VehicleSpec)
import numpy as np
import pytest

DAY = {'duration_s': 7200.0, 'imu_rate_hz': 2.0,
       'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 7200.0}]}}


def test_defaults_apply_and_round_trip():
    sc = Scenario.from_dict(dict(DAY, vehicle={}))
    assert isinstance(sc.vehicle, VehicleSpec)
    assert sc.vehicle.to_dict() == VEHICLE_DEFAULTS == sc.data['vehicle']
    assert sc.vehicle.drive_s == (600.0, 1800.0)


@pytest.mark.parametrize('key, value, expected', [
    ('drive_s', [0.0, 10.0], '0 < low'),
    ('turn_rate_dps', [5.0, 1.0], '0 <= low'),
    ('speed_mps', 0.0, '> 0'),
    ('slope_deg', -1.0, '>= 0'),
    ('self_heating_c', 'hot', 'a finite number'),
    ('wheels', 4, 'a known key'),
])
def test_bad_fields_are_named(key, value, expected):
    with pytest.raises(ScenarioError, match=f'`vehicle.{key}`: expected .*{expected}'):
        Scenario.from_dict(dict(DAY, vehicle={key: value}))


def test_schedule_parks_first_then_alternates_and_covers_the_day():
    spec = Scenario.from_dict(dict(DAY, vehicle={})).vehicle
    legs = plan_legs(spec, 20000.0, np.random.default_rng(4))
    assert legs[0].kind == 'park' and legs[0].t1_s == spec.start_parked_s
    assert all(a.t1_s == b.t0_s and a.kind != b.kind for a, b in zip(legs, legs[1:]))
    assert legs[-1].t1_s == 20000.0
    assert legs == plan_legs(spec, 20000.0, np.random.default_rng(4))


def test_driving_heats_the_set_point_and_moves_the_vehicle():
    spec = Scenario.from_dict(dict(DAY, vehicle={'start_parked_s': 600.0})).vehicle
    rng = np.random.default_rng(1)
    legs = plan_legs(spec, 7200.0, rng)
    ambient = Profile([0.0, 7200.0], [20.0, 20.0])
    setpoint, heating = heated_profile(ambient, spec, legs, 7200.0)
    assert heating.value([0.0, 590.0]).max() == 0.0 and heating.temp_c.max() > 1.0
    np.testing.assert_allclose(setpoint.temp_c, 20.0 + heating.temp_c)
    t = np.arange(0.0, 7200.0, 0.5)
    motion = vehicle_motion(spec, legs, t, rng, gravity_mps2=9.80665, heating=heating)
    assert motion.rate.shape == motion.force.shape == (t.size, 3)
    assert np.all(motion.speed[motion.parked] == 0.0) and motion.speed.max() > 5.0
    assert motion.cmd.shape == (motion.cmd_t.size, 6) and motion.cmd_t.size == 7200 * 5
