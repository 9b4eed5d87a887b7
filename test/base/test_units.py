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

"""Tests of gyro_tdc.base.units: the axes and the unit factors."""

import math

from gyro_tdc.base import AXES, DEG2_PER_RAD2, DEG_PER_RAD, G0, MG, RAD_PER_DEG


def test_the_factors_are_the_conversions_they_name():
    assert AXES == ('x', 'y', 'z')
    assert DEG_PER_RAD == 180.0 / math.pi and RAD_PER_DEG == math.pi / 180.0
    assert math.degrees(1.0) == DEG_PER_RAD and math.radians(1.0) == RAD_PER_DEG
    assert DEG2_PER_RAD2 == (180.0 / math.pi) ** 2
    assert G0 == 9.80665 and MG == G0 * 1e-3
