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
Write and read rosbag2 bags of IMU, temperature and reference-rate messages, fast.

Pure rosbags + numpy (no rclpy). The three message types this package records all share
one shape on the wire: a ``std_msgs/Header`` followed by a flat run of float64 values
(``sensor_msgs/Imu``: 37, ``sensor_msgs/Temperature``: 2, ``geometry_msgs/Vector3Stamped``:
3). For a given ``frame_id`` length the CDR bytes of such a message have a fixed layout,
described once in :mod:`gyro_tdc.imu_cdr`, so all messages of a topic are written and read
as one numpy structured array (:attr:`gyro_tdc.imu_cdr.Layout.dtype`) instead of one Python
object per message. Every fast path checks itself against rosbags' own serialiser
(``serialize_cdr`` / ``deserialize_cdr``) and falls back to it, per chunk of messages,
whenever the layout does not hold (frame ids of different lengths, another encapsulation,
trailing bytes...).

Modules: :mod:`~gyro_tdc.bagio.codec` (the fixed-layout codec and its rosbags checks),
:mod:`~gyro_tdc.bagio.writer` (:func:`write_bag`), :mod:`~gyro_tdc.bagio.reader`
(:func:`read_bag`, :class:`BagData`).
"""

from gyro_tdc.bagio.codec import IMU_TYPE, REFERENCE_TYPE, TEMPERATURE_TYPE
from gyro_tdc.bagio.reader import BagData, read_bag
from gyro_tdc.bagio.writer import write_bag

__all__ = [
    'BagData',
    'IMU_TYPE',
    'REFERENCE_TYPE',
    'TEMPERATURE_TYPE',
    'read_bag',
    'write_bag',
]
