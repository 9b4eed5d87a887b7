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

"""Tests of gyro_tdc.data.bag.writer: write_bag round trips through read_bag, bad bags."""

from __future__ import annotations

import ast
from pathlib import Path

from bag_msgs import _imu, _small_bag, _temperature, _write_raw, STORAGES, TS
from gyro_tdc import data as bagio
from gyro_tdc.data import IMU_TYPE, read_bag, REFERENCE_TYPE, TEMPERATURE_TYPE, write_bag
from gyro_tdc.data.bag import reader
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer


# ------------------------------------------------------------------------------------------
# Round trips through bags
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize('storage', STORAGES)
@pytest.mark.parametrize('frame_id', ['imu_link', 'odd', ''])
def test_write_read_round_trip(tmp_path, storage, frame_id):
    rng = np.random.default_rng(11)
    n, m = 2500, 30
    imu_t = 1.7e9 + np.arange(n) * 1e-3 + 0.25e-3
    gyro = rng.normal(size=(n, 3))
    accel = rng.normal(size=(n, 3))
    temp_t = 1.7e9 + np.arange(m) * 0.1
    temp_c = 20 + rng.normal(size=m)
    temp_var = rng.random(m)
    ref_t = 1.7e9 + np.array([0.0, 1.0, 2.0])
    ref = rng.normal(size=(3, 3))
    gyro_cov, accel_cov = np.array([1e-6, 2e-6, 3e-6]), np.array([0.1, 0.2, 0.3])
    bag = tmp_path / 'bag'
    write_bag(bag, imu_t=imu_t, gyro=gyro, accel=accel, temp_t=temp_t, temp_c=temp_c,
              temp_var=temp_var, ref_t=ref_t, ref=ref, storage=storage, frame_id=frame_id,
              gyro_cov=gyro_cov, accel_cov=accel_cov)

    data = read_bag(bag)
    assert data.storage == storage and data.path == str(bag) and data.frame_id == frame_id
    assert data.fallback == {'imu': 0, 'temperature': 0, 'reference': 0}
    assert data.rejected == {'imu_nonfinite': 0, 'temp_nonfinite': 0, 'ref_nonfinite': 0,
                             'undecodable': 0, 'temp_before_imu': 0}
    assert data.topics == {'/imu/data_raw': (IMU_TYPE, n),
                           '/imu/temperature': (TEMPERATURE_TYPE, m),
                           '/rate_table/reference': (REFERENCE_TYPE, 3)}
    np.testing.assert_allclose(data.imu_t, imu_t, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(data.gyro, gyro)
    np.testing.assert_array_equal(data.accel, accel)
    np.testing.assert_allclose(data.temp_t, temp_t, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(data.temp_c, temp_c)
    np.testing.assert_array_equal(data.temp_var, temp_var)
    np.testing.assert_allclose(data.ref_t, ref_t, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(data.ref, ref)

    # Without the accelerometer (the trainer's read): the same gyro, no accel array.
    lean = read_bag(bag, accel=False)
    assert lean.accel is None
    np.testing.assert_array_equal(lean.gyro, gyro)
    np.testing.assert_array_equal(lean.imu_t, data.imu_t)
    np.testing.assert_array_equal(lean.temp_c, temp_c)

    # Every field, as any ROS 2 tool would see it, and log times in global order.
    expected_ns = {k: np.round(np.asarray(v) * 1e9).astype(np.int64)
                   for k, v in (('imu', imu_t), ('temp', temp_t), ('ref', ref_t))}
    seen = {'imu': 0, 'temp': 0, 'ref': 0}
    last = -1
    with AnyReader([bag]) as reader:
        for conn, log_ns, raw in reader.messages():
            assert log_ns >= last
            last = log_ns
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            assert stamp == log_ns and msg.header.frame_id == frame_id
            if conn.msgtype == IMU_TYPE:
                i = seen['imu']
                assert abs(stamp - expected_ns['imu'][i]) <= 1000
                o = msg.orientation
                assert (o.x, o.y, o.z, o.w) == (0.0, 0.0, 0.0, 1.0)
                assert msg.orientation_covariance[0] == -1.0
                assert not np.any(msg.orientation_covariance[1:])
                w, a = msg.angular_velocity, msg.linear_acceleration
                assert [w.x, w.y, w.z] == gyro[i].tolist()
                assert [a.x, a.y, a.z] == accel[i].tolist()
                np.testing.assert_array_equal(msg.angular_velocity_covariance,
                                              np.diag(gyro_cov).ravel())
                np.testing.assert_array_equal(msg.linear_acceleration_covariance,
                                              np.diag(accel_cov).ravel())
                seen['imu'] += 1
            elif conn.msgtype == TEMPERATURE_TYPE:
                i = seen['temp']
                assert abs(stamp - expected_ns['temp'][i]) <= 1000
                assert (msg.temperature, msg.variance) == (temp_c[i], temp_var[i])
                seen['temp'] += 1
            else:
                i = seen['ref']
                assert abs(stamp - expected_ns['ref'][i]) <= 1000
                assert [msg.vector.x, msg.vector.y, msg.vector.z] == ref[i].tolist()
                seen['ref'] += 1
        assert seen == {'imu': n, 'temp': m, 'ref': 3}
        conns = {c.topic: c for c in reader.connections}
        assert conns['/imu/data_raw'].digest == TS.hash_rihs01(IMU_TYPE)
    meta = (bag / 'metadata.yaml').read_text()
    assert 'version: 9' in meta and f'storage_identifier: {storage}' in meta


@pytest.mark.parametrize('storage', STORAGES)
def test_round_trip_over_several_blocks(tmp_path, storage, monkeypatch):
    monkeypatch.setattr(reader, '_CHUNK', 256)
    data = _small_bag(tmp_path / 'bag', storage, n=3000, frame_id='imu_l')
    got = read_bag(tmp_path / 'bag', progress=True)
    np.testing.assert_array_equal(got.gyro, data['gyro'])
    np.testing.assert_array_equal(got.temp_c, data['temp_c'])
    assert got.ref is None and got.ref_t is None
    assert got.fallback == {'imu': 0, 'temperature': 0, 'reference': 0}


def test_an_error_of_the_decoder_reaches_the_caller(tmp_path, monkeypatch):
    # A DatasetError inside the read is the caller's, not a reason to read with rosbags.
    _small_bag(tmp_path / 'bag', 'sqlite3')
    assert len(read_bag(tmp_path / 'bag').gyro) == 300

    def broken(*args, **kwargs):
        raise DatasetError('decoder broke')

    monkeypatch.setattr(reader, 'decode_joined', broken)
    with pytest.raises(DatasetError, match='decoder broke'):
        read_bag(tmp_path / 'bag')


def test_write_bag_accepts_scalar_variance_and_no_reference(tmp_path):
    write_bag(tmp_path / 'bag', imu_t=[0.0, 0.5], gyro=np.zeros((2, 3)), accel=np.zeros((2, 3)),
              temp_t=[0.0], temp_c=[21.5], temp_var=0.25)
    data = read_bag(tmp_path / 'bag')
    assert data.storage == 'sqlite3' and data.temp_var.tolist() == [0.25]
    assert '/rate_table/reference' not in data.topics
    # A header stamp of zero falls back to the log time (also zero here).
    np.testing.assert_array_equal(data.imu_t, [0.0, 0.5])


@pytest.mark.parametrize('storage', STORAGES)
def test_mixed_frame_ids_fall_back_and_decode_right(tmp_path, storage):
    rng = np.random.default_rng(5)
    frames = ['a', 'imu_link', 'base', 'a']
    imu, temp, expected = [], [], []
    for i in range(40):
        g = rng.normal(size=3)
        expected.append(g)
        imu.append((10**9 + i * 10**7, bytes(TS.serialize_cdr(
            _imu(rng, 1, i * 10**7, frames[i % 4], gyro=g), IMU_TYPE))))
    for i in range(3):
        temp.append((10**9 + i * 2 * 10**8, bytes(TS.serialize_cdr(
            _temperature(rng, 1, i * 2 * 10**8, frames[i], value=20.0 + i), TEMPERATURE_TYPE))))
    _write_raw(tmp_path / 'bag', storage, {'/imu/data_raw': (IMU_TYPE, imu),
                                           '/imu/temperature': (TEMPERATURE_TYPE, temp)})
    data = read_bag(tmp_path / 'bag', via='rosbags')
    assert data.fallback['imu'] == 40 and data.fallback['temperature'] == 3
    # The columnar read blocks the messages otherwise (a lone reading decodes fast).
    columns = read_bag(tmp_path / 'bag', via='columnar')
    assert columns.fallback['imu'] == 40 and columns.via == 'columnar'
    for name in ('imu_t', 'gyro', 'accel', 'temp_t', 'temp_c'):
        np.testing.assert_array_equal(getattr(columns, name), getattr(data, name))
    assert data.frame_id == 'a'
    np.testing.assert_array_equal(data.gyro, np.array(expected))
    np.testing.assert_allclose(data.imu_t, 1 + np.arange(40) * 0.01, atol=1e-9)
    np.testing.assert_array_equal(data.temp_c, [20.0, 21.0, 22.0])
    lean = read_bag(tmp_path / 'bag', accel=False)     # rosbags path, gyro columns only
    assert lean.accel is None and lean.fallback['imu'] == 40
    np.testing.assert_array_equal(lean.gyro, np.array(expected))


@pytest.mark.parametrize('storage', STORAGES)
def test_zero_stamps_across_blocks_take_the_log_time(tmp_path, storage, monkeypatch):
    # Zero header stamps on the main IMU connection in several blocks, next to undecodable
    # messages and interleaved temperature: each gets its own message's log time.
    monkeypatch.setattr(reader, '_CHUNK', 16)
    rng = np.random.default_rng(12)
    n = 100
    gyro = rng.normal(size=(n, 3))
    zero = {0, 17, 18, 40, 63, 99}
    broken = {18 + 1, 50}
    imu, expected_t, expected_g = [], [], []
    for i in range(n):
        log = 3 * 10**9 + i * 10**7 + 123
        if i in zero:
            msg = _imu(rng, 0, 0, 'imu_link', gyro=gyro[i])
        else:
            msg = _imu(rng, 3, i * 10**7, 'imu_link', gyro=gyro[i])
        raw = bytes(TS.serialize_cdr(msg, IMU_TYPE))
        imu.append((log, raw[:60] if i in broken else raw))
        if i not in broken:
            expected_t.append(log * 1e-9 if i in zero else 3 + i * 1e-2)
            expected_g.append(gyro[i])
    temp = [(3 * 10**9 + k * 10**8 + 5, bytes(TS.serialize_cdr(
        _temperature(rng, 3, k * 10**8, value=20.0 + k), TEMPERATURE_TYPE))) for k in range(10)]
    _write_raw(tmp_path / 'bag', storage, {'/imu/data_raw': (IMU_TYPE, imu),
                                           '/imu/temperature': (TEMPERATURE_TYPE, temp)})
    data = read_bag(tmp_path / 'bag')
    assert data.rejected['undecodable'] == len(broken)
    np.testing.assert_array_equal(data.gyro, np.array(expected_g))
    np.testing.assert_allclose(data.imu_t, expected_t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(data.temp_c, 20.0 + np.arange(10))


@pytest.mark.parametrize('storage', STORAGES)
def test_big_endian_zero_stamps_nonfinite_and_undecodable(tmp_path, storage):
    rng = np.random.default_rng(9)
    gyro = rng.normal(size=(12, 3))
    gyro[3, 1] = np.nan
    gyro[7, 2] = np.inf
    imu = []
    for i in range(12):
        sec, nsec = (0, 0) if i == 5 else (2, i * 1000)    # zero stamp: use the log time
        msg = _imu(rng, sec, nsec, 'imu_link', gyro=gyro[i])
        imu.append((2 * 10**9 + i * 1000 + (777 if i == 5 else 0),
                    bytes(TS.serialize_cdr(msg, IMU_TYPE, little_endian=False))))
    imu.append((2 * 10**9 + 50_000, imu[0][1][:100]))     # truncated message
    temp = [(2 * 10**9 + i, bytes(TS.serialize_cdr(
        _temperature(rng, 2, i, value=v), TEMPERATURE_TYPE))) for i, v in
        enumerate([20.0, np.nan, 21.0, -np.inf])]
    _write_raw(tmp_path / 'bag', storage, {'/imu/data_raw': (IMU_TYPE, imu),
                                           '/imu/temperature': (TEMPERATURE_TYPE, temp)})
    data = read_bag(tmp_path / 'bag')
    assert data.rejected == {'imu_nonfinite': 2, 'temp_nonfinite': 2, 'ref_nonfinite': 0,
                             'undecodable': 1, 'temp_before_imu': 0}
    keep = [i for i in range(12) if i not in (3, 7)]
    np.testing.assert_array_equal(data.gyro, gyro[keep])
    expected_t = np.array([2 + i * 1e-6 for i in range(12)])
    expected_t[5] = 2 + 5 * 1e-6 + 777e-9
    np.testing.assert_allclose(data.imu_t, expected_t[keep], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(data.temp_c, [20.0, 21.0])


# ------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------

def test_missing_path(tmp_path):
    with pytest.raises(DatasetError, match='does not exist'):
        read_bag(tmp_path / 'nope')


def test_directory_that_is_not_a_bag(tmp_path):
    (tmp_path / 'notes.txt').write_text('hello')
    with pytest.raises(DatasetError, match='not a rosbag2 directory: no metadata.yaml'):
        read_bag(tmp_path)
    with pytest.raises(DatasetError, match='is a file, not a rosbag2 directory'):
        read_bag(tmp_path / 'notes.txt')
    (tmp_path / 'old.bag').write_bytes(b'#ROSBAG V2.0\n')
    with pytest.raises(DatasetError, match='ROS 1 bag'):
        read_bag(tmp_path / 'old.bag')


def test_storage_file_path_resolves_to_its_bag(tmp_path):
    _small_bag(tmp_path / 'bag', 'sqlite3')
    assert read_bag(tmp_path / 'bag' / 'bag.db3').path == str(tmp_path / 'bag')


def _garbage_after(head: int):
    """Return a damage that keeps ``head`` bytes and replaces the rest with seeded noise."""
    return lambda raw: raw[:head] + bytes(np.random.default_rng(0).integers(
        0, 256, len(raw) - head, dtype=np.uint8))


DAMAGES = {
    ('sqlite3', 'truncate'): lambda raw: raw[:len(raw) // 3],
    ('sqlite3', 'garbage'): _garbage_after(4096),
    ('sqlite3', 'empty'): lambda raw: b'',
    ('mcap', 'truncate'): lambda raw: raw[:len(raw) // 2],
    ('mcap', 'garbage'): lambda raw: raw[:8] + b'\x07' * (len(raw) - 8),
}


@pytest.mark.parametrize('storage, damage', sorted(DAMAGES))
def test_corrupt_storage_file(tmp_path, storage, damage):
    _small_bag(tmp_path / 'bag', storage, n=3000)
    path = tmp_path / 'bag' / ('bag.db3' if storage == 'sqlite3' else 'bag.mcap')
    path.write_bytes(DAMAGES[storage, damage](path.read_bytes()))
    with pytest.raises(DatasetError, match=r'unreadable or corrupt'):
        read_bag(tmp_path / 'bag')


@pytest.mark.parametrize('storage', STORAGES)
def test_a_damaged_metadata_yaml_yields_to_the_storage_files(tmp_path, storage):
    _small_bag(tmp_path / 'bag', storage)
    want = read_bag(tmp_path / 'bag')
    (tmp_path / 'bag' / 'metadata.yaml').write_text('rosbag2_bagfile_information: [\n')
    got = read_bag(tmp_path / 'bag')
    np.testing.assert_array_equal(got.gyro, want.gyro)
    np.testing.assert_array_equal(got.temp_c, want.temp_c)
    assert got.warnings[0] == (f'a damaged metadata.yaml (not valid YAML): read from '
                               f'{next((tmp_path / "bag").glob("*.*[p3]")).name} as `ros2 bag '
                               'reindex` would list it')
    # Beside other files the folder is no bare bag: the damaged metadata.yaml is refused.
    (tmp_path / 'bag' / 'notes.txt').write_text('calibration run 3\n')
    with pytest.raises(DatasetError, match=r'unreadable or corrupt'):
        read_bag(tmp_path / 'bag')


@pytest.mark.parametrize('storage', STORAGES)
def test_a_metadata_yaml_cut_anywhere_reads_the_same_messages(tmp_path, storage):
    # The power went while rosbag2 wrote metadata.yaml on close: every cut of it reads the
    # bag's messages, from the storage files where what is left lacks a key rosbag2 needs.
    bag = tmp_path / 'bag'
    _small_bag(bag, storage)
    whole = (bag / 'metadata.yaml').read_bytes()
    want = read_bag(bag)
    cuts = sorted({*range(1, len(whole), 7), *(i + 1 for i, b in enumerate(whole) if b == 10)})
    damaged = 0
    for cut in cuts:
        (bag / 'metadata.yaml').write_bytes(whole[:cut])
        got = read_bag(bag)
        np.testing.assert_array_equal(got.gyro, want.gyro, err_msg=f'cut at byte {cut}')
        np.testing.assert_array_equal(got.temp_t, want.temp_t, err_msg=f'cut at byte {cut}')
        damaged += any(w.startswith('a damaged metadata.yaml') for w in got.warnings)
    assert 0.9 * len(cuts) < damaged < len(cuts)      # the last keys' cuts leave it whole


@pytest.mark.parametrize('storage', STORAGES)
def test_missing_topic_lists_the_topics_present(tmp_path, storage):
    _small_bag(tmp_path / 'bag', storage, n=300)
    with pytest.raises(DatasetError) as err:
        read_bag(tmp_path / 'bag', imu_topic='/imu/raw')
    text = str(err.value)
    assert "no topic '/imu/raw'" in text
    assert '/imu/data_raw (sensor_msgs/msg/Imu, 300 msgs)' in text
    assert '/imu/temperature (sensor_msgs/msg/Temperature, 4 msgs)' in text
    assert '\n' not in text


def test_wrong_type_and_empty_topic(tmp_path):
    _small_bag(tmp_path / 'bag', 'sqlite3')
    with pytest.raises(DatasetError, match=r"'/imu/data_raw' .* has type 'sensor_msgs/msg/Imu', "
                                           r"expected 'sensor_msgs/msg/Temperature'"):
        read_bag(tmp_path / 'bag', temperature_topic='/imu/data_raw')
    rng = np.random.default_rng(0)
    imu = [(10**9, bytes(TS.serialize_cdr(_imu(rng), IMU_TYPE)))]
    _write_raw(tmp_path / 'empty', 'sqlite3', {'/imu/data_raw': (IMU_TYPE, imu),
                                               '/imu/temperature': (TEMPERATURE_TYPE, [])})
    with pytest.raises(DatasetError, match=r"'/imu/temperature' .* has no messages"):
        read_bag(tmp_path / 'empty')


def test_write_bag_rejects_bad_arguments(tmp_path):
    ok = dict(imu_t=[0.0, 1.0], gyro=np.zeros((2, 3)), accel=np.zeros((2, 3)), temp_t=[0.0],
              temp_c=[20.0])
    with pytest.raises(DatasetError, match=r'`gyro` to have shape \(2, 3\), got \(2, 2\)'):
        write_bag(tmp_path / 'a', **{**ok, 'gyro': np.zeros((2, 2))})
    with pytest.raises(DatasetError, match='`imu_t` to hold finite times'):
        write_bag(tmp_path / 'a', **{**ok, 'imu_t': [0.0, np.nan]})
    with pytest.raises(DatasetError, match='`ref_t` and `ref` to be given together'):
        write_bag(tmp_path / 'a', **ok, ref_t=[0.0])
    with pytest.raises(DatasetError, match="`storage` to be 'sqlite3' or 'mcap', got 'ros1'"):
        write_bag(tmp_path / 'a', **ok, storage='ros1')
    assert not (tmp_path / 'a').exists()
    write_bag(tmp_path / 'a', **ok)
    with pytest.raises(DatasetError, match='exists already'):
        write_bag(tmp_path / 'a', **ok)


def test_bagio_imports_no_ros_packages():
    files = sorted(Path(bagio.__file__).parent.rglob('*.py'))
    assert {f.relative_to(Path(bagio.__file__).parent).as_posix() for f in files} >= {
        '__init__.py', 'bag/codec.py', 'bag/reader.py', 'bag/writer.py'}
    trees = [ast.parse(f.read_text()) for f in files]
    modules = {alias.name for tree in trees for node in ast.walk(tree)
               if isinstance(node, ast.Import) for alias in node.names}
    modules |= {node.module for tree in trees for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom)}
    roots = {m.split('.')[0] for m in modules if m}
    assert not roots & {'rclpy', 'sensor_msgs', 'std_msgs', 'geometry_msgs', 'rosbag2_py'}


def test_write_bag_leaves_nothing_behind_on_failure(tmp_path, monkeypatch):
    def full_disk(self, connection, timestamp, data):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(Writer, 'write', full_disk)
    with pytest.raises(DatasetError, match='Cannot write bag .*No space left on device'):
        _small_bag(tmp_path / 'bag', 'mcap')
    assert not (tmp_path / 'bag').exists()
