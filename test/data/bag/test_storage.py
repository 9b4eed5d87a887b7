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

"""Tests of gyro_tdc.data.bag.storage: main messages gathered into blocks, and split."""

from __future__ import annotations

from gyro_tdc.data.bag.storage import Pending, split
import numpy as np


class _Main:
    """A Collector stand-in recording each main block handed over."""

    def __init__(self):
        self.blocks = []

    def main(self, buf, lengths, logs):
        self.blocks.append((bytes(buf), list(lengths), logs().tolist()))


def test_split_cuts_messages_stored_end_to_end():
    assert split(b'abcdefg', np.array([1, 0, 4, 2])) == [b'a', b'', b'bcde', b'fg']


def test_pending_hands_full_blocks_over_and_the_rest_on_flush():
    out = _Main()
    pending = Pending(out, chunk=4)
    pending.add(b'aabb', np.array([2, 2]), np.array([1, 2]))
    assert out.blocks == []                          # 2 of 4: gathered
    pending.add(b'ccddee', np.array([2, 2, 2]), lambda: np.array([3, 4, 5]))
    assert out.blocks == [(b'aabbccddee', [2, 2, 2, 2, 2], [1, 2, 3, 4, 5])]
    pending.add(b'f', np.array([1]), np.array([6]))
    pending.flush()
    pending.flush()                                  # nothing gathered: nothing handed over
    assert out.blocks[1:] == [(b'f', [1], [6])]
