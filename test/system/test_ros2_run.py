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
The ``ros2 run`` path: colcon build, ament-index lookup, installed params files, live data.

``ros2 run gyro_tdc <exe>`` is nothing more than the ament index lookup of
``<prefix>/lib/gyro_tdc/<exe>``; this test does exactly that on a colcon install tree built
from this checkout with the project's venv (in a temporary directory: no ``build/``,
``install/`` or ``log/`` in the repository), starts both nodes as real processes with the
*installed* parameter files and the shipped model (resolved by name through the index),
receives compensated messages in this process, and stops the nodes with SIGINT as Ctrl-C
would.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from rosutil import spin_until

ROOT = Path(__file__).resolve().parents[2]
# The two nodes, and gyro-tdc (the offline commands: `ros2 run gyro_tdc gyro-tdc train ...`).
EXECUTABLES = ('driver_node', 'compensator_node', 'gyro-tdc')
GENERIC = ('simulate', 'train', 'evaluate', 'discover', 'demo', 'fleet')   # never installed
CONFIG_FILES = ('compensator.yaml', 'still_logger.yaml', 'driver_sim.yaml', 'driver_iio.yaml',
                'models/l3gd20_modified.yaml', 'scenarios/demo_fast.yaml',
                'scenarios/l3gd20_paper.yaml')
MATCHED = 200           # raw/compensated pairs (same stamp) to compare
STOP_TIMEOUT_S = 10.0   # SIGINT to exit, then SIGKILL


def _litter():
    return {p.name for p in ROOT.iterdir()
            if p.name in ('build', 'install', 'log') or p.name.endswith('.egg-info')}


@pytest.fixture(scope='module')
def install_tree(tmp_path_factory):
    base = tmp_path_factory.mktemp('colcon')
    before = {name: (ROOT / name).stat().st_mtime_ns for name in _litter()}
    # colcon's ament_python build writes the building interpreter into the executables'
    # shebang and needs the venv's colcon extensions: run it as the venv's python.
    env = dict(os.environ, PATH=f'{Path(sys.executable).parent}{os.pathsep}{os.environ["PATH"]}')
    cmd = [sys.executable, '-m', 'colcon', '--log-base', str(base / 'log'), 'build',
           '--base-paths', str(ROOT), '--build-base', str(base / 'build'),
           '--install-base', str(base / 'install')]
    done = subprocess.run(cmd, env=env, cwd=base, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert 'Summary: 1 package finished' in done.stdout, done.stdout
    after = {name: (ROOT / name).stat().st_mtime_ns for name in _litter()}
    assert after == before, f'colcon wrote into the repository: {before} -> {after}'
    return base / 'install'


def _resolve(install: Path, monkeypatch):
    """Find the package as ``ros2 run`` does: the ament index on ``AMENT_PREFIX_PATH``."""
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    monkeypatch.setenv('AMENT_PREFIX_PATH', str(install / 'gyro_tdc'))
    prefix = Path(get_package_prefix('gyro_tdc'))
    share = Path(get_package_share_directory('gyro_tdc'))
    return prefix, share


def _sourced_env(prefix: Path) -> dict:
    """Return the environment of a shell that sourced the install tree."""
    site = prefix / 'lib' / f'python{sys.version_info[0]}.{sys.version_info[1]}' / 'site-packages'
    assert (site / 'gyro_tdc' / '__init__.py').is_file(), site
    path = os.environ.get('PYTHONPATH')
    ament = os.environ.get('AMENT_PREFIX_PATH')
    return dict(os.environ,
                PYTHONPATH=os.pathsep.join([str(site)] + ([path] if path else [])),
                AMENT_PREFIX_PATH=os.pathsep.join([str(prefix)] + ([ament] if ament else [])),
                ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')


def _stop(procs, timeout_s=STOP_TIMEOUT_S):
    """
    Send SIGINT to every process, wait for them, SIGKILL whatever is left at the deadline.

    Returns
    -------
    list of int or None
        Exit codes after SIGINT; ``None`` for a process that had to be killed.

    """
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    codes = []
    for p in procs:
        try:
            codes.append(p.wait(timeout=max(deadline - time.monotonic(), 0.01)))
        except subprocess.TimeoutExpired:
            codes.append(None)
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()
    return codes


def test_executables_and_config_are_where_ros2_run_looks(install_tree, monkeypatch):
    prefix, share = _resolve(install_tree, monkeypatch)
    assert prefix == install_tree / 'gyro_tdc'
    assert share == prefix / 'share' / 'gyro_tdc'
    # The marker that makes colcon's output an ament package (package.xml passed catkin_pkg).
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    assert (index / 'gyro_tdc').is_file(), index
    assert (share / 'package.xml').is_file()
    for exe in EXECUTABLES:
        path = prefix / 'lib' / 'gyro_tdc' / exe
        assert path.is_file() and os.access(path, os.X_OK), path
        assert path.read_text().startswith(f'#!{sys.executable}\n'), path
    for exe in GENERIC:
        assert not (prefix / 'lib' / 'gyro_tdc' / exe).exists(), exe
    for rel in CONFIG_FILES:
        assert (share / 'config' / rel).is_file(), rel
        assert (share / 'config' / rel).read_bytes() == (ROOT / 'config' / rel).read_bytes(), rel


def test_installed_nodes_compensate_live(install_tree, monkeypatch, ros_context, tmp_path):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    prefix, share = _resolve(install_tree, monkeypatch)
    env = _sourced_env(prefix)
    lib = prefix / 'lib' / 'gyro_tdc'
    cfg = share / 'config'
    commands = {
        'compensator': [str(lib / 'compensator_node'), '--ros-args', '--params-file',
                        str(cfg / 'compensator.yaml'), '-p', 'model_file:=l3gd20_modified'],
        'driver': [str(lib / 'driver_node'), '--ros-args', '--params-file',
                   str(cfg / 'driver_sim.yaml'), '-p', 'scenario:=demo_fast', '-p', 'seed:=5',
                   '-p', 'sim_rate_hz:=10.0', '-p', 'time_scale:=20.0'],
    }
    logs = {name: tmp_path / f'{name}.log' for name in commands}

    def log_text():
        return '\n'.join(f'--- {name}\n{path.read_text(errors="replace")}'
                         for name, path in logs.items() if path.exists())

    node = Node('ros2_run_probe', context=ros_context)
    raw, comp = {}, {}

    def keep(into):
        def cb(msg):
            s = msg.header.stamp
            w = msg.angular_velocity
            into[s.sec * 10 ** 9 + s.nanosec] = (w.x, w.y, w.z)
        return cb

    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(Imu, 'imu/data_raw', keep(raw), qos)
    node.create_subscription(Imu, 'imu/data_compensated', keep(comp), qos)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    procs = []

    def start(name):
        with open(logs[name], 'wb') as out:
            procs.append(subprocess.Popen(commands[name], env=env, cwd=tmp_path, stdout=out,
                                          stderr=subprocess.STDOUT))

    codes = None
    try:
        start('compensator')
        spin_until(ex, lambda: node.count_publishers('imu/data_compensated') > 0, 20.0,
                   what='compensator_node publishing')
        start('driver')
        spin_until(ex, lambda: len(raw.keys() & comp.keys()) >= MATCHED, 30.0,
                   what=f'{MATCHED} raw/compensated pairs')
    except AssertionError as exc:
        raise AssertionError(f'{exc}; raw {len(raw)}, compensated {len(comp)}\n{log_text()}')
    finally:
        codes = _stop(procs)
        ex.shutdown()
        node.destroy_node()
    # Ctrl-C stops both nodes cleanly, as under ``ros2 run``.
    assert codes == [0, 0], (codes, log_text())
    assert "from 'l3gd20_modified'" in logs['compensator'].read_text(), log_text()
    # The nodes ran the installed package, which found the model through the ament index
    # (not the checkout's config/: the same interpreter, environment and a neutral cwd).
    where = subprocess.run(
        [sys.executable, '-c', 'import gyro_tdc, gyro_tdc.base.resources as r; '
         "print(gyro_tdc.__file__); print(r.model_path('l3gd20_modified'))"],
        env=env, cwd=tmp_path, capture_output=True, text=True, check=True).stdout.split()
    assert where[0].startswith(str(prefix / 'lib')), where
    assert where[1] == str(share / 'config' / 'models' / 'l3gd20_modified.yaml'), where
    stamps = sorted(raw.keys() & comp.keys())
    r = np.array([raw[s] for s in stamps])
    c = np.array([comp[s] for s in stamps])
    # The simulated rate is zero: the raw output carries the few-dps L3GD20 offset and
    # drift; compensated, only noise (0.095 deg/s rms at 10 Hz) remains.
    r_norm = np.linalg.norm(r, axis=1).mean()
    c_norm = np.linalg.norm(c, axis=1).mean()
    assert c_norm < 0.2 * r_norm, (c_norm, r_norm)
    assert np.all(np.abs(c).mean(axis=0) < 0.2 * np.abs(r).mean(axis=0)), \
        (np.abs(c).mean(axis=0), np.abs(r).mean(axis=0))
