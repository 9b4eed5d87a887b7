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

"""IIO back-end against fake sysfs trees in tmp_path (no hardware, no rclpy)."""

from __future__ import annotations

import itertools
import math
import shutil

from fake_iio import l3gd20_files, make_device
from gyro_tdc.errors import DeviceError
from gyro_tdc.sources import find_iio_device, IioSource, ImuSample, ImuSource
import pytest

# st_gyro L3GD20 at 250 dps full scale: 8.75 mdps/digit in rad/s.
L3GD20_SCALE = 8.75e-3 * math.pi / 180.0


def test_l3gd20_units(tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    src = IioSource(dev, clock=lambda: 12.5)
    assert isinstance(src, ImuSource)
    assert src.name == 'l3gd20'
    sample = src.read()
    assert isinstance(sample, ImuSample)
    assert sample.t == 12.5
    scale = float(f'{L3GD20_SCALE:.9f}')
    assert sample.omega == pytest.approx((100 * scale, -200 * scale, 0.0), rel=1e-12)
    # 100 digits at 8.75 mdps/digit = 0.875 deg/s.
    assert math.degrees(sample.omega[0]) == pytest.approx(0.875, rel=1e-5)
    assert sample.accel is None
    assert not src.has_accel
    assert sample.temp_c == pytest.approx(25.0)
    src.close()


def test_bmi160_accel_offset_and_temp_offset(tmp_path):
    # BMI160-style: gyro and accel share a per-type scale; temperature raw + offset.
    files = {
        'name': 'bmi160',
        'in_anglvel_x_raw': 10, 'in_anglvel_y_raw': 20, 'in_anglvel_z_raw': 30,
        'in_anglvel_scale': '0.001065264',
        'in_anglvel_offset': 2,
        'in_accel_x_raw': 0, 'in_accel_y_raw': 0, 'in_accel_z_raw': 16384,
        'in_accel_scale': '0.000598550',
        'in_temp_raw': 512, 'in_temp_offset': 11776, 'in_temp_scale': '1.953125',
    }
    src = IioSource(make_device(tmp_path, files))
    s = src.read()
    assert s.omega == pytest.approx((12 * 0.001065264, 22 * 0.001065264, 32 * 0.001065264))
    assert s.accel == pytest.approx((0.0, 0.0, 16384 * 0.000598550))
    assert s.accel[2] == pytest.approx(9.8066, abs=1e-3)
    # (512 + 11776) * 1.953125 m°C = 24 000 m°C = 24 °C.
    assert s.temp_c == pytest.approx(24.0)


def test_per_axis_scale_and_offset_take_precedence(tmp_path):
    files = l3gd20_files()
    files.update({'in_anglvel_y_scale': '0.5', 'in_anglvel_z_offset': '-3',
                  'in_anglvel_z_raw': 4})
    s = IioSource(make_device(tmp_path, files)).read()
    scale = float(f'{L3GD20_SCALE:.9f}')
    assert s.omega == pytest.approx((100 * scale, -100.0, 1 * scale))


def test_mpu6050_temperature_formula(tmp_path):
    # inv_mpu6050: temp_scale 2.941176 m°C/LSB, offset 12420 LSB (36.53 °C at raw 0).
    files = {
        'name': 'mpu6050',
        'in_anglvel_x_raw': 0, 'in_anglvel_y_raw': 0, 'in_anglvel_z_raw': 0,
        'in_anglvel_scale': '0.000133090',
        'in_accel_x_raw': 0, 'in_accel_y_raw': 0, 'in_accel_z_raw': 0,
        'in_accel_scale': '0.000598',
        'in_temp_raw': -3000, 'in_temp_offset': 12420, 'in_temp_scale': '2.941176',
    }
    s = IioSource(make_device(tmp_path, files)).read()
    assert s.temp_c == pytest.approx((-3000 + 12420) * 2.941176 / 1000.0)
    assert s.accel == (0.0, 0.0, 0.0)


def test_processed_temperature_input(tmp_path):
    files = l3gd20_files()
    for key in ('in_temp_raw', 'in_temp_scale', 'in_temp_offset'):
        del files[key]
    files['in_temp_input'] = 31250
    s = IioSource(make_device(tmp_path, files)).read()
    assert s.temp_c == pytest.approx(31.25)


def test_no_thermometer(tmp_path):
    files = l3gd20_files()
    for key in ('in_temp_raw', 'in_temp_scale', 'in_temp_offset'):
        del files[key]
    dev = make_device(tmp_path, files)
    src = IioSource(dev)
    assert not src.has_temperature
    assert src.read().temp_c is None
    with pytest.raises(DeviceError, match='in_temp_raw'):
        IioSource(dev, require_temperature=True)


def test_a_thermometer_not_read_cannot_be_required(tmp_path):
    dev = make_device(tmp_path, l3gd20_files())         # it has one
    with pytest.raises(ValueError, match='`read_temperature` with `require_temperature`'):
        IioSource(dev, read_temperature=False, require_temperature=True)
    assert not IioSource(dev, read_temperature=False).has_temperature


def test_temperature_decimation(tmp_path):
    src = IioSource(make_device(tmp_path, l3gd20_files()), temp_every=3)
    temps = [src.read().temp_c for _ in range(7)]
    assert [t is not None for t in temps] == [True, False, False, True, False, False, True]
    with pytest.raises(ValueError, match='temp_every'):
        IioSource(tmp_path / 'iio:device0', temp_every=0)


def test_values_are_reread_each_sample(tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    src = IioSource(dev, clock=itertools.count(0.0, 1.0).__next__)   # 5 degC in 1 s: plausible
    first = src.read()
    (dev / 'in_anglvel_x_raw').write_text('-100\n')
    (dev / 'in_temp_raw').write_text('30\n')
    second = src.read()
    assert second.omega[0] == pytest.approx(-first.omega[0])
    assert second.temp_c == pytest.approx(30.0)


def test_an_implausible_thermometer_reading_is_not_published(tmp_path):
    # in_temp_raw of 2**31 - 1 for 0.1 s (ten samples at 100 Hz): no reading comes out, each
    # is counted, and the next good reading is published again.
    dev = make_device(tmp_path, l3gd20_files())
    src = IioSource(dev, clock=itertools.count(0.0, 0.01).__next__)
    assert [src.read().temp_c for _ in range(5)] == [25.0] * 5
    (dev / 'in_temp_raw').write_text('2147483647\n')
    assert [src.read().temp_c for _ in range(10)] == [None] * 10
    assert src.temperatures_rejected == 10
    (dev / 'in_temp_raw').write_text('26\n')
    assert src.read().temp_c == pytest.approx(26.0)
    # A jump no thermal mass makes (25 -> 80 degC in 10 ms) is dropped too, until the slew
    # allowance from the last good reading has grown to it.
    (dev / 'in_temp_raw').write_text('80\n')
    assert src.read().temp_c is None and src.temperatures_rejected == 11


@pytest.mark.parametrize('missing', ['in_anglvel_y_raw', 'in_anglvel_scale', 'in_temp_scale'])
def test_missing_required_file_names_it(tmp_path, missing):
    files = l3gd20_files()
    del files[missing]
    with pytest.raises(DeviceError, match=missing):
        IioSource(make_device(tmp_path, files))


def test_missing_device_dir(tmp_path):
    with pytest.raises(DeviceError, match='does not exist'):
        IioSource(tmp_path / 'iio:device7')


def test_missing_accel_scale_names_it(tmp_path):
    files = l3gd20_files()
    files.update({'in_accel_x_raw': 1, 'in_accel_y_raw': 2, 'in_accel_z_raw': 3})
    with pytest.raises(DeviceError, match='in_accel_scale'):
        IioSource(make_device(tmp_path, files))
    # An incomplete accelerometer is an error too, not a silent zero.
    del files['in_accel_z_raw']
    files['in_accel_scale'] = '0.01'
    with pytest.raises(DeviceError, match='in_accel_z_raw'):
        IioSource(make_device(tmp_path, files, 'iio:device1'))


@pytest.mark.parametrize('garbage', ['', 'abc', '12abc', 'nan', 'inf', '\x00\x01'])
@pytest.mark.parametrize('name', ['in_anglvel_z_raw', 'in_anglvel_scale', 'in_temp_raw'])
def test_garbled_file_at_open_names_it(tmp_path, name, garbage):
    files = l3gd20_files()
    files[name] = garbage
    with pytest.raises(DeviceError, match=name):
        IioSource(make_device(tmp_path, files))


@pytest.mark.parametrize('name', ['in_anglvel_x_raw', 'in_temp_raw', 'in_accel_y_raw'])
def test_garbled_file_mid_run_names_it(tmp_path, name):
    files = l3gd20_files()
    files.update({'in_accel_x_raw': 1, 'in_accel_y_raw': 2, 'in_accel_z_raw': 3,
                  'in_accel_scale': '0.01'})
    dev = make_device(tmp_path, files)
    src = IioSource(dev)
    src.read()
    (dev / name).write_text('garbage\n')
    with pytest.raises(DeviceError, match=f"{name}.*'garbage'"):
        src.read()
    (dev / name).write_text('5\n')
    assert src.read().omega is not None


def test_device_disappearing_mid_run(tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    src = IioSource(dev)
    src.read()
    shutil.rmtree(dev)
    with pytest.raises(DeviceError, match='disappeared'):
        src.read()
    # It comes back (e.g. after a USB/I2C re-probe): a new source reads again.
    make_device(tmp_path, l3gd20_files())
    assert IioSource(dev).read().temp_c == pytest.approx(25.0)


def test_file_vanishing_mid_run(tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    src = IioSource(dev)
    (dev / 'in_anglvel_y_raw').unlink()
    with pytest.raises(DeviceError, match='in_anglvel_y_raw.*missing'):
        src.read()


def test_find_device_by_name(tmp_path):
    make_device(tmp_path, {'name': 'bmp280'}, 'iio:device0')
    make_device(tmp_path, l3gd20_files(), 'iio:device1')
    (tmp_path / 'trigger0').mkdir()
    assert find_iio_device('l3gd20', root=tmp_path) == tmp_path / 'iio:device1'
    with pytest.raises(DeviceError, match="'bmi160'.*bmp280, l3gd20"):
        find_iio_device('bmi160', root=tmp_path)
    with pytest.raises(DeviceError, match='Cannot list'):
        find_iio_device('l3gd20', root=tmp_path / 'nope')
