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
    raw, comp = np.array(result.bs_raw_dps2), np.array(result.bs_compensated_dps2)
    # Raw BS holds the L3GD20's few-dps zero-rate offset; the model removes it down to
    # about the 10 Hz white-noise floor (0.009 (deg/s)^2).
    assert np.all(comp < 0.01 * raw)
    assert np.all(comp < 3 * 0.009)
    assert len(result.lines()) == 3
