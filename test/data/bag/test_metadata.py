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

"""Tests of gyro_tdc.data.bag.metadata: counts that lie are refused in one line."""

from __future__ import annotations

from pathlib import Path
import shutil

from gyro_tdc.data import IMU_TYPE, read_bag, REFERENCE_TYPE, TEMPERATURE_TYPE, write_bag
from gyro_tdc.data.bag import metadata
from gyro_tdc.errors import DatasetError
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import CompressionFormat, CompressionMode, Writer
from rosbags.typesys import get_typestore, Stores
import yaml

TS = get_typestore(Stores.ROS2_JAZZY)
N_IMU = 600


def _write(path: Path, *, seed: int = 1, n: int = N_IMU, scale: float = 1.0) -> Path:
    rng = np.random.default_rng(seed)
    t = 100.0 + np.arange(n) * 0.01
    write_bag(path, imu_t=t, gyro=scale * rng.normal(size=(n, 3)),
              accel=scale * rng.normal(size=(n, 3)), temp_t=t[::100],
              temp_c=20.0 + scale * rng.normal(size=len(t[::100])))
    return path


@pytest.fixture(scope='module')
def small_bag(tmp_path_factory):
    return _write(tmp_path_factory.mktemp('bag') / 'bag')


def edited(src: Path, dst: Path, edit) -> Path:
    """Copy a bag and apply ``edit`` to the ``rosbag2_bagfile_information`` of its metadata."""
    shutil.copytree(src, dst)
    meta = dst / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    edit(doc['rosbag2_bagfile_information'])
    meta.write_text(yaml.safe_dump(doc, sort_keys=False))
    return dst


def imu_count(value):
    """Return an edit setting the IMU topic's message_count to ``value``."""
    def edit(info):
        for entry in info['topics_with_message_count']:
            if entry['topic_metadata']['name'] == '/imu/data_raw':
                entry['message_count'] = value
    return edit


def _refused(bag: Path, *needles: str) -> str:
    with pytest.raises(DatasetError) as info:
        read_bag(bag)
    text = str(info.value)
    assert '\n' not in text and str(bag) in text
    for needle in needles:
        assert needle in text, text
    return text


@pytest.mark.parametrize('count, needle', [
    (10 ** 15, 'holds 1000000000000000 messages, more than its'),
    (N_IMU * 10, f'holds {N_IMU * 10} messages, more than its'),
    (-5, 'a message_count of -5, not a whole number >= 0'),
    ('600', "a message_count of '600', not a whole number"),
    (6.5, 'a message_count of 6.5, not a whole number'),
    (True, 'a message_count of True, not a whole number'),
])
def test_lying_topic_count_is_refused_before_anything_is_sized(tmp_path, small_bag, count,
                                                               needle):
    bag = edited(small_bag, tmp_path / 'bag', imu_count(count))
    _refused(bag, "topic '/imu/data_raw'", needle, '`ros2 bag reindex`')


def test_counts_no_topic_breaks_alone_are_refused_as_the_topics_together(tmp_path, small_bag):
    # Each topic within the storage on its own, both together beyond it: the line names the sum.
    size = (small_bag / 'bag.db3').stat().st_size
    least = {t: metadata.min_message_bytes(t) for t in (IMU_TYPE, 'sensor_msgs/msg/Temperature')}
    n = {t: (size // b) * 2 // 3 for t, b in least.items()}

    def both(info):
        for entry in info['topics_with_message_count']:
            entry['message_count'] = n[entry['topic_metadata']['type']]
    text = _refused(edited(small_bag, tmp_path / 'bag', both),
                    f'its topics hold {sum(n.values())} messages together',
                    f'more than its {size} bytes of storage', '`ros2 bag reindex`')
    assert 'the last counted' in text


def test_count_of_a_file_and_of_the_bag_must_be_whole_numbers(tmp_path, small_bag):
    def file_count(info):
        info['files'][0]['message_count'] = -1

    def bag_count(info):
        info['message_count'] = 'many'
    _refused(edited(small_bag, tmp_path / 'a', file_count), 'message_count of -1')
    _refused(edited(small_bag, tmp_path / 'b', bag_count), "the bag a message_count of 'many'")


def test_counts_are_checked_against_the_smallest_message_of_each_type(tmp_path, small_bag):
    # Within the storage size for a 4-byte message of another type, impossible for Imu.
    size = (small_bag / 'bag.db3').stat().st_size
    n = size // metadata.min_message_bytes(IMU_TYPE) + 1
    bag = edited(small_bag, tmp_path / 'bag', imu_count(n))
    _refused(bag, f'holds {n} messages', f'its {size} bytes of storage',
             f'at least {metadata.min_message_bytes(IMU_TYPE)} bytes')


@pytest.mark.parametrize('msgtype', [IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE])
def test_min_message_bytes_is_a_lower_bound_of_the_smallest_message(msgtype):
    types = TS.types
    header = types['std_msgs/msg/Header'](types['builtin_interfaces/msg/Time'](0, 0), '')
    vec = types['geometry_msgs/msg/Vector3'](0.0, 0.0, 0.0)
    msg = {IMU_TYPE: lambda: types[IMU_TYPE](
        header, types['geometry_msgs/msg/Quaternion'](0.0, 0.0, 0.0, 1.0), np.zeros(9), vec,
        np.zeros(9), vec, np.zeros(9)),
        TEMPERATURE_TYPE: lambda: types[TEMPERATURE_TYPE](header, 0.0, 0.0),
        REFERENCE_TYPE: lambda: types[REFERENCE_TYPE](header, vec)}[msgtype]()
    smallest = len(TS.serialize_cdr(msg, msgtype))
    least = metadata.min_message_bytes(msgtype)
    assert least <= smallest < least + 8


@pytest.mark.parametrize('mode', ['message', 'file'])
def test_compression_the_data_do_not_have_is_one_line(tmp_path, small_bag, mode):
    def compressed(info):
        info['compression_format'] = 'zstd'
        info['compression_mode'] = mode
    bag = edited(small_bag, tmp_path / 'bag', compressed)
    _refused(bag, 'not compressed as metadata.yaml says', "compression_format 'zstd'",
             f"compression_mode '{mode}'")


def _recompressed(src: Path, dst: Path, mode: CompressionMode) -> Path:
    """Copy a bag message by message into a zstd-compressed one (rosbags' own writer)."""
    wr = Writer(dst, version=9)
    wr.set_compression(mode, CompressionFormat.ZSTD)
    with AnyReader([src]) as rd, wr:
        out = {c.id: wr.add_connection(c.topic, c.msgtype, typestore=TS)
               for c in rd.connections}
        for conn, log, raw in rd.messages():
            wr.write(out[conn.id], log, raw)
    return dst


@pytest.mark.parametrize('mode', [CompressionMode.MESSAGE, CompressionMode.FILE])
def test_genuinely_compressed_bags_pass_the_count_check(tmp_path, mode):
    # Constant readings compress well: the compressed storage is smaller than the IMU
    # messages could be uncompressed, and the counts are still accepted.
    flat = _write(tmp_path / 'flat', scale=0.0)
    bag = _recompressed(flat, tmp_path / 'z', mode)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['compression_format'] == 'zstd'
    size = sum((bag / name).stat().st_size for name in info['relative_file_paths'])
    assert size < N_IMU * metadata.min_message_bytes(IMU_TYPE)
    got, want = read_bag(bag), read_bag(flat)
    np.testing.assert_array_equal(got.gyro, want.gyro)
    np.testing.assert_array_equal(got.temp_c, want.temp_c)


_NAMES = st.sampled_from(['bag_0.db3', 'bag_1.db3', 'bag_10.db3', 'bag_2.mcap', 'bag.db3',
                          'bag.mcap', 'x_3.mcap', 'x.db3', 'bag_0.db3-wal', 'bag_0.db3-shm',
                          'notes.txt', 'metadata.yaml', '_1.db3', 'bag_-1.db3', 'sub/'])


#: A metadata.yaml with every key rosbag2 requires of version 9 (the counts are not read here).
_WHOLE = yaml.safe_dump({'rosbag2_bagfile_information': {
    'version': 9, 'storage_identifier': 'sqlite3', 'duration': {'nanoseconds': 0},
    'starting_time': {'nanoseconds_since_epoch': 0}, 'message_count': 0,
    'topics_with_message_count': [], 'compression_format': '', 'compression_mode': '',
    'relative_file_paths': [], 'files': [], 'custom_data': None, 'ros_distro': 'jazzy'}})


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(names=st.sets(_NAMES, max_size=6), whole=st.booleans())
def test_a_folder_is_a_bag_or_one_line_saying_why_not(tmp_path_factory, names, whole):
    # Whatever a folder holds: its storage files as `ros2 bag reindex` finds them (by N,
    # one storage), metadata.yaml's bag, or one line naming what is there. A damaged
    # metadata.yaml (one byte, or cut) yields to storage files beside it.
    bag = tmp_path_factory.mktemp('x') / 'bag'
    bag.mkdir()
    for name in names:
        if name.endswith('/'):
            (bag / name.rstrip('/')).mkdir()
        elif name == 'metadata.yaml':          # whole, or one byte (damaged)
            (bag / name).write_text(_WHOLE if whole else 'x')
        else:
            (bag / name).write_bytes(b'')
    storage = metadata.storage_files(bag)
    try:
        where, files = metadata.locate(bag)
    except DatasetError as err:
        assert '\n' not in str(err) and str(bag) in str(err)
        assert 'metadata.yaml' not in names or not whole and storage
        return
    assert where == bag
    if 'metadata.yaml' in names and (whole or not storage):
        assert files is None
        return
    index = [int(f.stem.rsplit('_', 1)[1]) if f.stem != 'bag' else -1 for f in files]
    assert index == sorted(index)
