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
Columnar read of rosbag2 storage: each wanted topic's messages in bulk, in rosbags' order.

sqlite3: one query per time range returns every role's blobs end to end (``group_concat``
over the timestamp index); mcap: each indexed chunk decompressed once and its records found
with numpy. The same messages as rosbags' reader, byte for byte and in its order; what this
does not take (:func:`unfit`, :class:`Unfit`) rosbags reads. See ``doc/internals/data.md``.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Connection, ConnectionExtRosbag2
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.rosbag2.reader import DirectoryReader
from rosbags.rosbag2.storage_mcap import decompress, McapReader, read_exact
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

__all__ = ['open_reader', 'Source', 'unfit', 'Unfit']

# One-byte role codes of the sqlite3 query's order string (Float temperatures).
_CODES = {'imu': 'm', 'temperature': 't', 'reference': 'r'}


class Unfit(Exception):
    """The columnar read does not apply to this bag: rosbags' reader reads it."""


def unfit(info: Mapping) -> str | None:
    """Return why the columnar read does not take a bag with this metadata, or None."""
    storage = str(info.get('storage_identifier', ''))
    if storage not in ('sqlite3', 'mcap'):
        return f'storage {storage!r:.20}'
    mode = str(info.get('compression_mode') or '').lower()
    if mode == 'message':
        return 'every message compressed on its own'
    return None


class _Sqlite3Storage(Sqlite3Reader):
    """
    rosbags' sqlite3 storage reader without its counts at open.

    rosbags counts every topic's messages at open (a full scan of the messages table, a
    second one for the bag's total); the directory reader takes the counts of
    ``metadata.yaml`` instead, so the scans are skipped. Connections, schema and message
    definitions are read as rosbags reads them.
    """

    def _open(self) -> None:
        assert self.dbconn
        cur = self.dbconn.cursor()
        found = cur.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table' "
                            "AND name IN ('messages', 'topics')").fetchone()
        if found is None or found[0] != 2:
            raise ReaderError(f'Cannot open database {self.path} or database missing tables.')
        if cur.execute('PRAGMA table_info(schema)').fetchall():
            schema = (cur.execute('SELECT schema_version FROM schema').fetchone() or (-1,))[0]
        elif any(x[1] == 'offered_qos_profiles'
                 for x in cur.execute('PRAGMA table_info(topics)').fetchall()):
            schema = 2
        else:
            schema = 1
        msgtypes: list[dict[str, str]] = []
        if schema >= 4:
            msgtypes = [{'name': x[0], 'encoding': x[1], 'msgdef': x[2], 'digest': x[3]}
                        for x in cur.execute(
                            'SELECT topic_type, encoding, encoded_message_definition, '
                            'type_description_hash FROM message_definitions ORDER BY id')]
        self.msgtypes = msgtypes
        # The definitions and QoS as rosbags' own _open makes them (its helper is local).
        cols = ('id, name, type, serialization_format'
                + (', offered_qos_profiles' if schema >= 2 else '')
                + (', type_description_hash' if schema >= 4 else ''))
        conns = []
        for row in cur.execute(f'SELECT {cols} FROM topics ORDER BY id'):
            cid, topic, msgtype, fmt = row[:4]
            qos = parse_qos(row[4]) if schema >= 2 else []
            digest = row[5] if schema >= 4 else ''
            conns.append(Connection(cid, topic, msgtype, _msgdef(msgtypes, msgtype), digest, 0,
                                    ConnectionExtRosbag2(fmt, qos), self))
        self.schema = schema
        self.connections = conns


def _msgdef(msgtypes: Sequence[Mapping[str, str]], name: str) -> Any:
    """Return the message definition of ``name`` as rosbags' sqlite3 reader does."""
    from rosbags.interfaces import MessageDefinition, MessageDefinitionFormat

    fmtmap = {'ros2msg': MessageDefinitionFormat.MSG, 'ros2idl': MessageDefinitionFormat.IDL}
    found = next((x for x in msgtypes if x['name'] == name), None)
    if found:
        return MessageDefinition(fmtmap[found['encoding']], found['msgdef'])
    return MessageDefinition(MessageDefinitionFormat.NONE, '')


class _Directory(DirectoryReader):
    """rosbags' rosbag2 directory reader with the count-free sqlite3 storage."""

    STORAGE_PLUGINS = {'mcap': McapReader, 'sqlite3': _Sqlite3Storage}


class _Reader(Reader):
    """rosbags' rosbag2 reader of a directory through :class:`_Directory`."""

    STORAGE_PLUGINS = {'dir': _Directory, '.mcap': McapReader, '.db3': _Sqlite3Storage}


@contextmanager
def open_reader(bag: Path, typestore: Any) -> Iterator[AnyReader]:
    """
    Open a bag as rosbags' ``AnyReader`` does, without the sqlite3 count scans.

    The metadata, connections, typestore and their checks are rosbags' own; only the
    storage files' message counts, which ``AnyReader`` does not use, are not taken.
    """
    reader = AnyReader([bag], default_typestore=typestore)
    reader.readers = [_Reader(bag)]
    with reader:
        yield reader


class Source:
    """
    The wanted messages of an open bag, role by role in bag order, for a ``Collector``.

    Parameters
    ----------
    reader : AnyReader
        Opened with :func:`open_reader`.
    conns : dict[str, list]
        Role -> its connections (of the directory reader), 'imu' first.
    chunk : int
        About how many messages one block holds.

    """

    def __init__(self, reader: AnyReader, conns: Mapping[str, Sequence[Any]],
                 chunk: int) -> None:
        (self.directory,) = [r.storage for r in reader.readers]
        if not isinstance(self.directory, DirectoryReader):
            raise Unfit('not a rosbag2 directory')
        self.conns = conns
        self.chunk = max(int(chunk), 1)
        self.expected = sum(int(c.msgcount) for cs in conns.values() for c in cs)

    def _roles(self, storage: Any) -> dict[int, str]:
        """Return storage connection id -> role, matched as rosbags' directory reader does."""
        wanted = [(c, role) for role, cs in self.conns.items() for c in cs]
        out = {}
        for x in storage.connections:
            role = next((role for y, role in wanted
                         if y.topic == x.topic and y.msgtype == x.msgtype and y.ext == x.ext
                         and (not x.digest or not y.digest or y.digest == x.digest)), None)
            if role is not None:
                out[x.id] = role
        return out

    def feed(self, out: Any, update: Callable[[int], Any]) -> None:
        """Hand every wanted message to ``out`` (a ``Collector``), file after file."""
        for storage in self.directory.storages:
            roles = self._roles(storage)
            if not roles:
                continue
            if isinstance(storage, Sqlite3Reader):
                _Sqlite3Blocks(storage, roles, self, out, update).run()
            elif isinstance(storage, McapReader):
                _McapBlocks(storage, roles, self, out, update).run()
            else:
                raise Unfit(f'storage {type(storage).__name__}')

    def main_logs(self, index: NDArray[np.int64]) -> NDArray[np.int64]:
        """Never needed: every block comes with its log times at hand."""
        raise Unfit('log times asked for after the read')


def _split(buf: bytes, lengths: NDArray[np.int64]) -> list[bytes]:
    """Return the messages stored end to end in ``buf``."""
    ends = np.cumsum(lengths).tolist()
    return [buf[a:b] for a, b in zip([0] + ends[:-1], ends)]


class _Pending:
    """Main messages gathered until a block is full, then handed over."""

    def __init__(self, out: Any, chunk: int) -> None:
        self.out, self.chunk = out, chunk
        self.pieces: list[bytes] = []
        self.lengths: list[NDArray[np.int64]] = []
        self.logs: list[NDArray[np.int64] | Callable[[], NDArray[np.int64]]] = []
        self.n = 0

    def add(self, buf: bytes, lengths: NDArray[np.int64],
            logs: NDArray[np.int64] | Callable[[], NDArray[np.int64]]) -> None:
        self.pieces.append(buf)
        self.lengths.append(lengths)
        self.logs.append(logs)
        self.n += len(lengths)
        if self.n >= self.chunk:
            self.flush()

    def flush(self) -> None:
        if not self.n:
            return
        pieces, lengths, logs = self.pieces, self.lengths, self.logs
        self.pieces, self.lengths, self.logs, self.n = [], [], [], 0

        def fetch() -> NDArray[np.int64]:
            return np.concatenate([x if isinstance(x, np.ndarray) else x() for x in logs])
        buf = pieces[0] if len(pieces) == 1 else b''.join(pieces)
        self.out.main(buf, np.concatenate(lengths), fetch_logs=fetch)


class _Sqlite3Blocks:
    """
    One sqlite3 storage file read by time ranges over its timestamp index.

    rosbags orders a file's messages by ``ORDER BY timestamp`` through the index on it:
    ties in index order, by rowid. Each range's query walks the same index in the same
    order and returns, per role, the count, the smallest and largest message and the
    messages end to end; a role whose messages differ in size has their lengths fetched.
    """

    def __init__(self, storage: Sqlite3Reader, roles: Mapping[int, str], src: Source,
                 out: Any, update: Callable[[int], Any]) -> None:
        self.db = storage.dbconn
        self.src, self.out, self.update = src, out, update
        self.ids = {role: sorted(k for k, r in roles.items() if r == role)
                    for role in out.roles if role in roles.values()}

    def _in(self, role: str | None = None) -> str:
        ids = (self.ids[role] if role else sorted(k for v in self.ids.values() for k in v))
        return f'topic_id IN ({",".join(str(int(k)) for k in ids)})'

    def _check_plan(self, query: str, what: str, params: Sequence[int] = ()) -> None:
        rows = self.db.execute(f'EXPLAIN QUERY PLAN {query}', tuple(params))
        plan = ' '.join(str(x[-1]) for x in rows)
        if 'USING INDEX' not in plan or 'TEMP B-TREE' in plan:
            raise Unfit(f'{what} does not walk a timestamp index ({plan})')

    def run(self) -> None:
        db, out = self.db, self.out
        inner = (f'SELECT topic_id, data FROM messages WHERE {self._in()} AND timestamp >= ?1 '
                 'AND timestamp < ?2 ORDER BY timestamp, rowid')
        roles = list(self.ids)
        cols = []
        for role in roles:
            f = f'FILTER (WHERE {self._in(role)})'
            cols += [f'count(*) {f}', f'min(length(data)) {f}', f'max(length(data)) {f}',
                     f"CAST(group_concat(data, '') {f} AS BLOB)"]
        floating = out.floating and 'temperature' in self.ids
        if floating:
            case = ' '.join(f'WHEN {self._in(r)} THEN {_CODES[r]!r}' for r in roles)
            cols.append(f"group_concat(CASE {case} END, '')")
        query = f'SELECT count(*), {", ".join(cols)} FROM ({inner})'
        # rosbags' own query of the file, and ours: both in timestamp-index order.
        self._check_plan(
            'SELECT topics.id, messages.timestamp, messages.data FROM messages JOIN topics '
            f'ON messages.topic_id = topics.id WHERE topics.id IN '
            f'({",".join(str(k) for v in self.ids.values() for k in v)}) '
            'ORDER BY timestamp', "rosbags' query")
        self._check_plan(query, 'the range query', (0, 1))
        # Two subqueries: each a single min() or max() that SQLite answers from the timestamp
        # index; min() and max() in one SELECT scan the whole table (~0.2 s for 1 h at 1 kHz).
        lo, hi = db.execute('SELECT (SELECT min(timestamp) FROM messages), '
                            '(SELECT max(timestamp) FROM messages)').fetchone()
        if lo is None:
            return
        span = hi - lo + 1
        step = max(1, min(span * self.src.chunk // max(self.src.expected, 1), span // 16))
        pending = _Pending(out, self.src.chunk)
        t = lo
        while t <= hi:
            end = min(t + step, hi + 1)
            row = db.execute(query, (t, end)).fetchone()
            total = row[0]
            if total:
                self._range(row, roles, t, end, floating, pending)
                self.update(total)
                step = int(min(max(step * self.src.chunk / total, step / 4), step * 4)) or 1
            else:
                step *= 2
            t = end
        pending.flush()

    def _lengths(self, role: str, count: int, small: int, large: int, t: int, end: int
                 ) -> NDArray[np.int64]:
        if small == large:
            return np.full(count, small, dtype=np.int64)
        return np.fromiter((x for (x,) in self.db.execute(
            f'SELECT length(data) FROM messages WHERE {self._in(role)} AND timestamp >= ?1 '
            'AND timestamp < ?2 ORDER BY timestamp, rowid', (t, end))),
            dtype=np.int64, count=count)

    def _logs(self, role: str, count: int, t: int, end: int) -> Callable[[], NDArray[np.int64]]:
        def fetch() -> NDArray[np.int64]:
            return np.fromiter((x for (x,) in self.db.execute(
                f'SELECT timestamp FROM messages WHERE {self._in(role)} AND timestamp >= ?1 '
                'AND timestamp < ?2 ORDER BY timestamp, rowid', (t, end))),
                dtype=np.int64, count=count)
        return fetch

    def _range(self, row: Sequence[Any], roles: Sequence[str], t: int, end: int,
               floating: bool, pending: _Pending) -> None:
        out = self.out
        got = {}
        for k, role in enumerate(roles):
            count, small, large, buf = row[1 + 4 * k:5 + 4 * k]
            if not count:
                continue
            lengths = self._lengths(role, count, small, large, t, end)
            if buf is None or len(buf) != int(lengths.sum()):
                raise Unfit(f'{role}: the blobs of a range do not add up')
            got[role] = (count, buf, lengths)
        if 'imu' in got:
            count, buf, lengths = got['imu']
            pending.add(buf, lengths, self._logs('imu', count, t, end))
        if len(got) == ('imu' in got):
            return
        pending.flush()               # the other roles' blocks come after the main ones
        before = None
        if floating and 'temperature' in got:
            codes = np.frombuffer(row[-1].encode('ascii'), dtype=np.uint8)
            mains = np.cumsum(codes == ord(_CODES['imu']))
            before = out.n_main - int(mains[-1]) + mains[codes == ord(_CODES['temperature'])]
        for role in roles:
            if role == 'imu' or role not in got:
                continue
            count, buf, lengths = got[role]
            out.other(role, _split(buf, lengths), None, before if role == 'temperature'
                      else None, fetch_logs=self._logs(role, count, t, end))


class _McapBlocks:
    """
    One mcap storage file read chunk by chunk through its index.

    rosbags merges the chunks by log time (ties by chunk offset), each chunk's messages in
    a stable sort by log time, those outside the chunk's indexed time span dropped; when
    the chunks' spans follow each other in file order, that is the chunks one after the
    other, which is what this reads. Message records of one size that follow each other are
    located and cut out with numpy, a run at a time.
    """

    def __init__(self, storage: McapReader, roles: Mapping[int, str], src: Source,
                 out: Any, update: Callable[[int], Any]) -> None:
        self.storage, self.roles = storage, dict(roles)
        self.src, self.out, self.update = src, out, update
        self.codes = {role: k for k, role in enumerate(out.roles)}

    def run(self) -> None:
        storage = self.storage
        if not storage.chunks:
            raise Unfit('an mcap file without a chunk index')
        chunks = sorted((c for c in storage.chunks
                         if any(c.channel_count.get(cid, 0) for cid in self.roles)),
                        key=lambda c: c.chunk_start_offset)
        for a, b in zip(chunks, chunks[1:]):
            if not (a.chunk_start_offset < b.chunk_start_offset
                    and a.message_end_time <= b.message_start_time):
                raise Unfit('mcap chunks overlap in time')
        pending = _Pending(self.out, self.src.chunk)
        for chunk in chunks:
            self._chunk(chunk, pending)
        pending.flush()

    def _records(self, raw: bytes) -> list[tuple[int, int, int]]:
        """Return the runs of message records of ``raw``: (start, record size, count)."""
        size = len(raw)
        arr = np.frombuffer(raw, dtype=np.uint8)
        runs = []
        pos = 0
        while pos < size:
            if pos + 9 > size:
                raise Unfit('a chunk record cut short')
            length = int.from_bytes(raw[pos + 1:pos + 9], 'little')
            if raw[pos] != 0x05:
                pos += 9 + length             # rosbags skips it (even past the end)
                continue
            rec = 9 + length
            if length < 22 or pos + rec > size:
                raise Unfit('a message record cut short')
            head = arr[pos:pos + 9]
            n, w = 1, 64
            while True:                       # records of the same size and opcode
                m = min(w, (size - pos) // rec - n)
                if m <= 0:
                    break
                block = arr[pos + n * rec:pos + (n + m) * rec].reshape(m, rec)[:, :9]
                same = (block == head).all(axis=1)
                k = m if same.all() else int(np.argmin(same))
                n += k
                if k < m:
                    break
                w *= 4
            runs.append((pos, rec, n))
            pos += n * rec
        return runs

    def _chunk(self, chunk: Any, pending: _Pending) -> None:
        bio = self.storage.bio
        bio.seek(chunk.chunk_start_offset + 9 + 24)
        crc = int.from_bytes(read_exact(bio, 4), 'little')
        bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
        raw = decompress(read_exact(bio, chunk.compressed_size), chunk.compression,
                         chunk.uncompressed_size, crc)
        arr = np.frombuffer(raw, dtype=np.uint8)
        ids = np.zeros(1 << 16, dtype=np.int8) - 1         # channel id -> role code
        for cid, role in self.roles.items():
            ids[cid] = self.codes[role]
        pieces = []                                        # (rows view, code, logs)
        for pos, rec, n in self._records(raw):
            rows = arr[pos:pos + n * rec].reshape(n, rec)
            channel = rows[:, 9:11].copy().view('<u2').ravel()
            logs = rows[:, 15:23].copy().view('<u8').ravel()
            if logs.size and int(logs.max()) >= 1 << 63:
                raise Unfit('log times beyond int64')
            logs = logs.astype(np.int64)
            code = ids[channel]
            keep = ((code >= 0) & (logs >= chunk.message_start_time)
                    & (logs <= chunk.message_end_time))
            if keep.any():
                pieces.append((rows[keep] if not keep.all() else rows, code[keep], logs[keep]))
        if not pieces:
            return
        codes = np.concatenate([p[1] for p in pieces])
        logs = np.concatenate([p[2] for p in pieces])
        self.update(len(codes))
        main = self.codes['imu']
        # Every other message's bytes, log time and place in the chunk's order.
        others: list[tuple[int, bytes]] = []
        if np.any(logs[1:] < logs[:-1]):
            # rosbags' stable sort of the chunk by log time: message by message (rare).
            order = np.argsort(logs, kind='stable')
            data = [bytes(r[31:]) for p in pieces for r in p[0]]
            codes, logs = codes[order], logs[order]
            data = [data[i] for i in order.tolist()]
            idx = np.flatnonzero(codes == main).tolist()
            if idx:
                parts = [data[i] for i in idx]
                pending.add(b''.join(parts), np.fromiter(map(len, parts), dtype=np.int64,
                                                         count=len(parts)), logs[idx])
            others = [(i, data[i]) for i in np.flatnonzero(codes != main).tolist()]
        else:
            at = 0
            for rows, code, log in pieces:
                is_main = code == main
                if is_main.any():
                    sel = rows if is_main.all() else rows[is_main]
                    pending.add(np.ascontiguousarray(sel[:, 31:]).tobytes(),
                                np.full(len(sel), rows.shape[1] - 31, dtype=np.int64),
                                log[is_main])
                others += [(at + i, bytes(rows[i, 31:]))
                           for i in np.flatnonzero(~is_main).tolist()]
                at += len(code)
        if not others:
            return
        pending.flush()               # the other roles' blocks come after the main ones
        mains = np.cumsum(codes == main)
        first = self.out.n_main - int(mains[-1])
        where = np.fromiter((i for i, _ in others), dtype=np.int64, count=len(others))
        for role in self.out.roles:
            k = self.codes[role]
            if role == 'imu':
                continue
            mine = np.flatnonzero(codes[where] == k)
            if not mine.size:
                continue
            pos = where[mine]
            before = (first + mains[pos] if role == 'temperature' and self.out.floating
                      else None)
            self.out.other(role, [others[i][1] for i in mine.tolist()], logs[pos], before)
