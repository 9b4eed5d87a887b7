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

"""Tests of gyro_tdc.data.bag.motion: a cmd_vel Twist stream written, read back and refused."""

from __future__ import annotations

from bags import null_message_data
from gyro_tdc.data import encode_twists, read_motion, TWIST_TYPE, write_bag
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest


def _bag(path, storage, twist, t):
    n = 50
    write_bag(path, imu_t=np.arange(n) * 0.1, gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)),
              temp_t=[0.0, 4.9], temp_c=[20.0, 21.0], storage=storage,
              extra=[('/cmd_vel', TWIST_TYPE, t, encode_twists(twist))])
    return path


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_twists_read_back_in_time_order_with_their_log_times(tmp_path, storage):
    rng = np.random.default_rng(2)
    twist = rng.normal(size=(7, 6))
    t = np.array([0.5, 0.1, 0.3, 0.2, 0.9, 0.7, 0.8])
    got = read_motion(_bag(tmp_path / 'bag', storage, twist, t), '/cmd_vel')
    order = np.argsort(t, kind='stable')
    assert got.topic == '/cmd_vel' and got.msgtype == TWIST_TYPE
    np.testing.assert_allclose(got.t, t[order], atol=1e-9)
    np.testing.assert_array_equal(got.twist, twist[order])


def test_a_motion_topic_of_a_bag_without_metadata_yaml_reads_as_with_it(tmp_path):
    rng = np.random.default_rng(4)
    bag = _bag(tmp_path / 'bag', 'mcap', rng.normal(size=(5, 6)), [0.1, 0.2, 0.3, 0.4, 0.5])
    want = read_motion(bag, '/cmd_vel')
    (bag / 'bag.mcap').rename(bag / 'bag_0.mcap')
    (bag / 'metadata.yaml').unlink()
    got = read_motion(bag, '/cmd_vel')
    np.testing.assert_array_equal(got.twist, want.twist)
    np.testing.assert_array_equal(got.t, want.t)


def test_a_missing_or_mistyped_motion_topic_is_one_line(tmp_path):
    bag = _bag(tmp_path / 'bag', 'sqlite3', np.zeros((1, 6)), [0.0])
    with pytest.raises(DatasetError, match="no motion topic '/odom'; topics present: .*/cmd_vel"):
        read_motion(bag, '/odom')
    with pytest.raises(DatasetError, match="'/imu/temperature' .* has type 'sensor_msgs/msg/"
                                           "Temperature', expected one of"):
        read_motion(bag, '/imu/temperature')
    with pytest.raises(DatasetError, match=r"^Bag '.*nothing' does not exist\.$"):
        read_motion(tmp_path / 'nothing', '/cmd_vel')
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'empty' / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    with pytest.raises(DatasetError, match='Cannot read motion topic'):
        read_motion(tmp_path / 'empty', '/cmd_vel')


def test_a_motion_message_without_data_is_one_line(tmp_path):
    bag = _bag(tmp_path / 'bag', 'sqlite3', np.zeros((3, 6)), [0.0, 0.1, 0.2])
    null_message_data(next(bag.glob('*.db3')), '/cmd_vel', 1)
    with pytest.raises(DatasetError, match=rf"^cannot read bag '{bag}': a message on '/cmd_vel' "
                                           r'has no data \(a damaged file\)\.$'):
        read_motion(bag, '/cmd_vel')


def test_a_motion_topic_of_an_mcap_the_power_cut_reads_to_its_last_chunk(tmp_path):
    # No footer and no metadata.yaml, as a power cut leaves a recording: the motion topic is
    # read as the gyro is, up to the file's last whole chunk (the loss is the gyro read's to
    # say); before that every report is the whole recording's.
    n = 40000
    t = np.arange(n) * 0.01
    twist = np.random.default_rng(5).normal(size=(n, 6))
    bag = tmp_path / 'bag'
    write_bag(bag, imu_t=t, gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)), temp_t=t[::100],
              temp_c=np.full(n // 100, 20.0), storage='mcap',
              extra=[('/cmd_vel', TWIST_TYPE, t + 0.005, encode_twists(twist))])
    whole = read_motion(bag, '/cmd_vel')
    data = (bag / 'bag.mcap').read_bytes()
    cut = tmp_path / 'cut'
    cut.mkdir()
    (cut / 'cut_0.mcap').write_bytes(data[:len(data) * 3 // 4])
    got = read_motion(cut, '/cmd_vel')
    k = len(got.t)
    assert n // 4 < k < n
    assert got.t.tobytes() == whole.t[:k].tobytes()
    assert got.twist.tobytes() == whole.twist[:k].tobytes()
