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
Bring your own IMU: what the compensator accepts from other drivers, and whose model it is.

``temperature_type`` takes std_msgs Float32/Float64 readings (no header: each is stamped
with the latest IMU stamp received, readings before the first IMU message are ignored), and
``sensor_id`` makes the node warn, in the log and on /diagnostics, while the model in use
was trained for another sensor (the shipped simulated model has none).
"""

from __future__ import annotations

from bags import bag_from_run
from compensator_rig import RELIABLE, stamp_s, to_ns
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.identify import fit_model
from gyro_tdc.model.modelfile import load_model, save_model
from gyro_tdc.nodes.compensator_inputs import message_class
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import CompensatorCore, PARAMS, Policy, TEMPERATURE_TYPES
from gyro_tdc.runtime.health import health, OK, sensor_mismatch, WARN
import pytest
import rclpy
from rclpy.parameter import Parameter
from rosutil import (interrupt, Lines, matched_readers, matched_writers, node_process,
                     spin_until)
from sensor_msgs.msg import Imu
from std_msgs.msg import Float32, Float64
from synth import synth_run

T0 = 1_700_000_000.0


@pytest.fixture(scope='module')
def model():
    """Fit a paper model f(dT, dT2) on a synthetic run (no sensor_id)."""
    return fit_model([synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)],
                     features=('dT', 'dT2'), n_centers=8)


def test_train_writes_the_sensor_id(tmp_path, capsys):
    """``train --sensor-id`` names the sensor in the model; without it the id stays empty."""
    bag = bag_from_run(synth_run(hours=0.5, rate_hz=2.0, seed=2), tmp_path / 'bag')
    ids = {}
    for name, extra in (('own', ['--sensor-id', 'imu-7']), ('plain', [])):
        out = tmp_path / f'{name}.yaml'
        assert train_main([str(bag), '--features', 'dT', '--kind', 'poly', '--no-accel',
                           '--no-progress', '--out', str(out), *extra]) == 0
        model = load_model(out)
        ids[name] = model.model_id
        assert model.sensor_id == ('imu-7' if extra else '')
    assert ids['own'] != ids['plain']    # the id is part of the model's identity
    capsys.readouterr()


def test_temperature_types_agree_between_the_table_and_the_node():
    spec = {s.name: s for s in PARAMS}['temperature_type']
    # Any installed type is taken (read by temperature_field); the usual three are the
    # node's known ones, each loaded by name to its class.
    assert not spec.choices
    assert spec.default == TEMPERATURE_TYPES[0] == 'sensor_msgs/msg/Temperature'
    for name in TEMPERATURE_TYPES:
        cls = message_class(name, 'temperature_type')
        pkg, _, msg = name.split('/')
        assert cls.__module__.startswith(f'{pkg}.msg') and cls.__name__ == msg
        assert message_class(name, 'temperature_type') is cls


def test_sensor_mismatch_names_both_ids(model):
    assert sensor_mismatch(model, '') == ''           # no check asked for
    assert sensor_mismatch(None, 'imu-7') == ''       # no model: nothing to compare
    own = model.replace(sensor_id='imu-7')
    assert sensor_mismatch(own, 'imu-7') == ''
    other = sensor_mismatch(model.replace(sensor_id='imu-3'), 'imu-7')
    assert "'imu-3'" in other and "'imu-7'" in other and '\n' not in other
    shipped = sensor_mismatch(model, 'imu-7')
    assert 'no sensor_id' in shipped and model.model_id in shipped
    assert 'gyro-tdc train --sensor-id' in shipped


def test_health_warns_while_the_model_is_another_sensors(model):
    core = CompensatorCore(Policy(), model)
    assert health(core).level == OK
    assert health(core, sensor_id=model.sensor_id).level == OK
    h = health(core, sensor_id='imu-7')
    assert h.level == WARN and "'imu-7'" in h.message
    assert health(CompensatorCore(Policy(), model.replace(sensor_id='imu-7')),
                  sensor_id='imu-7').level == OK


class FloatRig:
    """A compensator whose temperature input is std_msgs, and a node feeding it."""

    def __init__(self, context, kind, **params):
        self.executor = make_executor('single', context)
        self.node = CompensatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.io = rclpy.create_node('feeder', context=context)
        self.cls = {'std_msgs/msg/Float32': Float32, 'std_msgs/msg/Float64': Float64}[kind]
        self.imu_pub = self.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.temp_pub = self.io.create_publisher(self.cls, 'imu/temperature', RELIABLE)
        self.out: list[Imu] = []
        self.io.create_subscription(Imu, 'imu/data_compensated', self.out.append, RELIABLE)
        for node in (self.node, self.io):
            self.executor.add_node(node)
        spin_until(self.executor, lambda: self.imu_pub.get_subscription_count() > 0
                   and self.temp_pub.get_subscription_count() > 0
                   and matched_writers(self.node, 'imu/data_raw') > 0
                   and matched_writers(self.node, 'imu/temperature') > 0
                   and matched_readers(self.node, 'imu/data_compensated') > 0
                   and matched_writers(self.io, 'imu/data_compensated') > 0, 10.0,
                   what='discovery')

    def temperature(self, value):
        self.temp_pub.publish(self.cls(data=value))

    def imu(self, ns, w):
        msg = Imu()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(ns), 10 ** 9)
        msg.orientation_covariance[0] = -1.0
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
        msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
        msg.angular_velocity_covariance[8] = 1e-6
        msg.linear_acceleration_covariance[0] = -1.0
        self.imu_pub.publish(msg)
        n = len(self.out)
        spin_until(self.executor, lambda: len(self.out) > n, 10.0, what='one output')
        return self.out[-1]

    def close(self):
        self.executor.shutdown()
        self.io.destroy_node()
        self.node.destroy_node()


@pytest.mark.parametrize('kind', ['std_msgs/msg/Float32', 'std_msgs/msg/Float64'])
def test_float_temperature_takes_the_latest_imu_stamp(ros_context, model, tmp_path, kind):
    path = save_model(model, tmp_path / 'model.yaml')
    rig = FloatRig(ros_context, kind, model_file=str(path), temperature_type=kind)
    try:
        node = rig.node
        # Before any IMU message a reading has no stamp to take: ignored, and said so.
        rig.temperature(40.0)
        spin_until(rig.executor, lambda: node.temperatures_ignored == 1, 10.0)
        assert node.core.temps.received == 0
        w = (0.01, -0.02, 0.03)
        first = rig.imu(to_ns(T0), w)
        assert (first.angular_velocity.x, first.angular_velocity.y,
                first.angular_velocity.z) == w       # no temperature yet: passed through
        rig.temperature(21.5)  # exact in float32 too
        spin_until(rig.executor, lambda: node.core.temps.received == 1, 10.0)
        assert node.core.temps.latest == (21.5, stamp_s(to_ns(T0)))
        t1 = T0 + 0.005
        out = rig.imu(to_ns(t1), w)
        # The same sequence through the pure core: stamps as the node computes them.
        ref = CompensatorCore(node.core.policy, model)
        ref.process(stamp_s(to_ns(T0)), *w)
        ref.add_temperature(stamp_s(to_ns(T0)), 21.5)
        wx, wy, wz, _, flags, _, _ = ref.process(stamp_s(to_ns(t1)), *w)
        assert flags == 0
        assert (out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z) == \
            (wx, wy, wz)
        assert (wx, wy, wz) != w
        assert node.temperatures_ignored == 1
    finally:
        rig.close()


def test_sensor_id_mismatch_is_logged_at_start_and_warned():
    """The shipped simulated model on an IMU named by sensor_id: WARN in the log at load."""
    with node_process('gyro_tdc.nodes.compensator_node', '-p', 'model_file:=l3gd20_modified',
                      '-p', 'sensor_id:=imu-7', '-p', 'executor:=single') as child:
        lines = Lines(child.stdout)
        line = lines.wait_for('not for this IMU', 30.0)
        assert 'WARN' in line and "'imu-7'" in line and 'no sensor_id' in line
        code, _ = interrupt(child)
        assert code == 0


def test_sensor_id_match_is_quiet_and_mismatch_warns(ros_context, model, tmp_path):
    own = save_model(model.replace(sensor_id='imu-7'), tmp_path / 'own.yaml')
    other = save_model(model, tmp_path / 'other.yaml')
    node = CompensatorNode(context=ros_context, parameter_overrides=[
        Parameter('model_file', value=str(own)), Parameter('sensor_id', value='imu-7'),
        Parameter('load_wait', value=10.0)])
    try:
        status = node.diagnostic_status()
        assert 'not for this IMU' not in status.message
        # Another sensor's model swapped in (read within load_wait, installed at once).
        assert node.set_parameters([Parameter('model_file', value=str(other))])[0].successful
        assert node.loading.model_file == str(other)
        status = node.diagnostic_status()
        assert status.level == bytes((WARN,)) and 'not for this IMU' in status.message
    finally:
        node.destroy_node()
