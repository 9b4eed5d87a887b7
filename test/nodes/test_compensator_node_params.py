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
A running compensator's parameters: policies set as ``ros2 param set`` sets them; sim time.

Real rclpy: the parameter service answered by the compensator of a rig, the next message
compensated under the new policy; ``use_sim_time`` with and without ``/clock``.
"""

from __future__ import annotations

import threading

from compensator_rig import to_ns
from diagnostic_msgs.msg import DiagnosticArray
from gyro_tdc.identify import fit_model
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.nodes.compensator_node import read_model
from gyro_tdc.runtime.flags import PASSTHROUGH, STALE
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosgraph_msgs.msg import Clock
from rosutil import spin_until
from synth import synth_run

T0 = 1_700_000_000.0


@pytest.fixture(scope='module')
def model_file(tmp_path_factory):
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    model = fit_model([run], features=('dT', 'dT2'), n_centers=10)
    return str(save_model(model, tmp_path_factory.mktemp('models') / 'paper.yaml'))


def param_client(rig):
    client = AsyncParameterClient(rig.io, 'compensator_node')
    spin_until(rig.executor, lambda: client.services_are_ready(), 10.0,
               what='parameter services')

    def set_one(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        spin_until(rig.executor, future.done, 10.0, what=f'set {name}')
        return future.result().results[0]
    return set_one


def send(rig, t, w=(0.02, 0.01, -0.01)):
    """Publish one IMU sample stamped ``t`` (s); return its output once it is back."""
    n = len(rig.out)
    rig.imu(to_ns(t), w)
    rig.spin_until(lambda: len(rig.out) > n, what='one output')
    out = rig.out[n]
    return (out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z)


def test_stale_policy_passthrough_takes_effect_on_the_next_message(rig_factory, model_file):
    rig = rig_factory(model_file=model_file, temperature_timeout=2.0)
    set_one = param_client(rig)
    rig.feed([to_ns(T0 + 0.1)], [(0.02, 0.01, -0.01)], [to_ns(T0)], [25.0])
    held = send(rig, T0 + 3.0)                         # 3 s after the reading: stale
    assert rig.node.core.last_flags == STALE and held != (0.02, 0.01, -0.01)
    result = set_one('stale_policy', 'passthrough')
    assert result.successful, result.reason
    assert rig.node.core.policy.stale_policy == 'passthrough'
    assert rig.node.params.stale_policy == 'passthrough'
    assert send(rig, T0 + 3.1) == (0.02, 0.01, -0.01)   # the very next message, raw
    assert rig.node.core.last_flags == STALE | PASSTHROUGH
    result = set_one('passthrough_variance', 0.5)
    assert result.successful, result.reason
    send(rig, T0 + 3.2)
    assert list(rig.out[-1].angular_velocity_covariance[0::4]) == [
        1e-6 + 0.5, 1e-6 + 0.5, 2e-6 + 0.5]               # the rig's input plus the new one


@pytest.mark.parametrize('name,value,why', [
    ('stale_policy', 'sometimes', 'stale_policy'),     # not a choice: the node's own check
    ('temperature_timeout', -1.0, 'temperature_timeout'),   # out of the declared range
    ('stale_variance', 'big', 'type'),                 # wrong type (rclpy)
    ('queue_depth', 10, 'read-only'),                  # QoS: needs a restart
    ('executor', 'single', 'read-only'),
])
def test_an_invalid_value_is_refused_with_a_reason_and_nothing_changes(
        rig_factory, model_file, name, value, why):
    rig = rig_factory(model_file=model_file)
    set_one = param_client(rig)
    policy, params = rig.node.core.policy, rig.node.params
    before = rig.node.get_parameter(name).value
    result = set_one(name, value)
    assert not result.successful
    assert why in result.reason.lower() or why in result.reason
    assert rig.node.get_parameter(name).value == before
    assert rig.node.core.policy is policy and rig.node.params is params


def test_a_model_file_and_a_policy_set_together_apply_both(rig_factory, model_file):
    # load_wait: the set answers once the file is installed, however busy the machine.
    rig = rig_factory(temperature_timeout=2.0, load_wait=10.0)
    client = AsyncParameterClient(rig.io, 'compensator_node')
    spin_until(rig.executor, lambda: client.services_are_ready(), 10.0)
    future = client.set_parameters_atomically([
        Parameter('model_file', value=model_file), Parameter('stale_variance', value=0.25)])
    spin_until(rig.executor, future.done, 10.0)
    assert future.result().result.successful
    rig.feed([to_ns(T0 + 0.1)], [(0.02, 0.01, -0.01)], [to_ns(T0)], [25.0])
    send(rig, T0 + 3.0)
    resid = rig.node.core.model.residual_var
    got = list(rig.out[-1].angular_velocity_covariance[0::4])
    assert got == pytest.approx([1e-6 + resid[0] + 0.25, 1e-6 + resid[1] + 0.25,
                                 2e-6 + resid[2] + 0.25], rel=1e-9)   # the mark


def diagnostics_listener(rig):
    arrays = []
    rig.io.create_subscription(DiagnosticArray, '/diagnostics', arrays.append, 10)
    return arrays


@pytest.mark.parametrize('executor', ['single', 'events'])   # main() spins events
def test_sim_time_without_clock_still_reports_and_compensates(rig_factory, model_file, executor):
    rig = rig_factory(executor_kind=executor, model_file=model_file, use_sim_time=True)
    assert rig.node.get_clock().now().nanoseconds == 0        # no /clock: time stands at 0
    arrays = diagnostics_listener(rig)
    out = rig.feed([to_ns(T0 + 0.1 * k) for k in range(1, 11)], [(0.02, 0.01, -0.01)] * 10,
                   [to_ns(T0)], [25.0])
    assert len(out) == 10 and rig.node.core.counts['compensated'] == 10   # stamps decide
    rig.spin_until(lambda: len(arrays) >= 2, 10.0, what='two /diagnostics reports')
    assert all(a.header.stamp.sec == 0 for a in arrays)      # stamped on the ROS clock


def test_sim_time_with_a_paused_clock_reports_on_the_steady_clock(rig_factory, model_file):
    rig = rig_factory(model_file=model_file, use_sim_time=True)
    clock_pub = rig.io.create_publisher(Clock, '/clock', 10)
    arrays = diagnostics_listener(rig)
    msg = Clock()
    msg.clock.sec = 4242                                     # a bag paused at 4242 s

    def clock_taken():
        clock_pub.publish(msg)
        return rig.node.get_clock().now().nanoseconds == 4242 * 10 ** 9

    rig.spin_until(clock_taken, 10.0, what='/clock taken by the compensator')
    n = len(arrays)
    rig.spin_until(lambda: len(arrays) >= n + 2, 10.0, what='two reports, /clock standing')
    assert [a.header.stamp.sec for a in arrays[n:]] == [4242] * (len(arrays) - n)
    assert rig.node.core.counts['in'] == 0
    rig.feed([to_ns(T0 + 0.1)], [(0.02, 0.01, -0.01)], [to_ns(T0)], [25.0])
    assert rig.node.core.counts['compensated'] == 1          # message stamps, not /clock


@pytest.mark.parametrize('executor', ['single', 'events'])
def test_sim_time_without_clock_installs_a_slow_model_file_set(rig_factory, model_file,
                                                               tmp_path, executor):
    """A model_file slower than load_wait is installed by the poll on the steady clock."""
    other = save_model(fit_model([synth_run(hours=1.0, rate_hz=2.0, seed=6)], features=('dT',),
                                 n_centers=4), tmp_path / 'linear.yaml')
    reading, release = threading.Event(), threading.Event()

    def loader(name):
        if name == str(other):
            reading.set()
            release.wait(30.0)          # until the set is answered: slower than load_wait
        return read_model(name)

    rig = rig_factory(executor_kind=executor, model_file=model_file, use_sim_time=True,
                      node_kwargs={'loader': loader})
    node = rig.node
    first = node.core.model_id
    try:
        result = param_client(rig)('model_file', str(other))
        assert result.successful and reading.is_set()
        assert node.get_clock().now().nanoseconds == 0         # no /clock: time stands at 0
        assert node.core.model_id == first and node.loading.last_reload == f'loading {other}'
    finally:
        release.set()
    rig.spin_until(lambda: node.loading.last_reload.startswith('loaded'), 10.0, what='installed')
    assert node.core.model_id == read_model(str(other)).model_id != first
    assert node.loading.model_file == str(other)
