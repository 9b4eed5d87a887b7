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
The learner's ``learn_file``: the state (:mod:`gyro_tdc.learn.codec`) read and written as JSON.

:class:`LearnFile` reads (bounded) and writes (atomically, never over a file that is not a
learner state, never through a symbolic link) one file, and :func:`open_learn_file` picks
the file a node learns into. A learned model is a model: :func:`model_from_file` gives a
learn_file's current model and :func:`read_model` takes a model file, a shipped model's name
or a learn_file alike. The rules: ``doc/internals/learn.md``.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import json
import os
from pathlib import Path
import re
import stat
from typing import Any, Callable

from gyro_tdc.base import atomic_write, model_path, read_text
from gyro_tdc.errors import LearnFileError, ModelFileError, OutputError
from gyro_tdc.learn.codec import decode_state, FORMAT
from gyro_tdc.learn.fit import model_of
from gyro_tdc.model import CompensationModel, load_model
import numpy as np

__all__ = ['ALTERNATE_SUFFIX', 'dumps', 'is_learn_file', 'LearnFile', 'MAX_BYTES', 'MAX_DEPTH',
           'model_from_file', 'Opened', 'open_learn_file', 'read_model']

#: Largest learn_file read, bytes (checked before reading). A full state (300 bins of 8
#: entries, three recent stretches of :data:`RECENT_ROWS` windows each) takes under 3 MiB.
MAX_BYTES = 4 * 1024 * 1024
#: Deepest nesting of lists and objects read (a learner's state nests 4 deep).
MAX_DEPTH = 16
#: Added to a refused learn_file's name for the file learned into instead.
ALTERNATE_SUFFIX = '.gyro_tdc-learn.json'
#: Bytes read to tell a learn_file from a model file (its ``format`` is on the second line).
_HEAD = 512
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)


# -- the file ------------------------------------------------------------------------------


def dumps(state: dict[str, Any]) -> str:
    """
    Return ``state`` as the text of a learn_file: strict JSON, one top-level field a line.

    Raises
    ------
    OutputError
        A field holds NaN or an infinite value (nothing would read it back).

    """
    lines = []
    for key, value in state.items():
        try:
            text = json.dumps(value, separators=(',', ':'), allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise OutputError(f'learner state not written: field `{key}`: {exc}') from None
        lines.append(f'{json.dumps(str(key))}: {text}')
    return '{\n' + ',\n'.join(lines) + '\n}\n'


def _depth(text: str) -> int:
    """Return the deepest nesting of lists and objects in JSON ``text`` (strings skipped)."""
    a = np.frombuffer(_STRING.sub('', text).encode('utf-8', 'surrogatepass'), dtype=np.uint8)
    step = ((a == 0x5B) | (a == 0x7B)).astype(np.int64) - ((a == 0x5D) | (a == 0x7D))
    return int(np.cumsum(step).max(initial=0))


def _lstat(path: Path, fail: Callable[[object], Exception]) -> os.stat_result | None:
    """Return ``os.lstat(path)``; None when nothing is there, else ``fail(why)`` is raised."""
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise fail(exc.strerror or exc) from None


def _signature(st: os.stat_result) -> tuple[int, int, int, int]:
    """Return what tells one version of a file from another."""
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


class LearnFile:
    """
    One learn_file: read bounded, written only over a learner state this node read or wrote.

    Parameters
    ----------
    path : str or PathLike
        The file (a symbolic link is refused: neither read nor written through).

    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        #: Lines worth a warning from the last read or write (a mode given back to the owner).
        self.notes: list[str] = []
        self._mine: tuple[int, int, int, int] | None = None

    def _owner_rw(self, st: os.stat_result) -> bool:
        """Give the owner read and write permission when it lacks them (a note); return if so."""
        if (mode := stat.S_IMODE(st.st_mode)) & 0o600 == 0o600:
            return False
        try:
            os.chmod(self.path, mode | 0o600)   # a regular file: the caller checked (lstat)
        except OSError:
            return False
        self.notes.append(f'learn_file {str(self.path)!r} had mode {mode:04o}: set to '
                          f'{mode | 0o600:04o} (the node must read at start-up what it writes)')
        return True

    def read(self, *, fix_mode: bool = True) -> Any:
        """
        Return the JSON document in the file, or None when there is none.

        Refused before anything is parsed: a symbolic link, anything but a regular file, a
        file over :data:`MAX_BYTES` or nested deeper than :data:`MAX_DEPTH`. A file the owner
        (this node's user) may not read or write is given ``u+rw`` first (unless
        ``fix_mode`` is False: a reader that never writes it).

        Raises
        ------
        LearnFileError
            One line naming the file and why it cannot be a learner state.

        """
        p = self.path
        self._mine, self.notes = None, []
        if (st := _lstat(p, lambda why: LearnFileError(f'{p}: cannot read: {why}'))) is None:
            return None
        if stat.S_ISLNK(st.st_mode):
            to = ''
            with contextlib.suppress(OSError):
                to = f' to {os.readlink(p)!r:.80}'
            raise LearnFileError(f'{p}: a symbolic link{to}: not followed (set learn_file to '
                                 'the file itself)')
        if not stat.S_ISREG(st.st_mode):
            raise LearnFileError(f'{p}: not a regular file')
        if fix_mode and st.st_uid == os.geteuid():
            self._owner_rw(st)
        text, st = read_text(p, MAX_BYTES, 'learn_file', LearnFileError, regular=True)
        if _depth(text) > MAX_DEPTH:
            raise LearnFileError(f'{p}: not a learner state (nested deeper than {MAX_DEPTH} '
                                 'levels)')
        try:
            doc = json.loads(text)
        except RecursionError:
            raise LearnFileError(f'{p}: not a learner state (nested too deep)') from None
        except ValueError as exc:
            raise LearnFileError(f'{p}: not JSON ({" ".join(str(exc).split())[:120]})') from None
        self._mine = _signature(st)
        return doc

    def resume(self, load: Callable[[Any], None]) -> bool:
        """
        Give the file's state to ``load`` (a learner's ``load_state``); return whether any.

        Raises
        ------
        LearnFileError
            The file is not a learner state (:meth:`read`, or ``load`` refused it).

        """
        if (doc := self.read()) is None:
            return False
        try:
            load(doc)
        except LearnFileError as exc:
            self._mine = None
            raise LearnFileError(f'{self.path}: {exc}') from None
        return True

    def write(self, state: dict[str, Any]) -> None:
        """
        Write ``state`` atomically, never over something that is not a learner state.

        An existing file is replaced only when it is the version this object last read or
        wrote, or holds a learner state (its ``format``); a symbolic link or anything but a
        regular file is refused. The new file keeps the old one's mode, with ``u+rw``.

        Raises
        ------
        OutputError
            One line: the file is refused (kept as it is), the state is over
            :data:`MAX_BYTES` or holds a non-finite value, or the write failed.

        """
        p = self.path
        text = dumps(state)
        if (size := len(text.encode('utf-8'))) > MAX_BYTES:
            raise OutputError(f'cannot write learn_file {str(p)!r}: the state takes {size} '
                              f'bytes, more than the {MAX_BYTES}-byte limit it is read with')
        st = _lstat(p, lambda why: OutputError(f'cannot write learn_file {str(p)!r}: {why}'))
        if st is not None and _signature(st) != self._mine:
            kept = f'learn_file {str(p)!r} not overwritten, kept as it is'
            try:
                doc = LearnFile(p).read()
            except LearnFileError as exc:
                raise OutputError(f'{kept}: {exc}') from None
            if not (isinstance(doc, dict) and doc.get('format') == FORMAT):
                raise OutputError(f'{kept}: it is not a learner state ({FORMAT!r} expected)')
        atomic_write(p, text, what='learn_file', follow_symlinks=False)
        self.notes, self._mine = [], None
        with contextlib.suppress(OSError):      # unknown: the next write checks the file
            st = os.lstat(p)
            if self._owner_rw(st):
                st = os.lstat(p)
            self._mine = _signature(st)


@dataclass(frozen=True)
class Opened:
    """The file a learner learns into, as :func:`open_learn_file` chose it, and why."""

    #: Where the state is written; None when both candidates were refused (nothing is kept).
    file: LearnFile | None
    #: Whether a saved state was loaded.
    resumed: bool
    #: One line when ``learn_file`` itself was refused (kept as it is), else ''.
    warning: str
    #: Other lines worth a warning (a mode given back to the owner).
    notes: tuple[str, ...] = ()


def open_learn_file(path: str | os.PathLike, load: Callable[[Any], None]) -> Opened:
    """
    Resume from ``path`` and learn into it; when it is refused, keep it and use one beside it.

    ``load(document)`` is a learner's ``load_state`` (LearnFileError refuses). Learning goes
    to ``path`` when missing or a learner state, else to the file beside it named ``NAME`` +
    :data:`ALTERNATE_SUFFIX` (resumed when a learner state) with one warning line; no file
    when both are refused.
    """
    main = LearnFile(path)
    try:
        return Opened(main, main.resume(load), '', tuple(main.notes))
    except LearnFileError as exc:
        why = str(exc).removeprefix(f'{main.path}: ')
    alt = LearnFile(main.path.with_name(main.path.name + ALTERNATE_SUFFIX))
    kept = f'learn_file {str(path)!r} is kept as it is and not written ({why})'
    try:
        resumed = alt.resume(load)
    except LearnFileError as exc:
        why = str(exc).removeprefix(f'{alt.path}: ')
        return Opened(None, False, f'{kept}; {str(alt.path)!r} is refused too ({why}): '
                      'learning from the start, nothing is kept across restarts',
                      tuple(main.notes + alt.notes))
    where = 'resumed from' if resumed else 'from the start into'
    return Opened(alt, resumed, f'{kept}: learning {where} {str(alt.path)!r}',
                  tuple(main.notes + alt.notes))


def is_learn_file(path: str | os.PathLike) -> bool:
    """Return whether ``path`` is a regular file that starts as a learn_file does."""
    p = Path(path)
    try:
        if not p.is_file():
            return False
        with open(p, 'rb') as stream:
            head = stream.read(_HEAD)
    except OSError:
        return False
    text = head.decode('utf-8', 'replace').lstrip()
    return text.startswith('{') and f'"{FORMAT}"' in text


def model_from_file(path: str | os.PathLike) -> CompensationModel:
    """
    Return the model a learner would install on resuming from the learn_file ``path``.

    Read as the node resumes it (bounded, every field checked), never written; the model's
    ``created`` names the file and its last update.

    Raises
    ------
    ModelFileError
        The file is missing or holds no accepted model yet (one line: what it holds).
    LearnFileError
        The file is not a learner state.

    """
    p = Path(path)
    if (doc := LearnFile(p).read(fix_mode=False)) is None:
        raise ModelFileError(f'learn_file {str(p)!r} does not exist')
    values, thermal = decode_state(doc)
    if (fit := values['fit']) is None:
        points = sum(len(v) for v in values['bins'].values())
        raise ModelFileError(
            f'learn_file {str(p)!r} holds no accepted model yet ({points} points in '
            f'{len(values["bins"])} bins, {values["still_s"]:.0f} s still): learn longer, or '
            'give a model file')
    model = model_of(fit, thermal, values['prior'])
    return model.replace(created={**model.created, 'learn_file': str(p),
                                  'last_update_stamp_s': values['last_update_t'],
                                  'sessions': values['session'] + 1, 'points': fit['points']})


def read_model(spec: str | os.PathLike) -> CompensationModel:
    """
    Return the model of a model file, of a shipped model's name or of a learn_file.

    Raises
    ------
    ModelFileError
        No such file or name, a malformed model file, or a learn_file without a model.
    LearnFileError
        A file that starts as a learn_file but is not a learner state.

    """
    return model_from_file(spec) if is_learn_file(spec) else load_model(model_path(spec))
