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

"""The demo's live step: driver_node -> compensator_node as two processes over DDS."""

import json

from gyro_tdc.base.resources import model_path
import numpy as np
import pytest


@pytest.mark.serial  # a 5 s window from two processes' start: not beside other tests
def test_live_stream_is_compensated_across_processes():
    # Imported here: rclpy only loads for the node tests.
    from gyro_tdc.nodes.live import run_live

    result = run_live(model_path('l3gd20_modified'), scenario='demo_fast', seed=11,
                      sim_rate_hz=10.0, time_scale=40.0, seconds=5.0)
    assert result.matched >= 100
    assert result.compensated_received >= result.matched
    # While the monitor heard both streams: one compensated message per raw one.
    assert result.compensated_in_window == result.raw_in_window >= result.matched
    # A raw rate passes only before the compensator's first temperature (its thermometer
    # subscription may match after its IMU one): never after the first corrected message.
    assert result.passed_raw_after_first_corrected == 0
    assert result.passed_raw < result.matched // 2
    raw, comp = np.array(result.bs_raw_dps2), np.array(result.bs_compensated_dps2)
    # Raw BS holds the L3GD20's few-dps zero-rate offset; the model removes it down to
    # about the 10 Hz white-noise floor (0.009 (deg/s)^2).
    assert np.all(comp < 0.01 * raw)
    assert np.all(comp < 3 * 0.009)
    assert len(result.lines()) == 3
    json.dumps(result.__dict__)      # the demo writes it as live.json: plain types only


def test_the_monitor_tells_a_raw_pass_through_by_the_variance_the_compensator_adds():
    import rclpy
    from rclpy.context import Context
    from gyro_tdc.nodes.live import MonitorNode
    from sensor_msgs.msg import Imu

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = MonitorNode(context=ctx)
        for stamp_s, raw_var, comp_var in ((1, 2.7e-6, 2.7e-6 + 1e-4), (2, 2.7e-6, 3.1e-6)):
            for into, v in ((node.raw, raw_var), (node.comp, comp_var)):
                msg = Imu()
                msg.header.stamp.sec = stamp_s
                msg.angular_velocity_covariance[0] = v
                node._store(into, msg)
        key = 1_000_000_000
        assert node.passed_raw(key, 1e-4) is True and node.passed_raw(2 * key, 1e-4) is False
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
