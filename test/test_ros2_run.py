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
from this checkout with the project's venv, starts both nodes with the *installed* parameter
files and the shipped model (resolved by name through the index), and receives compensated
messages.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys

import numpy as np
import pytest
from rosutil import spin_until

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope='module')
def install_tree(tmp_path_factory):
    base = tmp_path_factory.mktemp('colcon')
    env = dict(os.environ, PATH=f'{Path(sys.executable).parent}{os.pathsep}{os.environ["PATH"]}')
    cmd = [sys.executable, '-m', 'colcon', '--log-base', str(base / 'log'), 'build',
           '--base-paths', str(ROOT), '--build-base', str(base / 'build'),
           '--install-base', str(base / 'install')]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    for litter in ('build', 'install', 'log'):
        assert not (ROOT / litter).exists(), f'colcon left {litter}/ in the repository'
    return base / 'install'


def _resolve(install: Path, monkeypatch):
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    monkeypatch.setenv('AMENT_PREFIX_PATH', str(install / 'gyro_tdc'))
    prefix = Path(get_package_prefix('gyro_tdc'))
    share = Path(get_package_share_directory('gyro_tdc'))
    return prefix, share


def test_executables_and_config_are_where_ros2_run_looks(install_tree, monkeypatch):
    prefix, share = _resolve(install_tree, monkeypatch)
    assert prefix == install_tree / 'gyro_tdc'
    for exe in ('driver_node', 'compensator_node', 'simulate', 'train', 'evaluate',
                'discover', 'demo'):
        path = prefix / 'lib' / 'gyro_tdc' / exe
        assert path.is_file() and os.access(path, os.X_OK), path
        assert path.read_text().startswith(f'#!{sys.executable}')
    for rel in ('compensator.yaml', 'driver_sim.yaml', 'driver_iio.yaml',
                'models/l3gd20_modified.yaml', 'scenarios/demo_fast.yaml',
                'scenarios/l3gd20_paper.yaml'):
        assert (share / 'config' / rel).is_file(), rel


def test_installed_nodes_compensate_live(install_tree, monkeypatch, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    prefix, share = _resolve(install_tree, monkeypatch)
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    # As a sourced install tree: the installed package first, found through the index.
    env = dict(os.environ, PYTHONPATH=f'{site}{os.pathsep}{os.environ.get("PYTHONPATH", "")}',
               AMENT_PREFIX_PATH=str(prefix), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    lib = prefix / 'lib' / 'gyro_tdc'
    cfg = share / 'config'
    comp_cmd = [str(lib / 'compensator_node'), '--ros-args', '--params-file',
                str(cfg / 'compensator.yaml'), '-p', 'model_file:=l3gd20_modified']
    drv_cmd = [str(lib / 'driver_node'), '--ros-args', '--params-file',
               str(cfg / 'driver_sim.yaml'), '-p', 'scenario:=demo_fast', '-p', 'seed:=5',
               '-p', 'sim_rate_hz:=10.0', '-p', 'time_scale:=20.0']

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
    procs = [subprocess.Popen(comp_cmd, env=env, cwd=str(prefix), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT)]
    try:
        spin_until(ex, lambda: node.count_publishers('imu/data_compensated') > 0, 30.0)
        procs.append(subprocess.Popen(drv_cmd, env=env, cwd=str(prefix),
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        spin_until(ex, lambda: len(set(raw) & set(comp)) >= 200, 60.0)
    finally:
        for p in procs:
            p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        ex.shutdown()
        node.destroy_node()
    log = procs[0].stdout.read().decode(errors='replace')
    assert "from 'l3gd20_modified'" in log, log
    # The nodes ran the installed package, which found the model through the ament index.
    where = subprocess.run(
        [sys.executable, '-c', 'import gyro_tdc, gyro_tdc.resources as r; '
         "print(gyro_tdc.__file__); print(r.model_path('l3gd20_modified'))"],
        env=env, cwd=str(prefix), capture_output=True, text=True, check=True).stdout.split()
    assert where[0].startswith(str(site)) and where[1].startswith(str(share)), where
    stamps = sorted(set(raw) & set(comp))
    r = np.abs(np.array([raw[s] for s in stamps])).mean(axis=0)
    c = np.abs(np.array([comp[s] for s in stamps])).mean(axis=0)
    # The simulated rate is zero: the raw output carries the few-dps L3GD20 offset and
    # drift; compensated, only noise (0.095 deg/s rms at 10 Hz) remains.
    assert np.all(c < 0.2 * r), (c, r)
