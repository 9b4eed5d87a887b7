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
compensator_node's raw-bytes edge under hypothesis, with real rclpy: hostile bytes never stop it.

Each example hands one hostile serialized Imu (``cdr_strategies``) and hostile thermometer
readings to the node's callbacks, as its executor would, then takes what it published from a
real subscription: exactly one output or one more ``input malformed``, every /diagnostics report
made, and an output marked compensated finite and plausibly corrected.
"""

from __future__ import annotations

import math

from cdr_strategies import ANY_BYTES, FLOATS
from gyro_tdc.base import MAX_DRIFT_RAD_S, MAX_RATE_RAD_S
from gyro_tdc.data import diagonal_marked, ImuView, locate
from gyro_tdc.data.imu_cdr import encode
from hypothesis import given, HealthCheck, settings, strategies as st
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, Temperature


def good(w, k):
    """Return a plausible serialized Imu: rate ``w``, stamped ``k`` ms after the reading."""
    cov = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6]
    return encode([1_700_000_000], [k * 1_000_000], 'imu_link', [
        [0.0, 0.0, 0.0, 1.0] + [-1.0] + [0.0] * 8 + list(w) + cov
        + [0.0, 0.0, 9.81] + [1e-3] + [0.0] * 8])[0]


def input_rates(data):
    """Return the rates the node reads from ``data`` (None: it cannot read an Imu there)."""
    found = locate(data)
    if found is not None:
        return ImuView(data, found[2]).angular_velocity()
    try:
        w = deserialize_message(data, Imu).angular_velocity
    except Exception:  # what the node drops as malformed
        return None
    return (w.x, w.y, w.z)


@pytest.mark.parametrize('raw_cdr', [True, False])
def test_hostile_bytes_never_stop_the_node_nor_come_out_implausible(rig_factory, raw_cdr):
    rig = rig_factory(model_file='l3gd20_modified', temperature_timeout=86400.0)
    node = rig.node
    seen = {'out': 0, 'marked': 0}

    @settings(max_examples=120, suppress_health_check=[HealthCheck.too_slow,
                                                       HealthCheck.function_scoped_fixture])
    @given(data=ANY_BYTES, temps=st.lists(FLOATS | st.floats(15.0, 35.0), max_size=2),
           w=st.tuples(*[st.floats(-1.0, 1.0)] * 3), first=st.booleans())
    def one(data, temps, w, first):
        """Send a hostile message before or after a good one, hostile readings first."""
        for sample in ((data, good(w, 1)) if first else (good(w, 1), data)):
            step(sample, temps)
            temps = ()

    def step(data, temps):
        for temp_c in temps:
            msg = Temperature()
            msg.header.stamp.sec = 1_700_000_000
            msg.temperature = temp_c
            node._on_temperature(msg)
        malformed, out = node.inputs.malformed, len(rig.out)
        if raw_cdr:
            node._on_imu_raw(data)
        else:                         # the typed path: rclpy deserialises, or cannot
            try:
                msg = deserialize_message(data, Imu)
            except Exception:
                return
            node._on_imu(msg)
        w_in = input_rates(data) if raw_cdr else (msg.angular_velocity.x,
                                                  msg.angular_velocity.y,
                                                  msg.angular_velocity.z)
        if w_in is None:
            assert node.inputs.malformed == malformed + 1
            return
        rig.spin_until(lambda: len(rig.out) == out + 1, what='its output')
        node.diagnostic_status()      # a report over whatever came: never raises
        got = rig.out[-1]
        seen['out'] += 1
        if not diagonal_marked(got.angular_velocity_covariance):
            return
        seen['marked'] += 1
        w = (got.angular_velocity.x, got.angular_velocity.y, got.angular_velocity.z)
        assert all(math.isfinite(v) for v in w)
        assert all(abs(v) <= MAX_RATE_RAD_S for v in w_in)
        assert all(abs(o - i) <= MAX_DRIFT_RAD_S for o, i in zip(w, w_in)), (w, w_in)

    msg = Temperature()
    msg.header.stamp.sec = 1_699_999_999
    msg.temperature = 25.0
    node._on_temperature(msg)
    one()
    assert seen['out'] > 30 and seen['marked'] > 0       # the property was exercised
    assert node.core.counts['in'] == node.core.counts['out']
