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

"""``python -m gyro_tdc simulate``: bags readable by rosbags, clean errors on bad input."""

from __future__ import annotations

import math

from gyro_tdc.cli.simulate import main
from gyro_tdc.sim import simulate_run
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
from scenarios import TINY
import yaml

DEG = math.pi / 180.0


def _read(path):
    """Return {topic: (msgtype, [(log_time_ns, msg), ...])} of a bag."""
    out = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, (conn.msgtype, []))
        for conn, stamp, raw in reader.messages():
            out[conn.topic][1].append((stamp, reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.fixture
def tiny_file(tmp_path):
    path = tmp_path / 'tiny.yaml'
    path.write_text(yaml.safe_dump(TINY))
    return path


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_writes_a_bag_with_the_three_topics(tmp_path, tiny_file, storage, capsys):
    out = tmp_path / 'bag'
    assert main(['--scenario', str(tiny_file), '--out', str(out), '--storage', storage,
                 '--seed', '4']) == 0
    summary = capsys.readouterr().out.strip().splitlines()
    assert len(summary) == 1 and summary[0].startswith('tiny: 1200 IMU samples')
    topics = _read(out)
    assert set(topics) == {'/imu/data_raw', '/imu/temperature', '/rate_table/reference'}
    imu_type, imu = topics['/imu/data_raw']
    assert imu_type == 'sensor_msgs/msg/Imu' and len(imu) == 1200
    assert topics['/imu/temperature'][0] == 'sensor_msgs/msg/Temperature'
    assert len(topics['/imu/temperature'][1]) == 120
    ref_type, ref = topics['/rate_table/reference']
    assert ref_type == 'geometry_msgs/msg/Vector3Stamped' and len(ref) == 2
    run = simulate_run(tiny_file, seed=4)
    first = imu[5][1]
    assert first.header.frame_id == 'imu_link'
    assert first.header.stamp.sec + first.header.stamp.nanosec * 1e-9 == pytest.approx(0.25)
    np.testing.assert_allclose([first.angular_velocity.x, first.angular_velocity.y,
                                first.angular_velocity.z], run.gyro[5])
    assert first.linear_acceleration.z == pytest.approx(run.accel[5, 2])
    assert first.orientation_covariance[0] == -1.0
    assert first.angular_velocity_covariance[0] == pytest.approx(run.truth.noise_std[0] ** 2)
    temp = topics['/imu/temperature'][1][7][1]
    assert temp.temperature == pytest.approx(run.temp_c[7])
    assert temp.variance == pytest.approx(run.temp_var)
    vec = ref[0][1].vector
    np.testing.assert_allclose([vec.x, vec.y, vec.z], [10.0 * DEG, 5.0 * DEG, 20.0 * DEG])
    assert ref[1][0] == 30 * 10 ** 9


def test_still_table_writes_no_reference_topic(tmp_path, tiny_file):
    data = dict(TINY, rate_table=[])
    tiny_file.write_text(yaml.safe_dump(data))
    out = tmp_path / 'still'
    assert main(['--scenario', str(tiny_file), '--out', str(out), '--rate-hz', '5']) == 0
    topics = _read(out)
    assert set(topics) == {'/imu/data_raw', '/imu/temperature'}
    assert len(topics['/imu/data_raw'][1]) == 300


def test_multi_run_scenario_writes_one_bag_per_run(tmp_path, capsys):
    out = tmp_path / 'runs'
    assert main(['--scenario', 'warmup', '--out', str(out), '--rate-hz', '0.5',
                 '--storage', 'mcap']) == 0
    assert sorted(p.name for p in out.iterdir()) == ['run1', 'run2']
    lines = capsys.readouterr().out.strip().splitlines()
    assert [line.split(':')[0] for line in lines] == ['warmup/run1', 'warmup/run2']
    first = _read(out / 'run1')['/imu/data_raw'][1]
    second = _read(out / 'run2')['/imu/data_raw'][1]
    assert len(first) == len(second) == 1800
    assert first[0][1].angular_velocity.x != second[0][1].angular_velocity.x


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and 'Traceback' not in err, err
    return lines[0]


@pytest.mark.parametrize('argv, needle', [
    (['--scenario', 'no_such_scenario'], 'no_such_scenario'),
    (['--scenario', 'demo_fast', '--rate-hz', '-2'], '--rate-hz'),
    (['--scenario', 'demo_fast', '--seed', '-1'], '--seed'),
    (['--scenario', 'demo_fast', '--storage', 'rosbag1'], '--storage'),
    (['--scenario', 'demo_fast', '--seed', 'x'], '--seed'),
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys, argv, needle):
    assert main(argv + ['--out', str(tmp_path / 'out')]) == 2
    assert needle in _one_error_line(capsys)
    assert not (tmp_path / 'out').exists()


def test_bad_scenario_file_exit_2_naming_the_field(tmp_path, capsys):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(dict(TINY, gyro={'dT_dps_per_c': 'warm'})))
    assert main(['--scenario', str(path), '--out', str(tmp_path / 'o')]) == 2
    assert '`gyro.dT_dps_per_c`' in _one_error_line(capsys)
    path.write_text('profile: [unclosed\n')
    assert main(['--scenario', str(path), '--out', str(tmp_path / 'o')]) == 2
    assert 'not valid YAML' in _one_error_line(capsys)


def test_existing_output_is_not_overwritten(tmp_path, tiny_file, capsys):
    out = tmp_path / 'exists'
    out.mkdir()
    assert main(['--scenario', str(tiny_file), '--out', str(out)]) == 2
    assert 'already exists' in _one_error_line(capsys)


def test_missing_required_option_exit_2(capsys):
    assert main(['--scenario', 'demo_fast']) == 2
    assert '--out' in _one_error_line(capsys)
