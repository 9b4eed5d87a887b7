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
Work off the message path: one background job at a time, the newest request wins.

Pure (threading only). The compensator node reads, checks and primes a new model file in a
worker thread so that a large or slow file never holds up the IMU callback; the thread that
compensates then claims the finished job and swaps the model in (one assignment), so no
lock is ever taken on the message path. Starting a job makes any earlier one stale: its
result is dropped when it finishes. Worker threads are daemons, so a file still being read
does not hold up the process at shutdown.
"""

from __future__ import annotations

import threading
from typing import Any, Callable, Generic, TypeVar

__all__ = ['Job', 'LatestJob']

T = TypeVar('T')


class Job(Generic[T]):
    """
    One request run in a worker thread.

    Parameters
    ----------
    name : str
        What the job works on (e.g. the model file).
    origin : str
        Who asked (e.g. ``'reload'`` or ``'parameter'``).

    """

    def __init__(self, name: str, origin: str) -> None:
        self.name, self.origin = name, origin
        self.result: T | None = None
        self._done = threading.Event()

    @property
    def done(self) -> bool:
        """Return whether the work has finished."""
        return self._done.is_set()

    def wait(self, timeout_s: float) -> bool:
        """Wait at most ``timeout_s`` seconds for the work; return whether it finished."""
        return self._done.wait(timeout_s)


class LatestJob:
    """Run jobs in daemon worker threads and hand back the newest one once it is done."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._current: Job[Any] | None = None

    @property
    def pending(self) -> Job[Any] | None:
        """Return the newest job not yet claimed (running or done), or None."""
        return self._current

    def start(self, name: str, origin: str, work: Callable[[], T]) -> Job[T]:
        """
        Run ``work()`` in a new daemon thread and return its :class:`Job`; earlier jobs go stale.

        ``name`` and ``origin`` are those of :class:`Job`; ``work`` must not raise (catch at
        the caller's edge). The job's ``result`` is set before it is done.
        """
        job: Job[T] = Job(name, origin)

        def run() -> None:
            try:
                job.result = work()
            finally:
                job._done.set()

        with self._lock:
            self._current = job
        threading.Thread(target=run, name=f'load {name}', daemon=True).start()
        return job

    def drop(self) -> None:
        """Make the current job stale (a newer request was served another way)."""
        with self._lock:
            self._current = None

    def claim(self, job: Job[Any] | None = None) -> Job[Any] | None:
        """
        Take the newest job if it is done (and, when ``job`` is given, is that job).

        Each job is handed out once; a stale job is never.

        Returns
        -------
        Job or None
            The claimed job, or None.

        """
        with self._lock:
            current = self._current
            if current is None or not current.done or (job is not None and job is not current):
                return None
            self._current = None
            return current
