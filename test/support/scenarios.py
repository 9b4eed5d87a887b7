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

"""A tiny simulator scenario shared by the simulate tests, and what tests ask of sections."""

from gyro_tdc.sim.vehicle import gravity_in_sensor
import numpy as np


def gravity_vector(gravity_mps2, roll_deg, pitch_deg):
    """Return gravity in the sensor frame at one roll and pitch (deg), m/s^2, shape (3,)."""
    return gravity_in_sensor(gravity_mps2, np.array([roll_deg]), np.array([pitch_deg]))[0]


TINY = {
    'name': 'tiny',
    'sensor': 'l3gd20',
    'imu_rate_hz': 20.0,
    'profile': {'start_c': 20.0, 'segments': [{'kind': 'ramp', 'to_c': 21.0,
                                               'rate_c_per_h': 60.0}]},
    'thermometer': {'rate_hz': 2.0, 'resolution_c': 0.03},
    'rate_table': [{'t_s': 0.0, 'rate_dps': [10.0, 5.0, 20.0]},
                   {'t_s': 30.0, 'rate_dps': [0.0, 0.0, 0.0]}],
}


def accel_thermal(spec):
    """Return whether an accelerometer section's offset changes with temperature."""
    return any(v != 0.0 for v in spec.dT_mg_per_c + spec.dT2_mg_per_c2)


def table_moving(table):
    """Return whether a rate table has a non-zero rate."""
    return any(v != 0.0 for row in table.rate_rad_s for v in row)
