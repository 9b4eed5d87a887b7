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
Rosbag2 storage: the Imu codec, the block-wise reader, the writer and motion topics.

Other packages use these through the face of :mod:`gyro_tdc.data` (``read_bag``,
``write_bag``, ``read_motion``...); the modules here import each other directly.
"""

__all__: list[str] = []
