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
Bags recorded from drivers as they publish, read by field (``train``/``evaluate`` options).

The bag holds PX4's ``px4_msgs/msg/SensorGyro`` (FRD axes, a microsecond ``timestamp``) and
MicroStrain's ``MipSensorTemperatureStatistics`` (``mean_temp`` under a nested header), their
definitions from the drivers' own ``.msg`` files (px4_msgs a4a9864, microstrain_inertial_msgs
4.4.0; MipHeader without its GPS timestamp), written with rosbags. Read by field, it gives
the arrays of the same samples written as Imu + Temperature.
"""

from __future__ import annotations

import re
import sqlite3

from bags import null_message_data
from driver_msgs import driver_typestore
from gyro_tdc.cli.evaluate import main as evaluate_main
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import (DriverInputs, encode_twists, normalize_bag, read_bag, TWIST_TYPE,
                           write_bag)
from gyro_tdc.errors import ConfigError, DatasetError
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

GYRO_TYPE = 'px4_msgs/msg/SensorGyro'
STATS_TYPE = 'microstrain_inertial_msgs/msg/MipSensorTemperatureStatistics'
OPTIONS = dict(imu_type=GYRO_TYPE, angular_velocity_field='', stamp_field='timestamp',
               input_frame='frd', temperature_type=STATS_TYPE, temperature_field='mean_temp',
               temperature_stamp_field='header.header.stamp')
T0_US = 1_700_000_000_000_000


def samples(n=4000, rate_hz=100.0, seed=3):
    """Return stamps (us), FLU rates exact in float32, thermometer stamps and readings."""
    rng = np.random.default_rng(seed)
    us = T0_US + np.arange(n, dtype=np.int64) * int(1e6 / rate_hz)
    temp = np.round(20.0 + 10.0 * np.arange(n) / n, 2)
    w = np.stack([0.001 * (temp - 25.0), -0.002 * (temp - 25.0), 0.0005 * temp], axis=1)
    w = (w + rng.normal(0.0, 1e-3, w.shape)).astype(np.float32).astype(np.float64)
    t_us = us[::10]
    t_c = temp[::10].astype(np.float32).astype(np.float64)
    return us, w, t_us, t_c


def driver_bag(path, n=4000, storage='sqlite3', cmd_vel=False):
    """
    Write what a PX4 + MicroStrain pair would record: FRD SensorGyro, nested temperature.

    ``cmd_vel``: also a ``/cmd_vel`` Twist at every tenth gyro sample, commanding no motion.
    """
    store = driver_typestore()
    Gyro, Stats = store.types[GYRO_TYPE], store.types[STATS_TYPE]
    MipHeader = store.types['microstrain_inertial_msgs/msg/MipHeader']
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    us, w, t_us, t_c = samples(n)
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        gc = writer.add_connection('/fmu/out/sensor_gyro', GYRO_TYPE, typestore=store)
        tc = writer.add_connection('/mip/sensor/temperature_statistics', STATS_TYPE,
                                   typestore=store)
        twist = TWIST_TYPE if cmd_vel else None
        vc = writer.add_connection('/cmd_vel', twist, typestore=store) if twist else None
        j = 0
        for k, stamp in enumerate(us):
            if j < len(t_us) and t_us[j] <= stamp:
                sec, rest = divmod(int(t_us[j]), 1_000_000)
                msg = Stats(MipHeader(Header(Time(sec, rest * 1000), ''), 0, 0),
                            np.float32(t_c[j] - 1), np.float32(t_c[j] + 1), np.float32(t_c[j]))
                writer.write(tc, int(t_us[j]) * 1000, store.serialize_cdr(msg, STATS_TYPE))
                j += 1
            x, y, z = w[k]
            msg = Gyro(int(stamp), int(stamp), 1, np.float32(x), np.float32(-y), np.float32(-z),
                       np.float32(40.0), 0, np.zeros(3, dtype=np.uint8), 1)
            writer.write(gc, int(stamp) * 1000, store.serialize_cdr(msg, GYRO_TYPE))
            if vc is not None and k % 10 == 0:
                writer.write(vc, int(stamp) * 1000, encode_twists(np.zeros((1, 6)))[0])
    return path


def test_a_driver_bag_reads_as_the_same_samples_in_imu_and_temperature(tmp_path):
    bag = driver_bag(tmp_path / 'px4')
    out = normalize_bag(bag, DriverInputs(**OPTIONS), imu_topic='/fmu/out/sensor_gyro',
                        temperature_topic='/mip/sensor/temperature_statistics',
                        out=tmp_path / 'read')
    us, w, t_us, t_c = samples()
    plain = tmp_path / 'plain'
    write_bag(plain, imu_t=us * 1e-6, gyro=w, accel=np.zeros_like(w), temp_t=t_us * 1e-6,
              temp_c=t_c)
    got = read_bag(out, imu_topic='/fmu/out/sensor_gyro',
                   temperature_topic='/mip/sensor/temperature_statistics')
    want = read_bag(plain)
    np.testing.assert_array_equal(got.gyro, want.gyro)          # FRD turned to FLU
    np.testing.assert_allclose(got.imu_t, want.imu_t, atol=5e-7, rtol=0)   # float64 at 1.7e9 s
    np.testing.assert_array_equal(got.temp_c, want.temp_c)      # mean_temp
    np.testing.assert_allclose(got.temp_t, want.temp_t, atol=5e-7, rtol=0)   # float64 at 1.7e9 s


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_a_driver_bag_without_metadata_yaml_reads_as_with_it(tmp_path, storage):
    # The recording did not close: rosbags reads the storage through a rebuilt metadata.yaml.
    kw = dict(imu_topic='/fmu/out/sensor_gyro',
              temperature_topic='/mip/sensor/temperature_statistics')
    bag = driver_bag(tmp_path / 'px4', n=1000, storage=storage)
    want = read_bag(normalize_bag(bag, DriverInputs(**OPTIONS), out=tmp_path / 'a', **kw), **kw)
    (f,) = [p for p in bag.iterdir() if p.name != 'metadata.yaml']
    f.rename(bag / f'px4_0{f.suffix}')
    (bag / 'metadata.yaml').unlink()
    got = read_bag(normalize_bag(bag, DriverInputs(**OPTIONS), out=tmp_path / 'b', **kw), **kw)
    assert got.gyro.tobytes() == want.gyro.tobytes() and len(got.gyro) == 1000
    assert got.temp_c.tobytes() == want.temp_c.tobytes()
    assert sorted(p.name for p in bag.iterdir()) == [f'px4_0{f.suffix}']


def test_train_reads_a_driver_bag_with_the_node_parameters_as_options(tmp_path, capsys):
    bag = driver_bag(tmp_path / 'px4')
    args = [str(bag), '--imu-topic', '/fmu/out/sensor_gyro', '--temperature-topic',
            '/mip/sensor/temperature_statistics', '--features', 'dT', '--kind', 'poly',
            '--no-accel', '--no-progress', '--out', str(tmp_path / 'model.yaml')]
    opts = [x for k, v in OPTIONS.items() for x in ('--' + k.replace('_', '-'), v)]
    assert train_main(args + opts) == 0
    first = load_model(tmp_path / 'model.yaml')
    # The model names the bag the user gave (not the plain copy read by field, a temporary
    # directory): the same bag trains the same model id again.
    assert first.metrics['runs'] == [str(bag)] and first.created['bags'] == [str(bag)]
    assert train_main(args[:-1] + [str(tmp_path / 'again.yaml')] + opts) == 0
    assert load_model(tmp_path / 'again.yaml').model_id == first.model_id
    out = capsys.readouterr().out
    assert f'read {bag}: ' in out and 'gyro_tdc_driver_' not in out
    # Without the options the bag is refused in one line (not an Imu topic).
    assert train_main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'Traceback' not in err[0]


def test_still_only_training_of_a_driver_bag_reads_its_motion_topic(tmp_path, capsys):
    # The motion veto is read from the bag the user gave: the plain copy read by field holds
    # the gyro and the thermometer only (it was refused: "has no motion topic").
    bag = driver_bag(tmp_path / 'px4', n=8000, cmd_vel=True)
    args = [str(bag), '--imu-topic', '/fmu/out/sensor_gyro', '--temperature-topic',
            '/mip/sensor/temperature_statistics', '--features', 'dT', '--kind', 'poly',
            '--no-accel', '--no-progress', '--still-only', '--motion-topic', '/cmd_vel',
            '--min-still', '20', '--out', str(tmp_path / 'model.yaml')]
    opts = [x for k, v in OPTIONS.items() for x in ('--' + k.replace('_', '-'), v)]
    assert train_main(args + opts) == 0, capsys.readouterr()
    assert load_model(tmp_path / 'model.yaml').metrics['runs'] == [str(bag)]


def test_evaluate_reads_a_bag_by_field_as_the_plain_read_does(tmp_path, capsys):
    # An Imu + Temperature bag read by field (its own types' fields named): every line the
    # same as the plain read's, the bag named as given.
    us, w, t_us, t_c = samples(n=6000)
    bag = tmp_path / 'plain'
    write_bag(bag, imu_t=us * 1e-6, gyro=w, accel=np.zeros_like(w), temp_t=t_us * 1e-6,
              temp_c=t_c)
    args = [str(bag), '--model', 'config/models/l3gd20_modified.yaml', '--no-progress']
    assert evaluate_main(args) == 0
    plain = capsys.readouterr().out
    assert evaluate_main(args + ['--temperature-field', 'temperature']) == 0
    assert capsys.readouterr().out == plain and f'read {bag}: ' in plain


@pytest.mark.parametrize('change, error, needles', [
    (dict(temperature_field='mean_temperature'), ConfigError,
     ('--temperature-field', 'mean_temperature', 'mean_temp')),
    (dict(angular_velocity_field='temperature'), ConfigError,
     ('--angular-velocity-field', 'x/y/z')),
    (dict(stamp_field='x'), ConfigError, ('--stamp-field', 'microseconds')),
    (dict(imu_type='sensor_msgs/msg/Imu'), DatasetError, ('--imu-type', GYRO_TYPE)),
])
def test_bad_driver_options_name_the_option(tmp_path, change, error, needles):
    bag = driver_bag(tmp_path / 'px4', n=50)
    with pytest.raises(error) as err:
        normalize_bag(bag, DriverInputs(**{**OPTIONS, **change}),
                      imu_topic='/fmu/out/sensor_gyro',
                      temperature_topic='/mip/sensor/temperature_statistics',
                      out=tmp_path / 'read')
    for needle in needles:
        assert needle in str(err.value)


TOPICS = dict(imu_topic='/fmu/out/sensor_gyro',
              temperature_topic='/mip/sensor/temperature_statistics')


def power_cut(data, folder, size):
    """Write ``data[:size]`` as a power cut leaves an mcap file: ``NAME_0.mcap``, no metadata."""
    folder.mkdir()
    path = folder / f'{folder.name}_0.mcap'
    path.write_bytes(data[:size])
    return path


def assert_refused_naming(err, bag, mcap, out):
    """Assert a one-line refusal naming the bag, the file cut off and `mcap recover`."""
    text = str(err.value)
    assert text.startswith(f"cannot read bag '{bag}'") and '\n' not in text
    assert f'{mcap.name} ends without the mcap footer' in text and '`mcap recover`' in text
    assert not out.exists()


@pytest.fixture(scope='module')
def long_mcap(tmp_path_factory):
    """Return a 50,000-message driver bag's mcap bytes (5 chunks of 1 MiB) and its read."""
    tmp = tmp_path_factory.mktemp('long')
    bag = driver_bag(tmp / 'px4', n=50000, storage='mcap')
    whole = read_bag(normalize_bag(bag, DriverInputs(**OPTIONS), out=tmp / 'whole', **TOPICS),
                     **TOPICS)
    return next(bag.glob('*.mcap')).read_bytes(), whole


def test_an_mcap_file_cut_off_is_read_to_its_last_chunk_with_a_warning(tmp_path, long_mcap):
    # The power went: no footer and, as rosbag2 writes it on close, no metadata.yaml.
    data, whole = long_mcap
    mcap = power_cut(data, tmp_path / 'px4', len(data) * 3 // 4)
    warned = []
    got = read_bag(normalize_bag(mcap.parent, DriverInputs(**OPTIONS), out=tmp_path / 'b',
                                 warn=warned.append, **TOPICS), **TOPICS)
    n, m = len(got.imu_t), len(got.temp_t)
    assert 20000 < n < 50000 and 0 < m < len(whole.temp_t)
    assert got.gyro.tobytes() == whole.gyro[:n].tobytes()
    assert got.imu_t.tobytes() == whole.imu_t[:n].tobytes()
    assert got.temp_c.tobytes() == whole.temp_c[:m].tobytes()
    assert got.temp_t.tobytes() == whole.temp_t[:m].tobytes()
    (line,) = warned
    assert line.startswith(f'{mcap.name} ends without the mcap footer') and 'bytes after' in line


def test_train_reads_a_cut_driver_bag_and_prints_what_was_lost(tmp_path, capsys, long_mcap):
    data, _ = long_mcap
    bag = power_cut(data, tmp_path / 'px4', len(data) * 3 // 4).parent
    args = [str(bag), '--imu-topic', '/fmu/out/sensor_gyro', '--temperature-topic',
            '/mip/sensor/temperature_statistics', '--features', 'dT', '--kind', 'poly',
            '--no-accel', '--no-progress', '--out', str(tmp_path / 'model.yaml')]
    opts = [x for k, v in OPTIONS.items() for x in ('--' + k.replace('_', '-'), v)]
    assert train_main(args + opts) == 0
    out = capsys.readouterr().out
    assert f'warning: {bag}: px4_0.mcap ends without the mcap footer' in out
    assert (tmp_path / 'model.yaml').exists()


@pytest.mark.parametrize('share', [0.001, 0.05, 0.19, 0.21, 0.5, 0.77, 0.95, 0.9999])
def test_an_mcap_cut_anywhere_reads_a_prefix_or_is_one_line(tmp_path, long_mcap, share):
    data, whole = long_mcap
    size = int(share * len(data))          # 5 chunks of 1 MiB: the first ends near 0.2
    cut = power_cut(data, tmp_path / 'cut', size).parent
    warned = []
    try:
        out = normalize_bag(cut, DriverInputs(**OPTIONS), out=tmp_path / 'read',
                            warn=warned.append, **TOPICS)
    except DatasetError as err:
        # Before the first whole chunk nothing can be read: one line, nothing written.
        assert 'before its first whole chunk' in str(err) and '\n' not in str(err)
        assert share < 0.2 and not (tmp_path / 'read').exists()
        return
    got = read_bag(out, **TOPICS)
    assert got.gyro.tobytes() == whole.gyro[:len(got.gyro)].tobytes()
    assert got.temp_c.tobytes() == whole.temp_c[:len(got.temp_c)].tobytes()
    (line,) = warned
    lost = int(re.search(r'the (\d+) bytes after it are lost', line)[1])
    assert share > 0.2 and 0 < lost < size and len(got.gyro) <= len(whole.gyro)  # summary


def test_a_header_less_reading_of_a_cut_mcap_takes_the_imu_stamp_before_it(tmp_path):
    # The columnar read keeps rosbags' order between the topics: a Float32 reading is stamped
    # with the last IMU message logged before it, as on the whole file.
    bag = tmp_path / 'float'
    store = driver_typestore()
    Gyro, F32 = store.types[GYRO_TYPE], store.types['std_msgs/msg/Float32']
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        gc = writer.add_connection('/gyro', GYRO_TYPE, typestore=store)
        tc = writer.add_connection('/temp', 'std_msgs/msg/Float32', typestore=store)
        for k in range(30000):
            stamp = T0_US + 10_000 * k
            if k % 7 == 3:
                writer.write(tc, stamp * 1000 - 1, store.serialize_cdr(
                    F32(np.float32(20 + k * 1e-3)), 'std_msgs/msg/Float32'))
            msg = Gyro(stamp, stamp, 1, np.float32(0), np.float32(0), np.float32(0),
                       np.float32(40.0), 0, np.zeros(3, dtype=np.uint8), 1)
            writer.write(gc, stamp * 1000, store.serialize_cdr(msg, GYRO_TYPE))
    options = DriverInputs(imu_type=GYRO_TYPE, angular_velocity_field='',
                           stamp_field='timestamp', input_frame='frd')
    kw = dict(imu_topic='/gyro', temperature_topic='/temp')
    whole = read_bag(normalize_bag(bag, options, out=tmp_path / 'a', **kw), **kw)
    data = next(bag.glob('*.mcap')).read_bytes()
    cut = power_cut(data, tmp_path / 'cut', len(data) * 2 // 3).parent
    warned = []
    got = read_bag(normalize_bag(cut, options, out=tmp_path / 'b', warn=warned.append, **kw),
                   **kw)
    m = len(got.temp_t)
    assert 100 < m < len(whole.temp_t) and len(warned) == 1
    assert got.temp_t.tobytes() == whole.temp_t[:m].tobytes()
    assert got.temp_c.tobytes() == whole.temp_c[:m].tobytes()
    # Each reading is stamped with the IMU message before it (3, 10, 17, ... minus one).
    np.testing.assert_array_equal(np.round((got.temp_t - whole.imu_t[0]) * 100),
                                  2 + 7 * np.arange(m))


def test_an_mcap_file_cut_in_a_listed_bag_is_one_line_naming_it_and_mcap_recover(tmp_path):
    # metadata.yaml lists what the closed bag held: the read by field has no loss policy.
    bag = driver_bag(tmp_path / 'px4', n=2000, storage='mcap')
    (mcap,) = bag.glob('*.mcap')
    mcap.write_bytes(mcap.read_bytes()[:mcap.stat().st_size // 2])
    with pytest.raises(DatasetError) as err:
        normalize_bag(bag, DriverInputs(**OPTIONS), out=tmp_path / 'read', **TOPICS)
    assert_refused_naming(err, bag, mcap, tmp_path / 'read')


def test_an_mcap_file_damaged_in_its_middle_is_one_line_naming_it(tmp_path, long_mcap):
    # Cut off is read; bytes that are no records before the end are refused, as before.
    data = bytearray(long_mcap[0][:len(long_mcap[0]) * 3 // 4])
    data[len(data) // 3:len(data) // 3 + 64] = b'\xff' * 64
    mcap = power_cut(bytes(data), tmp_path / 'px4', len(data))
    with pytest.raises(DatasetError) as err:
        normalize_bag(mcap.parent, DriverInputs(**OPTIONS), out=tmp_path / 'read', **TOPICS)
    assert_refused_naming(err, mcap.parent, mcap, tmp_path / 'read')


def test_bno055_below_zero_is_read_signed(tmp_path):
    """The BNO055 quirk: a Temperature of 251 (the unsigned byte of -5 degC) reads -5."""
    plain = tmp_path / 'bno'
    write_bag(plain, imu_t=np.arange(20) * 0.01, gyro=np.zeros((20, 3)),
              accel=np.zeros((20, 3)), temp_t=np.array([0.0, 0.1]),
              temp_c=np.array([251.0, 3.0]))
    out = normalize_bag(plain, DriverInputs(temperature_quirk='bno055_unsigned_byte'),
                        imu_topic='/imu/data_raw', temperature_topic='/imu/temperature',
                        out=tmp_path / 'read')
    assert list(read_bag(out).temp_c) == [-5.0, 3.0]


@pytest.mark.parametrize('blob', [b'\x00\x01\x00\x00\x01\x02\x03',     # a message cut short
                                  b'\xff\xff\xff\xff' * 4,               # not CDR at all
                                  None])                   # data read as NULL (a damaged row)
def test_a_damaged_message_is_one_line_naming_the_bag(tmp_path, blob):
    # rosbags' deserializer raises its own errors (not AnyReaderError) on damaged bytes.
    bag = driver_bag(tmp_path / 'px4', n=50)
    (db3,) = bag.glob('*.db3')
    if blob is None:
        null_message_data(db3, '/fmu/out/sensor_gyro')
    else:
        with sqlite3.connect(db3) as db:
            db.execute('UPDATE messages SET data = ? WHERE id = (SELECT min(id) FROM messages '
                       'WHERE topic_id = (SELECT id FROM topics WHERE name = ?))',
                       (blob, '/fmu/out/sensor_gyro'))
        db.close()
    with pytest.raises(DatasetError) as err:
        normalize_bag(bag, DriverInputs(**OPTIONS), imu_topic='/fmu/out/sensor_gyro',
                      temperature_topic='/mip/sensor/temperature_statistics',
                      out=tmp_path / 'read')
    assert str(err.value).startswith(f"cannot read bag '{bag}'") and '\n' not in str(err.value)
    assert not (tmp_path / 'read').exists()
