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

"""Tests of gyro_tdc.data.options: BagOptions refuses what it cannot read with, naming it."""

from __future__ import annotations

from gyro_tdc.data.options import BagOptions, check_sessions
from gyro_tdc.errors import DatasetError
import pytest


@pytest.mark.parametrize('kw, needle', [({'sessions': 'x'}, '`sessions`'),
                                        ({'session_gap_s': float('nan')}, '`session_gap_s`')])
def test_bag_options_check_the_session_fields(kw, needle):
    with pytest.raises(DatasetError, match=needle):
        BagOptions(**kw)


@pytest.mark.parametrize('kw, needle', [
    ({'reference': (0.0, 1.0)}, '`reference` to be three finite rates'),
    ({'reference': (0.0, float('inf'), 0.0)}, '`reference` to be three finite rates'),
    ({'log_format': 'csv'}, '`log_format` to be one of auto, rosbag2, ulog, dataflash'),
    ({'imu_instance': -1}, '`imu_instance` to be an integer >= 0'),
    ({'imu_instance': True}, '`imu_instance` to be an integer >= 0'),
    ({'session_gap_s': True}, '`session_gap_s` to be a number >= 0'),
    ({'temperature_source': 'barometer'}, '`temperature_source` to be imu, baro or TOPIC.FIELD'),
])
def test_every_choice_is_checked_once_naming_it(kw, needle):
    with pytest.raises(DatasetError, match=needle):
        BagOptions(**kw)


def test_the_reference_is_held_as_floats_and_good_choices_pass():
    o = BagOptions(reference=[1, 0, -1], temperature_source='sensor_baro.temperature',
                   session_gap_s=30)
    assert o.reference == (1.0, 0.0, -1.0) and all(type(x) is float for x in o.reference)
    check_sessions('none', 0.0)
