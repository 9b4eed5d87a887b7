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
The three axes and the unit factors every package converts with.

One home for the axis names of tables and CSV columns, degrees against radians and the mg of
accelerometer figures, so a factor is written once and read the same everywhere.
"""

import math

__all__ = ['AXES', 'DEG2_PER_RAD2', 'DEG_PER_RAD', 'G0', 'MG', 'RAD_PER_DEG']

#: The gyro and accelerometer axes, in the order of every (N, 3) array.
AXES = ('x', 'y', 'z')
#: Degrees per radian: a rate in rad/s times this is in deg/s.
DEG_PER_RAD = 180.0 / math.pi
#: Square degrees per square radian: a mean square in (rad/s)^2 times this is in (deg/s)^2.
DEG2_PER_RAD2 = DEG_PER_RAD ** 2
#: Radians per degree: a rate in deg/s times this is in rad/s.
RAD_PER_DEG = math.pi / 180.0
#: Standard gravity, m/s^2 per g.
G0 = 9.80665
#: One mg in m/s^2.
MG = G0 * 1e-3
