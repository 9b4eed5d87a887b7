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
Read IMU, temperature and reference-rate arrays from a rosbag2 bag, fast (:func:`read_bag`).

The storage is read column by column (:mod:`gyro_tdc.data.bag.columnar`) or, where that does
not apply, through rosbags' reader in blocks of raw messages; either way a
:class:`Collector` decodes the blocks with the fixed-layout codec of
:mod:`gyro_tdc.data.bag.codec` (rosbags' deserialiser where the layout does not hold) into
columns sized by the counts of ``metadata.yaml``, checked first
(:func:`~gyro_tdc.data.bag.metadata.check_counts`).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import partial
from itertools import islice
import mmap
import os
from pathlib import Path
import struct
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import apsw
from gyro_tdc.data.bag import columnar, metadata
from gyro_tdc.data.bag.codec import (decode_float, decode_joined, Decoded, FLOAT_TYPES, IMU_TYPE,
                                     jazzy, KEEP, Logs, REFERENCE_TYPE, TEMPERATURE_TYPES)
from gyro_tdc.data.bag.storage_mcap import cut_off
from gyro_tdc.errors import DatasetError, one_line
import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError
import yaml

__all__ = ['BagData', 'Collector', 'READ_ERRORS', 'read_bag', 'topic_messages', 'VIA',
           'with_data']

# Messages per block when reading: small enough that a block's raw bytes (~5 MB of Imu) are
# recycled by the allocator, large enough to amortise the per-block checks.
_CHUNK = 1 << 14
# rosbags' own errors, plus what its parsers let through on damaged files (found by fuzzing
# sqlite3 and mcap bags: huge record lengths raise OverflowError from seek, or MemoryError
# from read, short reads struct.error, a damaged message definition naming a type it does
# not define KeyError from its typesys); zstd's error (data not compressed as metadata.yaml
# says) is caught apart.
READ_ERRORS = (AnyReaderError, ReaderError, apsw.Error, OSError, SerdeError, yaml.YAMLError,
               UnicodeDecodeError, OverflowError, MemoryError, struct.error, KeyError)


def with_data(messages: Iterable[tuple[Any, int, Any]],
              bag: str | os.PathLike) -> Iterator[tuple[Any, int, Any]]:
    """Pass rosbags' ``(connection, stamp, raw)``; a raw of None is a damaged file, refused."""
    for conn, ns, raw in messages:
        if raw is None:                 # a damaged sqlite3 row's data reads as NULL
            raise DatasetError(f'cannot read bag {str(bag)!r}: a message on {conn.topic!r} '
                               f'has no data (a damaged file).')
        yield conn, ns, raw


class _Raw:
    """The raw messages a columnar read hands over (``Bag.feed``'s ``out``), in bag order."""

    floating = False

    def __init__(self, conns: Sequence[Any]) -> None:
        self.conn = dict(zip(('imu', 'temperature'), conns))     # the first one is the main
        self.roles = tuple(self.conn)
        self.n_main, self.keyed = 0, []      # (main messages before it, 0 | 1, conn, ns, raw)

    def add(self, role: str, buf: bytes, lengths: Sequence[int], logs: Logs,
            before: Any = None) -> None:
        ends = np.cumsum(lengths).tolist()
        raw = [bytes(buf[e - n:e]) for e, n in zip(ends, np.asarray(lengths).tolist())]
        ns = np.asarray(logs() if callable(logs) else logs).tolist()
        if role == 'imu':             # a message with k main messages before it goes first
            keys = [(k, 1) for k in range(self.n_main, self.n_main + len(raw))]
            self.n_main += len(raw)
        else:
            keys = [(k, 0) for k in np.asarray(before).tolist()]
        self.keyed += [(*k, self.conn[role], t, m) for k, t, m in zip(keys, ns, raw)]


@contextmanager
def topic_messages(path: str | os.PathLike, topics: Sequence[str],
                   warn: Callable[[str], Any] = lambda _line: None
                   ) -> Iterator[tuple[Any, list, Callable]]:
    """
    Yield a bag's typestore, connections and ``messages(*connections)`` in bag order.

    ``messages`` yields ``(connection, log time ns, raw)`` of one or two connections of
    ``topics``. rosbags reads the bag. A recording the power cut (no metadata.yaml, an mcap
    file without its footer) is read to the file's last whole chunk by the columnar read,
    ``warn`` given a warning counting the bytes lost; a file cut in a bag that metadata.yaml
    lists is refused (these reads have no loss policy).
    """
    bag, paths = metadata.locate(path)
    if paths is None or not cut_off(paths):
        with columnar.readable(path) as opened, \
                AnyReader([opened], default_typestore=jazzy()) as r:
            yield r.typestore, r.connections, lambda *conns: with_data(
                r.messages(connections=conns), path)
        return
    with columnar.open_bag(bag, columnar.rebuild(bag, paths)) as opened:
        def messages(*conns: Any) -> Iterator[tuple[Any, int, bytes]]:
            raw = _Raw(conns)
            opened.feed({role: [c] for role, c in raw.conn.items()}, raw, lambda _n: None, 4096)
            for warning in opened.warnings:
                warn(warning)
            return (m[2:] for m in sorted(raw.keyed, key=lambda x: x[:2]))
        yield (opened.typestore({c.msgtype for c in opened.conns if c.topic in topics}),
               opened.conns, messages)


@dataclass(frozen=True)
class BagData:
    """
    Arrays read from a bag, one entry per message that held finite values.

    What was rejected, how the storage was read and which topics the bag holds come with
    them, for the reader's report.
    """

    #: IMU header stamps (N,), s (the log time where a header stamp is zero), in bag order
    #: (the order rosbags' reader yields the messages of every connection of the topic: log
    #: time within a storage file, the files one after the other; not sorted by header
    #: stamp).
    imu_t: NDArray[np.float64]
    #: Angular velocity (N, 3), rad/s; samples with a NaN or infinite component are rejected.
    gyro: NDArray[np.float64]
    #: Linear acceleration (N, 3), m/s^2, or None when read with ``accel=False``; not
    #: checked: a missing accelerometer does not reject gyro data.
    accel: NDArray[np.float64] | None
    #: Header frame id of the first IMU message.
    frame_id: str
    #: Thermometer stamps (M,), s. A ``std_msgs/msg/Float32`` or ``Float64`` reading, which
    #: has no header, takes the stamp of the latest IMU message before it in the bag's order
    #: (log time), as the compensator node stamps it live; readings before the first IMU
    #: message are dropped (``temp_before_imu``), as the node ignores them.
    temp_t: NDArray[np.float64]
    #: Temperature (M,), degC; non-finite samples rejected.
    temp_c: NDArray[np.float64]
    #: Temperature variance (M,) as recorded, degC^2 (0, unknown, for a Float reading).
    temp_var: NDArray[np.float64]
    #: Reference-rate stamps (R,), s; None when the bag has no (non-empty) reference topic.
    ref_t: NDArray[np.float64] | None
    #: Reference rate (R, 3), rad/s, or None.
    ref: NDArray[np.float64] | None
    #: Every topic of the bag, name -> (type, message count).
    topics: dict = field(default_factory=dict)
    #: Counts of rejected messages by reason, ``imu_nonfinite``, ``temp_nonfinite``,
    #: ``ref_nonfinite``, ``undecodable`` (messages rosbags could not deserialise) and
    #: ``temp_before_imu`` (Float readings before the first IMU message).
    rejected: dict = field(default_factory=dict)
    #: Storage plugin of the bag ('sqlite3' or 'mcap').
    storage: str = ''
    #: The bag directory.
    path: str = ''
    #: Messages per role ('imu', 'temperature', 'reference') decoded one by one with
    #: rosbags because the fixed-layout numpy decoder did not apply.
    fallback: dict = field(default_factory=dict, compare=False)
    #: How the storage was read, 'columnar' or 'rosbags' (see :func:`read_bag`).
    via: str = field(default='', compare=False)
    #: What the read warns of: a storage file cut off (an mcap file without its footer).
    warnings: tuple = field(default=(), compare=False)


def _columns(rows: int, width: int = 0) -> NDArray[np.float64]:
    """
    Return an uninitialised float64 array of ``rows`` (by ``width``) in ordinary pages.

    numpy asks the kernel to back arrays of 4 MB or more with huge pages; where the kernel
    then compacts memory to find them on first touch (transparent huge pages on advice,
    as Ubuntu and Debian ship them), filling the columns costs several times more. A
    private anonymous mapping of the standard ``mmap`` gets the kernel's default pages (a
    shared one, ``mmap``'s default, is shared memory: its pages cost more to fault in).
    """
    shape = (rows, width) if width else (rows,)
    size = rows * max(width, 1) * 8
    if size < 1 << 22:
        return np.empty(shape)
    return np.frombuffer(mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE),
                         dtype=np.float64).reshape(shape)


class _Sink:
    """Growable, preallocated output columns for one role: times plus value groups."""

    def __init__(self, capacity: int, widths: Sequence[int]) -> None:
        self.widths = list(widths)
        self.t = _columns(capacity)
        self.v = [_columns(capacity, w) for w in self.widths]
        self.n = 0

    def add(self, t: NDArray[np.float64], values: NDArray[np.float64]) -> None:
        """Append a block (values: all groups side by side), growing when it must."""
        end = self.n + len(t)
        if end > len(self.t):
            cap = max(end, 2 * len(self.t))
            grown = [_columns(cap)] + [_columns(cap, w) for w in self.widths]
            for new, old in zip(grown, [self.t] + self.v):
                new[:self.n] = old[:self.n]
            self.t, self.v = grown[0], grown[1:]
        self.t[self.n:end] = t
        for v, a in zip(self.v, np.cumsum([0] + self.widths).tolist()):
            v[self.n:end] = values[:, a:a + v.shape[1]]
        self.n = end

    def result(self, keep: NDArray[np.bool_] | None = None) -> list[NDArray[np.float64]]:
        """Return [t, *groups] of the filled rows (``keep`` selects rows)."""
        out = [self.t[:self.n]] + [v[:self.n] for v in self.v]
        if keep is not None and not keep.all():
            return [x[keep] for x in out]
        return [x.copy() for x in out] if self.n < 0.9 * len(self.t) else out


#: How :func:`read_bag` reads the storage: ``'auto'`` (columnar where it applies, else
#: rosbags), ``'columnar'`` (refuse a bag it does not apply to) or ``'rosbags'``.
VIA = ('auto', 'columnar', 'rosbags')


def read_bag(path, *, imu_topic='/imu/data_raw', temperature_topic='/imu/temperature',
             reference_topic='/rate_table/reference', progress=False, accel=True, via='auto'
             ) -> BagData:
    """
    Read IMU, temperature and reference-rate arrays from a rosbag2 bag, fast.

    The storage is read column by column (:mod:`gyro_tdc.data.bag.columnar`: the messages of
    each wanted topic in bulk, in bag order) where that applies, else through rosbags'
    reader, the reference, whose raw messages are collected in blocks; either way the blocks
    are decoded with numpy (see the module docstring), rosbags' per-message deserialiser
    only where the fixed layout does not hold. A columnar read that meets anything it does
    not expect gives way to rosbags', which then reads the bag or names what is wrong.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or mcap); a path to its .db3/.mcap file also works.
    imu_topic : str
        ``sensor_msgs/msg/Imu`` topic (required, non-empty).
    temperature_topic : str
        Temperature topic (required, non-empty): ``sensor_msgs/msg/Temperature``, or a bare
        ``std_msgs/msg/Float32`` / ``Float64`` in degC, its type taken from the bag and its
        readings stamped as the compensator node stamps them (see ``BagData.temp_t``).
    reference_topic : str or None
        ``geometry_msgs/msg/Vector3Stamped`` topic; optional (``ref`` is None when absent
        or empty); None skips it.
    progress : bool
        Show a tqdm progress bar (messages read).
    accel : bool
        Also extract the linear acceleration (``BagData.accel`` is None when False: the
        trainer does not need it, and skipping it saves 24 bytes per IMU message).
    via : {'auto', 'columnar', 'rosbags'}
        How to read the storage (:data:`VIA`); ``BagData.via`` says how it was read.

    Returns
    -------
    BagData
        The arrays, the topics of the bag and the counts of rejected samples.

    Raises
    ------
    DatasetError
        When the path does not exist, is not a rosbag2 directory, cannot be read or is
        corrupt, or when a topic is missing, empty or of the wrong type (with
        ``via='columnar'`` also when the columnar read does not apply).

    """
    if via not in VIA:
        raise DatasetError(f'Expected `via` to be one of {", ".join(VIA)}, got {via!r}.')
    bag, files, info = metadata.find(path)
    # A reference topic of None is no topic of the bag: skipped.
    wanted = [('imu', imu_topic, (IMU_TYPE,), True),
              ('temperature', temperature_topic, TEMPERATURE_TYPES, True),
              ('reference', reference_topic, (REFERENCE_TYPE,), False)]
    try:
        if not info:                # metadata.yaml not read (or empty), or none
            info = metadata.load(bag) if files is None else columnar.rebuild(bag, files)
        notes = () if files is None else columnar.rebuilt_notes(files)
        metadata.check_counts(bag, info)
        collect = partial(_collect, bag, info, progress, accel)
        why = columnar.unfit(info) if via != 'rosbags' else 'rosbags asked for'
        got = None
        if why is None:
            try:
                with columnar.open_bag(bag, info) as opened:
                    topics, conns = _connections(opened.topics, opened.conns, bag, wanted)
                    data = collect(opened.feed, opened.typestore(
                        c.msgtype for cs in conns.values() for c in cs), topics, conns,
                        'columnar', notes + opened.warnings)
                if opened.short is None or via == 'columnar':
                    return data
                # Fewer than listed: rosbags' walk of a damaged index may find the others.
                why, got = opened.short, data
            except DatasetError:
                raise                     # a topic missing or of the wrong type
            except Exception as err:      # noqa: B902 (whatever it is, rosbags decides)
                # Let rosbags read it, or say what is wrong with it.
                why = (str(err) if isinstance(err, metadata.Unfit)
                       else f'{type(err).__name__}: {one_line(err)}')
        if via == 'columnar':
            raise DatasetError(f'Cannot read bag {str(bag)!r} column by column: {why}.')
        try:
            with columnar.readable(path, info if files else None) as readable, \
                    AnyReader([readable], default_typestore=jazzy()) as reader:
                topics, conns = _connections(
                    {name: (t.msgtype or '?', int(t.msgcount))
                     for name, t in reader.topics.items()}, reader.connections, bag, wanted)
                # One bag: its rosbags Reader directly, without AnyReader's merge across bags.
                source = reader.readers[0] if len(reader.readers) == 1 else reader
                return collect(partial(_rosbags_feed, source), reader.typestore, topics, conns,
                               'rosbags', notes)
        except READ_ERRORS:
            if got is None:
                raise
            return got              # rosbags reads none of it: what the columnar read got
    except metadata.zstd.ZstdError as err:
        raise DatasetError(f'Cannot read bag {str(bag)!r}: its data are not compressed as '
                           f'metadata.yaml says (compression_format '
                           f'{info.get("compression_format")!r:.20}, compression_mode '
                           f'{info.get("compression_mode")!r:.20}): {one_line(err)}') from err
    except READ_ERRORS as err:
        why = (f'a message definition names {err}, a type no definition of the bag defines'
               if isinstance(err, KeyError) else one_line(err))
        hint = cut_off(metadata.storage_paths(bag, info))
        raise DatasetError(f'Cannot read bag {str(bag)!r} (unreadable or corrupt): '
                           + (f'{why.rstrip(".")}{hint}.' if hint else why)) from err


def _connections(topics: dict[str, tuple[str, int]], connections: Sequence[Any], bag: Path,
                 wanted: Sequence[tuple[str, str, tuple, bool]]
                 ) -> tuple[dict[str, tuple[str, int]], dict[str, list[Any]]]:
    """
    Check the wanted topics; return the bag's topics and the connections of each role.

    ``topics`` maps every topic to (type, count); ``connections`` are rosbags' or those of
    metadata.yaml (anything with ``topic`` and ``msgcount``).
    """
    conns: dict[str, list[Any]] = {}
    for role, topic, msgtype, required in wanted:
        if topic not in topics:
            if required:
                raise DatasetError(f'Bag {str(bag)!r} has no topic {topic!r} ({role}); topics '
                                   f'present: {metadata.describe(topics)}.')
            continue
        if topics[topic][0] not in msgtype:
            raise DatasetError(f'Topic {topic!r} in bag {str(bag)!r} has type {topics[topic][0]!r}'
                               f', expected {" or ".join(map(repr, msgtype))}.')
        if topics[topic][1] == 0 and required:
            raise DatasetError(f'Topic {topic!r} in bag {str(bag)!r} has no messages.')
        conns[role] = [c for c in connections if c.topic == topic]
    return topics, conns


class Collector:
    """
    Decode blocks of raw messages, role by role, into the columns of a :class:`BagData`.

    A storage reader hands over each role's messages in bag order, in blocks (:meth:`add`):
    the IMU topic's (all its connections, the *main* messages) and the others' in any
    interleaving. Small main blocks (an mcap chunk's) are gathered into blocks of about
    ``chunk`` messages before they are decoded. A bare Float temperature reading comes with
    the number of main messages before it in bag order, and takes the stamp of the last
    decodable one (resolved in :meth:`result`).
    """

    def __init__(self, roles: Sequence[str], msgtypes: Mapping[str, str],
                 expected: Mapping[str, int], typestore: Any, with_accel: bool,
                 chunk: int) -> None:
        self.roles, self.msgtypes, self.typestore = list(roles), dict(msgtypes), typestore
        self.floating = self.msgtypes['temperature'] in FLOAT_TYPES
        widths = {'imu': (3, 3) if with_accel else (3,), 'temperature': (1, 1), 'reference': (3,)}
        self.keep_imu = None if with_accel else KEEP[IMU_TYPE][:3]
        self.sinks = {role: _Sink(expected[role], widths[role]) for role in self.roles}
        self.frame_id = ''                                # of the first decodable IMU message
        self.fallback = {'imu': 0, 'temperature': 0, 'reference': 0}
        self.undecodable = 0
        self.received = dict.fromkeys(self.roles, 0)     # messages handed over, per role
        self.chunk, self.pending = chunk, []              # main blocks not decoded yet
        self.main_bad: list[NDArray[np.int64]] = []    # main messages undecodable
        self.before: list[NDArray[np.int64]] = []      # Float readings: main messages before

    @property
    def n_main(self) -> int:
        """Return the main (IMU) messages handed over so far."""
        return self.received['imu']

    def _store(self, role: str, dec: Decoded, logs: Logs | None) -> NDArray[np.bool_] | None:
        """Put a decoded block into its sink; return the mask of decodable messages."""
        self.fallback[role] += dec.fallback
        if role == 'imu' and not self.frame_id:
            self.frame_id = dec.frame_id
        stamp_ns = dec.sec * 1_000_000_000 + dec.nanosec
        zero = stamp_ns == 0
        # A zero header stamp: the log time instead (Float readings are stamped in result()).
        if zero.any() and not (role == 'temperature' and self.floating):
            stamp_ns[zero] = np.asarray(logs() if callable(logs) else logs, dtype=np.int64)[zero]
        # Float seconds, the whole seconds added exactly.
        t = (stamp_ns // 1_000_000_000) + (stamp_ns % 1_000_000_000) * 1e-9
        values, good = dec.values, None
        if dec.undecodable is not None:
            good = ~dec.undecodable
            self.undecodable += int(dec.undecodable.sum())
            t, values = t[good], values[good]
        self.sinks[role].add(t, values)
        return good

    def add(self, role: str, buf: bytes | memoryview, lengths: Sequence[int], logs: Logs,
            before: NDArray[np.int64] | None = None) -> None:
        """
        Take a block of one role's messages stored end to end in ``buf``.

        The storage reads hand over no empty block. ``logs``: their log times (or a function
        returning them); ``before``: of each message, the main messages before it in bag order
        (used for Float readings).
        """
        self.received[role] += len(lengths)
        if role == 'imu':
            self.pending.append((buf, lengths, logs))
            big = 2 * len(lengths) >= self.chunk      # a storage range's block: as it is
            if big or sum(len(x[1]) for x in self.pending) >= self.chunk:
                self.flush()
            return
        floating = role == 'temperature' and self.floating
        good = self._store(role, (decode_float if floating else decode_joined)(
            buf, lengths, self.msgtypes[role], self.typestore), logs)
        if floating:
            before = np.asarray(before, dtype=np.int64)
            self.before.append(before if good is None else before[good])

    def flush(self) -> None:
        """Decode the main blocks gathered (before :meth:`result`)."""
        if not self.pending:
            return
        bufs, lengths, logs = zip(*self.pending)
        self.pending, lengths = [], np.concatenate(lengths)
        dec = decode_joined(bufs[0] if len(bufs) == 1 else b''.join(bufs), lengths, IMU_TYPE,
                            self.typestore, self.keep_imu)
        good = self._store('imu', dec, lambda: np.concatenate(
            [x() if callable(x) else np.asarray(x, dtype=np.int64) for x in logs]))
        if good is not None:
            self.main_bad.append(self.n_main - len(lengths) + np.flatnonzero(~good))

    def result(self, bag: Path, storage: str, topics: dict, via: str,
               warnings: tuple = ()) -> BagData:
        """Return the :class:`BagData`."""
        self.flush()
        rejected = {'undecodable': self.undecodable, 'temp_before_imu': 0}
        kept = {'imu': True, 'temperature': True, 'reference': True}
        if self.floating:
            sink = self.sinks['temperature']
            before, bad = (np.concatenate(x or [np.zeros(0, dtype=np.int64)])
                           for x in (self.before, self.main_bad))
            # The last decodable main message before a reading is the one whose sink row is
            # the number of decodable main messages before it, less one. Readings before
            # the first IMU message are dropped, not counted as non-finite.
            row = before - np.searchsorted(bad, before, side='left') - 1
            kept['temperature'] = row >= 0
            rejected['temp_before_imu'] = int(np.count_nonzero(row < 0))
            sink.t[:sink.n] = self.sinks['imu'].t[row.clip(0)]
        out: dict[str, list] = {'reference': [None, None]}
        for role, key in (('imu', 'imu_nonfinite'), ('temperature', 'temp_nonfinite'),
                          ('reference', 'ref_nonfinite')):
            sink = self.sinks.get(role)
            finite = np.isfinite(sink.v[0][:sink.n]).all(axis=1) if sink else np.zeros(0, bool)
            rejected[key] = int(np.count_nonzero(~finite & kept[role]))
            if sink is not None and (sink.n or role != 'reference'):    # no empty reference
                out[role] = sink.result(finite & kept[role])
        imu_t, gyro, *accel = out['imu']
        temp_t, temp_c, temp_var = out['temperature']
        ref_t, ref = out['reference']
        return BagData(imu_t=imu_t, gyro=gyro, accel=accel[0] if accel else None,
                       frame_id=self.frame_id, temp_t=temp_t, temp_c=temp_c[:, 0],
                       temp_var=temp_var[:, 0], ref_t=ref_t, ref=ref, topics=topics,
                       rejected=rejected, storage=storage, path=str(bag),
                       fallback=self.fallback, via=via, warnings=warnings)


def _collect(bag: Path, info: Mapping, progress: bool, with_accel: bool, feed: Callable,
             typestore: Any, topics: dict[str, tuple[str, int]], conns: dict[str, list[Any]],
             via: str, warnings: tuple) -> BagData:
    """Feed a storage read's blocks (``feed(conns, collector, update, chunk)``) to a Collector."""
    from tqdm import tqdm

    msgtypes = {'imu': IMU_TYPE, 'temperature': topics[conns['temperature'][0].topic][0],
                'reference': REFERENCE_TYPE}
    expected = {role: sum(int(c.msgcount) for c in cs) for role, cs in conns.items()}
    size = metadata.storage_bytes(bag, info)
    if size is not None:             # compressed storage may hold more: the sinks grow
        expected = {role: min(n, size // metadata.min_message_bytes(msgtypes[role]) + 1)
                    for role, n in expected.items()}
    out = Collector(list(conns), msgtypes, expected, typestore, with_accel, _CHUNK)
    with tqdm(total=sum(expected.values()), unit='msg', unit_scale=True, desc=bag.name,
              disable=not progress, leave=False) as bar:
        feed(conns, out, bar.update, _CHUNK)
    return out.result(bag, str(info.get('storage_identifier', '')), topics, via, warnings)


def _rosbags_feed(source: Any, conns: dict[str, list[Any]], out: Collector,
                  update: Callable[[int], Any], chunk: int) -> None:
    """Hand rosbags' raw messages to ``out`` in blocks of ``chunk`` (the reference read)."""
    role_of = {id(c): role for role in out.roles for c in conns[role]}
    gen = source.messages(connections=[c for r in out.roles for c in conns[r]])
    while whole := list(islice(gen, chunk)):
        # A row whose data reads as NULL, or whose stamp as no whole number (a damaged sqlite3
        # record), is a message lost.
        block = [m for m in whole if isinstance(m[2], (bytes, bytearray, memoryview))
                 and isinstance(m[1], int)]
        roles = [role_of[id(conn)] for conn, _, _ in block]
        mains = out.n_main + np.cumsum([r == 'imu' for r in roles])   # main messages up to each
        for role in out.roles:
            if mine := [k for k, r in enumerate(roles) if r == role]:
                raws = [block[k][2] for k in mine]
                out.add(role, b''.join(raws), [len(x) for x in raws],
                        np.array([block[k][1] for k in mine], dtype=np.int64), mains[mine])
        update(len(whole))
