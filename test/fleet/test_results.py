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

"""The fleet's results: constant-axis notes, failed sensors, summary.json/csv and the table."""

from __future__ import annotations

from fleet_rig import constant_sensor
from gyro_tdc.fleet import FleetResult, format_table, SensorResult, summary_dict
import numpy as np


def test_constant_note_names_the_axes_in_the_right_number():
    assert SensorResult('a', 'ok').constant_note() == ''
    one = SensorResult('b', 'ok', constant_axes=['z']).constant_note()
    assert one.startswith('gyro axis z constant (not fitted, passed through')
    two = SensorResult('c', 'ok', constant_axes=['x', 'z']).constant_note()
    assert two.startswith('gyro axes x, z constant')


def test_failed_lists_every_sensor_not_ok():
    sensors = [SensorResult('a', 'ok'), SensorResult('b', 'failed', error='x'),
               SensorResult('c', 'ok', skipped=True)]
    assert [s.sensor_id for s in FleetResult('local', 1, sensors).failed] == ['b']


def test_table_of_a_large_fleet_lists_only_failed_and_flagged_sensors():
    sensors = [SensorResult(f's{i:02d}', 'ok', train_bs=[0.1] * 3) for i in range(45)]
    sensors[7] = SensorResult('s07', 'failed', error='Bag is corrupt')
    sensors[9].flags.append('drift slope on x 9.0σ from the fleet')
    lines = format_table(FleetResult('local', 2, sensors, seconds=1.0)).splitlines()
    assert [line.split()[0] for line in lines[1:-1]] == ['s07', 's09']
    assert 'Bag is corrupt' in lines[1] and '9.0σ' in lines[2]
    assert lines[-1].startswith('45 sensors: 44 ok (0 unchanged, skipped), 1 failed, 1 flagged')


def test_summary_and_table_name_the_constant_axes():
    """JSON key only when there are any; CSV column; table note and count; shown when many."""
    rng = np.random.default_rng(9)
    sensors = [constant_sensor(f's{i:02d}', rng) for i in range(44)]
    sensors.append(constant_sensor('zz', rng, 'z'))
    sensors[0].train_bs = [0.1] * 3
    result = FleetResult('local', 1, sensors, seconds=1.0)
    rows = {r['sensor_id']: r for r in summary_dict(result)['sensors']}
    assert rows['zz']['constant_axes'] == ['z'] and 'constant_axes' not in rows['s00']
    lines = format_table(result).splitlines()
    assert [line.split()[0] for line in lines[1:-1]] == ['zz']          # many: only it
    assert 'gyro axis z constant (not fitted' in lines[1]
    assert '1 with a constant gyro axis' in lines[-1] and '0 flagged' in lines[-1]
