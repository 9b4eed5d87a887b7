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

"""The fleet's results: a sensor's constant-axis note and the failed sensors of a fleet."""

from __future__ import annotations

from gyro_tdc.fleet import FleetResult, SensorResult


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
