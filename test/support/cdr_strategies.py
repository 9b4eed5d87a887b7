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
Hypothesis strategies of hostile serialized Imu messages (the CDR property suites use them).

``ANY_BYTES``: random bytes, real messages of either byte order with hostile field values
(``FLOATS``: NaN, Inf, 1e300, subnormals, any double, plausible values) and those messages made
hostile: truncated, extended, a big-endian or unknown header, a forged ``frame_id`` length (up
to 2**32 - 1, either byte order), overwritten bytes.
"""

from __future__ import annotations

import math

from gyro_tdc.data.imu_cdr import CDR_BE, CDR_LE, encode, FRAME_ID, FRAME_ID_LENGTH, IMU_DOUBLES
from hypothesis import strategies as st

__all__ = ['ANY_BYTES', 'FLOATS', 'hostile', 'messages', 'SPECIAL']

SPECIAL = [math.nan, math.inf, -math.inf, 1e300, -1e300, 5e-324, -0.0, 0.0, 1e30, -1.0]
#: Floats as a hostile driver sends them: specials, any double, and plausible values.
FLOATS = st.one_of(st.sampled_from(SPECIAL), st.floats(allow_nan=True, allow_infinity=True),
                   st.floats(-2.0, 2.0), st.floats(-20.0, 20.0))


@st.composite
def messages(draw):
    """Return a serialized Imu (either byte order) with hostile field values."""
    values = draw(st.lists(FLOATS, min_size=IMU_DOUBLES, max_size=IMU_DOUBLES))
    sec = draw(st.integers(-2 ** 31, 2 ** 31 - 1) | st.just(1_700_000_000))
    nanosec = draw(st.integers(0, 2 ** 32 - 1) | st.integers(0, 999_999_999))
    frame = draw(st.text(max_size=24))
    big = draw(st.booleans())
    return encode([sec], [nanosec], frame, [values], big_endian=big)[0]


@st.composite
def hostile(draw):
    """Return a message made hostile: truncated, extended, a header or a length forged."""
    data = bytearray(draw(messages()))
    how = draw(st.sampled_from(['as is', 'truncate', 'extend', 'header', 'strlen', 'bytes']))
    if how == 'truncate':
        del data[draw(st.integers(0, len(data) - 1)):]
    elif how == 'extend':
        data += draw(st.binary(min_size=1, max_size=64))
    elif how == 'header':
        data[:4] = draw(st.sampled_from([CDR_BE, CDR_LE, b'\x00\x07\x00\x00', b'\xff\xff\xff\xff',
                                         b'\x01\x00\x00\x00']))
    elif how == 'strlen':
        length = draw(st.sampled_from([0, 1, 3, 2 ** 31, 2 ** 32 - 1]) | st.integers(0, 600))
        data[FRAME_ID_LENGTH:FRAME_ID] = length.to_bytes(4, draw(st.sampled_from(['little',
                                                                                 'big'])))
    elif how == 'bytes':
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
    return bytes(data)


ANY_BYTES = st.one_of(st.binary(max_size=400), hostile(), messages())
