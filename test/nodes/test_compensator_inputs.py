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
Drivers as they publish: any IMU and thermometer type, read by field, FRD axes turned to FLU.

The probe starts ``compensator_node`` as users start it (a namespace, remaps and a
parameter file on its command line: in this process through ``cli_args``, and as ``python -m``
in a child process) and feeds it the same samples in other message types: the compensated
rates equal those of the ``sensor_msgs/Imu`` + ``sensor_msgs/Temperature`` run to 1e-9 rad/s.
Bad input choices stop the node at start with one line naming the parameter.
"""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

from compensator_rig import rates, RELIABLE
from geometry_msgs.msg import PoseWithCovarianceStamped, Vector3Stamped
from gyro_tdc.data import diagonal_marked
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime.flags import PASSTHROUGH
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rosutil import matched_readers, matched_writers, spin_until
from sensor_msgs.msg import Imu, Temperature
import yaml

MODEL = 'l3gd20_modified'
T0_NS = 1_700_000_000 * 10 ** 9
N = 60


def _stamp(header, ns: int) -> None:
    header.stamp.sec, header.stamp.nanosec = divmod(ns, 10 ** 9)


def imu_msg(ns, w):
    msg = Imu()
    _stamp(msg.header, ns)
    msg.header.frame_id = 'gyro_frame'
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def vector_msg(ns, w, frd=False):
    msg = Vector3Stamped()
    _stamp(msg.header, ns)
    msg.header.frame_id = 'gyro_frame'
    x, y, z = w
    msg.vector.x, msg.vector.y, msg.vector.z = (x, -y, -z) if frd else (x, y, z)
    return msg


def temperature_msg(ns, value):
    msg = Temperature()
    _stamp(msg.header, ns)
    msg.temperature = value
    return msg


def nested_msg(ns, value):
    """Return a thermometer reading of another type, in a nested field (pose.pose.position.z)."""
    msg = PoseWithCovarianceStamped()
    _stamp(msg.header, ns)
    msg.pose.pose.position.z = value
    return msg


#: name -> (IMU class, IMU builder, temperature class, temperature builder, parameters).
INPUTS = {
    'imu': (Imu, imu_msg, Temperature, temperature_msg, {}),
    'vector3stamped': (Vector3Stamped, vector_msg, Temperature, temperature_msg, {
        'imu_type': 'geometry_msgs/msg/Vector3Stamped', 'angular_velocity_field': 'vector'}),
    'nested_temperature': (Imu, imu_msg, PoseWithCovarianceStamped, nested_msg, {
        'temperature_type': 'geometry_msgs/msg/PoseWithCovarianceStamped',
        'temperature_field': 'pose.pose.position.z'}),
    'frd': (Vector3Stamped, lambda ns, w: vector_msg(ns, w, frd=True), Temperature,
            temperature_msg, {'imu_type': 'geometry_msgs/msg/Vector3Stamped',
                              'angular_velocity_field': 'vector', 'input_frame': 'frd'}),
}


def samples():
    """Return the IMU stamps and rates, and the thermometer stamps and readings (seeded)."""
    rng = np.random.default_rng(35)
    imu_ns = [T0_NS + k * 10_000_000 for k in range(N)]
    w = [tuple(float(v) for v in rng.normal(0.0, 0.02, 3)) for _ in range(N)]
    temp_ns = imu_ns[::10]
    temp_c = [30.0 + 0.25 * j for j in range(len(temp_ns))]
    return imu_ns, w, temp_ns, temp_c


def probe(context, tmp_path, name):
    """Start the node as users do and feed it ``samples()`` in the types of ``INPUTS[name]``."""
    imu_cls, make_imu, temp_cls, make_temp, params = INPUTS[name]
    path = tmp_path / f'{name}.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'model_file': MODEL, **params}}}))
    node = CompensatorNode(context=context, cli_args=[
        '--ros-args', '-r', '__ns:=/robot1', '-r', '__node:=gyro_comp',
        '-r', 'imu/data_raw:=/driver/gyro', '-r', 'imu/temperature:=/driver/thermometer',
        '--params-file', str(path)])
    io = rclpy.create_node('driver_' + name, context=context)
    executor = make_executor('single', context)
    out: list[Imu] = []
    output = node.resolve_topic_name('imu/data_compensated')
    assert output == '/robot1/imu/data_compensated'
    io.create_subscription(Imu, output, out.append, RELIABLE)
    imu_pub = io.create_publisher(imu_cls, '/driver/gyro', RELIABLE)
    temp_pub = io.create_publisher(temp_cls, '/driver/thermometer', RELIABLE)
    try:
        for n in (node, io):
            executor.add_node(n)
        spin_until(executor, lambda: imu_pub.get_subscription_count() > 0
                   and temp_pub.get_subscription_count() > 0
                   and matched_writers(node, '/driver/gyro') > 0
                   and matched_writers(node, '/driver/thermometer') > 0
                   and matched_readers(node, output) > 0
                   and matched_writers(io, output) > 0, 10.0, what='discovery')
        imu_ns, w, temp_ns, temp_c = samples()
        j = 0
        for k, ns in enumerate(imu_ns):
            if j < len(temp_ns) and temp_ns[j] <= ns:
                before = node.core.temps.received
                temp_pub.publish(make_temp(temp_ns[j], temp_c[j]))
                spin_until(executor, lambda: node.core.temps.received > before, 10.0,
                           what='temperature in')
                assert node.core.temps.latest[0] == temp_c[j]
                j += 1
            imu_pub.publish(make_imu(ns, w[k]))
            spin_until(executor, lambda: len(out) > k, 10.0, what=f'output {k}')
        assert not node.core.stream.flags & PASSTHROUGH
        return out, node.get_fully_qualified_name()
    finally:
        executor.shutdown()
        io.destroy_node()
        node.destroy_node()


@pytest.fixture(scope='module')
def reference():
    """Return the compensated rates of the sensor_msgs/Imu + Temperature run."""
    import tempfile
    from pathlib import Path
    from rclpy.context import Context
    context = Context()
    rclpy.init(context=context)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out, fqn = probe(context, Path(tmp), 'imu')
    finally:
        rclpy.try_shutdown(context=context)
    assert fqn == '/robot1/gyro_comp'
    return out


@pytest.mark.parametrize('name', ['vector3stamped', 'nested_temperature', 'frd'])
def test_other_types_give_the_rates_of_the_imu_run(ros_context, tmp_path, reference, name):
    out, _ = probe(ros_context, tmp_path, name)
    _, w, _, _ = samples()
    got, want = rates(out), rates(reference)
    assert len(out) == len(reference) == N
    assert not np.allclose(want, np.array(w), atol=1e-9, rtol=0)     # compensated
    np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)
    assert [m.header.stamp for m in out] == [m.header.stamp for m in reference]
    assert all(m.header.frame_id == 'gyro_frame' for m in out)
    if INPUTS[name][0] is not Imu:
        # The rate's covariance is unknown (REP 145: all zero), and marked all the same.
        for m in out:
            assert not any(m.angular_velocity_covariance)
            assert diagonal_marked(m.angular_velocity_covariance)
            assert m.orientation_covariance[0] == m.linear_acceleration_covariance[0] == -1.0


@pytest.mark.parametrize('args, needles', [
    (['imu_type:=nope_msgs/msg/Gyro'], ('imu_type', 'nope_msgs')),
    (['imu_type:=sensor_msgs/msg/Gyro'], ('imu_type', 'Gyro')),
    (['imu_type:=geometry_msgs/msg/Vector3Stamped'], ('angular_velocity_field',
                                                      'angular_velocity', 'vector')),
    (['imu_type:=geometry_msgs/msg/Vector3Stamped', 'angular_velocity_field:=header'],
     ('angular_velocity_field', 'x/y/z')),
    (['imu_type:=geometry_msgs/msg/Vector3', "angular_velocity_field:=''"],
     ('stamp_field', 'header')),
    (['imu_type:=geometry_msgs/msg/Vector3Stamped', 'angular_velocity_field:=vector',
      'stamp_field:=header.frame_id'], ('stamp_field', 'microseconds')),
    (['temperature_type:=geometry_msgs/msg/PoseStamped'], ('temperature_field',)),
    (['temperature_field:=header'], ('temperature_field', 'not a number')),
    (['temperature_field:=tempurature'], ('temperature_field', 'tempurature', 'variance')),
    (['temperature_type:=std_msgs/msg/Float32', 'temperature_stamp_field:=stamp'],
     ('temperature_stamp_field', 'stamp')),
    (['input_frame:=frd'], ('input_frame', 'frd')),
    (['temperature_quirk:=celsius'], ('temperature_quirk', 'bno055_unsigned_byte')),
])
def test_bad_input_parameters_are_one_line_naming_them(args, needles):
    done = subprocess.run([sys.executable, '-m', 'gyro_tdc.nodes.compensator_node',
                           '--ros-args', *[x for a in args for x in ('-p', a)]],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    errors = [x for x in done.stderr.splitlines() if x.strip()]
    assert len(errors) == 1 and 'Traceback' not in done.stderr + done.stdout, done.stderr
    assert errors[0].startswith('compensator_node: error: ')
    for needle in needles:
        assert needle in errors[0], errors[0]


def test_a_headerless_type_is_stamped_in_microseconds_and_framed_by_frame_id(monkeypatch):
    """px4_msgs SensorGyro (not installed here): its field table and a message of its shape."""
    from types import SimpleNamespace
    from gyro_tdc.nodes import compensator_inputs as inputs
    table = {'px4_msgs/msg/SensorGyro': {'timestamp': 'uint64', 'x': 'float', 'y': 'float',
                                         'z': 'float', 'temperature': 'float'}}
    monkeypatch.setattr(inputs, '_fields', table.get)
    params = SimpleNamespace(angular_velocity_field='', stamp_field='timestamp',
                             frame_id='base_link', input_frame='frd')
    to_imu = inputs._imu_converter('px4_msgs/msg/SensorGyro', params)
    gyro = SimpleNamespace(timestamp=123_456_789_012, x=0.25, y=-0.5, z=0.125,
                           temperature=40.0)
    out = to_imu(gyro)
    assert (out.header.stamp.sec, out.header.stamp.nanosec) == (123_456, 789_012_000)
    assert out.header.frame_id == 'base_link'
    assert (out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z) == \
        (0.25, 0.5, -0.125)
    assert not any(out.angular_velocity_covariance)
    assert out.orientation_covariance[0] == out.linear_acceleration_covariance[0] == -1.0


def test_the_node_run_as_users_run_it_gives_the_same_rates(ros_context, tmp_path, reference):
    """
    Run ``python -m gyro_tdc.nodes.compensator_node`` with remaps and a parameter file.

    A FRD Vector3Stamped gyro and a thermometer in a nested field of another type, both at
    once; the thermometer (held by stamp) is sent first and seen arrived on the child's
    /diagnostics before the IMU samples follow, one at a time.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from rosutil import interrupt, node_process
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'model_file': MODEL, 'executor': 'single',
        **INPUTS['frd'][4], **INPUTS['nested_temperature'][4]}}}))
    imu_ns, w, temp_ns, temp_c = samples()
    io = rclpy.create_node('driver_probe', context=ros_context)
    executor = make_executor('single', ros_context)
    executor.add_node(io)
    out: list[Imu] = []
    silent: list[float] = []      # 'temperature silent s' of each of the child's reports

    def on_diagnostics(msg):
        for status in msg.status:
            if status.name == '/robot1/gyro_comp: gyro compensation':
                values = {v.key: v.value for v in status.values}
                silent.append(float(values['temperature silent s']))

    io.create_subscription(Imu, '/robot1/imu/data_compensated', out.append, RELIABLE)
    io.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    imu_pub = io.create_publisher(Vector3Stamped, '/driver/gyro', RELIABLE)
    temp_pub = io.create_publisher(PoseWithCovarianceStamped, '/driver/thermometer', RELIABLE)
    try:
        with node_process('gyro_tdc.nodes.compensator_node', '-r', '__ns:=/robot1',
                          '-r', '__node:=gyro_comp', '-r', 'imu/data_raw:=/driver/gyro',
                          '-r', 'imu/temperature:=/driver/thermometer',
                          '--params-file', str(path)) as child:
            spin_until(executor, lambda: imu_pub.get_subscription_count() > 0
                       and temp_pub.get_subscription_count() > 0
                       and io.count_publishers('/robot1/imu/data_compensated') > 0, 30.0,
                       what='the child node')
            spin_until(executor, lambda: silent, 30.0, what='a first /diagnostics report')
            for ns, value in zip(temp_ns, temp_c):
                temp_pub.publish(nested_msg(ns, value))
            # The report after an arrival shows the thermometer silent for 0 s; a later one
            # silent for a whole report period says nothing more came in between: all six
            # (one reliable writer, in order) are held before the first IMU sample.
            n = len(silent)
            spin_until(executor, lambda: any(x < 0.5 for x in silent[n:]), 30.0,
                       what='the thermometer on /diagnostics')
            first = next(i for i in range(n, len(silent)) if silent[i] < 0.5)
            spin_until(executor, lambda: any(x >= 0.9 for x in silent[first + 1:]), 30.0,
                       what='the thermometer quiet on /diagnostics')
            for k, ns in enumerate(imu_ns):
                imu_pub.publish(vector_msg(ns, w[k], frd=True))
                spin_until(executor, lambda: len(out) > k, 10.0, what=f'output {k}')
            code, log = interrupt(child)
    finally:
        executor.shutdown()
        io.destroy_node()
    assert code == 0, log
    np.testing.assert_allclose(rates(out), rates(reference), atol=1e-9, rtol=0)
    assert [m.header.stamp for m in out] == [m.header.stamp for m in reference]


def test_an_unreadable_message_is_counted_and_the_stream_goes_on(ros_context):
    """A stamp out of a Time's range (a driver's garbage) is dropped and counted, once each."""
    node = CompensatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in INPUTS['vector3stamped'][4].items()])
    try:
        bad = vector_msg(T0_NS, (0.1, 0.2, 0.3))
        bad.header.stamp = SimpleNamespace(sec=2 ** 40, nanosec=0)   # not an int32
        node._on_imu(bad)
        assert node.inputs.malformed == 1
        assert node.core.counts['in'] == 0                 # never reached the core
    finally:
        node.destroy_node()
