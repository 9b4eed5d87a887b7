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

"""driver_node (simulated, accelerated) -> compensator_node -> BS far below the raw stream's."""

from __future__ import annotations

from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.driver_node import DriverNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import PASSTHROUGH
from gyro_tdc.signal.metrics import bias_stability
from gyro_tdc.sim import simulate_run, to_run
import numpy as np
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosutil import matched_writers, spin_until
from sensor_msgs.msg import Imu

SCENARIO = 'demo_fast'   # 20 -> 50 -> 20 degC, static effects bias, dT, dT2
RATE_HZ = 5.0            # IMU rate of the streamed run: 11,100 messages
DEEP = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20000,
                  reliability=ReliabilityPolicy.RELIABLE)


def test_driver_to_compensator_reduces_bias_stability(ros_context, tmp_path):
    # Train on one run (seed 0), stream a held-out run (seed 1).
    train = to_run(simulate_run(SCENARIO, seed=0))
    model = fit_model([train], features=('dT', 'dT2'), n_centers=10)
    model_file = save_model(model, tmp_path / 'model.yaml')
    held_out = simulate_run(SCENARIO, seed=1, rate_hz=RATE_HZ)
    run = to_run(held_out)
    bs_raw_offline = bias_stability(run.omega, run.omega_ref)
    bs_comp_offline = bias_stability(compensate(model, run.t, run.temp, run.omega),
                                     run.omega_ref)
    expected = bs_comp_offline / bs_raw_offline
    assert np.all(expected < 0.05)

    executor = make_executor('events', ros_context)
    driver = DriverNode(context=ros_context, parameter_overrides=[
        Parameter('backend', value='sim'), Parameter('scenario', value=SCENARIO),
        Parameter('seed', value=1), Parameter('sim_rate_hz', value=RATE_HZ),
        Parameter('time_scale', value=300.0), Parameter('qos_depth', value=5000)])
    comp = CompensatorNode(context=ros_context, parameter_overrides=[
        Parameter('model_file', value=str(model_file))])
    sink = rclpy.create_node('sink', context=ros_context)
    raw: dict[int, np.ndarray] = {}
    out: dict[int, np.ndarray] = {}
    order: list[int] = []

    def keep(store, track=False):
        def callback(msg: Imu) -> None:
            key = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
            w = msg.angular_velocity
            store[key] = np.array((w.x, w.y, w.z, msg.angular_velocity_covariance[0]))
            if track:
                order.append(key)
        return callback

    sink.create_subscription(Imu, 'imu/data_raw', keep(raw), DEEP)
    sink.create_subscription(Imu, 'imu/data_compensated', keep(out, True), DEEP)
    executor.add_node(sink)
    executor.add_node(comp)
    try:
        # Stream only once every subscription is matched, so nothing is lost to discovery.
        spin_until(executor, lambda: driver._imu_pub.get_subscription_count() >= 2
                   and driver._temp_pub.get_subscription_count() >= 1
                   and comp._pub.get_subscription_count() >= 1
                   and matched_writers(comp, 'imu/data_raw') >= 1
                   and matched_writers(comp, 'imu/temperature') >= 1
                   and matched_writers(sink, 'imu/data_raw') >= 1
                   and matched_writers(sink, 'imu/data_compensated') >= 1, 10.0,
                   what='discovery')
        executor.add_node(driver)
        spin_until(executor, lambda: driver._state == 'finished', 60.0,
                   what='the whole run published')
        spin_until(executor, lambda: len(raw) == len(out) == comp.core.counts['in']
                   == driver._published, 10.0,
                   what=f'every one of the {len(run)} messages through the compensator')
    finally:
        executor.shutdown()
        for node in (driver, comp, sink):
            node.destroy_node()

    # Every message the compensator took in came out once, in order, stamps unchanged.
    assert comp.core.counts['in'] == comp.core.counts['out'] == len(out) == len(run)
    assert order == sorted(order) and len(set(order)) == len(order)
    keys = sorted(out)
    assert set(keys) <= set(raw)
    omega_raw = np.array([raw[k][:3] for k in keys])
    omega_out = np.array([out[k][:3] for k in keys])
    # A sample that reaches the compensator before the first temperature passes through
    # raw, flagged by a widened covariance; the executor may order the first pair either way.
    passed = np.array([out[k][3] for k in keys]) >= comp.params.passthrough_variance
    assert passed.sum() == comp.core.flag_counts[PASSTHROUGH] <= 2
    assert not passed[2:].any()
    np.testing.assert_array_equal(omega_out[passed], omega_raw[passed])
    bs_raw = bias_stability(omega_raw[~passed], np.zeros(3))
    bs_out = bias_stability(omega_out[~passed], np.zeros(3))
    ratio = bs_out / bs_raw
    # The live pipeline matches the offline evaluation of the same run.
    np.testing.assert_allclose(ratio, expected, rtol=0.1)
    assert np.all(ratio < 0.05)
