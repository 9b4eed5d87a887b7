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
A rosbag2 directory's ``metadata.yaml``: where the bag is, its topics, and checks of its counts.

The counts size every column of :func:`gyro_tdc.data.bag.reader.read_bag`, so they are checked
against what the storage files can hold before anything is allocated (:func:`check_counts`).
:func:`entries` reads the topic entries as rosbags' reader does and refuses, with
:class:`Unfit`, what rosbags refuses: the columnar read then
leaves the bag to rosbags.
"""

from __future__ import annotations

from pathlib import Path, PurePath
import re
import sys
from typing import Any, Mapping, NamedTuple

from gyro_tdc.base import BAG_METADATA_LIMITS, load_yaml
from gyro_tdc.data.bag.codec import N_DOUBLES
from gyro_tdc.data.imu_cdr import FRAME_ID
from gyro_tdc.errors import DatasetError
import yaml

if sys.version_info >= (3, 14):
    from compression import zstd
else:                         # rosbags' own zstd before Python 3.14
    from backports import zstd

__all__ = ['check_counts', 'describe', 'entries', 'Entry', 'find', 'has_metadata', 'load',
           'locate', 'min_message_bytes', 'missing', 'qos', 'STORAGE_SUFFIXES', 'storage_bytes',
           'storage_files', 'storage_paths', 'topics_of', 'ZSTD_MAX_RATIO', 'Unfit', 'zstd',
           'ZSTD_MAGIC', 'ZSTD_MIN_FRAME_BYTES']

#: Smallest zstd frame (magic, frame header, one block header): a message compressed on its
#: own (``compression_mode: message``) takes at least this many bytes.
ZSTD_MIN_FRAME_BYTES = 9
#: The first bytes of a zstd frame.
ZSTD_MAGIC = b'\x28\xb5\x2f\xfd'
#: Largest expansion of zstd (a 4-byte RLE block stands for up to 128 KiB): a storage file
#: compressed whole (``compression_mode: file``) holds at most this many bytes per byte.
ZSTD_MAX_RATIO = 32768
# The newest metadata version rosbags reads (Jazzy writes 9).
_VERSION = 9


class Unfit(Exception):
    """The columnar read does not apply to this bag: rosbags' reader reads it."""


#: The keys rosbag2 requires of metadata.yaml, with the version that brought each (yaml.hpp).
_REQUIRED = (('version', 0), ('storage_identifier', 0), ('duration', 0), ('starting_time', 0),
             ('message_count', 0), ('topics_with_message_count', 0), ('relative_file_paths', 0),
             ('compression_format', 3), ('compression_mode', 3), ('files', 5),
             ('custom_data', 6), ('ros_distro', 8))
#: A split storage file as rosbag2 names it (``NAME_N``), as ``ros2 bag reindex`` finds them.
_SPLIT = re.compile(r'.+_(\d+)')
STORAGE_SUFFIXES = ('.db3', '.mcap')


def has_metadata(folder: Path) -> bool:
    """Return whether ``folder`` holds a metadata.yaml (an empty one is none: cut as written)."""
    meta = folder / 'metadata.yaml'
    return meta.is_file() and meta.stat().st_size > 0


def missing(folder: Path) -> str | None:
    """
    Return what is wrong with a folder's metadata.yaml for a read, or None when nothing is.

    'no metadata.yaml', 'an empty metadata.yaml', or 'a damaged metadata.yaml (why)': one
    that is no YAML or lacks a key rosbag2 requires of its version (cut while rosbag2 wrote
    it on close). One over a size or nesting limit is not damaged: its read says so.
    """
    return _read(folder)[0]


def _read(folder: Path) -> tuple[str | None, Mapping]:
    """Return what :func:`missing` says and the metadata read on the way (none: empty)."""
    if not (folder / 'metadata.yaml').is_file():
        return 'no metadata.yaml', {}
    if not has_metadata(folder):
        return 'an empty metadata.yaml', {}
    try:
        info = load(folder)
    except (yaml.YAMLError, UnicodeDecodeError):
        return 'a damaged metadata.yaml (not valid YAML)', {}
    except (DatasetError, OSError):
        return None, {}                      # load() says what is wrong
    version = info.get('version')
    version = version if type(version) is int else 0
    lacks = [k for k, since in _REQUIRED if since <= version and k not in info]
    return (f'a damaged metadata.yaml (no {lacks[0]})' if lacks else None), info


def storage_files(folder: Path) -> list[Path]:
    """
    Return the storage files of a folder that holds nothing else, as ``ros2 bag reindex`` does.

    ``NAME_N.db3`` / ``NAME_N.mcap`` by N (rosbag2's), and ``FOLDER.db3`` / ``.mcap``
    (rosbags' writer's name); SQLite's own ``-wal``, ``-shm`` and ``-journal`` files may
    stand beside them. Anything else there: none (a folder of other things, walked).
    """
    found, other = [], False
    for p in folder.iterdir():
        if p.suffix in STORAGE_SUFFIXES and p.is_file() and (
                _SPLIT.fullmatch(p.stem) or p.stem == folder.name):
            found.append(p)
        else:
            other |= p.name != 'metadata.yaml' and not p.name.endswith(
                ('-wal', '-shm', '-journal'))
    return [] if other else sorted(found, key=lambda p: (
        int(m[1]) if (m := _SPLIT.fullmatch(p.stem)) else -1, p.name))


def locate(path: str | Path) -> tuple[Path, list[Path] | None]:
    """
    Return a bag (its directory, or a storage file alone) and its files without metadata.yaml.

    A recording cut off (the power went) has no metadata.yaml: rosbag2 writes it on close.
    Such a directory is a bag when it holds storage files named as rosbag2 names them (of
    one storage); a ``.db3`` or ``.mcap`` file without metadata.yaml beside it is a bag of
    that file alone. A damaged metadata.yaml (:func:`missing`) counts as none. Raises
    DatasetError saying why ``path`` is no bag.
    """
    return find(path)[:2]


def find(path: str | Path) -> tuple[Path, list[Path] | None, Mapping]:
    """Return :func:`locate`'s bag and files, and the metadata it read (none: empty)."""
    p = Path(path)
    if not p.exists():
        raise DatasetError(f'Bag {str(p)!r} does not exist.')
    if p.is_file():
        if p.suffix == '.bag':
            raise DatasetError(f'Bag {str(p)!r} is a ROS 1 bag; expected a rosbag2 directory '
                               '(convert it with rosbags-convert).')
        if p.suffix in STORAGE_SUFFIXES:
            why, info = _read(p.parent)
            return (p, [p], {}) if why else (p.parent, None, info)
        raise DatasetError(f'Bag {str(p)!r} is a file, not a rosbag2 directory (a folder '
                           'with metadata.yaml and .db3 or .mcap files).')
    files, (why, info) = storage_files(p), _read(p)
    if why is None or (has_metadata(p) and not files):
        return p, None, info      # a damaged one without storage files beside it: refused
    if not files:
        found = sorted(x.name for x in p.iterdir())[:5]
        raise DatasetError(f'Bag {str(p)!r} is not a rosbag2 directory: {why}, and not only '
                           f'storage files named NAME_N.db3 or NAME_N.mcap (found '
                           f'{found or "nothing"}).')
    if len({f.suffix for f in files}) > 1:
        raise DatasetError(f'Bag {str(p)!r} has {why} and holds both .db3 and .mcap files: '
                           'give the storage file to read.')
    return p, files, {}


def load(bag: Path) -> Mapping:
    """Return the ``rosbag2_bagfile_information`` of metadata.yaml (empty when absent)."""
    meta_path = bag / 'metadata.yaml'
    meta = load_yaml(meta_path.read_text(encoding='utf-8'), BAG_METADATA_LIMITS,
                     source=str(meta_path), error=DatasetError)
    info = meta.get('rosbag2_bagfile_information') if isinstance(meta, Mapping) else None
    return info if isinstance(info, Mapping) else {}


def min_message_bytes(msgtype: str) -> int:
    """
    Return the fewest bytes a serialized message of ``msgtype`` can take.

    The three recorded types are a header (CDR encapsulation, stamp, a ``frame_id`` of at
    least its NUL) and a run of float64 values; any other type at least its 4-byte CDR
    encapsulation.
    """
    return FRAME_ID + 1 + 8 * N_DOUBLES[msgtype] if msgtype in N_DOUBLES else 4


def _list(info: Mapping, key: str) -> list:
    """Return the list metadata.yaml gives under ``key`` (none: an empty one)."""
    return info[key] if isinstance(info.get(key), list) else []


def _folder(bag: Path) -> Path:
    """Return the folder of a bag's storage files (a storage file alone: its folder)."""
    return bag if bag.is_dir() else bag.parent


def storage_paths(bag: Path, info: Mapping) -> list[Path]:
    """Return the paths of the storage files metadata.yaml lists (beside it, by name)."""
    return [_folder(bag) / PurePath(str(name)).name
            for name in _list(info, 'relative_file_paths')]


def storage_bytes(bag: Path, info: Mapping) -> int | None:
    """Return the size of the storage files metadata.yaml lists, bytes (None: one is missing)."""
    try:
        return sum(path.stat().st_size for path in storage_paths(bag, info))
    except OSError:
        return None           # rosbags names the missing file


def check_counts(bag: Path, info: Mapping) -> None:
    """
    Check that the message counts of a bag's metadata are plausible, before any sizing.

    Every count (per topic, per file and in total) must be a whole number >= 0, and the
    topics together no more messages than the storage files can hold: each message takes
    at least :func:`min_message_bytes` of its type (at least ``ZSTD_MIN_FRAME_BYTES`` when
    compressed message by message; a file compressed whole, or an mcap file of compressed
    chunks, holds at most ``ZSTD_MAX_RATIO`` times its size).

    Parameters
    ----------
    bag : Path
        The bag directory.
    info : Mapping
        Its ``rosbag2_bagfile_information`` (rosbags reports its topic counts unchecked).

    Raises
    ------
    DatasetError
        One line naming the bag, the count and why it cannot be true (a storage file cut
        short fails here too).

    """
    where = f'Cannot read bag {str(bag)!r} (unreadable or corrupt): metadata.yaml'
    fix = '`ros2 bag reindex` rebuilds metadata.yaml from the storage files'
    # (name, type, message_count) of every well-formed topic entry
    topics = [(str(meta.get('name')), str(meta.get('type')), e['message_count'])
              for e in _list(info, 'topics_with_message_count') if isinstance(e, Mapping)
              and isinstance(meta := e.get('topic_metadata'), Mapping) and 'message_count' in e]
    counts = ([(f'topic {name!r}', count) for name, _, count in topics]
              + [(f'file {f.get("path")!r}', f['message_count'])
                 for f in _list(info, 'files') if isinstance(f, Mapping) and 'message_count' in f]
              + ([('the bag', info['message_count'])] if 'message_count' in info else []))
    for what, count in counts:
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise DatasetError(f'{where} gives {what} a message_count of {count!r:.40}, not a '
                               f'whole number >= 0 ({fix}).')
    size = storage_bytes(bag, info)
    if size is None:
        return
    mode = str(info.get('compression_mode') or '').lower()
    # A storage file compressed whole, or an mcap file whose chunks are (zstd or lz4, which
    # metadata.yaml does not say), holds more than its size.
    packed = mode == 'file' or str(info.get('storage_identifier', '')) == 'mcap'
    room = size * ZSTD_MAX_RATIO if packed else size
    need = total = 0
    for name, msgtype, count in topics:
        each = ZSTD_MIN_FRAME_BYTES if mode == 'message' else min_message_bytes(msgtype)
        need, total = need + count * each, total + count
        if need > room:
            what = (f'topic {name!r} holds {count} messages' if count * each > room else
                    f'its topics hold {total} messages together (at least {need} bytes; '
                    f'topic {name!r}, the last counted, {count})')
            raise DatasetError(f'{where} says {what}, more than its {size} bytes of storage '
                               f'can hold (a {msgtype} message takes at least {each} bytes): '
                               f'the storage is truncated or the metadata wrong ({fix}).')


def describe(topics: Mapping[str, tuple[str, int]]) -> str:
    """Return 'name (type, N msgs), ...' for error messages."""
    return ', '.join(f'{k} ({t}, {c} msgs)' for k, (t, c) in sorted(topics.items())) or 'none'


def qos(value: Any) -> Any:
    """Return offered QoS profiles as plain data (storage files keep them as YAML text)."""
    return (load_yaml(value, BAG_METADATA_LIMITS, source='offered_qos_profiles',
                      error=DatasetError) if isinstance(value, str) else value) or []


class Entry(NamedTuple):
    """A connection: a topic entry of metadata.yaml, or a topic of one storage file."""

    id: int
    topic: str
    msgtype: str
    msgcount: int
    fmt: str
    qos: Any
    digest: str

    def same(self, other: Entry) -> bool:
        """Return whether a storage file's connection is this one, as rosbags matches them."""
        return (self.topic == other.topic and self.msgtype == other.msgtype
                and self.fmt == other.fmt and qos(self.qos) == qos(other.qos)
                and (not self.digest or not other.digest or self.digest == other.digest))


def entries(bag: Path, info: Mapping) -> list[Entry]:
    """
    Return the connections of metadata.yaml, refusing what rosbags' reader refuses.

    The storage plugin is :func:`gyro_tdc.data.bag.columnar.unfit`'s to check, first.

    Raises
    ------
    Unfit
        A version, compression or serialization rosbags does not read, a missing storage
        file or a missing key; rosbags' reader then says what is wrong.

    """
    try:
        if info['version'] > _VERSION:
            raise Unfit(f'metadata version {info["version"]!r:.20}')
        if any(not (_folder(bag) / PurePath(x).name).exists()
               for x in info['relative_file_paths']):
            raise Unfit('a storage file is missing')
        mode = info.get('compression_mode', '').lower()
        if mode not in ('', 'none') and info.get('compression_format') != 'zstd':
            raise Unfit('compression other than zstd')
        out = [Entry(k + 1, m['name'], m['type'], x['message_count'],
                     m['serialization_format'], m.get('offered_qos_profiles', []),
                     m.get('type_description_hash', ''))
               for k, x in enumerate(info['topics_with_message_count'])
               for m in [x['topic_metadata']]]
        _ = (info['duration']['nanoseconds'], info['starting_time']['nanoseconds_since_epoch'],
             info['message_count'])
    except (KeyError, TypeError, AttributeError) as err:
        raise Unfit(f'metadata.yaml: {type(err).__name__} {err}') from err
    if any(x.fmt != 'cdr' for x in out):
        raise Unfit('a serialization format other than cdr')
    return out


def topics_of(conns: list[Entry]) -> dict[str, tuple[str, int]]:
    """Return name -> (type, message count) of connections, as rosbags' ``topics`` has them."""
    out: dict[str, tuple[str, int]] = {}
    for c in sorted(conns, key=lambda x: x.topic):
        msgtype, count = out.get(c.topic, (c.msgtype, 0))
        out[c.topic] = (msgtype if msgtype == c.msgtype else '?', count + int(c.msgcount))
    return out
