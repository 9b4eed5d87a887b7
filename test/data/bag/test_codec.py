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

"""Tests of gyro_tdc.data.bag.codec: the fixed-layout codec against rosbags' serialiser."""

from __future__ import annotations

import io

from bag_msgs import _fields, _imu, FRAME_IDS, MAKERS, TS
from gyro_tdc.data import IMU_TYPE, REFERENCE_TYPE, TEMPERATURE_TYPE
from gyro_tdc.data.bag import codec
from gyro_tdc.data.imu_cdr import encode, Layout
import numpy as np
import pytest


def _decode(raws, msgtype, typestore, keep=None):
    """Decode a list of messages (joined end to end, as the storage reads hand them over)."""
    return codec.decode_joined(b''.join(raws), [len(x) for x in raws], msgtype, typestore, keep)


# ------------------------------------------------------------------------------------------
# The fixed-layout codec equals rosbags' serialiser
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize('msgtype', [IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE])
@pytest.mark.parametrize('frame_id', FRAME_IDS)
@pytest.mark.parametrize('little_endian', [True, False])
def test_fixed_layout_decodes_every_field_like_rosbags(msgtype, frame_id, little_endian):
    rng = np.random.default_rng(len(frame_id))
    msgs = [MAKERS[msgtype](rng, sec=int(rng.integers(0, 2**31)),
                            nsec=int(rng.integers(0, 10**9)), frame_id=frame_id)
            for _ in range(7)]
    raws = [bytes(TS.serialize_cdr(m, msgtype, little_endian=little_endian)) for m in msgs]
    frame = frame_id.encode() + b'\0'
    dt = Layout(len(frame), codec.N_DOUBLES[msgtype], big_endian=not little_endian).dtype
    assert dt.itemsize == len(raws[0])
    rec = np.frombuffer(b''.join(raws), dtype=dt)
    for i, raw in enumerate(raws):
        sec, nsec, fid, row = _fields(msgtype, TS.deserialize_cdr(raw, msgtype))
        assert (rec['sec'][i], rec['nanosec'][i]) == (sec, nsec)
        assert rec['strlen'][i] == len(frame)
        assert rec['frame'][i].tobytes() == frame
        np.testing.assert_array_equal(rec['data'][i], row)

    dec = _decode(raws, msgtype, TS)
    assert dec.fallback == 0 and dec.frame_id == frame_id
    keep = list(codec.KEEP[msgtype])
    for i, raw in enumerate(raws):
        sec, nsec, _, row = _fields(msgtype, TS.deserialize_cdr(raw, msgtype))
        assert (dec.sec[i], dec.nanosec[i]) == (sec, nsec)
        np.testing.assert_array_equal(dec.values[i], np.asarray(row)[keep])


@pytest.mark.parametrize('msgtype', [IMU_TYPE, TEMPERATURE_TYPE, REFERENCE_TYPE])
@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_fixed_layout_encodes_like_rosbags(msgtype, frame_id):
    rng = np.random.default_rng(7)
    n = 5
    sec = rng.integers(0, 2**31, size=n)
    nsec = rng.integers(0, 10**9, size=n)
    data = rng.normal(size=(n, codec.N_DOUBLES[msgtype]))
    data[1, 0] = np.nan
    data[2, -1] = -np.inf
    encoded = encode(sec, nsec, frame_id, data)
    for i in range(n):
        msg = codec.to_msg(msgtype, sec[i], nsec[i], frame_id, data[i])
        assert encoded[i] == bytes(TS.serialize_cdr(msg, msgtype))


def test_fast_decoder_refuses_mixed_layouts():
    rng = np.random.default_rng(3)
    same_len = [bytes(TS.serialize_cdr(_imu(rng, frame_id=f), IMU_TYPE)) for f in ('imu0', 'imu1')]
    assert _decode(same_len, IMU_TYPE, TS).fallback == len(same_len)
    other_len = [bytes(TS.serialize_cdr(_imu(rng, frame_id=f), IMU_TYPE)) for f in ('a', 'bcd')]
    assert _decode(other_len, IMU_TYPE, TS).fallback == len(other_len)
    mixed_endian = [bytes(TS.serialize_cdr(_imu(rng), IMU_TYPE, little_endian=le))
                    for le in (True, False)]
    assert _decode(mixed_endian, IMU_TYPE, TS).fallback == len(mixed_endian)
    trailing = [bytes(TS.serialize_cdr(_imu(rng), IMU_TYPE)) + b'\0\0' for _ in range(2)]
    assert _decode(trailing, IMU_TYPE, TS).fallback == len(trailing)
    # ...and the rosbags fallback decodes all of them right.
    for raws in (same_len, other_len, mixed_endian, trailing):
        dec = _decode(raws, IMU_TYPE, TS)
        assert dec.fallback == len(raws)
        for i, raw in enumerate(raws):
            row = np.asarray(_fields(IMU_TYPE, TS.deserialize_cdr(raw, IMU_TYPE))[3])
            np.testing.assert_array_equal(dec.values[i], row[list(codec.KEEP[IMU_TYPE])])


def _same_decoded(a, b):
    assert (a.frame_id, a.fallback) == (b.frame_id, b.fallback)
    for x, y in ((a.sec, b.sec), (a.nanosec, b.nanosec), (a.values, b.values)):
        np.testing.assert_array_equal(x, y)
    assert (a.undecodable is None) == (b.undecodable is None)


def test_decode_joined_equals_decode_on_one_reused_buffer():
    # The reader's path: messages written end to end into one BytesIO reused from block to
    # block (a longer block first, so stale bytes follow the shorter one), decoded from a
    # view of it: the same result as _decode() on the list, fast path and fallback alike.
    rng = np.random.default_rng(5)
    uniform = [bytes(TS.serialize_cdr(_imu(rng, sec=i + 1, nsec=7 * i), IMU_TYPE))
               for i in range(9)]
    mixed = [bytes(TS.serialize_cdr(_imu(rng, frame_id=f), IMU_TYPE)) for f in ('a', 'bcd')]
    trailing = [bytes(TS.serialize_cdr(_imu(rng), IMU_TYPE)) + b'\0\0' for _ in range(2)]
    scratch = io.BytesIO()
    for raws in (uniform + uniform, uniform, mixed, trailing):
        scratch.seek(0)
        lengths = [scratch.write(raw) for raw in raws]
        view = scratch.getbuffer()
        dec = codec.decode_joined(view, lengths, IMU_TYPE, TS)
        del view
        _same_decoded(dec, _decode(raws, IMU_TYPE, TS))
        assert dec.fallback == (0 if raws[0] is uniform[0] else len(raws))
    scratch.seek(0)
    scratch.write(b'')            # nothing returned still holds the buffer


def test_decode_slow_cuts_messages_stored_end_to_end():
    rng = np.random.default_rng(9)
    raws = [bytes(TS.serialize_cdr(_imu(rng, frame_id=f), IMU_TYPE)) for f in ('a', 'bcd')]
    dec = codec.decode_slow(b''.join(raws), np.array([len(raws[0]), 0, len(raws[1])]),
                            IMU_TYPE, TS)
    assert dec.fallback == 3 and dec.undecodable.tolist() == [False, True, False]
    for i, raw in ((0, raws[0]), (2, raws[1])):
        row = np.asarray(_fields(IMU_TYPE, TS.deserialize_cdr(raw, IMU_TYPE))[3])
        np.testing.assert_array_equal(dec.values[i], row[list(codec.KEEP[IMU_TYPE])])
