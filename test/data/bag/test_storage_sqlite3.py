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

"""Tests of gyro_tdc.data.bag.storage_sqlite3: the documented schema, rosbags' order."""

from __future__ import annotations

import re
import sqlite3

from bags import null_message_data
from columnar_tape import _chamber, _same_data, _same_tape, _write, ARRAYS
from gyro_tdc.data import read_bag
from gyro_tdc.data.bag import codec, columnar, metadata, reader
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
from rosbags.rosbag2 import ReaderError


@pytest.mark.parametrize('change, via', [
    ('DROP INDEX timestamp_idx', 'rosbags'),
    ('CREATE INDEX size_idx ON messages (length(data))', 'columnar'),
    ('CREATE INDEX topic_idx ON messages (topic_id)', 'rosbags'),
    ('CREATE INDEX pair_idx ON messages (timestamp, topic_id)', 'rosbags'),
])
def test_sqlite3_indexes_other_than_rosbag2s_keep_rosbags_order(tmp_path, change, via):
    # The range query walks rosbag2's timestamp index and nothing else; without it, or
    # beside another index rosbags' query might walk (ties in another order), rosbags reads.
    rng = np.random.default_rng(11)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(rng, ties=True, split_imu=True,
                                                       floating=True), shuffle=True)
    (db3,) = bag.glob('*.db3')
    with sqlite3.connect(db3) as db:
        db.execute(change)
    db.close()
    got, ref = read_bag(bag), read_bag(bag, via='rosbags')
    assert got.via == via
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))


@pytest.mark.parametrize('chunk', [64, 100_000])
def test_a_damaged_timestamp_index_is_read_as_rosbags_reads_it(tmp_path, monkeypatch, chunk):
    # One key of the index written out of order in the file (as a flipped bit on an SD card
    # does): the seeks of the time ranges miss messages that rosbags' walk of the index
    # finds. Fewer messages than metadata.yaml lists: rosbags reads the bag.
    monkeypatch.setattr(reader, '_CHUNK', chunk)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(np.random.default_rng(14), n=300))
    (db3,) = bag.glob('*.db3')
    with sqlite3.connect(db3) as db:
        ts = [t for (t,) in db.execute('SELECT timestamp FROM messages ORDER BY timestamp')]
    db.close()
    # An index record (timestamp, rowid) is: header size 3, serial types 5 (a 6-byte
    # integer) and 1 or 2 (the rowid), then the big-endian timestamp (the file format).
    raw = bytearray(db3.read_bytes())
    (hit,) = re.finditer(rb'\x03\x05[\x01\x02]' + re.escape(ts[150].to_bytes(6, 'big')), raw)
    raw[hit.start() + 3:hit.end()] = (ts[-1] + 10**9).to_bytes(6, 'big')
    db3.write_bytes(bytes(raw))
    got, ref = read_bag(bag), read_bag(bag, via='rosbags')
    assert got.via == 'rosbags' and len(ref.imu_t) + len(ref.temp_t) == len(ts)
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    # Where rosbags cannot open the bag at all, what the columnar read got (the loss policy
    # of load_run judges it against metadata.yaml's counts).
    forced = read_bag(bag, via='columnar')
    assert forced.via == 'columnar' and len(forced.imu_t) + len(forced.temp_t) < len(ts)

    class Refusing:
        def __init__(self, *args, **kwargs):
            raise ReaderError('database disk image is malformed')
    monkeypatch.setattr(reader, 'AnyReader', Refusing)
    partial = read_bag(bag)
    assert partial.via == 'columnar'
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(partial, name), getattr(forced, name))


def test_a_message_whose_data_reads_as_null_is_one_message_lost(tmp_path):
    # A damaged record header can make a row's data column NULL: rosbags hands it over as
    # None. Every read skips it; metadata.yaml's count tells the loss policy it is missing.
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(np.random.default_rng(15), n=300))
    (db3,) = bag.glob('*.db3')
    null_message_data(db3, '/imu/data_raw', 150)
    whole = _write(tmp_path / 'whole', 'sqlite3', _chamber(np.random.default_rng(15), n=300))
    want = read_bag(whole)
    with pytest.raises(DatasetError, match='column by column') as info:
        read_bag(bag, via='columnar')           # the fast read leaves it to rosbags
    assert '\n' not in str(info.value)
    for via in ('auto', 'rosbags'):
        got = read_bag(bag, via=via)
        assert got.via == 'rosbags' and len(got.imu_t) == len(want.imu_t) - 1
        np.testing.assert_array_equal(np.delete(want.imu_t, 150), got.imu_t)
        np.testing.assert_array_equal(want.temp_c, got.temp_c)


def test_a_sqlite3_file_without_definitions_is_read_with_the_jazzy_types(tmp_path):
    rng = np.random.default_rng(12)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(rng, reference=True))
    (db3,) = bag.glob('*.db3')
    with sqlite3.connect(db3) as db:
        db.execute('DELETE FROM message_definitions')
    db.close()
    with columnar.open_bag(bag, metadata.load(bag)) as opened:
        assert opened.files[0].definitions == {}
        assert opened.typestore([c.msgtype for c in opened.conns]) is codec.jazzy()
    _same_data(bag)


def test_the_ranges_keep_ties_whole_and_cover_every_message_once(tmp_path, monkeypatch):
    # 300 messages (IMU and thermometer) at one log time, more than a range holds: the ranges
    # are cut from the index between distinct times, in order, and end to end.
    monkeypatch.setattr(reader, '_CHUNK', 64)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(np.random.default_rng(13), floating=True))
    (db3,) = bag.glob('*.db3')
    with sqlite3.connect(db3) as db:
        db.execute('UPDATE messages SET timestamp = (SELECT min(timestamp) FROM messages) + 7 '
                   'WHERE rowid BETWEEN 50 AND 349')
    db.close()
    _same_tape(bag)
    _same_data(bag)
    with columnar.open_bag(bag, metadata.load(bag)) as opened:
        f = opened.files[0]
        f.ids, f.chunk = {'imu': sorted(c.id for c in f.conns)}, 64    # as feed() sets them
        f._query(['imu'], False)
        cut = list(f._bounds())
        counts = [f.db.execute('SELECT count(*) FROM messages WHERE timestamp >= ? AND '
                               'timestamp < ?', r).fetchone()[0] for r in cut]
        total, = f.db.execute('SELECT count(*) FROM messages').fetchone()
    assert all(a < b for a, b in cut) and all(x[1] == y[0] for x, y in zip(cut, cut[1:]))
    assert sum(counts) == total and max(counts) >= 300 and len(cut) > total // 64 - 5
