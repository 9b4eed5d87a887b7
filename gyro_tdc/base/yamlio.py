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
Bounded YAML reading: every YAML file the package reads goes through :func:`read_yaml`.

The file size, the nesting depth, aliases and the node count are checked on the parser's
event stream before the document is built, so a nesting or alias bomb is refused in one
line naming the file, the line and the limit. See ``doc/internals/base.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import stat
from typing import Any

from gyro_tdc.errors import GyroTdcError
import yaml

__all__ = ['BAG_METADATA_LIMITS', 'SCENARIO_LIMITS', 'YamlLimits', 'load_yaml', 'read_text',
           'read_yaml']

_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
_OPEN = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
_CLOSE = (yaml.MappingEndEvent, yaml.SequenceEndEvent)


@dataclass(frozen=True)
class YamlLimits:
    """Hard limits of one kind of YAML file, checked before the document is built."""

    #: Kind of file, for messages (e.g. ``'model file'``).
    what: str
    #: Largest file size, bytes.
    max_bytes: int = field(kw_only=True)
    #: Deepest nesting of mappings and sequences.
    max_depth: int = field(kw_only=True)
    #: Most nodes, an alias counting as the size of the node it repeats.
    max_nodes: int = field(kw_only=True)
    #: Whether anchors and aliases (``&a`` / ``*a``) are allowed at all.
    aliases: bool = field(kw_only=True)


# Scenario files and rosbag2 metadata.yaml may use anchors and aliases; their expansion is
# counted. (Model files have their own, stricter limits in gyro_tdc.model.modelfile.)
SCENARIO_LIMITS = YamlLimits('scenario file', max_bytes=4 * 1024 * 1024, max_depth=64,
                             max_nodes=1_000_000, aliases=True)
BAG_METADATA_LIMITS = YamlLimits('bag metadata file', max_bytes=16 * 1024 * 1024,
                                 max_depth=64, max_nodes=2_000_000, aliases=True)


def _line(event: Any) -> str:
    """Return ' at line N' for an event (empty when it has no mark)."""
    mark = getattr(event, 'start_mark', None)
    return f' at line {mark.line + 1}' if mark is not None else ''


def _check_events(text: str, limits: YamlLimits, source: str,
                  error: type[GyroTdcError]) -> None:
    """Walk the event stream once and raise ``error`` at the first limit exceeded."""
    total = 0
    sizes: dict[str, int] = {}          # anchor -> expanded size of its node
    open_: list[list] = []              # per open collection: [anchor, expanded size]
    for event in yaml.parse(text, Loader=_LOADER):
        kind = type(event)
        if kind in _CLOSE:
            anchor, size = open_.pop()
        elif kind in _OPEN or kind in (yaml.ScalarEvent, yaml.AliasEvent):
            alias = kind is yaml.AliasEvent
            if kind in _OPEN and len(open_) >= limits.max_depth:
                raise error(f'{source}: nesting deeper than {limits.max_depth} levels'
                            f'{_line(event)} (the limit of a {limits.what})')
            if event.anchor is not None and not limits.aliases:
                raise error(f'{source}: YAML {"alias *" if alias else "anchor &"}{event.anchor}'
                            f'{_line(event)}: anchors and aliases are not allowed in a '
                            f'{limits.what}')
            if alias and any(frame[0] == event.anchor for frame in open_):
                raise error(f'{source}: recursive YAML alias *{event.anchor}{_line(event)}')
            size = sizes.get(event.anchor, 1) if alias else 1
            if (total := total + size) > limits.max_nodes:
                raise error(f'{source}: more than {limits.max_nodes} YAML nodes'
                            + (' (aliases expanded)' if limits.aliases else '')
                            + f'{_line(event)} (the limit of a {limits.what})')
            if kind in _OPEN:
                open_.append([event.anchor, 1])
                continue
            anchor = None if alias else event.anchor
        else:
            continue
        # A node is complete (a collection closed, a scalar, an alias): its anchor's size is
        # known and its parent holds it.
        if anchor is not None:
            sizes[anchor] = size
        if open_:
            open_[-1][1] += size


def load_yaml(text: str, limits: YamlLimits, *, source: str = '<string>',
              error: type[GyroTdcError] = GyroTdcError) -> Any:
    """
    Parse one YAML document ``text`` within ``limits`` (safe types only); None when empty.

    Raises
    ------
    GyroTdcError
        As ``error`` (a subclass), in one line naming ``source``: a limit exceeded.
    yaml.YAMLError
        Invalid YAML (the caller words it; :func:`read_yaml` raises ``error``).

    """
    size = len(text.encode('utf-8', errors='surrogatepass'))
    if size > limits.max_bytes:
        raise error(f'{source}: {size} bytes, more than the {limits.max_bytes}-byte limit of '
                    f'a {limits.what}')
    _check_events(text, limits, source, error)
    return yaml.load(text, Loader=_LOADER)


def read_text(path: str | os.PathLike, max_bytes: int, what: str,
              error: type[GyroTdcError] = GyroTdcError, *, regular: bool = False
              ) -> tuple[str, os.stat_result]:
    """
    Return a UTF-8 file's text, read within ``max_bytes`` (its size checked first), and its stat.

    ``regular``: never through a symbolic link, never waiting on a FIFO, a regular file only.
    Raises ``error`` in one line naming the file and ``what`` it is: unreadable, not a
    regular file, too large, or not UTF-8.
    """
    extra = os.O_NOFOLLOW | os.O_NONBLOCK if regular else 0
    try:
        with open(path, 'rb', opener=lambda p, flags: os.open(p, flags | extra)) as stream:
            st = os.fstat(stream.fileno())
            if regular and not stat.S_ISREG(st.st_mode):
                raise error(f'{path}: not a regular file')
            if st.st_size > max_bytes:
                raise error(f'{path}: {st.st_size} bytes, more than the {max_bytes}-byte limit '
                            f'of a {what}')
            data = stream.read(max_bytes + 1)
    except OSError as exc:
        raise error(f'{path}: cannot read {what}: {exc.strerror or exc}') from None
    if len(data) > max_bytes:
        raise error(f'{path}: more than the {max_bytes}-byte limit of a {what}')
    try:
        return data.decode('utf-8'), st
    except UnicodeDecodeError:
        raise error(f'{path}: not a text (UTF-8) {what}') from None


def read_yaml(path: str | os.PathLike, limits: YamlLimits, *,
              error: type[GyroTdcError] = GyroTdcError) -> Any:
    """
    Read and parse a YAML file within ``limits``, the size checked before reading.

    Returns the document (None when empty). Raises ``error`` (a
    :class:`~gyro_tdc.errors.GyroTdcError` subclass) in one line naming the file: unreadable,
    not UTF-8, too large, malformed, or over a limit.
    """
    path = Path(path)
    text = read_text(path, limits.max_bytes, limits.what, error)[0]
    try:
        return load_yaml(text, limits, source=str(path), error=error)
    except yaml.YAMLError as exc:       # on one line
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark is not None else ''
        problem = getattr(exc, 'problem', None) or type(exc).__name__
        raise error(f'{path}: malformed YAML{where}: {" ".join(str(problem).split())}') from None
