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
Run ``python -m gyro_tdc ARGS...`` in child processes that stop before their Nth change.

A change is a file-system operation below a folder that the interpreter announces on its audit
hook (:func:`sys.addaudithook`): ``open`` for writing, ``os.mkdir``, ``os.rename`` (also
``os.replace``), ``os.remove``, ``os.rmdir``, ``shutil.rmtree``, ``sqlite3.connect``, and the
look-up of ``renameat2`` through ``ctypes`` (made just before the first swap). A child stopped
there prints ``paused PID N EVENT PATH`` and sleeps until it is killed, so a test can
``kill -9`` it at that exact point.

Run as a script (``python pause_at.py``) this is a fork server: it imports ``gyro_tdc``'s
command line once, then reads requests ``STOP FOLDER ARG...`` (tab-separated) on stdin and
forks one child per request, answering ``started PID`` and, when the child ends,
``exited PID RC`` (``-9`` when killed). :class:`PausingRunner` is its client for tests.
"""

from __future__ import annotations

import os
from pathlib import Path
import runpy
import selectors
import signal
import subprocess
import sys
import time
from typing import Callable

_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
_PATH_EVENTS = {'os.mkdir', 'os.rename', 'os.remove', 'os.rmdir', 'shutil.rmtree',
                'sqlite3.connect'}


def _path_of(path) -> str | None:
    """Return a hooked event's path argument as an absolute path, or None."""
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        return None
    path = os.fspath(path)
    if path.startswith('file:'):            # an sqlite URI
        path = path[5:].split('?')[0]
    return os.path.realpath(path)


def _install_hook(folder: str, stop: int) -> None:
    """Pause this process just before its change number ``stop`` below ``folder``."""
    folder = os.path.realpath(folder) + os.sep
    count = [0]

    def hook(event: str, args: tuple) -> None:
        if event == 'open':
            path, mode, flags = args
            if not (any(c in mode for c in 'wax+') if isinstance(mode, str)
                    else flags & _WRITE_FLAGS):
                return
        elif event in _PATH_EVENTS:
            path = args[0]
        elif event == 'ctypes.dlsym' and args[1] == 'renameat2':
            path = folder
        else:
            return
        path = _path_of(path)
        if path is None or not (path + os.sep).startswith(folder):
            return
        if count[0] == stop:
            sys.stdout.write(f'paused {os.getpid()} {stop} {event} {path}\n')
            sys.stdout.flush()
            while True:
                time.sleep(60)
        count[0] += 1

    sys.addaudithook(hook)


def _child(stop: int, folder: str, argv: list) -> int:
    """Run ``python -m gyro_tdc argv`` with the hook; return its exit code."""
    _install_hook(folder, stop)
    sys.argv = ['gyro_tdc', *argv]
    try:
        runpy.run_module('gyro_tdc', run_name='__main__', alter_sys=True)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return 0


def serve() -> None:
    """Fork one paused child per request line on stdin (see the module docstring)."""
    import gyro_tdc.cli.simulate  # noqa: F401  (imported once, before any fork)
    for name in ('gyro_tdc.data', 'gyro_tdc.bagio'):     # the bag writer, where it lives
        try:
            __import__(name).write_bag
        except (ImportError, AttributeError):
            pass
    import rosbags.rosbag2  # noqa: F401
    import tqdm  # noqa: F401
    print('ready', flush=True)
    for line in sys.stdin:
        stop, folder, *argv = line.rstrip('\n').split('\t')
        pid = os.fork()
        if pid == 0:
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            code = 1
            try:
                code = _child(int(stop), folder, argv)
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
        print(f'started {pid}', flush=True)
        _, status = os.waitpid(pid, 0)
        print(f'exited {pid} {os.waitstatus_to_exitcode(status)}', flush=True)


class PausingRunner:
    """
    Client of the fork server: run a command, stopped before change N, and kill it.

    Parameters
    ----------
    timeout_s : float, s
        Longest wait for any answer of the server (a safety bound, not a measurement).

    """

    def __init__(self, timeout_s: float = 120.0) -> None:
        self.timeout_s = timeout_s
        env = {**os.environ, 'OPENBLAS_NUM_THREADS': '1', 'OMP_NUM_THREADS': '1'}
        self.proc = subprocess.Popen([sys.executable, __file__], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=env, bufsize=1)
        self._sel = selectors.DefaultSelector()
        self._sel.register(self.proc.stdout, selectors.EVENT_READ)
        self._pending = b''   # read from the pipe, not yet returned as lines
        assert self._line() == 'ready'

    def _line(self) -> str:
        # The pipe is read raw: a buffered readline() could take two lines at once (``started``
        # and ``paused`` of a quick child), and select() would then wait for the second in vain.
        while b'\n' not in self._pending:
            if not self._sel.select(self.timeout_s):
                raise TimeoutError(f'no answer from the fork server in {self.timeout_s:g} s')
            chunk = os.read(self.proc.stdout.fileno(), 65536)
            if not chunk:
                raise RuntimeError('the fork server ended')
            self._pending += chunk
        line, self._pending = self._pending.split(b'\n', 1)
        return line.decode()

    def run(self, stop: int, folder: Path, argv: list,
            on_pause: Callable[[int, str], None] | None = None) -> tuple[str | None, int]:
        """
        Run ``python -m gyro_tdc argv``; kill it with SIGKILL when it pauses at ``stop``.

        ``on_pause(pid, paused)`` is called before the kill. Returns the ``paused`` line
        (None when the command ended first) and the exit code.
        """
        self.proc.stdin.write('\t'.join([str(stop), str(folder), *map(str, argv)]) + '\n')
        self.proc.stdin.flush()
        paused, pid = None, None
        while True:
            words = self._line().split(' ', 4)
            if words[0] == 'started':
                pid = int(words[1])
            elif words[0] == 'paused':
                paused = ' '.join(words[2:])
                try:
                    if on_pause is not None:
                        on_pause(int(words[1]), paused)
                finally:
                    os.kill(int(words[1]), signal.SIGKILL)
            elif words[0] == 'exited' and pid is not None:
                return paused, int(words[2])

    def close(self) -> None:
        """End the server."""
        self.proc.stdin.close()
        try:
            self.proc.wait(10.0)
        except subprocess.TimeoutExpired:   # a server stuck in a dead child's pipe: end it
            self.proc.kill()
            self.proc.wait(self.timeout_s)
        self.proc.stdout.close()
        self._sel.close()

    def __enter__(self) -> PausingRunner:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


if __name__ == '__main__':
    serve()
