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

from pathlib import Path
import re
import shutil

from columnar_tape import _chamber, _tapes, _write
from gyro_tdc.data import BagOptions, read_bag
from gyro_tdc.data.bag import columnar, metadata
from gyro_tdc.data.bag.metadata import Unfit
from gyro_tdc.data.bag.storage_mcap import McapFile
from gyro_tdc.data.dataset import load_run
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
import yaml


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


@pytest.mark.parametrize('keep', [0.3, 0.9])
def test_an_mcap_file_cut_inside_its_first_chunk_names_the_file_and_mcap_recover(tmp_path, keep):
    # The power went while the file was written: no footer, its only chunk cut short.
    bag = _write(tmp_path / 'bag', 'mcap', _chamber(np.random.default_rng(16)))
    (path,) = bag.glob('*.mcap')
    raw = path.read_bytes()
    path.write_bytes(raw[:int(keep * len(raw))])
    with pytest.raises(Unfit, match='cut off before its first whole chunk'):
        _open(bag)
    for via in ('auto', 'rosbags'):
        with pytest.raises(DatasetError, match='unreadable or corrupt') as err:
            read_bag(bag, via=via)
        text = str(err.value)
        assert '\n' not in text and f'{path.name} ends without the mcap footer' in text
        assert '`mcap recover`' in text and '.;' not in text


def _open(bag):
    with columnar.open_bag(bag, metadata.load(bag)):
        pass


@pytest.fixture(scope='module')
def four_chunks(tmp_path_factory):
    """Return a bag of four chunks (rosbags' writer closes a chunk at 1 MB) and its read."""
    bag = _write(tmp_path_factory.mktemp('whole') / 'bag', 'mcap',
                 _chamber(np.random.default_rng(16), n=9000))
    return bag, read_bag(bag)


@pytest.mark.parametrize('keep', [0.5, 0.9, 0.99, 0.99999])
def test_an_mcap_file_cut_off_is_read_to_its_last_whole_chunk_with_a_warning(
        tmp_path, four_chunks, keep):
    whole, ref = four_chunks
    bag = tmp_path / 'bag'
    shutil.copytree(whole, bag)
    (path,) = bag.glob('*.mcap')
    raw = path.read_bytes()
    path.write_bytes(raw[:int(keep * len(raw))])
    got = read_bag(bag)
    # The whole chunks before the cut, message for message; rosbags reads none of it.
    n, m = len(got.imu_t), len(got.temp_t)
    assert got.via == 'columnar' and 0 < n <= len(ref.imu_t) and 0 < m <= len(ref.temp_t)
    for name, k in (('imu_t', n), ('gyro', n), ('accel', n), ('temp_t', m), ('temp_c', m)):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name)[:k])
    (warning,) = got.warnings
    assert re.fullmatch(r'bag\.mcap ends without the mcap footer \(cut off while it was '
                        r'written\): read to its last whole chunk, the \d+ bytes after it '
                        r'are lost', warning)
    with pytest.raises(DatasetError, match='File end magic is invalid'):
        read_bag(bag, via='rosbags')


def test_a_cut_off_mcap_file_is_lost_messages_for_the_loss_policy(tmp_path, four_chunks):
    whole, _ = four_chunks
    bag = tmp_path / 'bag'
    shutil.copytree(whole, bag)
    (path,) = bag.glob('*.mcap')
    raw = path.read_bytes()
    path.write_bytes(raw[:len(raw) // 2])
    with pytest.raises(DatasetError) as err:        # metadata.yaml lists the whole recording
        load_run(bag)
    text = str(err.value)
    assert '\n' not in text and 'a storage file cut off at its end' in text
    assert '--allow-loss accepts it' in text and 'ends without the mcap footer' in text
    run = load_run(bag, BagOptions(max_loss=1.0))
    cut, *lost = run.info['warnings']
    assert cut.startswith('bag.mcap ends without the mcap footer') and len(lost) == 2
    assert all('a storage file cut off at its end' in w for w in lost)
    # As `ros2 bag reindex` writes it: the counts of what the file holds, no loss.
    got = read_bag(bag)
    meta = bag / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    for t in doc['rosbag2_bagfile_information']['topics_with_message_count']:
        t['message_count'] = {'/imu/data_raw': len(got.imu_t),
                              '/imu/temperature': len(got.temp_t)}[t['topic_metadata']['name']]
    meta.write_text(yaml.safe_dump(doc))
    assert load_run(bag).info['warnings'] == [cut]


def test_an_mcap_file_whose_records_stop_far_before_its_end_is_no_cut(tmp_path, four_chunks):
    # A length field damaged in the middle of a file without its footer: what follows is
    # more than a chunk, not the record the power cut short.
    whole, _ = four_chunks
    bag = tmp_path / 'bag'
    shutil.copytree(whole, bag)
    (path,) = bag.glob('*.mcap')
    raw = bytearray(path.read_bytes()[:-100])
    first = 44 + 8 + int.from_bytes(raw[44:52], 'little')     # after the first chunk record
    raw[first + 1:first + 9] = (len(raw) * 4).to_bytes(8, 'little')
    path.write_bytes(bytes(raw))
    with pytest.raises(Unfit, match='records stop \\d+ bytes before its end'):
        _open(bag)
    with pytest.raises(DatasetError, match='unreadable or corrupt'):
        read_bag(bag)


@pytest.mark.parametrize('name', ['talker.mcap', 'only_topics.mcap'])
def test_rosbag2s_own_mcap_files_scan_without_their_footer_as_their_summary_lists(
        tmp_path, name):
    # Written by rosbag2's C++ plugin: the scan of the records finds the chunks the summary
    # lists and every channel with messages (one without may stand in the summary only).
    real = Path(__file__).parents[2] / 'support' / 'files' / 'rosbag2' / name
    raw = real.read_bytes()
    cut = tmp_path / name
    cut.write_bytes(raw[:-37])                          # the footer record and magic gone
    files = []
    for path in (real, cut):
        f = McapFile(path)
        f.load()
        f.close()
        files.append(f)
    whole, scanned = files
    assert whole.lost is None and scanned.lost > 0 and scanned.chunks == whole.chunks
    counted = {k for c in whole.chunks for k in c.counts}
    ids = {c.id for c in scanned.conns}
    assert counted and counted <= ids and all(c in whole.conns for c in scanned.conns)
    assert {whole.definitions[c.msgtype] for c in scanned.conns} == {
        scanned.definitions[c.msgtype] for c in scanned.conns}
