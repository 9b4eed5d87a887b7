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
import re
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
       junk=st.binary(min_size=1, max_size=64), cut=st.booleans(), bare=st.booleans())
@example(storage='sqlite3', where=0.9616038597528169, junk=b'\x01', cut=False,
         bare=False)                                                          # the index
@example(storage='sqlite3', where=0.8784913624986797, junk=b'\x00', cut=False,
         bare=False)                                                          # NULL data
@example(storage='mcap', where=0.9808085268678934, junk=b' ', cut=False,
         bare=False)                                            # a schema naming no type
@example(storage='sqlite3', where=0.984375, junk=b'\x00', cut=True, bare=True)  # NULL stamps
def test_damaged_storage_is_read_as_rosbags_reads_it_or_refused_in_one_line(
        tmp_path_factory, pristine, storage, where, junk, cut, bare):
    # ``bare``: without metadata.yaml, listed from the damaged file for either read.
    bag = tmp_path_factory.mktemp('hurt') / 'bag'
    shutil.copytree(pristine[storage], bag)
    (path,) = [p for p in bag.iterdir() if p.suffix in ('.db3', '.mcap')]
    raw = bytearray(path.read_bytes())
    at = int(where * (len(raw) - 1))
    raw = raw[:at] if cut else raw[:at] + junk + raw[at + len(junk):]
    path.write_bytes(bytes(raw))
    if bare:
        _without_metadata(bag, path.suffix)
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
        store = b.typestore([IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE])
        for name in (IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE):
            assert store.fielddefs[name] == a.typestore.fielddefs[name]
            assert store.hash_rihs01(name) == a.typestore.hash_rihs01(name)


#: A service event's definition as rosbag2 stores it (the request and response of the .srv
#: file): rosbags cannot parse it.
SERVICE_EVENT = ('test_msgs/srv/BasicTypes_Event', 'bool bool_value\nint64 int64_value\n---\n'
                 'bool bool_value\nint64 int64_value\n')


@pytest.mark.parametrize('storage', STORAGES)
def test_a_service_event_definition_rosbags_cannot_parse_stops_nothing(tmp_path, storage):
    # Jazzy records service events beside topics (`ros2 bag record --all`): only the
    # definitions of the topics read are parsed.
    rng = np.random.default_rng(14)
    plain = _write(tmp_path / 'plain', storage, _chamber(rng))
    event = ('/svc/_service_event', SERVICE_EVENT[0], 10, [(5 * 10**9 + 7, b'\x00\x01\x00\x00')])
    bag = _write(tmp_path / 'bag', storage, _chamber(np.random.default_rng(14)) + [event],
                 definitions=dict([SERVICE_EVENT]))
    with pytest.raises(DatasetError, match='unreadable or corrupt'):
        read_bag(bag, via='rosbags')                   # rosbags refuses the whole bag
    got, ref = read_bag(bag), read_bag(plain)
    assert got.via == 'columnar' and got.topics['/svc/_service_event'] == (SERVICE_EVENT[0], 1)
    for name in ARRAYS:
        a, b = getattr(got, name), getattr(ref, name)
        assert (a is None) == (b is None) and (a is None or a.tobytes() == b.tobytes()), name


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


# ------------------------------------------------------------------------------------------
# A bag without metadata.yaml (the recording did not close), as `ros2 bag reindex` lists it
# ------------------------------------------------------------------------------------------

REAL = Path(__file__).parents[2] / 'support' / 'files' / 'rosbag2'


def _without_metadata(bag: Path, ext: str) -> list[str]:
    """Name the storage files as rosbag2 splits them (in metadata.yaml's order), drop it."""
    info = metadata.load(bag)
    for k, name in enumerate(info['relative_file_paths']):
        (bag / name).rename(bag / f'{bag.name}_{k}{ext}')
    (bag / 'metadata.yaml').unlink()
    return sorted(p.name for p in bag.iterdir())


@pytest.mark.parametrize('storage', STORAGES)
def test_a_bag_without_metadata_yaml_is_read_as_ros2_bag_reindex_lists_it(tmp_path, storage):
    bag = _several_files(tmp_path, storage)
    ref, info = read_bag(bag), metadata.load(bag)
    ext = '.db3' if storage == 'sqlite3' else '.mcap'
    files = _without_metadata(bag, ext)
    got = read_bag(bag)
    for name in ARRAYS:
        a, b = getattr(got, name), getattr(ref, name)
        assert (a is None) == (b is None) and (a is None or a.tobytes() == b.tobytes()), name
    assert got.topics == ref.topics and got.via == 'columnar'
    (warning,) = got.warnings
    assert warning == (f'no metadata.yaml (the recording did not close: rosbag2 writes it '
                       f'then): read from bag_0{ext}, bag_1{ext} as `ros2 bag reindex` would '
                       'list it')
    _same_data(bag)                         # rosbags' read, of the rebuilt metadata.yaml
    # Nothing is written into the bag.
    assert sorted(p.name for p in bag.iterdir()) == files
    rebuilt = columnar.rebuild(*metadata.locate(bag))
    for key in ('message_count', 'storage_identifier'):
        assert rebuilt[key] == info[key], key
    starts = [f['starting_time']['nanoseconds_since_epoch'] for f in info['files']]
    ends = [a + f['duration']['nanoseconds'] for a, f in zip(starts, info['files'])]
    assert rebuilt['starting_time']['nanoseconds_since_epoch'] == min(starts)
    assert rebuilt['duration']['nanoseconds'] == max(ends) - min(starts)
    assert [(t['topic_metadata']['name'], t['message_count'])
            for t in rebuilt['topics_with_message_count']] == [
        (t['topic_metadata']['name'], t['message_count'])
        for t in info['topics_with_message_count']]
    assert [f['message_count'] for f in rebuilt['files']] == [
        f['message_count'] for f in info['files']]


@pytest.mark.parametrize('storage', STORAGES)
def test_rosbag2s_own_bag_without_metadata_reads_as_its_reindex_test_lists_it(tmp_path, storage):
    # rosbag2's reindex test bag (written by its C++ storage plugins, split in three files):
    # the same topic, counts and times from either storage, read in full by rosbags.
    real = REAL / storage / 'multiple_files'
    bag, files = metadata.locate(real)
    assert bag == real and [f.name for f in files] == [
        f'multiple_files_{k}.{"db3" if storage == "sqlite3" else "mcap"}' for k in range(3)]
    info = columnar.rebuild(bag, files)
    assert info['message_count'] == 3177 and [
        (t['topic_metadata']['name'], t['topic_metadata']['type'], t['message_count'])
        for t in info['topics_with_message_count']] == [('/chatter', 'std_msgs/msg/String', 3177)]
    assert info['starting_time']['nanoseconds_since_epoch'] == 1616653333034080451
    assert info['duration']['nanoseconds'] == 6352112906
    with columnar.readable(real) as opened, AnyReader([opened], default_typestore=TS) as r:
        texts = {r.deserialize(raw, c.msgtype).data for c, _, raw in r.messages()}
        assert sum(1 for _ in r.messages()) == 3177 and texts == {'test'}
    assert not opened.exists() and sorted(p.name for p in real.iterdir()) == [
        f.name for f in files]
    with pytest.raises(DatasetError, match=r"has no topic '/imu/data_raw' \(imu\); topics "
                                           r'present: /chatter \(std_msgs/msg/String, 3177'):
        read_bag(real)


def test_a_storage_file_without_metadata_beside_it_is_a_bag_of_that_file(tmp_path):
    rng = np.random.default_rng(12)
    one = _write(tmp_path / 'one', 'mcap', _chamber(rng))
    other = _write(tmp_path / 'other', 'mcap', _chamber(rng, n=50))
    ref = read_bag(one)
    shutil.copy(other / 'other.mcap', tmp_path / 'loose_1.mcap')
    shutil.copy(one / 'one.mcap', tmp_path / 'loose_2.mcap')
    got = read_bag(tmp_path / 'loose_2.mcap')
    assert got.gyro.tobytes() == ref.gyro.tobytes() and got.topics == ref.topics
    assert 'read from loose_2.mcap as' in got.warnings[0]
    assert got.path == str(tmp_path / 'loose_2.mcap')
    # The real talker (rosbag2's, no IMU): its topics named.
    shutil.copy(REAL / 'talker.mcap', tmp_path / 'talker.mcap')
    with pytest.raises(DatasetError, match=rf"^Bag '{tmp_path / 'talker.mcap'}' has no topic "
                                           r"'/imu/data_raw' \(imu\); topics present: "
                                           r'/parameter_events \(rcl_interfaces/msg/'
                                           r'ParameterEvent, 0 msgs\), /rosout \(rcl_interfaces/'
                                           r'msg/Log, 10 msgs\), '
                                           r'/topic \(std_msgs/msg/String, 10 msgs\)\.$'):
        read_bag(tmp_path / 'talker.mcap')


def test_an_mcap_file_cut_off_without_metadata_yaml_is_read_with_both_warnings(tmp_path):
    # The power went during `ros2 bag record`: no footer and no metadata.yaml.
    rng = np.random.default_rng(16)
    whole = _write(tmp_path / 'whole', 'mcap', _chamber(rng, n=9000))
    ref = read_bag(whole)
    bag = tmp_path / 'rec'
    bag.mkdir()
    raw = (whole / 'whole.mcap').read_bytes()
    (bag / 'rec_0.mcap').write_bytes(raw[:int(0.7 * len(raw))])
    got = read_bag(bag)
    n = len(got.imu_t)
    assert 0 < n < len(ref.imu_t) and got.gyro.tobytes() == ref.gyro[:n].tobytes()
    rebuilt, cut = got.warnings
    assert rebuilt.startswith('no metadata.yaml') and cut.startswith('rec_0.mcap ends without')
    # rosbags reads no file without its footer: the paths through it say so in one line.
    with pytest.raises(DatasetError, match=r'unreadable or corrupt.*rec_0\.mcap ends without '
                                           'the mcap footer'):
        read_bag(bag, via='rosbags')


@pytest.mark.parametrize('storage', STORAGES)
def test_a_bag_compressed_message_by_message_without_metadata_goes_to_rosbags(tmp_path,
                                                                              storage):
    rng = np.random.default_rng(5)
    bag = _write(tmp_path / 'bag', storage, _chamber(rng), compression=CompressionMode.MESSAGE)
    ref = read_bag(bag)
    _without_metadata(bag, '.db3' if storage == 'sqlite3' else '.mcap')
    got = read_bag(bag)
    assert got.gyro.tobytes() == ref.gyro.tobytes()
    assert got.temp_c.tobytes() == ref.temp_c.tobytes()
    assert got.warnings[0].startswith('no metadata.yaml')


@pytest.mark.parametrize('files, needle', [
    ({'notes.txt': b'hello', 'old.db3': b''},
     r'not a rosbag2 directory: no metadata\.yaml, and not only storage files named '
     r"NAME_N\.db3 or NAME_N\.mcap \(found \['notes\.txt', 'old\.db3'\]\)\.$"),
    ({'x_0.db3': b'', 'x_1.mcap': b''}, r'holds both \.db3 and \.mcap files'),
    ({'x_0.db3': b'', 'old_metadata.yaml': b''},
     r"not only storage files named .* \(found \['old_metadata\.yaml', 'x_0\.db3'\]\)"),
    ({'x_0.db3': b'SQLite format 3\x00' + bytes(200)},
     r'\(no metadata\.yaml\): storage file x_0\.db3 is unreadable or corrupt: '),
    ({'x_0.db3': b'not a database at all' * 100},
     r'\(no metadata\.yaml\): storage file x_0\.db3 is unreadable or corrupt: .* '
     r'\(`sqlite3 x_0\.db3 \.recover \| sqlite3 NEW/x_0\.db3` copies what it holds to a new '
     r'file\)$'),
    ({'x_0.mcap': b'\x89MCAP0\r\n' + bytes(40)},
     r'\(no metadata\.yaml\): storage file x_0\.mcap is unreadable or corrupt: '),
    ({'x_0.mcap': b'plain text'},
     r'\(no metadata\.yaml\): storage file x_0\.mcap is unreadable or corrupt: not an mcap'),
])
def test_a_folder_without_metadata_that_is_no_bag_is_one_line(tmp_path, files, needle):
    bag = tmp_path / 'x'
    bag.mkdir()
    for name, data in files.items():
        (bag / name).write_bytes(data)
    with pytest.raises(DatasetError, match=needle) as err:
        read_bag(bag)
    assert '\n' not in str(err.value)
    assert sorted(p.name for p in bag.iterdir()) == sorted(files)


def test_an_unmerged_sqlite_write_ahead_log_is_named_not_read(tmp_path):
    # rosbag2's `resilient` preset records with SQLite's write-ahead log: after a power loss
    # the messages written last may stand in NAME_0.db3-wal only.
    import sqlite3
    rng = np.random.default_rng(13)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(rng))
    ref = read_bag(bag)
    _without_metadata(bag, '.db3')
    db = sqlite3.connect(bag / 'bag_0.db3')
    try:
        db.execute('PRAGMA journal_mode=WAL')
        db.execute('PRAGMA wal_autocheckpoint=0')
        db.execute('INSERT INTO messages (topic_id, timestamp, data) SELECT topic_id, '
                   'timestamp + 1000000000000, data FROM messages')
        db.commit()
        cut = tmp_path / 'cut'
        cut.mkdir()
        for name in ('bag_0.db3', 'bag_0.db3-wal'):       # the power goes: the files as they are
            shutil.copy(bag / name, cut / name)
    finally:
        db.close()
    got = read_bag(cut)
    assert got.gyro.tobytes() == ref.gyro.tobytes()
    rebuilt, wal = got.warnings
    assert rebuilt.startswith('no metadata.yaml') and re.fullmatch(
        r"bag_0\.db3-wal: \d+ bytes of SQLite's write-ahead log not read \(the messages "
        r"written last; `sqlite3 bag_0\.db3 'PRAGMA wal_checkpoint'` merges them into the "
        r'file\)', wal)
    assert sorted(p.name for p in cut.iterdir()) == ['bag_0.db3', 'bag_0.db3-wal']


@pytest.mark.parametrize('bare', [False, True])
def test_a_stamp_of_another_type_in_a_db3_is_a_message_lost_not_a_crash(tmp_path, bare):
    # SQLite keeps what a damaged record says: a blob where a stamp was. The listing of a
    # bag without metadata.yaml skips it; rosbags' read (the columnar one comes up short)
    # loses that one message, and the loss policy names damage, not a cut.
    import sqlite3
    from gyro_tdc.data.dataset import load_run
    rng = np.random.default_rng(15)
    bag = _write(tmp_path / 'bag', 'sqlite3', _chamber(rng))
    total = metadata.load(bag)['message_count']
    if bare:
        _without_metadata(bag, '.db3')
    db = sqlite3.connect(next(bag.glob('*.db3')))
    try:
        db.execute("UPDATE messages SET timestamp = X'00' WHERE id = 300")
        db.commit()
    finally:
        db.close()
    if bare:
        assert columnar.rebuild(*metadata.locate(bag))['message_count'] == total
    got = read_bag(bag)
    assert len(got.imu_t) + len(got.temp_t) == total - 1
    warnings = load_run(bag).info['warnings']
    assert any(': read 699 of 700 messages' in w and '1 lost' in w
               and 'a damaged file or undecodable messages' in w for w in warnings), warnings
