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
Atomic output: every file and bag directory the package writes goes through here.

:func:`atomic_write` leaves either the old content or the complete new one (a new file with
the mode of a plain ``open``, an overwritten one keeping its mode, symbolic links written
through), :func:`atomic_json` so a JSON document; :func:`atomic_dir` builds a directory beside
its target and renames it into place.
A failure leaves nothing behind and is one :class:`~gyro_tdc.errors.OutputError` line.
See ``doc/internals/base.md``.
"""

from __future__ import annotations

from contextlib import contextmanager, suppress
import ctypes
import errno
import functools
import hashlib
import json
import logging
import os
from pathlib import Path
import re
import secrets
import shutil
import socket
import stat
from typing import Callable, IO, Iterator, Union

from gyro_tdc.errors import OutputError

__all__ = ['atomic_dir', 'atomic_json', 'atomic_write', 'clean_leftovers']

Content = Union[str, bytes, Callable[[IO], None]]
_NAME_MAX = 200     # characters of the target name kept in a temporary name
_HOST = hashlib.sha256(socket.gethostname().encode('utf-8', 'replace')).hexdigest()[:4]
# What follows '.NAME.' in a hidden sibling of ours: host, pid, random, kind.
_OWNED = re.compile(r'(?P<host>[0-9a-f]{4})-(?P<pid>[0-9]{1,10})-[0-9a-f]{8}\.(?P<kind>tmp|old)')
_RENAME_NOREPLACE, _RENAME_EXCHANGE = 1, 2
_AT_FDCWD = -100
_log = logging.getLogger(__name__)


def _describe(exc: OSError) -> str:
    """Return the OS error text (``strerror``) or the exception text."""
    return ' '.join(str(exc.strerror or exc).split())


def _fail(what: str, path: Path, exc: OSError) -> OutputError:
    """Return an OutputError for ``path`` on one line."""
    return OutputError(f'cannot write {what} {str(path)!r}: {_describe(exc)}')


def _fresh(directory: Path, name: str, make: Callable[[Path], object], kind: str = 'tmp'
           ) -> tuple[object, Path]:
    """
    Return ``make(tmp)`` for the first unused hidden name ``tmp`` beside ``name``, and it.

    The name is owned by this process (host, pid, random); ``make`` raises FileExistsError
    when it is taken; after 100 tries this does.
    """
    for _ in range(100):
        tmp = directory / (f'.{name[:_NAME_MAX]}.{_HOST}-{os.getpid()}-'
                           f'{secrets.token_hex(4)}.{kind}')
        try:
            return make(tmp), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f'no free temporary name beside {name!r}')


def _create_temp(directory: Path, name: str) -> tuple[int, Path]:
    """Create a new temporary file (mode 0666 & ~umask) and return its descriptor and path."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_CLOEXEC', 0)
    return _fresh(directory, name, lambda tmp: os.open(tmp, flags, 0o666))


def _unused(path: Path) -> None:
    """Raise FileExistsError when something is at ``path``."""
    if os.path.lexists(path):
        raise FileExistsError(errno.EEXIST, 'it exists already', str(path))


def _sync_dir(directory: Path) -> None:
    """Flush a directory entry to disk (best effort)."""
    with suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _alive(pid: int) -> bool:
    """Return True unless process ``pid`` certainly does not exist (this one counts as alive)."""
    if pid <= 0 or pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):
        pass                # another user's process, or a number no process can have
    return True


def clean_leftovers(path: str | os.PathLike) -> list[str]:
    """
    Remove what killed runs left beside ``path``; put a backup back when ``path`` is missing.

    A hidden sibling ``.NAME.HOST-PID-RANDOM.tmp`` (a temporary file or staging directory) or
    ``.old`` (the old output during a replacing write) whose process, on this host, no
    longer exists is removed; an ``.old`` backup is renamed back to ``path`` first when
    ``path`` does not exist (the run died between moving the old output aside and moving the
    new one in). Siblings of running processes are left alone. Those of another host and
    those that cannot be removed are reported on one warning line of the
    ``gyro_tdc.base.atomicio`` logger.

    Parameters
    ----------
    path : str or PathLike
        The output about to be written.

    Returns
    -------
    list of str
        One note per action taken (``removed ...``, ``restored ...``), for messages.

    """
    path = Path(path)
    prefix = f'.{path.name[:_NAME_MAX]}.'
    try:
        with os.scandir(path.parent) as entries:
            names = sorted(e.name for e in entries if e.name.startswith(prefix))
    except OSError:
        return []
    done, kept = [], []
    for name in names:
        if (owned := _OWNED.fullmatch(name[len(prefix):])) is None:
            continue
        if owned['host'] != _HOST:
            kept.append(name)           # another host's process: it may be running
            continue
        if _alive(int(owned['pid'])):
            continue
        leftover, backup = path.parent / name, owned['kind'] == 'old'
        try:
            if (backup and len(path.name) <= _NAME_MAX and not os.path.lexists(path)):
                os.rename(leftover, path)
                done.append(f'restored {str(path)!r} from {name!r} (a run was killed while '
                            'replacing it)')
                continue
            if os.path.isdir(leftover) and not os.path.islink(leftover):
                shutil.rmtree(leftover)
            else:
                os.unlink(leftover)
            done.append(f'removed {name!r} (left by a killed run)')
        except OSError as exc:
            kept.append(f'{name} ({_describe(exc)})')
    if kept:
        _log.warning('%d hidden leftover(s) of earlier runs beside %r not removed (owner '
                     'unknown, running elsewhere or not removable): %s; remove them when no '
                     'gyro_tdc run writes there', len(kept), str(path), ', '.join(kept))
    return done


def atomic_write(path: str | os.PathLike, content: Content, *, binary: bool = False,
                 what: str = 'file', encoding: str = 'utf-8',
                 newline: str | None = None, follow_symlinks: bool = True) -> Path:
    """
    Write a file atomically (temporary file beside it, fsync, rename).

    Leftovers of killed writes of the same file are removed first (:func:`clean_leftovers`).

    Parameters
    ----------
    path : str or PathLike
        The file to write (created with its parent directories, or replaced); a symbolic
        link is written through to its target.
    content : str, bytes or callable
        The content, or ``writer(stream)`` writing it to an open stream (text unless
        ``binary``; bytes content implies binary).
    binary : bool
        Give ``writer`` a binary stream.
    what : str
        What the file is, for messages (``'model file'``, ``'CSV file'``...).
    encoding : str
        Text encoding.
    newline : str, optional
        Newline translation of the text stream (as for :func:`open`).
    follow_symlinks : bool
        False: a symbolic link at ``path`` is replaced by the new file, its target left
        alone (the rename does not follow it, so a link put there meanwhile cannot redirect
        the write).

    Returns
    -------
    Path
        ``path`` as given (the link when it is one).

    Raises
    ------
    OutputError
        When the file cannot be written (the target is a directory, no space left,
        permission denied...); nothing is left behind and an existing file is unchanged.

    """
    path = Path(path)
    target = Path(os.path.realpath(path)) if follow_symlinks and os.path.islink(path) else path
    if target.is_dir() and (follow_symlinks or not os.path.islink(target)):
        raise OutputError(f'cannot access {what} {str(path)!r} for writing: it is a directory')
    clean_leftovers(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        old = None
        with suppress(FileNotFoundError):
            old = os.stat(target, follow_symlinks=follow_symlinks)
        if old is not None and stat.S_ISLNK(old.st_mode):
            old = None          # a link replaced by a file: a fresh file's mode
        fd, tmp = _create_temp(target.parent, target.name)
    except OSError as exc:
        raise _fail(what, path, exc) from None
    binary = binary or isinstance(content, bytes)
    try:
        try:
            if old is not None:
                if (old.st_uid, old.st_gid) != (os.geteuid(), os.getegid()):
                    with suppress(OSError):     # not permitted: ours, as with open()
                        os.fchown(fd, old.st_uid, old.st_gid)
                os.fchmod(fd, stat.S_IMODE(old.st_mode))
            stream = (os.fdopen(fd, 'wb') if binary
                      else os.fdopen(fd, 'w', encoding=encoding, newline=newline))
        except BaseException:
            os.close(fd)
            raise
        with stream:
            if callable(content):
                content(stream)
            else:
                stream.write(content)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with suppress(OSError):         # cleanup: the write's own error is the one raised
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _fail(what, path, exc) from None
        raise
    _sync_dir(target.parent)
    return path


def atomic_json(path: str | os.PathLike, doc: object, *, what: str = 'JSON file',
                indent: int | None = 1, **dumps: object) -> Path:
    """
    Write ``doc`` as JSON and a final newline with :func:`atomic_write`; return the path.

    The one JSON writer of the package: ``indent`` one space (None: one line) and ``dumps``
    the other options of ``json.dumps`` (``allow_nan=False``, ``ensure_ascii=False``).
    """
    return atomic_write(path, json.dumps(doc, indent=indent, **dumps) + '\n', what=what)


@functools.lru_cache(maxsize=1)
def _renameat2_func() -> Callable | None:
    """Return libc's ``renameat2``, or None (not Linux, or glibc older than 2.28)."""
    try:
        func = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return None
    func.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    func.restype = ctypes.c_int
    return func


def _renameat2(src: Path, dst: Path, flags: int) -> bool:
    """
    Rename with Linux ``renameat2`` flags; return False when the system cannot.

    Raises OSError for any other failure (``dst`` exists with ``RENAME_NOREPLACE``...).
    """
    if (func := _renameat2_func()) is None:
        return False
    if func(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False        # the kernel or this file system does not do it
    raise OSError(err, os.strerror(err), str(dst))


def _move_in(new: Path, path: Path, replace: bool) -> None:
    """
    Put the complete tree ``new`` at ``path``; an old ``path`` ends at ``new``.

    The old tree stays at ``path`` until the new one takes its place: swapped in one step
    where the system can, else moved to a backup beside it (restored when the second rename
    fails; after a kill between the two, restored by the next :func:`clean_leftovers`).
    """
    if not (replace and os.path.lexists(path)):
        if not _renameat2(new, path, _RENAME_NOREPLACE):
            _unused(path)
            os.rename(new, path)
        return
    if _renameat2(new, path, _RENAME_EXCHANGE):
        return              # ``new`` now names the old tree, removed with the staging dir
    _, backup = _fresh(path.parent, path.name, _unused, 'old')
    os.rename(path, backup)
    try:
        os.rename(new, path)
    except BaseException:
        os.rename(backup, path)
        raise
    os.rename(backup, new)


@contextmanager
def atomic_dir(path: str | os.PathLike, *, what: str = 'directory',
               replace: bool = False) -> Iterator[Path]:
    """
    Build a new directory out of sight and move it into place only when complete.

    The yielded path lies in a hidden staging directory beside ``path`` (leftovers of killed
    runs removed first); the caller creates it. On an exception the staging tree is removed.
    ``path`` must not exist unless ``replace`` (then swapped once the new tree is complete);
    ``what`` names the directory in messages (``'bag'``...).

    Raises
    ------
    OutputError
        ``path`` exists (without ``replace``) or cannot be created; any ``OSError``.

    """
    path = Path(path)
    clean_leftovers(path)
    if not replace and os.path.lexists(path):
        raise OutputError(f'cannot write {what} {str(path)!r}: it exists already')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _, staging = _fresh(path.parent, path.name, lambda tmp: os.mkdir(tmp, 0o700))
    except OSError as exc:
        raise _fail(what, path, exc) from None
    inner = staging / path.name
    try:
        yield inner
        _move_in(inner, path, replace)
    except OSError as exc:
        raise _fail(what, path, exc) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # empty, the replaced tree, or a failure's
    _sync_dir(path.parent)
