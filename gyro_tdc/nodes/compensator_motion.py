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

:class:`MotionInput` is a part of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`:
the node subscribes ``motion_topic`` with :meth:`MotionInput.qos` and hands each report to
:meth:`MotionInput.on_motion`, which passes it to the core by stamp.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from gyro_tdc.runtime import CompensatorCore
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['MOTION_MESSAGES', 'MotionInput']

#: The message class of each ``motion_type`` (compensator_params.MOTION_TYPES).
MOTION_MESSAGES = {'twist': Twist, 'twist_stamped': TwistStamped, 'odometry': Odometry}


class MotionInput:
    """
    Take outside motion reports and pass them to the core by stamp.

    Parameters
    ----------
    core : CompensatorCore
        The core the reports go to.
    topic : str
        ``motion_topic`` ('' when there is none: no reports, no /diagnostics pairs).

    """

    def __init__(self, core: CompensatorCore, topic: str) -> None:
        self.core = core
        self.topic = topic
        #: Reports without a stamp before the first IMU message (nothing to stamp them with).
        self.ignored = 0

    @staticmethod
    def qos(reliability: str, depth: int) -> QoSProfile:
        """Return the subscription's QoS: ``input_reliability``, keep last ``depth``."""
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=(ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                                       else ReliabilityPolicy.BEST_EFFORT),
                          durability=DurabilityPolicy.VOLATILE)

    def on_motion(self, msg: Any) -> None:
        """Hand one Twist, TwistStamped or Odometry to the core at its stamp (or the latest)."""
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
                self.ignored += 1
                return
        lin, ang = twist.linear, twist.angular
        self.core.motion(t, (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))

    def values(self) -> dict[str, str]:
        """Return the motion input's /diagnostics key/value pairs (none without a topic)."""
        if not self.topic:
            return {}
        core = self.core
        state = {None: 'no report yet', True: 'moving', False: 'not moving'}[core.moving]
        return {'motion': state, 'motion reports': str(core.motion_reports),
                'motion reports ignored': str(self.ignored)}
