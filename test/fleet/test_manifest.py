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

"""The fleet manifest: rows, paths relative to it, sensor ids that can name a file."""

from __future__ import annotations

from gyro_tdc.errors import FleetError
from gyro_tdc.fleet import check_sensor_id, read_manifest
import pytest


def test_manifest_paths_relative_to_the_manifest(tmp_path):
    (tmp_path / 'm').mkdir()
    path = tmp_path / 'm' / 'fleet.csv'
    path.write_text('sensor_id,train,test\n'
                    'imu-1, bags/a ; bags/b ,bags/c\n'
                    '\n'
                    'IMU_2.rev3,/abs/x,\n')
    specs = read_manifest(path)
    assert [s.sensor_id for s in specs] == ['imu-1', 'IMU_2.rev3']
    assert specs[0].train == (str(tmp_path / 'm' / 'bags/a'), str(tmp_path / 'm' / 'bags/b'))
    assert specs[0].test == (str(tmp_path / 'm' / 'bags/c'),)
    assert specs[1].train == ('/abs/x',) and specs[1].test == ()
    assert specs[1].line == 4


@pytest.mark.parametrize('text', ['a/b', '../up', '', '.hidden', 'x' * 129, 'a b', 'ü'])
def test_sensor_id_that_cannot_be_a_file_name_is_refused(text):
    with pytest.raises(FleetError, match='cannot be a file name'):
        check_sensor_id(text)
