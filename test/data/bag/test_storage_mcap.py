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

"""Tests of gyro_tdc.data.bag.storage_mcap: what the MCAP read leaves to rosbags."""

from __future__ import annotations

from columnar_tape import _chamber, _tapes, _write
from gyro_tdc.data import read_bag
from gyro_tdc.data.bag.metadata import Unfit
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest


def test_an_mcap_file_without_a_summary_goes_to_rosbags(tmp_path):
    # rosbags scans such a file record by record; the columnar read wants the chunk index.
    rng = np.random.default_rng(13)
    bag = _write(tmp_path / 'bag', 'mcap', _chamber(rng))
    (path,) = bag.glob('*.mcap')
    raw = bytearray(path.read_bytes())
    raw[-28:-20] = bytes(8)                  # the footer's summary_start
    path.write_bytes(bytes(raw))
    with pytest.raises(Unfit, match='without a summary'):
        _tapes(bag)
    got, ref = read_bag(bag), read_bag(bag, via='rosbags')
    assert got.via == 'rosbags'
    np.testing.assert_array_equal(got.gyro, ref.gyro)


def test_mcap_chunks_overlapping_in_time_go_to_rosbags(tmp_path):
    # rosbags merges chunks whose time spans overlap message by message: not read columnar.
    rng = np.random.default_rng(3)
    bag = _write(tmp_path / 'bag', 'mcap', _chamber(rng, n=9000), shuffle=True)
    with pytest.raises(Unfit, match='overlap'):
        _tapes(bag)
    got, ref = read_bag(bag), read_bag(bag, via='rosbags')
    assert got.via == 'rosbags'
    np.testing.assert_array_equal(got.imu_t, ref.imu_t)
    np.testing.assert_array_equal(got.temp_c, ref.temp_c)


def test_a_summary_record_claiming_exabytes_is_a_corrupt_bag_in_one_line(tmp_path):
    # A damaged length field: rosbags reads the 2**62 bytes it claims (MemoryError).
    rng = np.random.default_rng(15)
    bag = _write(tmp_path / 'bag', 'mcap', _chamber(rng))
    (path,) = bag.glob('*.mcap')
    raw = bytearray(path.read_bytes())
    start = int.from_bytes(raw[-28:-20], 'little')     # the footer's summary_start
    raw[start + 1:start + 9] = (1 << 62).to_bytes(8, 'little')  # its first record's length
    path.write_bytes(bytes(raw))
    for via in ('auto', 'rosbags'):
        with pytest.raises(DatasetError, match='unreadable or corrupt') as err:
            read_bag(bag, via=via)
        assert '\n' not in str(err.value) and str(bag) in str(err.value)
        assert 'mcap recover' not in str(err.value)        # its footer is whole


@pytest.mark.parametrize('keep', [0.3, 0.9, 0.99999])
def test_an_mcap_file_cut_off_names_the_file_and_mcap_recover(tmp_path, keep):
    # The power went while the file was written: no footer, a chunk cut short.
    bag = _write(tmp_path / 'bag', 'mcap', _chamber(np.random.default_rng(16)))
    (path,) = bag.glob('*.mcap')
    raw = path.read_bytes()
    path.write_bytes(raw[:int(keep * len(raw))])
    for via in ('auto', 'rosbags'):
        with pytest.raises(DatasetError, match='unreadable or corrupt') as err:
            read_bag(bag, via=via)
        text = str(err.value)
        assert '\n' not in text and f'{path.name} ends without the mcap footer' in text
        assert '`mcap recover`' in text and '.;' not in text
