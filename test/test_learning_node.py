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

"""compensator_node learn:=true: services, learn_file persistence, restart-resume."""

from __future__ import annotations

import json

from compensator_rig import RELIABLE, to_ns
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
import numpy as np
import rclpy
from rclpy.parameter import Parameter
from rosutil import spin_until
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger

RATE = 5.0          # Hz: 50 samples per 10 s still window


class LearnRig:
    """A learning compensator and a node that feeds it, calls its services and listens."""

    def __init__(self, context, **params):
        self.executor = make_executor('single', context)
        self.node = CompensatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.io = rclpy.create_node('feeder', context=context)
        self.imu_pub = self.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.temp_pub = self.io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
        self.out: list[Imu] = []
        self.io.create_subscription(Imu, 'imu/data_compensated', self.out.append, RELIABLE)
        self.save = self.io.create_client(Trigger, 'compensator_node/learn_save')
        self.reset = self.io.create_client(Trigger, 'compensator_node/learn_reset')
        for node in (self.node, self.io):
            self.executor.add_node(node)
        spin_until(self.executor, lambda: self.imu_pub.get_subscription_count() > 0
                   and self.temp_pub.get_subscription_count() > 0
                   and self.save.service_is_ready() and self.reset.service_is_ready()
                   and self.node.count_subscribers('imu/data_compensated') > 0, 10.0,
                   what='discovery')

    def feed(self, t0, secs, temp, bias, moving, seed):
        """Publish ``secs`` of IMU at RATE (still at ``bias`` or moving) and 1 Hz temperature."""
        rng = np.random.default_rng(seed)
        n = int(secs * RATE)
        start = len(self.out)
        for k in range(n):
            t = t0 + k / RATE
            if k % int(RATE) == 0:
                m = Temperature()
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(to_ns(t), 10 ** 9)
                m.temperature = temp
                self.temp_pub.publish(m)
            w = (0.3 if moving else 1e-4) * rng.standard_normal(3) + (0 if moving else bias)
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(to_ns(t), 10 ** 9)
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = \
                (float(v) for v in w)
            msg.orientation_covariance[0] = -1.0
            msg.linear_acceleration_covariance[0] = -1.0
            self.imu_pub.publish(msg)
            if k % 200 == 199:
                spin_until(self.executor, lambda: len(self.out) >= start + k + 1, 10.0,
                           what='outputs')
        spin_until(self.executor, lambda: len(self.out) >= start + n, 10.0, what='outputs')
        return t0 + n / RATE

    def call(self, client):
        future = client.call_async(Trigger.Request())
        spin_until(self.executor, future.done, 10.0, what='service answer')
        return future.result()

    def close(self):
        self.executor.shutdown()
        self.io.destroy_node()
        self.node.destroy_node()


def _values(node):
    return {kv.key: kv.value for kv in node.diagnostic_status().values}


def test_learn_save_reset_and_restart_resume(ros_context, tmp_path):
    path = tmp_path / 'learn' / 'learned.json'
    bias = np.array([0.01, -0.02, 0.005])
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        node = rig.node
        assert node.core.model is None and node.learner is not None
        t = rig.feed(1000.0, 100.0, 20.0, bias, False, 1)
        t = rig.feed(t, 20.0, 20.0, bias, True, 2)
        r = rig.call(rig.save)
        assert r.success and r.message == f'saved {path}' and path.is_file()
        # The first still stretch's bias is the model now: a still sample comes out ~0.
        assert node.core.model is not None
        np.testing.assert_allclose(node.core.model.intercept, bias, atol=5e-5)
        t = rig.feed(t, 20.0, 20.0, bias, False, 3)
        assert abs(rig.out[-1].angular_velocity.x) < 1e-3
        v = _values(node)
        assert v['learn points'] == '1' and v['learn still s'] == '100'
        assert v['learn features'] == 'bias' and 'swapped' in v['learn prediction check']
        assert v['learn covered degC'] == '20.00 .. 20.00'
        # A second stretch 4 degC warmer: two bins, a dT model.
        t = rig.feed(t, 100.0, 24.0, bias + [4e-3, 0.0, 0.0], False, 4)
        t = rig.feed(t, 20.0, 24.0, bias, True, 5)
        assert rig.call(rig.save).success
        saved = json.loads(path.read_text())
        assert saved['fit']['features'] == ['dT'] and len(saved['bins']) >= 2
        state = json.loads(json.dumps(node.learner.state()))
        assert state == saved
    finally:
        rig.close()            # destroy_node saves again: the window in progress judged too
    final = json.loads(path.read_text())
    assert final['bins'] == saved['bins'] and final['fit'] == saved['fit']
    assert final['windows'] == saved['windows'] + 1
    saved = final
    # Restarted: resumes learn_file, nothing lost; the learned model is in use at once.
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        node = rig.node
        assert json.loads(json.dumps(node.learner.state())) == saved
        assert node.core.model is not None
        np.testing.assert_allclose(node.core.model.linear[0, 0], 1e-3, rtol=0.05)
        r = rig.call(rig.reset)
        assert r.success and 'no model' in r.message
        assert node.core.model is None and _values(node)['learn points'] == '0'
    finally:
        rig.close()
    assert json.loads(path.read_text())['bins'] == {}
