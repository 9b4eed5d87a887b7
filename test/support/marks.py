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


"""The node's compensation mark written and read by hand, for tests (``gyro_tdc.data.mark``)."""

from __future__ import annotations

import math
import struct

from gyro_tdc.data.mark import MARK

_F64 = struct.Struct('<d')


def mark(value):
    """Return a variance with MARK in its two lowest mantissa bytes, as the node writes it."""
    return _F64.unpack(MARK + _F64.pack(value)[2:])[0] if 0.0 < value < math.inf else value


def is_marked(value):
    """Return whether one variance carries MARK (positive and finite)."""
    return bool(0.0 < value < math.inf) and _F64.pack(value)[:2] == MARK
