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
``gyro-tdc simulate``: bags readable by rosbags, clean errors on bad input, --force, --help.

--force replaces its own earlier output only; a replacing run killed with ``kill -9`` before
any of its file-system changes leaves the old or the new output, complete, at its path; the
next run removes what the killed one left; --help lists the shipped scenarios.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
from pathlib import Path

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.cli.simulate import main
from gyro_tdc.sim import simulate_run
import numpy as np
from pause_at import PausingRunner
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader
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
    assert 'malformed YAML' in _one_error_line(capsys)


def test_existing_output_is_not_overwritten(tmp_path, tiny_file, capsys):
    out = tmp_path / 'exists'
    out.mkdir()
    assert main(['--scenario', str(tiny_file), '--out', str(out)]) == 2
    assert 'already exists' in _one_error_line(capsys)


def test_missing_required_option_exit_2(capsys):
    assert main(['--scenario', 'demo_fast']) == 2
    assert '--out' in _one_error_line(capsys)


# The tiny scenario without its rate table, two runs.
TWO_RUNS = {**{k: v for k, v in TINY.items() if k != 'rate_table'}, 'runs': {'count': 2}}


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / 'tiny.yaml'
    path.write_text(yaml.safe_dump(TWO_RUNS))
    return str(path)


def _data(bag):
    """Return the bytes of a bag's storage files."""
    return b''.join(p.read_bytes() for p in sorted(bag.iterdir()) if p.name != 'metadata.yaml')


def _err(capsys):
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_existing_output_needs_force_and_force_replaces_it(tmp_path, tiny, capsys):
    out = tmp_path / 'out' / 'bags'
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '1']) == 0
    first = _data(out / 'run1')
    (out / 'run2' / 'stale.txt').write_text('left from before')
    capsys.readouterr()
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '2']) == 2
    line = _err(capsys)
    assert line.startswith('gyro-tdc simulate: error: --out:') and '--force' in line
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '2', '--force']) == 0
    assert sorted(p.name for p in out.iterdir()) == ['run1', 'run2']
    assert not (out / 'run2' / 'stale.txt').exists()
    assert _data(out / 'run1') != first           # the new seed's data, not the old bag
    # Nothing is left beside the output (no staging or replaced copies).
    assert sorted(p.name for p in out.parent.iterdir()) == ['bags']


@pytest.mark.parametrize('make', ['file', 'dir_with_file', 'empty_dir', 'foreign_subdir'])
def test_force_refuses_what_simulate_did_not_write(tmp_path, tiny, capsys, make):
    out = tmp_path / 'precious'
    if make == 'file':
        out.write_text('keep me')
    else:
        out.mkdir()
        if make == 'dir_with_file':
            (out / 'notes.txt').write_text('keep me')
        elif make == 'foreign_subdir':
            (out / 'run1').mkdir()       # looks like a run but holds no bag
    before = sorted(p.name for p in tmp_path.rglob('*'))
    assert main(['--scenario', tiny, '--out', str(out), '--force']) == 2
    assert 'not a bag or a folder of run bags' in _err(capsys)
    assert sorted(p.name for p in tmp_path.rglob('*')) == before


def test_help_lists_every_shipped_scenario(capsys):
    assert main(['--help']) == 0
    text = capsys.readouterr().out
    assert 'usage: gyro-tdc simulate' in text and '--force' in text
    listing = text.split('shipped scenarios', 1)[1]
    for name in scenario_names():
        assert f'\n  {name}: ' in listing
    assert '  l3gd20_paper: 5 runs of 8.11 h at 10 Hz' in listing


def _digest(out: Path) -> str:
    """Return a hash of every message of the bag (or of the run bags) at ``out``, via rosbags."""
    sha = hashlib.sha256()
    bags = sorted(out.glob('run*')) if (out / 'run1').is_dir() else [out]
    for bag in bags:
        with Reader(bag) as reader:
            assert reader.message_count > 0
            for con, stamp, raw in reader.messages():
                sha.update(f'{bag.name} {con.topic} {stamp}'.encode())
                sha.update(raw)
    return sha.hexdigest()


def _hidden(folder: Path) -> list:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith('.'))


def test_force_killed_before_any_change_keeps_the_old_or_the_new_bag(tmp_path):
    scenario = tmp_path / 'tiny.yaml'
    scenario.write_text(yaml.safe_dump({**TWO_RUNS, 'runs': {'count': 1}}))
    out = tmp_path / 'w' / 'bags'
    args = ['simulate', '--scenario', scenario, '--out', out, '--no-progress', '--force']
    assert main([*args[1:], '--seed', '2']) == 0
    new = _digest(out)
    assert main([*args[1:], '--seed', '1']) == 0
    old = _digest(out)
    assert old != new
    seen = []

    def only_its_own(pid, paused):
        # This run has removed what the killed one before it left beside the output.
        assert all(f'-{pid}-' in name for name in _hidden(out.parent)), paused

    with PausingRunner() as runner:
        for stop in range(40):
            paused, code = runner.run(stop, out.parent, [*args, '--seed', '2'], only_its_own)
            if paused is None:           # ran to its end: every change has been tried
                assert code == 0
                break
            assert code == -9, paused
            # The path holds a complete bag, the old or the new one.
            assert out.is_dir(), f'{out} missing after kill -9 {paused}'
            got = _digest(out)
            assert got in (old, new), paused
            seen.append('old' if got == old else 'new')
            if got == new:                  # back to the old output for the next change
                assert main([*args[1:], '--seed', '1']) == 0
                assert _digest(out) == old and _hidden(out.parent) == [], paused
    assert paused is None, 'more changes than expected'
    assert _digest(out) == new and _hidden(out.parent) == []
    assert len(seen) >= 5 and 'old' in seen and 'new' in seen, seen
    assert seen == sorted(seen, key=('old', 'new').index), seen     # old until the swap


def test_next_run_puts_back_a_bag_lost_by_a_kill_and_removes_leftovers(tmp_path, caplog):
    from gyro_tdc.base.atomicio import _HOST
    import subprocess
    import sys
    dead = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                          capture_output=True, text=True, check=True).stdout.strip()
    scenario = tmp_path / 'tiny.yaml'
    scenario.write_text(yaml.safe_dump({**TWO_RUNS, 'runs': {'count': 1}}))
    folder = tmp_path / 'w'
    out = folder / 'bags'
    assert main(['--scenario', scenario, '--out', out, '--seed', '1']) == 0
    old = _digest(out)
    # What a kill -9 during a replacing write leaves: the old bag moved aside and a
    # half-written new one.
    out.rename(folder / f'.bags.{_HOST}-{dead}-00000000.old')
    staging = folder / f'.bags.{_HOST}-{dead}-0123abcd.tmp'
    staging.mkdir()
    (staging / 'bags.db3').write_bytes(b'x' * 1000)
    running = folder / f'.bags.{_HOST}-{os.getpid()}-89abcdef.tmp'     # a live owner
    running.mkdir()
    unknown = folder / f'.bags.{"eeee" if _HOST == "ffff" else "ffff"}-1-0123abcd.tmp'
    unknown.mkdir()                                                  # another host's
    other = folder / '.bagsX.ffff-1-00000000.tmp'
    other.mkdir()
    # Without --force: the bag is back, so it exists.
    with caplog.at_level(logging.WARNING, logger='gyro_tdc.base.atomicio'):
        assert main(['--scenario', scenario, '--out', out, '--seed', '2']) == 2
    assert _digest(out) == old
    assert _hidden(folder) == sorted([running.name, unknown.name, other.name])
    assert len(caplog.records) == 1 and unknown.name in caplog.records[0].getMessage()
