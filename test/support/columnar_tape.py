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

"""Bags written message by message, and the columnar read taped beside rosbags' reader."""

from __future__ import annotations

from pathlib import Path

from gyro_tdc.data import IMU_TYPE, read_bag, REFERENCE_TYPE, TEMPERATURE_TYPE
from gyro_tdc.data.bag import columnar, metadata, reader
import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
from rosbags.interfaces import QosTime
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

TS = get_typestore(Stores.ROS2_JAZZY)
STORAGES = ('sqlite3', 'mcap')
PLUGINS = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
FLOAT_TYPE = 'std_msgs/msg/Float64'
ARRAYS = ('imu_t', 'gyro', 'accel', 'temp_t', 'temp_c', 'temp_var', 'ref_t', 'ref')


def _qos(depth: int) -> list[Qos]:
    inf = QosTime(0x7FFFFFFF, 0xFFFFFFFF)
    return [Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE, QosDurability.VOLATILE,
                inf, inf, QosLiveliness.AUTOMATIC, inf, False)]


def _header(ns: int, frame: str = 'imu_link'):
    return TS.types['std_msgs/msg/Header'](
        TS.types['builtin_interfaces/msg/Time'](ns // 10**9, ns % 10**9), frame)


def _imu(rng, ns: int, frame: str = 'imu_link') -> bytes:
    vec, quat = TS.types['geometry_msgs/msg/Vector3'], TS.types['geometry_msgs/msg/Quaternion']
    msg = TS.types[IMU_TYPE](_header(ns, frame), quat(0.0, 0.0, 0.0, 1.0), np.zeros(9),
                             vec(*rng.normal(size=3)), np.zeros(9), vec(*rng.normal(size=3)),
                             np.zeros(9))
    return bytes(TS.serialize_cdr(msg, IMU_TYPE))


def _temperature(rng, ns: int) -> bytes:
    msg = TS.types[TEMPERATURE_TYPE](_header(ns), 20.0 + rng.normal(), 0.01)
    return bytes(TS.serialize_cdr(msg, TEMPERATURE_TYPE))


def _float(rng, ns: int) -> bytes:
    return bytes(TS.serialize_cdr(TS.types[FLOAT_TYPE](20.0 + rng.normal()), FLOAT_TYPE))


def _reference(rng, ns: int) -> bytes:
    msg = TS.types[REFERENCE_TYPE](_header(ns), TS.types['geometry_msgs/msg/Vector3'](
        *rng.normal(size=3)))
    return bytes(TS.serialize_cdr(msg, REFERENCE_TYPE))


def _write(path: Path, storage: str, streams, *, shuffle: bool = False,
           compression: CompressionMode | None = None, seed: int = 0,
           definitions: dict | None = None) -> Path:
    """
    Write ``streams``: [(topic, msgtype, qos depth, [(log ns, raw), ...])] with rosbags.

    Two streams of one topic with different QoS depths are two connections of it. Messages
    are written in time order, or shuffled (rowids and mcap chunks out of time order).
    ``definitions``: msgtype -> definition text of a type the Jazzy typestore lacks.
    """
    definitions = definitions or {}
    wr = Writer(path, version=9, storage_plugin=PLUGINS[storage])
    if compression is not None:
        wr.set_compression(compression, CompressionFormat.ZSTD)
    items = [(ns, k, raw) for k, (_, _, _, msgs) in enumerate(streams) for ns, raw in msgs]
    items.sort(key=lambda x: x[0])
    if shuffle:
        order = np.random.default_rng(seed).permutation(len(items))
        items = [items[i] for i in order]
    with wr:
        given = {k: {'msgdef': v, 'rihs01': 'RIHS01_' + '0' * 64} for k, v in definitions.items()}
        conns = [wr.add_connection(topic, msgtype, offered_qos_profiles=_qos(depth),
                                   **given.get(msgtype, {'typestore': TS}))
                 for topic, msgtype, depth, _ in streams]
        for ns, k, raw in items:
            wr.write(conns[k], ns, raw)
    return path


def _chamber(rng, n: int = 700, *, step: int = 10**7, t0: int = 5 * 10**9, floating=False,
             reference=False, split_imu=False, ties=False, zero=()):
    """Streams of a small chamber bag: IMU (one or two connections), temperature, reference."""
    logs = t0 + np.arange(n) * step
    if ties:
        logs[1::7] = logs[0::7][:len(logs[1::7])]       # equal log times
    imu = [(int(ns), _imu(rng, 0 if i in zero else int(ns) + 3)) for i, ns in enumerate(logs)]
    make = _float if floating else _temperature
    temps = [(int(ns) + (0 if ties else 1), make(rng, int(ns) + 1)) for ns in logs[::50]]
    streams = [('/imu/data_raw', IMU_TYPE, 10, imu[0::2] if split_imu else imu)]
    if split_imu:
        streams.append(('/imu/data_raw', IMU_TYPE, 20, imu[1::2]))
    streams.append(('/imu/temperature', FLOAT_TYPE if floating else TEMPERATURE_TYPE, 10,
                    temps[0::2] if split_imu else temps))
    if split_imu:
        streams.append(('/imu/temperature', FLOAT_TYPE if floating else TEMPERATURE_TYPE, 20,
                        temps[1::2]))
    if reference:
        streams.append(('/rate_table/reference', REFERENCE_TYPE, 10,
                        [(int(ns) + 2, _reference(rng, int(ns))) for ns in logs[::3]]))
    return streams


class _Tape:
    """A Collector stand-in recording every message handed over, per role."""

    def __init__(self, roles, floating):
        self.roles, self.floating = list(roles), floating
        self.n_main = 0
        self.got = {role: [] for role in self.roles}
        self.before = []

    def add(self, role, buf, lengths, logs, before=None):
        logs = logs() if callable(logs) else logs
        ends = np.cumsum(lengths).tolist()
        for a, b, log in zip([0] + ends[:-1], ends, list(logs)):
            self.got[role].append((int(log), bytes(buf[a:b])))
        self.n_main += len(lengths) if role == 'imu' else 0
        if role == 'temperature' and self.floating:
            self.before += [int(x) for x in before]

    @property
    def received(self):
        """Return the messages handed over, per role (as the Collector counts them)."""
        return {role: len(x) for role, x in self.got.items()}


WANTED = [('imu', '/imu/data_raw', (IMU_TYPE,), True),
          ('temperature', '/imu/temperature', (TEMPERATURE_TYPE, FLOAT_TYPE), True),
          ('reference', '/rate_table/reference', (REFERENCE_TYPE,), False)]


def _topics(rd: AnyReader) -> dict[str, tuple[str, int]]:
    return {name: (t.msgtype or '?', t.msgcount) for name, t in rd.topics.items()}


def _tapes(bag: Path, chunk: int = 64):
    """Return (rosbags' messages per role, Float 'before' counts) and the columnar tape."""
    with AnyReader([bag], default_typestore=TS) as rd:
        _, conns = reader._connections(_topics(rd), rd.connections, bag, WANTED)
        role_of = {id(c): role for role, cs in conns.items() for c in cs}
        want = {role: [] for role in conns}
        before, n_main = [], 0
        for conn, log, raw in rd.readers[0].messages(
                connections=[c for cs in conns.values() for c in cs]):
            role = role_of[id(conn)]
            want[role].append((log, bytes(raw)))
            n_main += role == 'imu'
            if role == 'temperature':
                before.append(n_main)
    with columnar.open_bag(bag, metadata.load(bag)) as opened:
        topics, conns = reader._connections(opened.topics, opened.conns, bag, WANTED)
        floating = topics['/imu/temperature'][0] == FLOAT_TYPE
        tape = _Tape(conns, floating)
        opened.feed(conns, tape, lambda n: None, chunk)
    return want, (before if floating else []), tape


def _same_tape(bag: Path, chunk: int = 64) -> None:
    want, before, tape = _tapes(bag, chunk)
    assert set(tape.got) == set(want)
    for role in want:
        assert len(tape.got[role]) == len(want[role]), role
        assert tape.got[role] == want[role], role
    assert tape.before == before


def _same_data(bag: Path) -> None:
    """read_bag gives the same arrays, bit for bit, through both reads."""
    got, ref = read_bag(bag), read_bag(bag, via='rosbags')
    assert got.via == 'columnar' and ref.via == 'rosbags'
    for name in ARRAYS:
        a, b = getattr(got, name), getattr(ref, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), name
    assert got.rejected == ref.rejected and got.topics == ref.topics
    assert got.frame_id == ref.frame_id and got.storage == ref.storage
