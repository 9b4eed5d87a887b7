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
What the two storage reads share: the refusal that hands a bag to rosbags, and the main blocks.

A storage read (:mod:`~gyro_tdc.data.bag.storage_sqlite3`, :mod:`~gyro_tdc.data.bag.storage_mcap`)
hands a ``Collector`` the wanted messages role by role in rosbags' order; it raises
:class:`Unfit` on anything it does not expect, and rosbags' reader, the reference, reads the
bag instead.
"""

from __future__ import annotations

from typing import Any, Callable, Union

import numpy as np
from numpy.typing import NDArray

__all__ = ['Logs', 'Pending', 'split', 'Unfit']

#: Log times of a block, or a function that fetches them when a message needs them.
Logs = Union[NDArray[np.int64], Callable[[], NDArray[np.int64]]]


class Unfit(Exception):
    """The columnar read does not apply to this bag: rosbags' reader reads it."""


def split(buf: bytes, lengths: NDArray[np.int64]) -> list[bytes]:
    """Return the messages stored end to end in ``buf``."""
    ends = np.cumsum(lengths).tolist()
    return [buf[a:b] for a, b in zip([0] + ends[:-1], ends)]


class Pending:
    """Main (IMU) messages gathered until a block is full, then handed to ``out.main``."""

    def __init__(self, out: Any, chunk: int) -> None:
        self.out, self.chunk = out, chunk
        self.parts: list[tuple[bytes, NDArray[np.int64], Logs]] = []
        self.n = 0

    def add(self, buf: bytes, lengths: NDArray[np.int64], logs: Logs) -> None:
        """Add messages stored end to end in ``buf``; hand the block over once it is full."""
        self.parts.append((buf, lengths, logs))
        self.n += len(lengths)
        if self.n >= self.chunk:
            self.flush()

    def flush(self) -> None:
        """Hand what is gathered over (before any other role's block of the same span)."""
        if not self.n:
            return
        pieces, lengths, logs = zip(*self.parts)
        self.parts, self.n = [], 0
        self.out.main(pieces[0] if len(pieces) == 1 else b''.join(pieces),
                      np.concatenate(lengths),
                      lambda: np.concatenate([x() if callable(x) else x for x in logs]))
