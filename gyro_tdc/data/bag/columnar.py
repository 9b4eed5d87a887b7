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

The bag is opened from its ``metadata.yaml`` (:mod:`~gyro_tdc.data.bag.metadata`) and its
storage files through their documented formats: sqlite3 with the standard ``sqlite3``
(:mod:`~gyro_tdc.data.bag.storage_sqlite3`), mcap record by record
(:mod:`~gyro_tdc.data.bag.storage_mcap`). The same messages as rosbags' reader, byte for
byte and in its order, decoded with the typestore rosbags' ``AnyReader`` would build; what
this does not take (:func:`unfit`, :class:`~gyro_tdc.data.bag.metadata.Unfit`) rosbags reads.
See ``doc/internals/data.md``.
"""

from __future__ import annotations

from contextlib import closing, contextmanager, ExitStack
from functools import lru_cache
from pathlib import Path
import shutil
import sqlite3
from tempfile import TemporaryDirectory
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

from gyro_tdc.data.bag.codec import jazzy
from gyro_tdc.data.bag.metadata import (entries, Entry, has_metadata, locate, missing,
                                        storage_paths, topics_of, Unfit, zstd)
from gyro_tdc.data.bag.storage_mcap import CUT_OFF, McapFile
from gyro_tdc.data.bag.storage_sqlite3 import Sqlite3File
from gyro_tdc.errors import DatasetError, one_line
from rosbags.typesys import get_types_from_idl, get_types_from_msg, get_typestore, Stores
import yaml

__all__ = ['Bag', 'open_bag', 'readable', 'rebuild', 'rebuilt_notes', 'unfit']

_FILES = {'sqlite3': Sqlite3File, 'mcap': McapFile}
# Message definition encodings of sqlite3 and mcap storage: 'msg' or 'idl' ('' is none).
_ENCODINGS = {'ros2msg': 'msg', 'ros2idl': 'idl', 'omgidl': 'idl', '': ''}
_IDL_SEPARATOR = '=' * 80 + '\n'


def unfit(info: Mapping) -> str | None:
    """Return why the columnar read does not take a bag with this metadata, or None."""
    storage = str(info.get('storage_identifier', ''))
    if storage not in _FILES:
        return f'storage {storage!r:.20}'
    return ('every message compressed on its own'
            if str(info.get('compression_mode') or '').lower() == 'message' else None)


@lru_cache(maxsize=8)
def _typestore(definitions: tuple[tuple[str, str, str, str], ...]) -> Any:
    """Return a typestore of (type, kind, text, digest) definitions, checking the digests."""
    typs: dict[str, Any] = {}
    for msgtype, kind, text, _ in definitions:
        if kind == 'msg':
            typs.update(get_types_from_msg(text, msgtype))
        elif text.startswith(f'{_IDL_SEPARATOR}IDL: '):
            for part in text.split(_IDL_SEPARATOR)[1:]:
                typs.update(get_types_from_idl(part.split('\n', 1)[1]))
        else:
            typs.update(get_types_from_idl(text))
    store = get_typestore(Stores.EMPTY)
    store.register(typs)
    for msgtype, _, _, digest in definitions:
        if digest and store.hash_rihs01(msgtype) != digest:
            raise Unfit(f'the definition of {msgtype} does not match its hash')
    return store


class Bag:
    """
    A bag opened for the columnar read.

    Attributes
    ----------
    conns : list[Entry]
        The connections of metadata.yaml.
    topics : dict[str, tuple[str, int]]
        Topic -> (type, message count), as rosbags' ``AnyReader.topics`` has them.
    files : list[Sqlite3File | McapFile]
        The storage files, in metadata.yaml's order.
    short : str or None
        After :meth:`feed`, on sqlite3: what it handed over of fewer messages than
        metadata.yaml lists (None: every one).

    """

    def __init__(self, conns: list[Entry], files: list[Any]) -> None:
        self.conns, self.files = conns, files
        self.short: str | None = None
        self.topics = topics_of(conns)

    def typestore(self, msgtypes: Iterable[str]) -> Any:
        """
        Return the types of ``msgtypes`` from the bag's own definitions, as AnyReader would.

        Jazzy's types where the bag has none. The other types' definitions are not parsed:
        one rosbags cannot parse (a service event's) stops nothing.
        """
        defs, wanted = [], set(msgtypes)
        for c in (c for c in self.conns if c.msgtype in wanted):
            found = [f.definitions[c.msgtype] for f in self.files if c.msgtype in f.definitions]
            found = [(_ENCODINGS.get(enc), text) for enc, text in found]
            if any(kind is None for kind, _ in found):
                raise Unfit(f'a message definition encoding of {c.msgtype} rosbags does not read')
            kind, text = next(((k, t) for k, t in found if k), ('', ''))
            if kind:
                defs.append((c.msgtype, kind, text, c.digest))
        return _typestore(tuple(defs)) if defs else jazzy()

    @property
    def warnings(self) -> tuple[str, ...]:
        """Return a warning per storage file cut off (an mcap file read to its last chunk)."""
        return tuple(f'{f.name} {CUT_OFF} (cut off while it was written): '
                     f'read to its last whole chunk, the {f.lost} bytes after it are lost'
                     for f in self.files if isinstance(f, McapFile) and f.lost is not None)

    def feed(self, conns: Mapping[str, Sequence[Entry]], out: Any,
             update: Callable[[int], Any], chunk: int) -> None:
        """
        Hand every wanted message to ``out`` (a ``Collector``), file after file.

        ``conns`` maps each role to its connections (of metadata.yaml), 'imu' first. A
        storage connection of a wanted topic that none of them matches (rosbags would skip
        its messages, or match them after normalising their QoS) is :class:`Unfit`.
        """
        wanted = [(c, role) for role, cs in conns.items() for c in cs]
        for f in self.files:
            roles = {}
            for x in f.conns:
                role = next((role for y, role in wanted if y.same(x)), None)
                if role is not None:
                    roles[x.id] = role
                elif any(y.topic == x.topic for y, _ in wanted):
                    raise Unfit(f'topic {x.topic!r} of a storage file is not as metadata.yaml '
                                'lists it')
            if roles:
                f.feed(roles, out, update, chunk=max(int(chunk), 1))
        # The sqlite3 read seeks its time ranges in the timestamp index, where rosbags walks
        # it end to end: a damaged index can hide messages from the seeks alone.
        if any(isinstance(f, Sqlite3File) for f in self.files):
            listed = {role: sum(int(c.msgcount) for c in cs) for role, cs in conns.items()}
            self.short = '; '.join(
                f'{out.received[role]} {role} messages of the {n} metadata.yaml lists'
                for role, n in listed.items() if out.received[role] < n) or None


@contextmanager
def open_bag(bag: Path, info: Mapping) -> Iterator[Bag]:
    """
    Open a bag's storage files for the columnar read (see :class:`Bag`).

    A storage compressed file by file is decompressed into a temporary directory first,
    as rosbags does. Raises :class:`Unfit` where rosbags' reader must decide.
    """
    conns = entries(bag, info)
    paths = storage_paths(bag, info)
    with ExitStack() as stack:
        if info.get('compression_mode', '').lower() == 'file':
            tmp = Path(stack.enter_context(TemporaryDirectory()))
            for k, path in enumerate(paths):
                paths[k] = tmp / path.stem
                with path.open('rb') as packed, zstd.open(packed, 'rb') as src, \
                        paths[k].open('wb') as dst:
                    shutil.copyfileobj(src, dst)
        files = []
        for path in paths:
            files.append(_FILES[info['storage_identifier']](path))
            stack.callback(files[-1].close)
            files[-1].load()              # a file refused is closed with the others
        yield Bag(conns, files)


def rebuild(bag: Path, paths: Sequence[Path]) -> dict:
    """
    Return the metadata.yaml of storage files that have none, as ``ros2 bag reindex`` does.

    Every topic with its messages counted in the files (a cut-off mcap file's up to its last
    whole chunk). Raises DatasetError naming the bag and why when a file cannot be read.
    """
    storage = 'sqlite3' if paths[0].suffix == '.db3' else 'mcap'
    topics: list[list] = []                        # [entry, messages]
    listed, spans, packed = [], [], False
    for path in paths:
        try:
            with closing(_FILES[storage](path)) as f:
                f.load()
                counts, packed = f.counts(), packed or f.compressed()
        except (Unfit, sqlite3.Error, OSError, ValueError, MemoryError) as err:
            fix = (f' (`sqlite3 {path.name} .recover | sqlite3 NEW/{path.name}` copies what '
                   'it holds to a new file)' if storage == 'sqlite3' else '')
            raise DatasetError(f'Cannot read bag {str(bag)!r} ({missing(path.parent)}): storage '
                               f'file {path.name} is unreadable or corrupt: {one_line(err)}{fix}'
                               ) from err
        for conn in f.conns:
            if (t := next((t for t in topics if t[0].same(conn)), None)) is None:
                topics.append(t := [conn, 0])
            t[1] += counts.get(conn.id, (0,))[0]
        # Stamps NULL or of another type (SQLite keeps what a damaged record says): damage.
        spans += [v[1:] for v in counts.values() if all(type(x) is int for x in v[1:])]
        listed.append({'path': path.name, 'message_count': sum(v[0] for v in counts.values())})
    start, end = (min(a for a, _ in spans), max(b for _, b in spans)) if spans else (0, 0)
    return {'version': 9, 'storage_identifier': storage,
            'relative_file_paths': [p.name for p in paths],
            'duration': {'nanoseconds': end - start},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(n for _, n in topics),
            'compression_format': 'zstd' if packed else '',
            'compression_mode': 'message' if packed else '',
            'topics_with_message_count': [
                {'topic_metadata': {'name': c.topic, 'type': c.msgtype,
                                    'serialization_format': c.fmt,
                                    'offered_qos_profiles': c.qos,
                                    'type_description_hash': c.digest},
                 'message_count': n} for c, n in topics],
            'files': listed}


def rebuilt_notes(paths: Sequence[Path]) -> tuple[str, ...]:
    """Return the warnings of a read of storage files without their metadata.yaml."""
    wal = [(p.name, w.stat().st_size) for p in paths
           if (w := p.with_name(p.name + '-wal')).is_file() and w.stat().st_size]
    folder = paths[0].parent
    # None or empty: never closed; a damaged one says why itself.
    why = missing(folder) if has_metadata(folder) else (
        f'{missing(folder)} (the recording did not close: rosbag2 writes it then)')
    return (f'{why}: read from {", ".join(p.name for p in paths)} as `ros2 bag reindex` would '
            'list it',
            *(f"{name}-wal: {size} bytes of SQLite's write-ahead log not read (the messages "
              f"written last; `sqlite3 {name} 'PRAGMA wal_checkpoint'` merges them into the "
              'file)' for name, size in wal))


@contextmanager
def readable(path: str | Path, info: Mapping | None = None) -> Iterator[Path]:
    """
    Yield a bag directory rosbags' reader opens: the bag's, or one with a rebuilt metadata.yaml.

    A bag without metadata.yaml (:func:`~gyro_tdc.data.bag.metadata.locate`) is given a
    temporary directory of links to its storage files beside its :func:`rebuild`
    metadata.yaml (``info``, where the caller has it); nothing is written into the bag.
    """
    bag, paths = locate(path)
    if paths is None:
        yield bag
        return
    info = rebuild(bag, paths) if info is None else info
    with TemporaryDirectory(prefix='gyro_tdc_bag_') as tmp:
        for p in paths:
            (Path(tmp) / p.name).symlink_to(p.absolute())
        (Path(tmp) / 'metadata.yaml').write_text(
            yaml.safe_dump({'rosbag2_bagfile_information': info}), encoding='utf-8')
        yield Path(tmp)
