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


"""Field paths of driver messages: checks naming the parameter, stamps, FRD axes, quirks."""

from __future__ import annotations

from types import SimpleNamespace

from gyro_tdc.base import TEMPERATURE_QUIRKS
from gyro_tdc.data.field_paths import (check_number, check_vector, frd_to_flu, normalize_type,
                                       reader, split_path, stamp_kind, stamp_seconds,
                                       temperature_path, unquirk)
from gyro_tdc.errors import ConfigError
import pytest

#: A field table as rclpy spells it: px4_msgs SensorGyro and MicroStrain's temperature.
TABLES = {
    'px4_msgs/msg/SensorGyro': {'timestamp': 'uint64', 'timestamp_sample': 'uint64',
                                'device_id': 'uint32', 'x': 'float', 'y': 'float',
                                'z': 'float', 'temperature': 'float',
                                'error_count': 'uint32', 'clip_counter': 'uint8[3]',
                                'samples': 'uint8'},
    'microstrain_inertial_msgs/msg/MipSensorTemperatureStatistics': {
        'header': 'microstrain_inertial_msgs/MipHeader', 'min_temp': 'float',
        'max_temp': 'float', 'mean_temp': 'float'},
    'microstrain_inertial_msgs/MipHeader': {'header': 'std_msgs/Header',
                                            'event_source': 'uint8',
                                            'reference_timestamp': 'uint64'},
    'std_msgs/Header': {'stamp': 'builtin_interfaces/Time', 'frame_id': 'string'},
    'builtin_interfaces/Time': {'sec': 'int32', 'nanosec': 'uint32'},
}
GYRO = 'px4_msgs/msg/SensorGyro'
STATS = 'microstrain_inertial_msgs/msg/MipSensorTemperatureStatistics'


def fields_of(name):
    return TABLES.get(name)


def test_paths_of_real_driver_types_pass():
    check_vector(GYRO, '', fields_of, 'angular_velocity_field')    # x, y, z at the top
    check_number(GYRO, 'temperature', fields_of, 'temperature_field')
    assert stamp_kind(GYRO, 'timestamp', fields_of, 'stamp_field') == 'micros'
    check_number(STATS, 'mean_temp', fields_of, 'temperature_field')
    assert stamp_kind(STATS, 'header.header.stamp', fields_of, 'x') == 'time'


def test_the_temperature_path_is_the_given_one_or_the_type_default():
    """One rule for the node's temperature_field and the CLI's --temperature-field."""
    tables = dict(TABLES, **{'sensor_msgs/msg/Temperature': {'temperature': 'double'},
                             'std_msgs/msg/Float32': {'data': 'float'}})
    assert temperature_path('sensor_msgs/msg/Temperature', '', tables.get, 'p') == 'temperature'
    assert temperature_path('std_msgs/msg/Float32', '', tables.get, 'p') == 'data'
    assert temperature_path(STATS, 'mean_temp', tables.get, 'p') == 'mean_temp'
    with pytest.raises(ConfigError, match=f'^--temperature-field: {STATS} has no default '
                       r'temperature field; give the dotted path to its degC number \(e.g.'):
        temperature_path(STATS, '', tables.get, '--temperature-field')
    with pytest.raises(ConfigError, match="^temperature_field: 'header' in .* not a number"):
        temperature_path(STATS, 'header', tables.get, 'temperature_field')


@pytest.mark.parametrize('check, type_name, path, needles', [
    (check_number, STATS, 'mean_temperature', ('temperature_field', "'mean_temperature'",
                                               'mean_temp')),
    (check_number, STATS, 'header', ('temperature_field', 'not a number')),
    (check_number, STATS, 'mean_temp.x', ('temperature_field', 'not a message')),
    (check_vector, GYRO, 'temperature', ('angular_velocity_field', 'x/y/z')),
    (check_vector, STATS, '', ('angular_velocity_field', 'the message itself')),
    (stamp_kind, GYRO, 'x', ('stamp_field', 'microseconds')),
    (check_number, GYRO, 'a..b', ('temperature_field', 'dotted path')),
])
def test_bad_paths_are_refused_naming_the_parameter(check, type_name, path, needles):
    param = needles[0]
    with pytest.raises(ConfigError) as err:
        check(type_name, path, fields_of, param)
    text = str(err.value)
    assert text.startswith(param) and '\n' not in text
    for needle in needles:
        assert needle in text


def test_readers_and_stamps():
    gyro = SimpleNamespace(timestamp=1_700_000_000_123_456, x=0.1, y=0.2, z=0.3)
    assert reader('')(gyro) is gyro
    stats = SimpleNamespace(header=SimpleNamespace(header=SimpleNamespace(
        stamp=SimpleNamespace(sec=5, nanosec=250_000_000))), mean_temp=21.5)
    assert reader('mean_temp')(stats) == 21.5
    assert stamp_seconds('time', reader('header.header.stamp')(stats)) == 5.25
    seconds = stamp_seconds('micros', gyro.timestamp)
    assert seconds == pytest.approx(1_700_000_000.123456, abs=1e-6)
    assert split_path('', 'p') == () and split_path('a.b_2', 'p') == ('a', 'b_2')


def test_type_names():
    assert normalize_type('sensor_msgs/Imu') == 'sensor_msgs/msg/Imu'
    assert normalize_type('px4_msgs/msg/SensorGyro') == 'px4_msgs/msg/SensorGyro'
    for bad in ('Imu', 'sensor_msgs/srv/Imu', 'a/b/c/d', 'sensor msgs/Imu'):
        with pytest.raises(ConfigError, match='pkg/msg/Type'):
            normalize_type(bad)


def test_frd_turns_to_flu_and_back():
    assert frd_to_flu(0.1, 0.2, 0.3) == (0.1, -0.2, -0.3)
    assert frd_to_flu(*frd_to_flu(0.1, -0.2, 0.3)) == (0.1, -0.2, 0.3)


def test_quirks_undo_the_drivers_encodings():
    assert unquirk('') is None
    bno = unquirk('bno055_unsigned_byte')
    # The byte read unsigned: 25 degC reads 25, -5 degC reads 251, -40 degC reads 216.
    assert [bno(float(b)) for b in (25, 85, 251, 216, 0)] == [25.0, 85.0, -5.0, -40.0, 0.0]
    sbg = unquirk('sbg_legacy_div256')
    assert sbg(31.5 / 256.0) == 31.5
    assert set(TEMPERATURE_QUIRKS) == {'', 'bno055_unsigned_byte', 'sbg_legacy_div256'}
    with pytest.raises(ConfigError, match='temperature_quirk'):
        unquirk('fahrenheit')
