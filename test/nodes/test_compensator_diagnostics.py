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
compensator_node's /diagnostics with real rclpy: names, hardware_id, input liveness, frames.

The liveness clock is the node's ``_live_clock`` (``time.monotonic``), replaced here by a fake one
the test advances, so the verdicts of seconds of silence need no waiting.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus
from gyro_tdc.nodes.compensator_node import CompensatorNode
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, Temperature

T0 = 1_700_000_000


class FakeClock:
    """A monotonic clock that moves only when told."""

    def __init__(self, now):
        self.now = now

    def __call__(self):
        return self.now


class Log:
    """Record a node's log lines by level."""

    def __init__(self):
        self.lines = {}

    def __getattr__(self, level):
        return lambda text, **_: self.lines.setdefault(level, []).append(text)


def make(ros_context, nodes, namespace='/mavros', **params):
    params.setdefault('model_file', 'l3gd20_modified')
    node = CompensatorNode(context=ros_context, namespace=namespace, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])
    nodes.append(node)
    node.diagnostics.live_clock = FakeClock(node.diagnostics.live_clock())
    return node


@pytest.fixture
def nodes():
    made = []
    yield made
    for node in made:
        node.destroy_node()


def imu(k, frame='base_link', rate_hz=100.0):
    msg = Imu()
    msg.header.stamp.sec, msg.header.stamp.nanosec = T0 + int(k // rate_hz), int(
        round((k % rate_hz) / rate_hz * 1e9))
    msg.header.frame_id = frame
    msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
    msg.angular_velocity_covariance[8] = 1e-6
    return msg


def temperature(node, sec):
    msg = Temperature()
    msg.header.stamp.sec = sec
    msg.temperature = 30.0
    node._on_temperature(msg)


def second(node, k, n=100, raw=True, frame='base_link'):
    """Feed one fake second of a 100 Hz IMU (and a temperature); return the status."""
    temperature(node, T0 + k // 100)
    for j in range(k, k + n):
        msg = imu(j, frame)
        node._on_imu_raw(serialize_message(msg)) if raw else node._on_imu(msg)
    node.diagnostics.live_clock.now += 1.0
    return node.diagnostic_status()


def values(st):
    return {kv.key: kv.value for kv in st.values}


def test_statuses_are_named_by_the_fully_qualified_node_name(ros_context, nodes):
    left = make(ros_context, nodes, '/left')
    right = make(ros_context, nodes, '/right')
    mavros = make(ros_context, nodes)
    assert mavros.diagnostic_status().name == '/mavros/compensator_node: gyro compensation'
    assert left.diagnostic_status().name != right.diagnostic_status().name
    assert left.diagnostic_status().name.endswith(': gyro compensation')


@pytest.mark.parametrize('raw', [True, False])
def test_hardware_id_is_the_sensor_id_else_the_data_frame(ros_context, nodes, raw):
    node = make(ros_context, nodes, expected_rate_hz=100.0)
    assert node.diagnostic_status().hardware_id == ''          # no data yet, no sensor_id
    st = second(node, 0, raw=raw, frame='imu_link')
    assert st.hardware_id == 'imu_link' and values(st)['data frame'] == 'imu_link'
    named = make(ros_context, nodes, '/other', sensor_id='imu-7')
    assert second(named, 0, raw=raw, frame='imu_link').hardware_id == 'imu-7'


def test_a_stopped_imu_warns_then_errors_and_never_reads_ok(ros_context, nodes):
    node = make(ros_context, nodes, expected_rate_hz=100.0)
    st = node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN and 'no imu/data_raw yet' in st.message
    k = 0
    for _ in range(8):
        st = second(node, k, frame='imu_link')
        k += 100
        assert st.level == DiagnosticStatus.OK, st.message
    v = values(st)
    assert float(v['imu rate Hz']) == pytest.approx(100.0)
    assert v['imu expected rate Hz'] == '100.00' and float(v['imu silent s']) == 0.0
    assert float(v['temperature rate Hz']) == pytest.approx(1.0)
    # The IMU stops; the thermometer goes on (temperature stamps run ahead of the last IMU
    # stamp): never OK again.
    levels = []
    for s in range(8):
        temperature(node, T0 + 8 + s)
        node.diagnostics.live_clock.now += 1.0
        st = node.diagnostic_status()
        levels.append(st.level)
    assert levels[0] == DiagnosticStatus.WARN
    assert DiagnosticStatus.OK not in levels
    assert levels[-1] == DiagnosticStatus.ERROR and 'no imu/data_raw for 8.0 s' in st.message
    assert values(st)['imu silent s'] == '8.000'
    # It comes back: OK once the window holds the rate again.
    for _ in range(6):
        st = second(node, k, frame='imu_link')
        k += 100
    assert st.level == DiagnosticStatus.OK, st.message


def test_a_stopped_imu_never_reads_ok_while_the_temperature_is_hours_old(ros_context, nodes):
    """The thermometer died 3 h before; then the IMU stops: no report is OK again."""
    node = make(ros_context, nodes, expected_rate_hz=100.0)
    temperature(node, T0 - 10_800)
    k = 0
    for _ in range(6):
        for j in range(k, k + 100):
            node._on_imu_raw(serialize_message(imu(j, 'imu_link')))
        k += 100
        node.diagnostics.live_clock.now += 1.0
        st = node.diagnostic_status()
        assert st.level == DiagnosticStatus.WARN and 'temperature stale' in st.message
    levels = []
    for _ in range(8):                       # the IMU stops: nothing new is flagged stale
        node.diagnostics.live_clock.now += 1.0
        st = node.diagnostic_status()
        levels.append(st.level)
        assert float(values(st)['temperature age s']) > 10_800.0
    assert DiagnosticStatus.OK not in levels, levels
    assert levels[-1] == DiagnosticStatus.ERROR and 'no imu/data_raw for' in st.message


def test_a_slow_imu_warns(ros_context, nodes):
    node = make(ros_context, nodes, expected_rate_hz=200.0)
    k = 0
    for _ in range(6):
        st = second(node, k, frame='imu_link')          # 100 Hz where 200 are expected
        k += 100
    assert st.level == DiagnosticStatus.WARN and 'imu/data_raw too slow: 100.00 Hz' in st.message


def test_a_model_in_another_frame_warns_while_it_lasts_logged_once(ros_context, nodes):
    node = make(ros_context, nodes, expected_rate_hz=100.0)
    log = Log()
    node.diagnostics.log = log
    assert node.core.model.frame_id == 'imu_link'
    k = 0
    for _ in range(3):
        st = second(node, k, frame='base_link')
        k += 100
        assert st.level == DiagnosticStatus.WARN
        assert "imu/data_raw is in frame 'base_link'" in st.message and "'imu_link'" in st.message
    assert len([t for t in log.lines.get('warning', []) if 'frame' in t]) == 1
    st = second(node, k, frame='imu_link')
    assert st.level == DiagnosticStatus.OK, st.message


def test_the_published_status_reports_a_silent_imu(rig_factory):
    rig = rig_factory(model_file='l3gd20_modified', expected_rate_hz=100.0)
    clock = FakeClock(rig.node.diagnostics.live_clock())
    rig.node.diagnostics.live_clock = clock
    rig.feed([T0 * 10 ** 9 + k * 10 ** 7 for k in range(50)], [(0.0, 0.0, 0.0)] * 50)
    rig.node.diagnostic_status()                       # a report sees the messages
    clock.now += 30.0                                  # then 30 s without one
    seen = len(rig.diag)
    rig.spin_until(lambda: len(rig.diag) > seen and rig.diag[-1].level ==
                   DiagnosticStatus.ERROR, what='an ERROR on /diagnostics')
    assert 'no imu/data_raw for 30.0 s' in rig.diag[-1].message
    assert rig.diag[-1].name == '/compensator_node: gyro compensation'
    assert rig.diag[-1].hardware_id == 'imu_link'
