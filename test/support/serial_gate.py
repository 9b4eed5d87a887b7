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
Run ``serial`` tests alone among the pytest-xdist workers of one run (a readers-writer lock).

Every test holds a shared ``flock`` on the run's *room* file while it runs (set-up and
tear-down included); a serial test holds it exclusively, so it starts once the tests running
on the other workers end and none starts beside it. A *gate* file, taken exclusively for a
moment by every test and held by a waiting serial test, keeps new tests out meanwhile.
"""

from __future__ import annotations

import fcntl
import os
import tempfile

__all__ = ['SerialGate']


class SerialGate:
    """
    The gate and room lock files of one run, named by the run's key (the controller's pid).

    Parameters
    ----------
    key : str
        The same in every worker of a run, unique among the runs alive on the machine.

    """

    def __init__(self, key: str) -> None:
        base = os.path.join(tempfile.gettempdir(), f'gyro_tdc-serial-{key}')
        self.paths = (base + '.gate', base + '.room')
        self._fds = None
        self.alone = False  # this worker holds the room exclusively

    def _open(self) -> tuple[int, int]:
        if self._fds is None:
            self._fds = tuple(os.open(p, os.O_RDONLY | os.O_CREAT, 0o644) for p in self.paths)
        return self._fds

    def enter(self, serial: bool) -> None:
        """Wait until a test may start here: alone when ``serial``, else beside others."""
        if serial and self.alone:
            return
        gate, room = self._open()
        if self.alone:                         # a serial run ends: share the room again
            fcntl.flock(room, fcntl.LOCK_UN)
            self.alone = False
        fcntl.flock(gate, fcntl.LOCK_EX)
        try:
            fcntl.flock(room, fcntl.LOCK_EX if serial else fcntl.LOCK_SH)
        finally:
            fcntl.flock(gate, fcntl.LOCK_UN)
        self.alone = serial

    def leave(self, next_serial: bool) -> None:
        """Let others in after a test, unless the next one here is serial too (kept alone)."""
        if self._fds is None or (self.alone and next_serial):
            return
        fcntl.flock(self._fds[1], fcntl.LOCK_UN)
        self.alone = False

    def remove(self) -> None:
        """Delete the lock files (the controller, once the run is over)."""
        for path in self.paths:
            try:
                os.unlink(path)
            except FileNotFoundError:
                pass
