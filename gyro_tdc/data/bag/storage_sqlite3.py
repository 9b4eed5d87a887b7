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
rosbag2's sqlite3 storage read through its documented schema with the standard ``sqlite3``.

Tables ``topics`` (id, name, type, serialization_format, offered_qos_profiles and, from
schema 4, type_description_hash), ``messages`` (id, topic_id, timestamp, data; indexed on
timestamp), ``schema`` (schema_version) and ``message_definitions`` (schema 4). rosbags
reads a file's messages ``ORDER BY timestamp`` through that index, ties by rowid; one query
per time range walks the same index and returns every role's messages end to end
(``group_concat``); two connections run the ranges, two at once.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from itertools import islice
from pathlib import Path
import sqlite3
import threading
from typing import Any, Callable, Iterator, Mapping, Sequence

from gyro_tdc.data.bag.metadata import Entry, Unfit, ZSTD_MAGIC
import numpy as np
from numpy.typing import NDArray

__all__ = ['Sqlite3File']

# Ranges asked ahead of the decode (two running, two waiting).
_AHEAD = 4
# One-byte role codes of the range query's order string (Float temperatures).
_CODES = {'imu': 'm', 'temperature': 't', 'reference': 'r'}


class Sqlite3File:
    """
    One sqlite3 storage file, opened read-only: its connections and message definitions.

    Parameters
    ----------
    path : Path
        The ``.db3`` file.

    Attributes
    ----------
    conns : list[Entry]
        Its topics (``msgcount`` 0: the counts of metadata.yaml are used, not a table scan).
    definitions : dict[str, tuple[str, str]]
        Message type -> (encoding, definition text) of the file's own definitions.

    """

    def __init__(self, path: Path) -> None:
        # Range queries run on connections of their own, opened from the same URI (feed).
        self.uri = f'{path.absolute().as_uri()}?mode=ro&immutable=1'
        self.db, self.path = sqlite3.connect(self.uri, uri=True, check_same_thread=False), path

    def load(self) -> None:
        """Read the topics and definitions (:func:`~.columnar.open_bag`: once it can close)."""
        db, path = self.db, self.path
        if db.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table' "
                      "AND name IN ('messages', 'topics')").fetchone() != (2,):
            raise Unfit(f'{path.name}: no messages and topics tables')
        if db.execute('PRAGMA table_info(schema)').fetchall():
            schema = (db.execute('SELECT schema_version FROM schema').fetchone() or (-1,))[0]
        else:
            schema = 1 + any(x[1] == 'offered_qos_profiles'
                             for x in db.execute('PRAGMA table_info(topics)').fetchall())
        cols = ('id, name, type, serialization_format'
                + (', offered_qos_profiles' if schema >= 2 else ", ''")
                + (', type_description_hash' if schema >= 4 else ", ''"))
        self.conns = [Entry(cid, topic, msgtype, 0, *rest) for cid, topic, msgtype, *rest
                      in db.execute(f'SELECT {cols} FROM topics ORDER BY id')]
        types = {c.msgtype for c in self.conns}
        self.definitions: dict[str, tuple[str, str]] = {}
        for name, encoding, text in (db.execute(
                'SELECT topic_type, encoding, encoded_message_definition '
                'FROM message_definitions ORDER BY id') if schema >= 4 else ()):
            if name in types:
                self.definitions.setdefault(name, (encoding, text))

    def counts(self) -> dict[int, tuple[int, int, int]]:
        """Return topic id -> (messages, first and last log time, ns), from the table."""
        return {k: (n, lo, hi) for k, n, lo, hi in self.db.execute(
            'SELECT topic_id, count(*), min(timestamp), max(timestamp) FROM messages '
            'GROUP BY topic_id')}

    def compressed(self) -> bool:
        """Return whether the first message is a zstd frame (compressed message by message)."""
        first = self.db.execute('SELECT substr(data, 1, 4) FROM messages LIMIT 1').fetchone()
        return first is not None and first[0] == ZSTD_MAGIC

    def close(self) -> None:
        """Close the database."""
        self.db.close()

    def _in(self, role: str | None = None) -> str:
        ids = (self.ids[role] if role else sorted(k for v in self.ids.values() for k in v))
        return f'topic_id IN ({",".join(str(int(k)) for k in ids)})'

    def _check_plan(self, query: str, what: str, params: Sequence[int] = ()) -> None:
        rows = self.db.execute(f'EXPLAIN QUERY PLAN {query}', tuple(params))
        plan = ' '.join(str(x[-1]) for x in rows)
        if f'USING INDEX {self.index}' not in plan or 'TEMP B-TREE' in plan:
            raise Unfit(f'{what} does not walk a timestamp index ({plan})')

    def _query(self, roles: Sequence[str], floating: bool) -> str:
        """
        Return the range query (parameters: start, end) after checking its plan.

        The aggregates take the rows in the order of the scan, which walks the timestamp
        index (``INDEXED BY``: ties by rowid), the order of rosbags' ``ORDER BY timestamp``.
        """
        cols = []
        for role in roles:
            f = f'FILTER (WHERE {self._in(role)})'
            cols += [f'count(*) {f}', f'min(length(data)) {f}',
                     f"CAST(group_concat(data, '') {f} AS BLOB)"]
        if floating:
            case = ' '.join(f'WHEN {self._in(r)} THEN {_CODES[r]!r}' for r in roles)
            cols.append(f"group_concat(CASE {case} END, '')")
        # The index on messages(timestamp), rosbag2's own: the only one there.
        found = [(row[1], [x[2] for x in self.db.execute(
                  'SELECT * FROM pragma_index_info(?)', (row[1],))])
                 for row in self.db.execute("PRAGMA index_list('messages')")]
        found = [(name, cols) for name, cols in found if cols[:1] == ['timestamp']]
        if len(found) != 1 or found[0][1] != ['timestamp'] or "'" in found[0][0]:
            raise Unfit(f'indexes on the timestamps {[x[1] for x in found]} (one expected)')
        self.index = found[0][0]
        query = (f'SELECT {", ".join(cols)} FROM messages INDEXED BY '
                 f"'{self.index}' WHERE {self._in()} AND timestamp >= ?1 AND timestamp < ?2")
        # rosbags' query of the file, and ours: both in timestamp-index order.
        self._check_plan(
            'SELECT topics.id, messages.timestamp, messages.data FROM messages JOIN topics '
            'ON messages.topic_id = topics.id WHERE topics.id IN '
            f'({",".join(str(k) for v in self.ids.values() for k in v)}) ORDER BY timestamp',
            "rosbags' query")
        self._check_plan(query, 'the range query', (0, 1))
        return query

    def feed(self, roles: Mapping[int, str], out: Any, update: Callable[[int], Any], *,
             chunk: int) -> None:
        """
        Hand the messages of ``roles`` (connection id -> role) to ``out``, a range at a time.

        The file is read by time ranges over its timestamp index, each of about ``chunk``
        messages of any topic (:meth:`_bounds`). Each range's query returns, per role, the
        count, the shortest message and the messages end to end; a role whose messages
        differ in size has their lengths fetched. SQLite runs a query without the
        interpreter lock, so two threads, each with its own connection, run the next ranges
        on the other cores while this one decodes the answers in order.
        """
        self.chunk = chunk
        self.ids = {role: sorted(k for k, r in roles.items() if r == role)
                    for role in out.roles if role in roles.values()}
        names = list(self.ids)
        floating = out.floating and 'temperature' in self.ids
        query, ranges = self._query(names, floating), self._bounds()
        local, dbs = threading.local(), []

        def ask(t: int, end: int) -> Any:
            if not hasattr(local, 'db'):          # a connection per thread
                local.db = sqlite3.connect(self.uri, uri=True, check_same_thread=False)
                dbs.append(local.db)
            return local.db.execute(query, (t, end)).fetchone()
        try:
            with ThreadPoolExecutor(2, thread_name_prefix='gyro_tdc sqlite3') as pool:
                asked = deque((r, pool.submit(ask, *r)) for r in islice(ranges, _AHEAD))
                while asked:
                    (t, end), answer = asked.popleft()
                    row = answer.result()
                    asked.extend((r, pool.submit(ask, *r)) for r in islice(ranges, 1))
                    count = sum(row[3 * j] for j in range(len(names)))
                    if count:
                        self._range(out, row, names, t, end, floating)
                        update(count)
        finally:
            for db in dbs:
                db.close()

    def _bounds(self) -> Iterator[tuple[int, int]]:
        """
        Yield time ranges of about ``chunk`` messages of any topic, from the timestamp index.

        Each range ends where the index holds ``chunk`` later timestamps: one covering-index
        query per range, a walk over the index alone, made as the ranges are asked.
        """
        # Two subqueries: each a single min() or max() that SQLite answers from the
        # timestamp index; min() and max() in one SELECT scan the whole table.
        t, hi = self.db.execute('SELECT (SELECT min(timestamp) FROM messages), '
                                '(SELECT max(timestamp) FROM messages)').fetchone()
        while t is not None:
            nxt = self.db.execute(
                f"SELECT timestamp FROM messages INDEXED BY '{self.index}' WHERE timestamp > ?1 "
                'ORDER BY timestamp LIMIT 1 OFFSET ?2', (t, self.chunk - 1)).fetchone()
            yield t, hi + 1 if nxt is None else nxt[0]
            t = None if nxt is None else nxt[0]

    def _column(self, what: str, role: str, count: int, t: int, end: int
                ) -> NDArray[np.int64]:
        """Return ``what`` (an SQL expression) of a role's messages of a range, in order."""
        return np.fromiter((x for (x,) in self.db.execute(
            f'SELECT {what} FROM messages WHERE {self._in(role)} AND timestamp >= ?1 '
            'AND timestamp < ?2 ORDER BY timestamp, rowid', (t, end))),
            dtype=np.int64, count=count)

    def _range(self, out: Any, row: Sequence[Any], roles: Sequence[str], t: int, end: int,
               floating: bool) -> None:
        """Hand over the messages of one range (``row``: the range query's answer)."""
        got = {}
        for k, role in enumerate(roles):
            count, small, buf = row[3 * k:3 * k + 3]
            if not count:
                continue
            if buf is None:
                raise Unfit(f'{role}: no blobs in a range')
            # None shorter than the shortest: all of that length exactly when they add up.
            lengths = (np.full(count, small, dtype=np.int64) if count * small == len(buf)
                       else self._column('length(data)', role, count, t, end))
            if len(buf) != int(lengths.sum()):
                raise Unfit(f'{role}: the blobs of a range do not add up')
            got[role] = (count, buf, lengths)
        before = None
        if floating and 'temperature' in got:
            codes = np.frombuffer(row[-1].encode('ascii'), dtype=np.uint8)
            mains = np.cumsum(codes == ord(_CODES['imu']))
            before = out.n_main + mains[codes == ord(_CODES['temperature'])]
        for role, (count, buf, lengths) in got.items():     # the main messages first
            # The log times, fetched only where a message needs them.
            out.add(role, buf, lengths, partial(self._column, 'timestamp', role, count, t, end),
                    before)
