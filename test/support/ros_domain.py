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
A ``ROS_DOMAIN_ID`` for each pytest process: the run's own, or one per pytest-xdist worker.

Standard library only (conftest.py uses it before anything imports ``rclpy``). Each id a
process takes is claimed with an exclusive ``flock`` on ``/tmp/gyro_tdc-ros-domain-<id>.lock``,
held until the process ends (the kernel drops it even on a crash), so no two live pytest
processes of this repository on one machine choose the same id.
"""

from __future__ import annotations

import fcntl
import os
from typing import Iterator, List, Optional

__all__ = ['DOMAINS', 'STRIDE', 'candidates', 'claim', 'run_domain', 'worker_domain']

#: Domain ids used: 1..101 (the range whose DDS ports stay clear of Linux's ephemeral ports).
DOMAINS = 101
#: Step between the ids of the workers of one run (101 is prime: the steps visit every id but
#: the base). 20 keeps the first four workers' ids at least 20 apart from the base, from each
#: other, and from those of a run whose base is within 19 of this one's.
STRIDE = 20
LOCK_DIR = '/tmp' if os.path.isdir('/tmp') else os.path.abspath(os.curdir)

_held: List[int] = []  # descriptors of the claimed locks, open for the life of the process


def candidates(base: int, worker: int) -> Iterator[int]:
    """
    Yield the ids worker number ``worker`` (0 for ``gw0``) tries, its own first.

    Parameters
    ----------
    base : int
        The run's ``ROS_DOMAIN_ID``; never yielded (nor any id equal to it modulo 101).
    worker : int
        The worker's number, >= 0.

    Yields
    ------
    int
        ``(base - 1 + k * STRIDE) % 101 + 1`` for ``k = worker + 1, worker + 2, ...``, wrapping
        around: each of the 100 ids in 1..101 other than the base, once.

    """
    for m in range(DOMAINS - 1):
        k = (worker + m) % (DOMAINS - 1) + 1
        yield (base - 1 + k * STRIDE) % DOMAINS + 1


def claim(domain: int) -> bool:
    """Take the lock of ``domain`` for the life of this process; return False if it is held."""
    path = os.path.join(LOCK_DIR, f'gyro_tdc-ros-domain-{domain}.lock')
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CREAT, 0o644)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return False
    _held.append(fd)
    return True


def run_domain(given: Optional[str], pid: int) -> tuple[int, bool]:
    """
    Return ``(id, claimed)`` for a run that is not an xdist worker.

    An id the caller set (``given``, e.g. by ``make test``) is kept, claimed if it is free.
    Without one, the first free id from ``pid % 101 + 1`` on, else that id unclaimed.
    """
    if given:
        domain = int(given)
        return domain, claim(domain)
    first = pid % DOMAINS + 1
    for domain in [first, *candidates(first, 0)]:
        if claim(domain):
            return domain, True
    return first, False


def worker_domain(base: int, worker: str) -> tuple[int, bool]:
    """
    Return ``(id, claimed)`` for xdist worker ``worker`` (``'gw0'``, ...) of a run on ``base``.

    The first id of :func:`candidates` not claimed by another process; if every one is, the
    worker's own first id, unclaimed.
    """
    index = int(worker[2:]) if worker[:2] == 'gw' and worker[2:].isdigit() else 0
    tried = candidates(base, index)
    first = next(tried)
    if claim(first):
        return first, True
    for domain in tried:
        if claim(domain):
            return domain, True
    return first, False
