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

import math
import struct
from typing import Sequence

__all__ = ['MARK', 'cov_marked', 'diagonal_marked', 'is_marked', 'mark', 'UNKNOWN_MARK']

#: The two low-order bytes (little-endian float64) written into each marked variance.
MARK = b'TG'
#: The little-endian float64 -0.0: each diagonal entry of a marked unknown covariance.
UNKNOWN_MARK = struct.pack('<d', -0.0)
_F64 = struct.Struct('<d')


def mark(value: float) -> float:
    """
    Return ``value`` with :data:`MARK` in its two lowest mantissa bytes.

    Parameters
    ----------
    value : float
        A positive, finite variance; anything else is returned unchanged.

    Returns
    -------
    float
        The marked value (within 2**-36 relative of ``value``).

    """
    return _F64.unpack(MARK + _F64.pack(value)[2:])[0] if 0.0 < value < float('inf') else value


def is_marked(value: float) -> bool:
    """Return whether ``value`` carries :data:`MARK` (and is positive and finite)."""
    return bool(0.0 < value < float('inf')) and _F64.pack(value)[:2] == MARK


def cov_marked(data: bytes, offset: int) -> bool:
    """Return whether the serialized covariance at ``offset`` carries the mark on its diagonal."""
    if data[offset:offset + 2] == MARK:
        return data[offset + 32:offset + 34] == MARK and data[offset + 64:offset + 66] == MARK
    return (data[offset:offset + 8] == data[offset + 32:offset + 40]
            == data[offset + 64:offset + 72] == UNKNOWN_MARK)


def _negative_zero(value: float) -> bool:
    return bool(value == 0.0) and math.copysign(1.0, value) < 0.0


def diagonal_marked(cov: Sequence[float]) -> bool:
    """Return whether entries 0, 4 and 8 of a row-major 3x3 covariance carry a mark."""
    if is_marked(cov[0]):
        return is_marked(cov[4]) and is_marked(cov[8])
    return (_negative_zero(cov[0]) and _negative_zero(cov[4]) and _negative_zero(cov[8])
            and not any(cov[i] for i in (1, 2, 3, 5, 6, 7)))
