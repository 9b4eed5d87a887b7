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
through); :func:`atomic_dir` builds a directory beside its target and renames it into place.
A failure leaves nothing behind and is one :class:`~gyro_tdc.errors.OutputError` line.
See ``doc/internals/base.md``.
"""

from __future__ import annotations

from contextlib import contextmanager
import errno
import os
from pathlib import Path
import secrets
import shutil
import stat
from typing import Callable, IO, Iterator, Union

from gyro_tdc.errors import OutputError

__all__ = ['atomic_dir', 'atomic_write']

Content = Union[str, bytes, Callable[[IO], None]]
_NAME_MAX = 200     # characters of the target name kept in a temporary name


def _describe(exc: OSError) -> str:
    """Return the OS error text (``strerror``) or the exception text."""
    return ' '.join(str(exc.strerror or exc).split())


def _fail(what: str, path: Path, exc: OSError) -> OutputError:
    """Return an OutputError for ``path`` on one line."""
    return OutputError(f'cannot write {what} {str(path)!r}: {_describe(exc)}')


def _temp_name(directory: Path, name: str) -> Path:
    """Return an unused hidden name beside ``name`` (not created)."""
    return directory / f'.{name[:_NAME_MAX]}.{secrets.token_hex(4)}.tmp'


def _create_temp(directory: Path, name: str) -> tuple[int, Path]:
    """Create a new temporary file (mode 0666 & ~umask) and return its descriptor and path."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_CLOEXEC', 0)
    for _ in range(100):
        tmp = _temp_name(directory, name)
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f'no free temporary name beside {name!r}')


def _unlink(path: Path) -> None:
    """Remove ``path`` if it exists (cleanup: errors are ignored)."""
    try:
        os.unlink(path)
    except OSError:
        pass


def _sync_dir(directory: Path) -> None:
    """Flush a directory entry to disk (best effort)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _target(path: Path) -> Path:
    """Return the file to replace: ``path``, or the final target when it is a symlink."""
    if os.path.islink(path):
        return Path(os.path.realpath(path))
    return path


def atomic_write(path: str | os.PathLike, content: Content, *, binary: bool = False,
                 what: str = 'file', encoding: str = 'utf-8',
                 newline: str | None = None) -> Path:
    """
    Write a file atomically (temporary file beside it, fsync, rename).

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
    target = _target(path)
    if target.is_dir():
        raise OutputError(f'cannot access {what} {str(path)!r} for writing: it is a directory')
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            old = os.stat(target)
        except FileNotFoundError:
            old = None
        fd, tmp = _create_temp(target.parent, target.name)
    except OSError as exc:
        raise _fail(what, path, exc) from None
    binary = binary or isinstance(content, bytes)
    try:
        try:
            if old is not None:
                if (old.st_uid, old.st_gid) != (os.geteuid(), os.getegid()):
                    try:
                        os.fchown(fd, old.st_uid, old.st_gid)
                    except OSError:
                        pass        # not permitted: the new file is ours, as with open()
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
    except OSError as exc:
        _unlink(tmp)
        raise _fail(what, path, exc) from None
    except BaseException:
        _unlink(tmp)
        raise
    _sync_dir(target.parent)
    return path


@contextmanager
def atomic_dir(path: str | os.PathLike, *, what: str = 'directory') -> Iterator[Path]:
    """
    Build a new directory out of sight and move it into place only when complete.

    Yields a path that does not exist yet, inside a hidden staging directory beside
    ``path``; the caller creates it (``mkdir``, a bag writer...). When the block ends
    normally it is renamed to ``path``; when it raises, the staging directory and all it
    holds are removed and the exception propagates (an ``OSError`` as
    :class:`~gyro_tdc.errors.OutputError` naming ``path``).

    Parameters
    ----------
    path : str or PathLike
        The directory to create; must not exist.
    what : str
        What the directory is, for messages (``'bag'``...).

    Yields
    ------
    Path
        Where to build the directory.

    Raises
    ------
    OutputError
        When ``path`` exists already or cannot be created.

    """
    path = Path(path)
    if os.path.lexists(path):
        raise OutputError(f'cannot write {what} {str(path)!r}: it exists already')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        for _ in range(100):
            staging = _temp_name(path.parent, path.name)
            try:
                os.mkdir(staging, 0o700)
                break
            except FileExistsError:
                continue
        else:
            raise FileExistsError(f'no free temporary name beside {path.name!r}')
    except OSError as exc:
        raise _fail(what, path, exc) from None
    inner = staging / path.name
    try:
        yield inner
        if os.path.lexists(path):
            raise FileExistsError(errno.EEXIST, 'it exists already')
        os.rename(inner, path)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise _fail(what, path, exc) from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    try:
        os.rmdir(staging)
    except OSError:
        shutil.rmtree(staging, ignore_errors=True)
    _sync_dir(path.parent)
