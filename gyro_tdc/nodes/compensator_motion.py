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
The compensator's motion input (``motion_topic``): a veto on stillness for moving vehicles.

:class:`MotionInput` is a mixin of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`
(see doc/internals/runtime.md); the node provides ``core`` and ``params``.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions

__all__ = ['MOTION_MESSAGES', 'MotionInput']

#: The message class of each ``motion_type`` (compensator_params.MOTION_TYPES).
MOTION_MESSAGES = {'twist': Twist, 'twist_stamped': TwistStamped, 'odometry': Odometry}


class MotionInput:
    """Take outside motion reports and pass them to the core by stamp (mixin)."""

    def _init_motion(self) -> None:
        """Subscribe ``motion_topic`` (when set) with ``input_reliability``'s QoS (overridable)."""
        p = self.params
        self.motion_ignored = 0     # bare Twists before the first IMU message
        if not p.motion_topic:
            return
        reliable = p.input_reliability == 'reliable'
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                         reliability=(ReliabilityPolicy.RELIABLE if reliable
                                      else ReliabilityPolicy.BEST_EFFORT),
                         durability=DurabilityPolicy.VOLATILE)
        cls = MOTION_MESSAGES[p.motion_type]
        self.create_subscription(  # qos above: the default of its qos_overrides parameters
            cls, p.motion_topic, self._on_motion, qos,
            qos_overriding_options=QoSOverridingOptions.with_default_policies())

    def _on_motion(self, msg: Any) -> None:
        if isinstance(msg, Twist):
            twist, st = msg, None
        else:
            twist = msg.twist.twist if isinstance(msg, Odometry) else msg.twist
            st = msg.header.stamp
        if st is not None and (st.sec or st.nanosec):
            t = st.sec + st.nanosec * 1e-9
        else:                       # no stamp: the latest IMU stamp received
            t = self.core.last_t
            if t is None:
                self.motion_ignored += 1
                return
        lin, ang = twist.linear, twist.angular
        self.core.motion(t, (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))

    def motion_values(self) -> dict[str, str]:
        """Return the motion input's /diagnostics key/value pairs (none without a topic)."""
        if not self.params.motion_topic:
            return {}
        core = self.core
        state = {None: 'no report yet', True: 'moving', False: 'not moving'}[core.moving]
        return {'motion': state, 'motion reports': str(core.motion_reports),
                'motion reports ignored': str(self.motion_ignored)}
