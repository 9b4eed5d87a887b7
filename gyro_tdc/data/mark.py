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
The gyro_tdc compensation mark: how a compensated Imu says that a model was applied to it.

Pure (struct only). The mark lives in the lowest mantissa bits of the three diagonal
entries of ``angular_velocity_covariance`` (a relative change under 1.5e-11), so a chained or
looped compensator can warn instead of removing the drift twice. An all-zero covariance
(REP 145: unknown) is marked by the sign of its three diagonal zeros (``-0.0 == 0.0``: still
all zero to every reader), so no covariance is invented.
See ``doc/internals/data.md``.
"""

from __future__ import annotations

import struct
from typing import Sequence

__all__ = ['MARK', 'cov_marked', 'diagonal_marked', 'UNKNOWN_MARK']

MARK = b'TG'
UNKNOWN_MARK = struct.pack('<d', -0.0)
_COV = struct.Struct('<9d')
_INF = float('inf')


def cov_marked(data: bytes, offset: int) -> bool:
    """
    Return whether the serialized covariance (row-major 3x3) at ``offset`` carries the mark.

    :data:`MARK` in the two lowest bytes of its three diagonal entries, each positive and
    finite; or, for an all-zero (unknown) covariance, -0.0 on its diagonal.
    """
    if data[offset:offset + 2] == MARK:
        return (data[offset + 32:offset + 34] == MARK and data[offset + 64:offset + 66] == MARK
                and all(0.0 < v < _INF for v in _COV.unpack_from(data, offset)[::4]))
    return (data[offset:offset + 8] == data[offset + 32:offset + 40]
            == data[offset + 64:offset + 72] == UNKNOWN_MARK
            and not any(_COV.unpack_from(data, offset)))


def diagonal_marked(cov: Sequence[float]) -> bool:
    """Return whether a deserialized 3x3 covariance carries the mark (:func:`cov_marked`)."""
    return cov_marked(_COV.pack(*cov), 0)
