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
Motion reports in bags: ``cmd_vel`` Twists and odometry, the veto of the still test.

:func:`read_motion` reads a Twist, TwistStamped or Odometry topic into the six twist
components per report; :func:`encode_twists` writes a Twist stream (the simulator's
``cmd_vel``). See ``doc/internals/data.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from gyro_tdc.data.bag.codec import jazzy
from gyro_tdc.data.bag.metadata import describe, Unfit
from gyro_tdc.data.bag.reader import READ_ERRORS, topic_messages
from gyro_tdc.data.field_paths import reader as field_reader, stamp_seconds
from gyro_tdc.errors import DatasetError, one_line
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['MOTION_TYPES', 'MotionReports', 'ODOMETRY_TYPE', 'TWIST_STAMPED_TYPE',
           'TWIST_TYPE', 'encode_twists', 'read_motion']

TWIST_TYPE = 'geometry_msgs/msg/Twist'
TWIST_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'
ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'
# Where the Twist is in each message type a motion topic may have (a dotted field path).
_TWIST_PATHS = {TWIST_TYPE: '', TWIST_STAMPED_TYPE: 'twist', ODOMETRY_TYPE: 'twist.twist'}
#: Message types a motion topic may have.
MOTION_TYPES = tuple(_TWIST_PATHS)


@dataclass(frozen=True)
class MotionReports:
    """The motion reports of one bag topic, as the still test's veto reads them."""

    #: The topic.
    topic: str
    #: Its type (one of :data:`MOTION_TYPES`).
    msgtype: str
    #: Stamps (M,), s, the header stamp or (for a plain Twist) the log time.
    t: NDArray[np.float64]
    #: Twist (M, 6), linear x, y, z (m/s) and angular x, y, z (rad/s).
    twist: NDArray[np.float64]


def read_motion(path: str | Path, topic: str) -> MotionReports:
    """
    Read a motion topic (Twist, TwistStamped or Odometry) of a bag.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory.
    topic : str
        The topic (e.g. ``/cmd_vel`` or ``/odom``).

    Returns
    -------
    MotionReports
        Stamps and twist components, in time order.

    Raises
    ------
    DatasetError
        When the bag cannot be read, has no such topic (the topics present are named), or
        the topic has another type or no messages.

    """
    bag = Path(path)
    try:
        with topic_messages(bag, (topic,)) as (store, conns, messages):
            topics: dict[str, tuple[str, int]] = {}
            for c in conns:                 # as rosbags' AnyReader.topics has them
                msgtype, n = topics.get(c.topic, (c.msgtype, 0))
                topics[c.topic] = (msgtype if msgtype == c.msgtype else '?', n + c.msgcount)
            if topic not in topics:
                raise DatasetError(f'Bag {str(bag)!r} has no motion topic {topic!r}; topics '
                                   f'present: {describe(topics)}.')
            msgtype = topics[topic][0]
            if msgtype not in MOTION_TYPES:
                raise DatasetError(f'Motion topic {topic!r} in bag {str(bag)!r} has type '
                                   f'{msgtype!r}, expected one of {", ".join(MOTION_TYPES)}.')
            stamps, rows, twist_of = [], [], field_reader(_TWIST_PATHS[msgtype])
            for conn, log_ns, raw in messages(*(c for c in conns if c.topic == topic)):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                stamps.append(log_ns * 1e-9 if msgtype == TWIST_TYPE
                              else stamp_seconds('time', msg.header.stamp))
                tw = twist_of(msg)
                rows.append((tw.linear.x, tw.linear.y, tw.linear.z,
                             tw.angular.x, tw.angular.y, tw.angular.z))
    except (*READ_ERRORS, Unfit) as err:
        raise DatasetError(f'Cannot read motion topic {topic!r} of bag {str(bag)!r}: '
                           f'{one_line(err)}') from err
    if not stamps:
        raise DatasetError(f'Motion topic {topic!r} in bag {str(bag)!r} has no messages.')
    t = np.asarray(stamps, dtype=np.float64)
    order = np.argsort(t, kind='stable')
    return MotionReports(topic, msgtype, t[order],
                         np.asarray(rows, dtype=np.float64).reshape(-1, 6)[order])


def encode_twists(twist: ArrayLike) -> Sequence[bytes]:
    """
    Serialise ``geometry_msgs/Twist`` messages (CDR, as rosbag2 records them).

    Parameters
    ----------
    twist : ArrayLike, shape (M, 6)
        Linear x, y, z (m/s) and angular x, y, z (rad/s) per message.

    Returns
    -------
    list of bytes
        One CDR message per row.

    """
    ts = jazzy()
    vec, make = ts.types['geometry_msgs/msg/Vector3'], ts.types[TWIST_TYPE]
    return [ts.serialize_cdr(make(vec(*r[:3]), vec(*r[3:])), TWIST_TYPE)
            for r in np.asarray(twist, dtype=np.float64).reshape(-1, 6).tolist()]
