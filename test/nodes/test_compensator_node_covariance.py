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
REP 145 covariances through compensator_node: known, unknown (all zero) and no data (-1).

Both input paths (``raw_cdr`` true: the serialized bytes patched; false: the message
deserialised) give the same output: a known covariance is widened by the model's variance and
marked; an unknown one stays all zero (marked by negative zeros) unless ``base_variance`` gives
it a base; -1 stays as it came.
"""

from __future__ import annotations

import math

from gyro_tdc.data.mark import diagonal_marked
from marks import mark
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

T0_NS = 1_700_000_000 * 10 ** 9
KNOWN = (1e-6, 0.0, 0.0, 0.0, 2e-6, 0.0, 0.0, 0.0, 3e-6)
UNKNOWN = (0.0,) * 9
NO_DATA = (-1.0,) + (0.0,) * 8


def _feed(rig, covariances):
    rig.temperature(T0_NS, 30.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='the temperature')
    for k, cov in enumerate(covariances):
        msg = Imu()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(T0_NS + k * 10 ** 7, 10 ** 9)
        msg.header.frame_id = 'imu_link'
        msg.angular_velocity.x = 0.01
        msg.angular_velocity_covariance = [float(v) for v in cov]
        rig.imu_pub.publish(msg)
    rig.spin_until(lambda: len(rig.out) == len(covariances), what='every output')
    return [tuple(o.angular_velocity_covariance) for o in rig.out]


@pytest.mark.parametrize('raw_cdr', [True, False])
@pytest.mark.parametrize('base_variance', [0.0, 4e-6])
def test_unknown_stays_unknown_unless_a_base_variance_is_given(rig_factory, raw_cdr,
                                                               base_variance):
    rig = rig_factory(model_file='l3gd20_modified', raw_cdr=raw_cdr,
                      base_variance=base_variance)
    known, unknown, no_data = _feed(rig, [KNOWN, UNKNOWN, NO_DATA])
    var = rig.node.core.model.residual_var     # in range, fresh: just the model's
    # Exact values, the same in both paths: the known diagonal plus the model's variance,
    # an unknown one the base plus it, both marked; the off-diagonal entries untouched.
    assert known == tuple(mark(KNOWN[k] + float(var[k // 4])) if k in (0, 4, 8) else v
                          for k, v in enumerate(KNOWN))
    assert diagonal_marked(known)
    if base_variance:
        assert unknown == tuple(mark(0.0 + (base_variance + float(var[k // 4])))
                                if k in (0, 4, 8) else 0.0 for k in range(9))
        assert diagonal_marked(unknown)
    else:
        # Unknown stays unknown (every entry == 0.0, no variance invented) and is marked by
        # the sign of its diagonal zeros, so a second compensator still sees the first.
        assert unknown == UNKNOWN and diagonal_marked(unknown)
        assert [math.copysign(1.0, unknown[k]) for k in (0, 4, 8)] == [-1.0] * 3
    assert no_data == NO_DATA and not diagonal_marked(no_data)
    assert rig.node.core.counts['compensated'] == 3       # compensated all the same


def test_passthrough_keeps_unknown_unknown_and_never_marks(rig_factory):
    rig = rig_factory(passthrough_variance=0.25)          # no model: passed through
    known, unknown, _ = _feed(rig, [KNOWN, UNKNOWN, NO_DATA])
    assert unknown == UNKNOWN
    assert known[0] == KNOWN[0] + 0.25 and not diagonal_marked(known)


def test_base_variance_is_set_at_run_time(rig_factory):
    rig = rig_factory(model_file='l3gd20_modified')
    before = _feed(rig, [UNKNOWN])[0]
    result = rig.node.set_parameters([Parameter('base_variance', value=4e-6)])[0]
    assert result.successful, result.reason
    msg = Imu()
    msg.header.stamp.sec = T0_NS // 10 ** 9 + 1
    msg.header.frame_id = 'imu_link'
    rig.imu_pub.publish(msg)                                 # all zero: unknown
    rig.spin_until(lambda: len(rig.out) == 2, what='the next output')
    after = tuple(rig.out[1].angular_velocity_covariance)
    assert before == UNKNOWN and after[0] > 4e-6 and diagonal_marked(after)
