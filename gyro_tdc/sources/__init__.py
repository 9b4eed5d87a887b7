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
Driver back-ends: where raw gyro samples come from.

Every back-end satisfies :class:`ImuSource`: ``read()`` returns the next
:class:`ImuSample` or raises :class:`gyro_tdc.errors.DeviceError`; ``close()``
releases it. Nothing here imports rclpy; ``gyro_tdc.nodes.driver_node`` turns
samples into messages. The face imports a module when one of its names is asked for.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'base': ['Backoff', 'check_sample', 'ImuSample', 'ImuSource', 'SourceExhausted'],
    'iio': ['find_iio_device', 'IioSource'],
    'sim': ['SimSource'],      # it pulls in the simulator
})
