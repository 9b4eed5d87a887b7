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
rosbag2's mcap storage read through the documented MCAP format (https://mcap.dev/spec).

The summary section (found through the footer) lists the schemas, the channels and a chunk
index; each wanted chunk is decompressed once (zstd; lz4 is left to rosbags) and its message
records found with numpy. rosbags merges the chunks by log time (ties by chunk offset), each
chunk's messages in a stable sort by log time, those outside the chunk's indexed span
dropped; when the chunks' spans follow each other in file order, that is the chunks one
after the other, which is what this reads (anything else is :class:`Unfit`: rosbags reads).
A file without its footer (cut off while it was written: the power went), which rosbags
refuses, is scanned record by record up to its last whole chunk (``lost``: the bytes after
it), as the mcap libraries' fallback scan and ``mcap recover`` read it.
"""

from __future__ import annotations

from binascii import crc32
import contextlib
from functools import partial
from pathlib import Path
import struct
from typing import Any, Callable, Iterable, Mapping, NamedTuple

from gyro_tdc.data.bag.metadata import Entry, Unfit, zstd, ZSTD_MAGIC
import numpy as np
from numpy.typing import NDArray

__all__ = ['CUT_OFF', 'cut_off', 'McapFile']

_MAGIC = b'\x89MCAP0\r\n'
_FOOTER = b'\x02\x14\x00\x00\x00\x00\x00\x00\x00'     # opcode and length of the footer
_SCHEMA, _CHANNEL, _MESSAGE, _CHUNK_INDEX, _STATISTICS = 0x03, 0x04, 0x05, 0x08, 0x0B
_CHUNK, _DATA_END = 0x06, 0x0F
#: Bytes a file cut off may lose beyond twice its largest chunk (a chunk is written whole,
#: then its message indexes, at most as long); more is a damaged record, not a cut.
_CUT_SLACK = 1 << 16
_SUMMARY_END = (0x02, 0x0E)                            # footer, summary offset
#: What the warnings and refusals say of an mcap file cut off (the loss policy looks for it).
CUT_OFF = 'ends without the mcap footer'


def cut_off(paths: Iterable[Path]) -> str:
    """Return a hint naming the first mcap file of ``paths`` that ends without its magic ('')."""
    for path in (p for p in paths if p.suffix == '.mcap'):
        with contextlib.suppress(OSError), path.open('rb') as f:
            f.seek(max(f.seek(0, 2) - len(_MAGIC), 0))
            if f.read(len(_MAGIC)) != _MAGIC:
                return (f'; {path.name} {CUT_OFF} (cut off while it was written?): '
                        '`mcap recover` (the mcap CLI) copies what it holds to a new file')
    return ''


class _Chunk(NamedTuple):
    """A chunk index record (the fields this read uses)."""

    start: int                 # message_start_time, ns
    end: int                   # message_end_time, ns
    offset: int                # chunk_start_offset
    counts: dict[int, int]     # channel id -> messages, derived as rosbags derives it
    compression: str
    compressed_size: int
    uncompressed_size: int


class _Fields:
    """Little-endian fields read one after the other from a record's bytes."""

    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 0

    def take(self, fmt: str) -> tuple[Any, ...]:
        out = struct.unpack_from(fmt, self.data, self.pos)
        self.pos += struct.calcsize(fmt)
        return out

    def raw(self, size_fmt: str = '<I') -> bytes:
        (size,) = self.take(size_fmt)
        self.pos += size
        if self.pos > len(self.data):
            raise Unfit('an mcap record cut short')
        return self.data[self.pos - size:self.pos]

    def text(self) -> str:
        return self.raw().decode()


def _chunk_index(f: _Fields) -> _Chunk:
    """Parse a chunk index record: channel counts from the message index offsets."""
    start, end, offset, length = f.take('<QQQQ')
    index = f.raw()
    offsets = dict(struct.iter_unpack('<HQ', index[:len(index) // 10 * 10]))
    (index_length,) = f.take('<Q')
    compression = f.text()
    compressed, uncompressed = f.take('<QQ')
    # A message index record is 15 bytes plus 16 per message; its length is the distance to
    # the next one (the last one's to the end of the chunk's indexes).
    pairs = sorted((v, k) for k, v in offsets.items())
    ends = [v for v, _ in pairs[1:]] + [offset + length + index_length]
    counts = {k: (e - v - 15) // 16 for (v, k), e in zip(pairs, ends) if e - v - 15}
    return _Chunk(start, end, offset, counts, compression, compressed, uncompressed)


def _qos(metadata: bytes) -> str:
    """Return the offered_qos_profiles of a channel's metadata map ('' when absent)."""
    f = _Fields(metadata)
    while f.pos < len(metadata):
        key, value = f.text(), f.text()
        if key == 'offered_qos_profiles':
            return value
    return ''


class McapFile:
    """
    One mcap storage file: its connections, message definitions and chunk index.

    Attributes
    ----------
    conns : list[Entry]
        Its channels (``msgcount`` 0: the counts of metadata.yaml are used).
    definitions : dict[str, tuple[str, str]]
        Message type -> (encoding, definition text) of the file's schemas.

    """

    def __init__(self, path: Path) -> None:
        self.bio, self.name = path.open('rb'), path.name
        #: Bytes after the last whole chunk of a file cut off (None: the file is whole).
        self.lost: int | None = None
        self.conns: list[Entry] = []
        self.definitions: dict[str, tuple[str, str]] = {}
        self.chunks: list[_Chunk] = []

    def load(self) -> None:
        """Read the header, footer and summary (:func:`~.columnar.open_bag`: once it can close)."""
        bio = self.bio
        if bio.read(9) != _MAGIC + b'\x01':       # the magic, then a header record
            raise Unfit('not an mcap file with a header')
        (size,) = struct.unpack('<Q', self._exact(8, 9))     # the header record's length
        if _Fields(self._exact(size)).text() != 'ros2':
            raise Unfit('an mcap profile other than ros2')
        data_start = bio.tell()
        size = bio.seek(0, 2)
        bio.seek(max(size - 37, 0))
        footer = bio.read(37)
        if len(footer) != 37 or footer[:9] != _FOOTER or footer[-8:] != _MAGIC:
            self._scan(data_start, size)
            return
        (summary,) = struct.unpack_from('<Q', footer, 9)
        if not data_start <= summary <= size - 37:
            raise Unfit('an mcap file without a summary')
        bio.seek(summary)
        self._summary(bio.read(size - 37 - summary))

    def _exact(self, size: int, at: int | None = None) -> bytes:
        """Return ``size`` bytes read (from file offset ``at``), or raise Unfit."""
        if at is not None:
            self.bio.seek(at)
        data = self.bio.read(size)
        if len(data) != size:
            raise Unfit('an mcap record cut short')
        return data

    def _summary(self, data: bytes) -> None:
        """Parse the summary section's schemas, channels and chunk index."""
        schemas: dict = {}
        statistics = False
        f = _Fields(data)
        while True:
            if f.pos >= len(data):
                raise Unfit('an mcap summary cut short')
            (op,) = f.take('<B')
            if op in _SUMMARY_END:
                break
            body = f.raw('<Q')
            self._register(op, body, schemas)
            if op == _CHUNK_INDEX:
                self.chunks.append(_chunk_index(_Fields(body)))
            statistics |= op == _STATISTICS
        if statistics and not schemas:
            raise Unfit('an mcap summary without schemas')     # rosbags scans the file
        if not self.chunks:
            raise Unfit('an mcap file without a chunk index')

    def _register(self, op: int, body: bytes, schemas: dict) -> None:
        """Take a schema or a channel record (any other is left alone)."""
        rec = _Fields(body)
        if op == _SCHEMA:
            (key,) = rec.take('<H')
            schemas[key] = (rec.text(), rec.text(), rec.text())
        elif op == _CHANNEL:
            key, schema_id = rec.take('<HH')
            name, encoding, text = schemas.get(schema_id, ('__schemaless__', '', ''))
            topic, fmt, meta = rec.text(), rec.text(), rec.raw()
            if all(c.id != key for c in self.conns):
                self.conns.append(Entry(key, topic, name, 0, fmt, _qos(meta), ''))
                if schema_id in schemas:
                    self.definitions.setdefault(name, (encoding, text))

    def _scan(self, pos: int, size: int) -> None:
        """Read a file without its footer record by record, up to its last whole chunk."""
        schemas: dict = {}
        register, longest, ended = partial(self._register, schemas=schemas), 0, False
        while pos + 9 <= size:
            op, length = struct.unpack('<BQ', self._exact(9, pos))
            ended = op == _DATA_END           # what follows is the summary
            if ended or pos + 9 + length > size:
                break
            if op == _MESSAGE:
                raise Unfit('mcap messages outside chunks')
            if op == _CHUNK:
                head = _Fields(self._exact(min(length, 1 << 16), pos + 9))
                start, end, uncompressed, _ = head.take('<QQQI')
                compression = head.text()
                (compressed,) = head.take('<Q')
                c = _Chunk(start, end, pos, {}, compression, compressed, uncompressed)
                # Its schemas and channels taken, its messages counted per channel id.
                for rows in self.runs(self._decompress(c), register):
                    ids, n = np.unique(rows[:, 9:11].copy().view('<u2'), return_counts=True)
                    for key, k in zip(ids.tolist(), n.tolist()):
                        c.counts[key] = c.counts.get(key, 0) + k
                self.chunks.append(c)
                longest = max(longest, 9 + length)
            else:
                register(op, self._exact(length, pos + 9))
            pos += 9 + length
        if not self.chunks:
            raise Unfit('an mcap file cut off before its first whole chunk')
        if not ended and size - pos > 2 * longest + _CUT_SLACK:
            raise Unfit(f'an mcap file whose records stop {size - pos} bytes before its end')
        self.lost = size - pos

    def counts(self) -> dict[int, tuple[int, int, int]]:
        """Return channel id -> (messages, first and last log time, ns), from the chunks."""
        out: dict[int, tuple[int, int, int]] = {}
        for c in self.chunks:
            for key, n in c.counts.items():
                m, lo, hi = out.get(key, (0, c.start, c.end))
                out[key] = (m + n, min(lo, c.start), max(hi, c.end))
        return out

    def compressed(self) -> bool:
        """Return whether the first message is a zstd frame (compressed message by message)."""
        if not self.chunks or self.chunks[0].compression not in ('', 'zstd'):
            return False                      # lz4 chunks: rosbags reads them
        runs = self.runs(self._decompress(self.chunks[0]))
        return bool(runs) and runs[0][0, 31:35].tobytes() == ZSTD_MAGIC

    def close(self) -> None:
        """Close the file."""
        self.bio.close()

    def feed(self, roles: Mapping[int, str], out: Any, update: Callable[[int], Any], *,
             chunk: int) -> None:
        """Hand the messages of ``roles`` (channel id -> role) to ``out``, chunk by chunk."""
        chunks = sorted((c for c in self.chunks if any(c.counts.get(k, 0) for k in roles)),
                        key=lambda c: c.offset)
        for a, b in zip(chunks, chunks[1:]):
            if not (a.offset < b.offset and a.end <= b.start):
                raise Unfit('mcap chunks overlap in time')
        self.codes = {role: k for k, role in enumerate(out.roles)}
        self.ids = np.full(1 << 16, -1, dtype=np.int8)          # channel id -> role code
        self.ids[list(roles)] = [self.codes[role] for role in roles.values()]
        for c in chunks:
            self._chunk(self._decompress(c), c, out, update)

    def _decompress(self, c: _Chunk) -> bytes:
        """Return a chunk's records, checked against its size and checksum."""
        (crc,) = struct.unpack('<I', self._exact(4, c.offset + 9 + 24))
        data = self._exact(c.compressed_size, c.offset + 9 + 40 + len(c.compression))
        if c.compression == 'zstd':
            data = zstd.decompress(data)
        elif c.compression:           # lz4: rosbags reads it
            raise Unfit(f'chunk compression {c.compression!r:.20}')
        if len(data) != c.uncompressed_size or (crc and crc32(data) != crc):
            raise Unfit('a chunk of the wrong size or checksum')
        return data

    @staticmethod
    def runs(raw: bytes, other: Callable[[int, bytes], Any] | None = None
             ) -> list[NDArray[np.uint8]]:
        """Return the runs of message records of ``raw``, each (count, record size) bytes."""
        size = len(raw)
        arr = np.frombuffer(raw, dtype=np.uint8)
        runs = []
        pos = 0
        while pos < size:
            if pos + 9 > size:
                raise Unfit('a chunk record cut short')
            length = int.from_bytes(raw[pos + 1:pos + 9], 'little')
            if raw[pos] != _MESSAGE:
                if other is not None:     # other(opcode, body) takes it
                    other(raw[pos], raw[pos + 9:pos + 9 + length])
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
            runs.append(arr[pos:pos + n * rec].reshape(n, rec))
            pos += n * rec
        return runs

    def _chunk(self, raw: bytes, c: _Chunk, out: Any, update: Callable) -> None:
        """Hand over the wanted messages of one chunk, in rosbags' order."""
        pieces = []                                        # (rows, role codes, log times)
        for rows in self.runs(raw):
            code = self.ids[rows[:, 9:11].copy().view('<u2').ravel()]
            logs = rows[:, 15:23].copy().view('<u8').ravel()
            if logs.size and int(logs.max()) >= 1 << 63:
                raise Unfit('log times beyond int64')
            logs = logs.astype(np.int64)
            keep = (code >= 0) & (logs >= c.start) & (logs <= c.end)
            if keep.any():
                pieces.append((rows[keep] if not keep.all() else rows, code[keep], logs[keep]))
        if not pieces:
            return
        codes, logs = (np.concatenate([p[k] for p in pieces]) for k in (1, 2))
        update(len(codes))
        if np.any(logs[1:] < logs[:-1]):
            # rosbags sorts a chunk stably by log time: here message by message (rare, a
            # chunk written out of order), each its own piece.
            order = np.argsort(logs, kind='stable')
            single = [(rows[k:k + 1], code[k:k + 1], log[k:k + 1])
                      for rows, code, log in pieces for k in range(len(code))]
            pieces = [single[i] for i in order.tolist()]
            codes, logs = codes[order], logs[order]
        # The main messages go over piece by piece (the Collector gathers them), the others'
        # of the chunk in one block per role, each with the main messages before it.
        mains = out.n_main + np.cumsum(codes == self.codes['imu'])
        got: dict[str, list] = {role: [] for role in out.roles[1:]}
        at = 0
        for rows, code, log in pieces:
            for role in out.roles:
                mine = np.flatnonzero(code == self.codes[role])
                if mine.size:
                    sel = rows if mine.size == len(code) else rows[mine]
                    part = (np.ascontiguousarray(sel[:, 31:]).tobytes(),
                            np.full(mine.size, rows.shape[1] - 31, dtype=np.int64), log[mine],
                            mains[at + mine])
                    if role == 'imu':
                        out.add(role, *part)
                    else:
                        got[role].append(part)
            at += len(code)
        for role, parts in got.items():
            if parts:
                bufs, lengths, times, before = zip(*parts)
                out.add(role, b''.join(bufs), np.concatenate(lengths), np.concatenate(times),
                        np.concatenate(before))
