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

"""The columnar storage read against rosbags' reader: the same bytes in the same order."""

from __future__ import annotations

from pathlib import Path
import shutil

from columnar_tape import (_chamber, _same_data, _same_tape, _tapes, _topics, _write, ARRAYS,
                           STORAGES, TS)
from gyro_tdc.data import IMU_TYPE, read_bag, REFERENCE_TYPE, TEMPERATURE_TYPE
from gyro_tdc.data.bag import columnar, metadata, reader
from gyro_tdc.data.bag.metadata import Unfit
from gyro_tdc.errors import DatasetError
from hypothesis import example, given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import CompressionMode
import yaml


@pytest.mark.parametrize('storage', STORAGES)
@pytest.mark.parametrize('case', ['plain', 'reference', 'two_connections', 'float', 'ties',
                                  'zero_stamps', 'float_two_connections'])
def test_the_columnar_read_hands_over_rosbags_bytes(tmp_path, storage, case, monkeypatch):
    monkeypatch.setattr(reader, '_CHUNK', 64)        # many blocks and ranges
    rng = np.random.default_rng(len(case))
    kw = {'plain': {}, 'reference': {'reference': True}, 'two_connections': {'split_imu': True},
          'float': {'floating': True}, 'ties': {'ties': True, 'split_imu': True},
          'zero_stamps': {'zero': {0, 1, 65, 66, 300}},
          'float_two_connections': {'floating': True, 'split_imu': True}}[case]
    bag = _write(tmp_path / 'bag', storage, _chamber(rng, **kw))
    _same_tape(bag)
    _same_data(bag)


@pytest.mark.parametrize('storage', STORAGES)
def test_out_of_order_writes_keep_rosbags_order(tmp_path, storage, monkeypatch):
    # Rowids (sqlite3) and an mcap chunk out of time order, equal log times: sqlite3 is read
    # through its timestamp index in rosbags' order, the mcap chunk sorted as rosbags does.
    monkeypatch.setattr(reader, '_CHUNK', 64)
    rng = np.random.default_rng(3)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng, ties=True, split_imu=True,
                                                     floating=True), shuffle=True)
    _same_tape(bag)
    _same_data(bag)


@pytest.mark.parametrize('storage, mode', [('sqlite3', CompressionMode.FILE),
                                           ('mcap', CompressionMode.FILE),
                                           ('mcap', CompressionMode.STORAGE)])
def test_compressed_files_and_chunks_are_read_columnar(tmp_path, storage, mode):
    rng = np.random.default_rng(4)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng, reference=True), compression=mode)
    _same_tape(bag)
    _same_data(bag)


@pytest.mark.parametrize('storage', STORAGES)
def test_messages_compressed_one_by_one_go_to_rosbags(tmp_path, storage):
    rng = np.random.default_rng(5)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng), compression=CompressionMode.MESSAGE)
    got, plain = read_bag(bag), read_bag(_write(tmp_path / 'plain', storage, _chamber(
        np.random.default_rng(5))))
    assert got.via == 'rosbags'
    np.testing.assert_array_equal(got.gyro, plain.gyro)
    with pytest.raises(DatasetError, match='column by column: every message compressed'):
        read_bag(bag, via='columnar')


def _several_files(tmp_path: Path, storage: str) -> Path:
    """Two storage files in one bag (the second earlier in time), as rosbag2 splits them."""
    rng = np.random.default_rng(6)
    late = _write(tmp_path / 'late', storage, _chamber(rng, t0=900 * 10**9))
    early = _write(tmp_path / 'early', storage, _chamber(rng, n=300, t0=10**9))
    bag = tmp_path / 'bag'
    shutil.copytree(late, bag)
    ext = '.db3' if storage == 'sqlite3' else '.mcap'
    shutil.copy(early / f'early{ext}', bag / f'early{ext}')
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    other = yaml.safe_load((early / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    info = meta['rosbag2_bagfile_information']
    info['relative_file_paths'].append(f'early{ext}')
    info['files'] += other['files']
    info['message_count'] += other['message_count']
    for entry, more in zip(info['topics_with_message_count'],
                           other['topics_with_message_count']):
        entry['message_count'] += more['message_count']
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(meta, sort_keys=False))
    return bag


@pytest.mark.parametrize('storage', STORAGES)
def test_storage_files_follow_each_other_as_rosbags_reads_them(tmp_path, storage):
    bag = _several_files(tmp_path, storage)
    _same_tape(bag)
    _same_data(bag)
    assert read_bag(bag).imu_t[0] > 800          # the files in order, not merged by time


def _edit(bag: Path, edit) -> Path:
    meta = bag / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    edit(doc['rosbag2_bagfile_information'])
    meta.write_text(yaml.safe_dump(doc, sort_keys=False))
    return bag


def _count(value):
    def edit(info):
        info['topics_with_message_count'][0]['message_count'] = value
    return edit


def _drop_files(info):
    info['files'] = []
    info['message_count'] = 0


def _say_file_compressed(info):
    info['compression_format'] = 'zstd'
    info['compression_mode'] = 'file'


def _version(info):
    info['version'] = 10


def _json(info):
    info['topics_with_message_count'][0]['topic_metadata']['serialization_format'] = 'json'


def _rename_type(info):
    info['topics_with_message_count'][1]['topic_metadata']['type'] = 'std_msgs/msg/String'


@pytest.mark.parametrize('storage', STORAGES)
@pytest.mark.parametrize('edit, outcome', [
    (_count(1), 'same'),                 # listed low: every message is still read
    (_count(0), "'/imu/data_raw' in bag"),     # ... has no messages: both say so
    (_drop_files, 'same'),
    (_count(10**9), 'holds 1000000000 messages, more than its'),
    (_say_file_compressed, 'not compressed as metadata.yaml says'),
    (_rename_type, "has type 'std_msgs/msg/String', expected"),
    (_version, 'Rosbag2 version 10 not supported'),
    (_json, "Serialization format {'json'} is not supported"),
])
def test_hostile_metadata_reads_as_rosbags_does(tmp_path, storage, edit, outcome):
    rng = np.random.default_rng(7)
    bag = _edit(_write(tmp_path / 'bag', storage, _chamber(rng)), edit)
    if outcome == 'same':
        _same_data(bag)
        return
    for via in ('auto', 'rosbags'):
        with pytest.raises(DatasetError) as info:
            read_bag(bag, via=via)
        assert outcome in str(info.value) and '\n' not in str(info.value)


@pytest.fixture(scope='module')
def pristine(tmp_path_factory):
    rng = np.random.default_rng(8)
    root = tmp_path_factory.mktemp('pristine')
    return {s: _write(root / s, s, _chamber(rng, n=300)) for s in STORAGES}


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(storage=st.sampled_from(STORAGES), where=st.floats(0.0, 1.0),
       junk=st.binary(min_size=1, max_size=64), cut=st.booleans())
@example(storage='sqlite3', where=0.9616038597528169, junk=b'\x01', cut=False)  # the index
@example(storage='sqlite3', where=0.8784913624986797, junk=b'\x00', cut=False)  # NULL data
def test_damaged_storage_is_read_as_rosbags_reads_it_or_refused_in_one_line(
        tmp_path_factory, pristine, storage, where, junk, cut):
    bag = tmp_path_factory.mktemp('hurt') / 'bag'
    shutil.copytree(pristine[storage], bag)
    (path,) = [p for p in bag.iterdir() if p.suffix in ('.db3', '.mcap')]
    raw = bytearray(path.read_bytes())
    at = int(where * (len(raw) - 1))
    raw = raw[:at] if cut else raw[:at] + junk + raw[at + len(junk):]
    path.write_bytes(bytes(raw))
    outcomes = []
    for via in ('auto', 'rosbags'):
        try:
            outcomes.append(read_bag(bag, via=via))
        except DatasetError as err:
            assert '\n' not in str(err) and str(bag) in str(err)
            outcomes.append(None)
    got, ref = outcomes
    if got is not None and ref is not None:
        for name in ARRAYS:
            a, b = getattr(got, name), getattr(ref, name)
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a, b)
    if ref is not None:
        assert got is not None           # what rosbags reads, the columnar read reads too


@pytest.mark.parametrize('storage', STORAGES)
def test_the_open_lists_rosbags_topics_connections_and_types(tmp_path, storage):
    rng = np.random.default_rng(9)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng, split_imu=True, reference=True))
    with AnyReader([bag], default_typestore=TS) as a, \
            columnar.open_bag(bag, metadata.load(bag)) as b:
        assert _topics(a) == b.topics
        assert [(x.id, x.topic, x.msgtype, x.digest, x.msgcount) for x in a.connections] == [
            (y.id, y.topic, y.msgtype, y.digest, y.msgcount) for y in b.conns]
        (f,) = b.files
        assert {x.msgtype: x.msgdef.data for x in a.connections} == {
            name: text for name, (_, text) in f.definitions.items()}
        for name in (IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE):
            assert b.typestore.fielddefs[name] == a.typestore.fielddefs[name]
            assert b.typestore.hash_rihs01(name) == a.typestore.hash_rihs01(name)


@pytest.mark.parametrize('storage', STORAGES)
def test_a_storage_topic_unlike_its_metadata_goes_to_rosbags(tmp_path, storage):
    # rosbags matches storage connections to metadata.yaml's by type, format, QoS and hash;
    # one the columnar read cannot match is left to rosbags, which skips or reads it.
    rng = np.random.default_rng(10)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng))

    def deeper(info):
        info['topics_with_message_count'][0]['topic_metadata']['offered_qos_profiles'][0][
            'depth'] = 99
    _edit(bag, deeper)
    with pytest.raises(Unfit, match="topic '/imu/data_raw' of a storage file"):
        _tapes(bag)
    with pytest.raises(DatasetError, match='column by column: topic'):
        read_bag(bag, via='columnar')
    assert read_bag(bag).via == 'rosbags'
