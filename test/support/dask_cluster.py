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
Dask clusters for the fleet tests that always close, within a bound.

A ``LocalCluster`` closed by its ``with`` block waits without a limit for its scheduler and
workers; a test that hangs there holds the run (once 8 minutes on a fresh clone). Here the
close has a deadline, and whatever process the block started and is still alive after it
(worker processes, nannies, a ``gyro-tdc fleet`` child and its cluster) is killed.
"""

from __future__ import annotations

import contextlib
import gc
import logging
from multiprocessing import resource_tracker
from typing import Any, Iterator

import psutil

__all__ = ['CLOSE_S', 'local_cluster', 'reaped']

#: Longest wait for a cluster to close before its processes are killed [s].
CLOSE_S = 30.0


def _descendants() -> set[int]:
    return {p.pid for p in psutil.Process().children(recursive=True)}


@contextlib.contextmanager
def reaped() -> Iterator[None]:
    """
    Kill, after the block, every process it started (recursively) that is still alive.

    multiprocessing's resource tracker, which the block's first process start launches for
    the rest of the run, is started before: killed, the next start relaunches it with a
    warning on stderr ("process died unexpectedly") that a test of one error line reads.
    """
    resource_tracker.ensure_running()
    before = _descendants()
    try:
        yield
    finally:
        left = []
        for pid in _descendants() - before:
            try:
                left.append(psutil.Process(pid))
            except psutil.NoSuchProcess:
                continue
        for proc in left:
            with contextlib.suppress(psutil.NoSuchProcess):
                proc.kill()
        psutil.wait_procs(left, timeout=10.0)


@contextlib.contextmanager
def local_cluster(n_workers: int = 1, **kwargs: Any) -> Iterator[Any]:
    """
    Yield a ``distributed.LocalCluster`` on loopback, closed within :data:`CLOSE_S`.

    Parameters
    ----------
    n_workers : int
        Worker processes (one thread each); 0 for a scheduler alone.
    **kwargs
        More ``LocalCluster`` arguments.

    """
    from distributed import LocalCluster

    options = dict(n_workers=n_workers, processes=True, threads_per_worker=1,
                   host='127.0.0.1', scheduler_port=0, dashboard_address='127.0.0.1:0',
                   silence_logs=logging.CRITICAL)
    options.update(kwargs)
    with reaped():
        # Garbage collected while the cluster's loop thread starts under distributed's
        # process-wide loop lock, a Client's finaliser (which takes that lock) deadlocks it.
        gc.collect()
        cluster = LocalCluster(**options)
        try:
            yield cluster
        finally:
            with contextlib.suppress(TimeoutError):
                cluster.close(timeout=CLOSE_S)
