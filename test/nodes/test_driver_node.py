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

"""driver_node with real rclpy: IIO against a fake sysfs tree, and the simulator."""

from __future__ import annotations

import math
from pathlib import Path
import shutil

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from fake_iio import l3gd20_files, make_device
from geometry_msgs.msg import Vector3Stamped
from gyro_tdc.base.resources import scenario_names
from gyro_tdc.errors import ConfigError
from gyro_tdc.nodes.driver_node import DriverNode, PARAMS
from gyro_tdc.sources.base import ImuSample, ImuSource, PolledSource
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosutil import interrupt, node_process, spin_until
from sensor_msgs.msg import Imu, Temperature
import yaml

CONFIG = Path(__file__).resolve().parents[2] / 'config'
DEEP = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000,
                  reliability=ReliabilityPolicy.RELIABLE)


class Listener:
    """A test node collecting imu/data_raw, imu/temperature, the reference and diagnostics."""

    def __init__(self, context, executor):
        self.node = rclpy.create_node('listener', context=context)
        self.imu: list[Imu] = []
        self.temp: list[Temperature] = []
        self.ref: list[Vector3Stamped] = []
        self.diag: list[DiagnosticStatus] = []
        self.node.create_subscription(Imu, 'imu/data_raw', self.imu.append, DEEP)
        self.node.create_subscription(Temperature, 'imu/temperature', self.temp.append, DEEP)
        self.node.create_subscription(Vector3Stamped, 'rate_table/reference', self.ref.append,
                                      DEEP)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10)
        executor.add_node(self.node)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        self.diag.extend(s for s in msg.status if 'gyro driver' in s.name)


def overrides(**values) -> list[Parameter]:
    """Turn keyword arguments into parameter overrides."""
    return [Parameter(k, value=v) for k, v in values.items()]


@pytest.fixture
def executor(ros_context):
    ex = SingleThreadedExecutor(context=ros_context)
    yield ex
    for node in list(ex.get_nodes()):
        ex.remove_node(node)
        node.destroy_node()
    ex.shutdown()


def start(ros_context, executor, **params) -> tuple[DriverNode, Listener]:
    listener = Listener(ros_context, executor)
    node = DriverNode(context=ros_context, parameter_overrides=overrides(**params))
    executor.add_node(node)
    return node, listener


def iio_params(dev: Path, **extra) -> dict:
    params = dict(backend='iio', device_dir=str(dev), rate_hz=500.0, frame_id='gyro_frame',
                  angular_velocity_variance=4.0e-6, temperature_variance=0.25,
                  retry_initial=0.01, retry_max=0.02)
    params.update(extra)
    return params


def test_iio_publishes_rep145_imu_and_temperature(ros_context, executor, tmp_path):
    files = l3gd20_files()
    dev = make_device(tmp_path, files)
    node, lis = start(ros_context, executor, **iio_params(dev))
    spin_until(executor, lambda: len(lis.imu) >= 5 and len(lis.temp) >= 5, 10.0)
    msg = lis.imu[-1]
    scale = float(files['in_anglvel_scale'])
    assert msg.header.frame_id == 'gyro_frame'
    assert (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z) == \
        pytest.approx((100 * scale, -200 * scale, 0.0), rel=1e-12)
    assert msg.orientation_covariance[0] == -1.0
    assert list(msg.angular_velocity_covariance) == [4.0e-6, 0, 0, 0, 4.0e-6, 0, 0, 0, 4.0e-6]
    # The L3GD20 has no accelerometer: REP 145 says covariance[0] = -1.
    assert msg.linear_acceleration_covariance[0] == -1.0
    stamps = [m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for m in lis.imu]
    assert stamps == sorted(stamps) and stamps[0] > 0
    t = lis.temp[-1]
    assert t.temperature == pytest.approx(25.0)
    assert t.variance == pytest.approx(0.25)
    assert t.header.frame_id == 'gyro_frame'
    assert lis.ref == []


def test_iio_accelerometer_covariance(ros_context, executor, tmp_path):
    files = l3gd20_files()
    files.update({'in_accel_x_raw': 0, 'in_accel_y_raw': 0, 'in_accel_z_raw': 1000,
                  'in_accel_scale': '0.0098'})
    dev = make_device(tmp_path, files)
    node, lis = start(ros_context, executor, **iio_params(dev, linear_acceleration_variance=0.5))
    spin_until(executor, lambda: len(lis.imu) >= 2, 10.0)
    msg = lis.imu[-1]
    assert msg.linear_acceleration.z == pytest.approx(9.8)
    assert list(msg.linear_acceleration_covariance) == [0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5]


def test_iio_device_vanishes_and_returns(ros_context, executor, tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    node, lis = start(ros_context, executor, **iio_params(dev))
    spin_until(executor, lambda: len(lis.imu) >= 3, 10.0)
    shutil.rmtree(dev)
    spin_until(executor, lambda: any(s.level == DiagnosticStatus.ERROR for s in lis.diag),
               5.0, what='ERROR on /diagnostics')
    err = next(s for s in lis.diag if s.level == DiagnosticStatus.ERROR)
    assert 'iio:device0' in err.message and 'retry' in err.message
    values = {kv.key: kv.value for kv in err.values}
    assert values['state'] == 'error' and int(values['errors']) >= 1
    # Nothing is published while the device is gone, retries go on without crashing.
    count = len(lis.imu)
    spin_until(executor, lambda: node._errors >= 3, 5.0, what='retries')
    assert len(lis.imu) == count
    make_device(tmp_path, l3gd20_files())
    spin_until(executor, lambda: len(lis.imu) >= count + 3, 5.0, what='publishing again')
    assert node.diagnostic_status().level == DiagnosticStatus.OK


def test_iio_garbage_is_never_published(ros_context, executor, tmp_path):
    dev = make_device(tmp_path, l3gd20_files())
    node, lis = start(ros_context, executor, **iio_params(dev))
    spin_until(executor, lambda: len(lis.imu) >= 3, 10.0)
    (dev / 'in_anglvel_y_raw').write_text('\x00garbage\n')
    spin_until(executor, lambda: node._errors >= 2, 5.0, what='garbage seen')
    st = node.diagnostic_status()
    assert st.level == DiagnosticStatus.ERROR and 'in_anglvel_y_raw' in st.message
    n_bad = len(lis.imu)
    (dev / 'in_anglvel_y_raw').write_text('-200\n')
    spin_until(executor, lambda: len(lis.imu) >= n_bad + 3, 5.0, what='publishing again')
    assert all(math.isfinite(m.angular_velocity.y) and m.angular_velocity.y < 0 for m in lis.imu)


def test_iio_missing_device_at_start_does_not_crash(ros_context, executor, tmp_path):
    node, lis = start(ros_context, executor, backend='iio', device_dir='',
                      device_name='bmi160', iio_root=str(tmp_path), rate_hz=100.0,
                      retry_initial=0.01, retry_max=0.02)
    spin_until(executor, lambda: any(s.level == DiagnosticStatus.ERROR for s in lis.diag),
               5.0)
    assert "'bmi160'" in node.diagnostic_status().message
    files = l3gd20_files()
    files['name'] = 'bmi160'
    make_device(tmp_path, files)
    spin_until(executor, lambda: len(lis.imu) >= 2, 5.0, what='found by name')


class NaNSource(PolledSource):
    """A source whose second sample is NaN, then healthy again (read once per tick)."""

    name = 'nan-source'
    has_accel = False

    def __init__(self):
        self.n = 0

    def read(self) -> ImuSample:
        self.n += 1
        w = float('nan') if self.n == 2 else 0.01
        return ImuSample(float(self.n), (w, 0.0, 0.0), None, 20.0)

    def close(self) -> None:
        pass


def test_non_finite_sample_is_rejected(ros_context, executor):
    assert isinstance(NaNSource(), ImuSource)
    listener = Listener(ros_context, executor)
    node = DriverNode(context=ros_context, source=NaNSource(), parameter_overrides=overrides(
        backend='iio', rate_hz=1000.0, retry_initial=0.001, retry_max=0.001))
    executor.add_node(node)
    spin_until(executor, lambda: len(listener.imu) >= 3, 10.0)
    assert node._errors == 1 and 'omega' in node._last_error
    assert all(m.angular_velocity.x == 0.01 for m in listener.imu)


@pytest.mark.parametrize('name', ['driver_sim.yaml', 'driver_iio.yaml'])
def test_config_files_match_declared_parameters(name):
    doc = yaml.safe_load((CONFIG / name).read_text())
    params = doc['/**']['ros__parameters']
    specs = {s.name: s for s in PARAMS}
    assert set(params) <= set(specs)
    for key, value in params.items():
        assert type(value) is type(specs[key].default), key
        if specs[key].choices:
            assert value in specs[key].choices
        if specs[key].lo is not None:
            assert specs[key].lo <= value <= specs[key].hi, key


def test_bad_backend_is_refused(ros_context):
    with pytest.raises(ValueError, match='backend'):
        DriverNode(context=ros_context, parameter_overrides=overrides(backend='serial'))


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


def test_sim_publishes_the_scenario(ros_context, executor):
    from gyro_tdc.sim import SimStream
    run = SimStream('demo_fast', seed=3).run
    node, lis = start(ros_context, executor, backend='sim', scenario='demo_fast', seed=3,
                      time_scale=20.0, frame_id='sim_imu', angular_velocity_variance=2.0e-6,
                      temperature_variance=1.0e-4, linear_acceleration_variance=0.01)
    spin_until(executor, lambda: len(lis.imu) >= 200 and len(lis.temp) >= 20, 60.0)
    assert len(lis.imu) < len(run)  # paced: 20x real time, not flat out
    msgs = lis.imu[:200]
    w = np.array([(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)
                  for m in msgs])
    np.testing.assert_array_equal(w, run.gyro[:200])
    a = np.array([(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z)
                  for m in msgs])
    np.testing.assert_array_equal(a, run.accel[:200])
    m = msgs[0]
    assert m.header.frame_id == 'sim_imu' and m.orientation_covariance[0] == -1.0
    assert list(m.angular_velocity_covariance) == [2e-6, 0, 0, 0, 2e-6, 0, 0, 0, 2e-6]
    assert list(m.linear_acceleration_covariance) == [0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01]
    # Simulated stamps keep their spacing, shifted onto the node clock.
    t0 = stamp_ns(msgs[0])
    offsets = np.array([stamp_ns(x) - t0 for x in msgs]) * 1e-9
    np.testing.assert_allclose(offsets, run.imu_t[:200] - run.imu_t[0], atol=1e-9)
    temps = lis.temp[:20]
    np.testing.assert_array_equal([x.temperature for x in temps], run.temp_c[:20])
    np.testing.assert_allclose([(stamp_ns(x) - t0) * 1e-9 for x in temps],
                               run.temp_t[:20] - run.imu_t[0], atol=1e-9)
    assert temps[0].variance == 1.0e-4 and temps[0].header.frame_id == 'sim_imu'
    assert lis.ref == []  # demo_fast's table does not move
    st = node.diagnostic_status()
    assert st.level == DiagnosticStatus.OK and 'sim:demo_fast' in st.hardware_id


def test_sim_rate_table_reference_and_end_of_run(ros_context, executor):
    from gyro_tdc.sim import SimStream
    run = SimStream('rate_steps', seed=0, rate_hz=0.5).run
    node, lis = start(ros_context, executor, backend='sim', scenario='rate_steps',
                      sim_rate_hz=0.5, time_scale=0.0, qos_depth=5000)
    spin_until(executor, lambda: node._state == 'finished' and len(lis.imu) == len(run),
               60.0, what='whole run received')
    assert len(lis.ref) == run.ref_t.size
    got = np.array([(r.vector.x, r.vector.y, r.vector.z) for r in lis.ref])
    np.testing.assert_array_equal(got, run.ref)
    t0 = stamp_ns(lis.imu[0])
    np.testing.assert_allclose([(stamp_ns(r) - t0) * 1e-9 for r in lis.ref], run.ref_t,
                               atol=1e-9)
    st = node.diagnostic_status()
    assert st.level == DiagnosticStatus.OK and st.message == 'scenario finished'


def test_sim_unknown_scenario_is_a_configuration_error(ros_context):
    """An unknown scenario is no device error retried forever: the node does not start."""
    with pytest.raises(ConfigError) as err:
        DriverNode(context=ros_context, parameter_overrides=overrides(
            backend='sim', scenario='no_such_scenario', retry_initial=0.01))
    message = str(err.value)
    assert '\n' not in message and "'no_such_scenario'" in message
    for name in scenario_names():
        assert name in message


def test_sim_run_too_large_is_a_configuration_error(ros_context):
    """A rate that would simulate gigabytes is refused before any memory is spent."""
    with pytest.raises(ConfigError, match=r'sim_rate_hz 100000: .*\(use sim_rate_hz <= \d+'):
        DriverNode(context=ros_context, parameter_overrides=overrides(
            backend='sim', scenario='l3gd20_paper', sim_rate_hz=100000.0))


def test_iio_missing_device_is_retried_not_fatal(ros_context, executor, tmp_path):
    """A device may appear later: its absence at start-up is a device error, retried."""
    node, lis = start(ros_context, executor, backend='iio', iio_root=str(tmp_path),
                      device_name='l3gd20', retry_initial=0.01, retry_max=0.02)
    spin_until(executor, lambda: node._errors >= 2, 5.0)
    st = node.diagnostic_status()
    assert st.level == DiagnosticStatus.ERROR and 'l3gd20' in st.message
    assert lis.imu == []


def test_main_runs_as_a_process_with_the_sim_params_file(ros_context, executor):
    """Run ``driver_node`` main() in a child process with config/driver_sim.yaml."""
    with node_process('gyro_tdc.nodes.driver_node', '--params-file',
                      str(CONFIG / 'driver_sim.yaml'), '-p', 'scenario:=demo_fast',
                      '-p', 'time_scale:=10.0', '-p', 'frame_id:=proc_imu') as child:
        lis = Listener(ros_context, executor)
        spin_until(executor, lambda: len(lis.imu) >= 20 and len(lis.temp) >= 2, 60.0,
                   what='messages from the driver process')
        assert lis.imu[0].header.frame_id == 'proc_imu'
        assert lis.imu[0].orientation_covariance[0] == -1.0
        code, log = interrupt(child)
        assert code == 0
    assert 'sim back-end' in log
