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

"""Tests of gyro_tdc.data.imu_cdr: the Imu wire layout against rosbags' CDR serialiser."""

from __future__ import annotations

import struct

from gyro_tdc.data import imu_cdr
from gyro_tdc.data.imu_cdr import (encode, field_slice, IMU_DOUBLES, IMU_FIELDS, ImuView, Layout,
                                   layout_of, locate)
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores

TS = get_typestore(Stores.ROS2_JAZZY)
IMU = 'sensor_msgs/msg/Imu'
# Every frame_id length 0..9 (all paddings mod 8, NUL included), a long one, a non-ASCII one.
FRAME_IDS = (['imu_link0'[:k] for k in range(10)]
             + ['base_link/imu_sensor_frame_number_12', 'caf\u00e9'])
ENDIAN = [pytest.param(True, id='little'), pytest.param(False, id='big')]


def _imu(rng, frame_id, sec=1_700_000_000, nanosec=123_456_789):
    t = TS.types
    vec = t['geometry_msgs/msg/Vector3']
    return t[IMU](t['std_msgs/msg/Header'](t['builtin_interfaces/msg/Time'](sec, nanosec),
                                           frame_id),
                  t['geometry_msgs/msg/Quaternion'](*rng.normal(size=4)), rng.normal(size=9),
                  vec(*rng.normal(size=3)), rng.normal(size=9), vec(*rng.normal(size=3)),
                  rng.normal(size=9))


def _values(msg):
    """Return the 37 float64 values of an Imu by field name (rosbags' objects)."""
    def flat(v):
        if hasattr(v, 'w'):
            return [v.x, v.y, v.z, v.w]
        if hasattr(v, 'x'):
            return [v.x, v.y, v.z]
        return list(v)
    return {name: flat(getattr(msg, name)) for name in IMU_FIELDS}


def test_field_table_is_the_imu_definition_of_jazzy():
    _, fields = TS.fielddefs[IMU]
    assert [name for name, _ in fields] == ['header'] + list(IMU_FIELDS)
    sizes = {'geometry_msgs/msg/Quaternion': 4, 'geometry_msgs/msg/Vector3': 3}
    for name, (_, desc) in fields[1:]:
        count = desc[1] if isinstance(desc, tuple) else sizes[desc]
        assert IMU_FIELDS[name][1] == count, name
    assert IMU_DOUBLES == 37
    assert [field_slice(n) for n in ('angular_velocity', 'linear_acceleration')] == \
        [slice(13, 16), slice(25, 28)]


@pytest.mark.parametrize('little', ENDIAN)
@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_layout_reads_every_field_that_rosbags_writes(frame_id, little):
    rng = np.random.default_rng(len(frame_id))
    msg = _imu(rng, frame_id)
    raw = bytes(TS.serialize_cdr(msg, IMU, little_endian=little))
    frame = frame_id.encode() + b'\0'
    lay = layout_of(raw)
    assert lay == Layout(len(frame), IMU_DOUBLES, big_endian=not little)
    assert lay.size == len(raw) == lay.dtype.itemsize
    assert lay.body % 8 == 4 and lay.body >= imu_cdr.FRAME_ID + len(frame)
    assert raw[:4] == lay.encapsulation
    rec = np.frombuffer(raw, dtype=lay.dtype)[0]
    assert (rec['sec'], rec['nanosec']) == (1_700_000_000, 123_456_789)
    assert rec['strlen'] == len(frame) and rec['frame'].tobytes() == frame
    order = '<' if little else '>'
    for name, want in _values(msg).items():
        np.testing.assert_array_equal(rec['data'][field_slice(name)], want)
        got = struct.unpack_from(f'{order}{len(want)}d', raw, lay.offset(name))
        assert list(got) == want, name


@pytest.mark.parametrize('little', ENDIAN)
@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_encode_writes_what_rosbags_writes_and_reads_back(frame_id, little):
    rng = np.random.default_rng(100 + len(frame_id))
    msgs = [_imu(rng, frame_id, sec=int(s), nanosec=int(ns))
            for s, ns in zip(rng.integers(0, 2**31, 4), rng.integers(0, 10**9, 4))]
    values = np.array([np.concatenate(list(_values(m).values())) for m in msgs])
    values[1, 0] = np.nan
    values[2, -1] = -np.inf
    sec = [m.header.stamp.sec for m in msgs]
    nanosec = [m.header.stamp.nanosec for m in msgs]
    out = encode(sec, nanosec, frame_id, values, big_endian=not little)
    for i, raw in enumerate(out):
        back = TS.deserialize_cdr(raw, IMU)
        assert (back.header.stamp.sec, back.header.stamp.nanosec) == (sec[i], nanosec[i])
        assert back.header.frame_id == frame_id
        np.testing.assert_array_equal(np.concatenate(list(_values(back).values())), values[i])
        assert raw == bytes(TS.serialize_cdr(back, IMU, little_endian=little))


@pytest.mark.parametrize('msgtype, n', [('sensor_msgs/msg/Temperature', 2),
                                        ('geometry_msgs/msg/Vector3Stamped', 3)])
@pytest.mark.parametrize('frame_id', ['', 'imu', 'imu_link'])
def test_other_stamped_float64_messages_share_the_header_layout(msgtype, n, frame_id):
    t = TS.types
    header = t['std_msgs/msg/Header'](t['builtin_interfaces/msg/Time'](5, 6), frame_id)
    if n == 2:
        msg = t[msgtype](header, 21.5, 0.01)
    else:
        msg = t[msgtype](header, t['geometry_msgs/msg/Vector3'](1.0, -2.0, 3.0))
    raw = bytes(TS.serialize_cdr(msg, msgtype))
    assert layout_of(raw, n).size == len(raw)
    assert encode([5], [6], frame_id, [[21.5, 0.01] if n == 2 else [1.0, -2.0, 3.0]]) == [raw]


@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_locate_and_view_patch_only_the_angular_velocity(frame_id):
    rng = np.random.default_rng(7)
    msg = _imu(rng, frame_id)
    msg.angular_velocity_covariance[:] = np.arange(9) * 1e-6
    raw = bytes(TS.serialize_cdr(msg, IMU))
    sec, nanosec, base = locate(raw)
    assert (sec, nanosec, base) == (1_700_000_000, 123_456_789, layout_of(raw).body)
    view = ImuView(raw, base)
    w, a = msg.angular_velocity, msg.linear_acceleration
    assert view.angular_velocity() == (w.x, w.y, w.z)
    assert view.linear_acceleration() == (a.x, a.y, a.z)
    out = TS.deserialize_cdr(view.patched(1.5, 2.5, -3.5, (1.0, 2.0, 4.0)), IMU)
    assert (out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z) == \
        (1.5, 2.5, -3.5)
    expect = np.arange(9) * 1e-6
    expect[[0, 4, 8]] += (1.0, 2.0, 4.0)
    np.testing.assert_array_equal(out.angular_velocity_covariance, expect)
    before, after = _values(msg), _values(out)
    for name in ('orientation', 'orientation_covariance', 'linear_acceleration',
                 'linear_acceleration_covariance'):
        assert after[name] == before[name], name
    assert out.header.frame_id == frame_id

    msg.linear_acceleration_covariance[0] = -1.0       # no accelerometer (REP 145)
    msg.angular_velocity_covariance[0] = -1.0          # rate covariance unknown
    raw = bytes(TS.serialize_cdr(msg, IMU))
    assert ImuView(raw, base).linear_acceleration() is None
    out = TS.deserialize_cdr(ImuView(raw, base).patched(0.0, 0.0, 0.0, (1.0, 1.0, 1.0)), IMU)
    assert out.angular_velocity_covariance[0] == -1.0  # "unknown" stays so


@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_view_patches_the_linear_acceleration_and_keeps_the_mark_on_the_rate(frame_id):
    rng = np.random.default_rng(11)
    msg = _imu(rng, frame_id)
    msg.angular_velocity_covariance[:] = np.arange(1, 10) * 1e-6
    msg.linear_acceleration_covariance[:] = np.arange(1, 10) * 1e-4
    raw = bytes(TS.serialize_cdr(msg, IMU))
    view = ImuView(raw, locate(raw)[2])
    out = TS.deserialize_cdr(view.patched(0.1, 0.2, 0.3, (1e-6,) * 3, True,
                                          (0.5, -9.75, 1.25), (1.0, 2.0, 4.0)), IMU)
    a = out.linear_acceleration
    assert (a.x, a.y, a.z) == (0.5, -9.75, 1.25)
    expect = np.arange(1, 10) * 1e-4
    expect[[0, 4, 8]] += (1.0, 2.0, 4.0)
    np.testing.assert_array_equal(out.linear_acceleration_covariance, expect)
    assert ImuView(bytes(TS.serialize_cdr(out, IMU)), view.base).marked()
    before, after = _values(msg), _values(out)
    for name in ('orientation', 'orientation_covariance'):
        assert after[name] == before[name], name
    # Only the covariance: the values stay; None and None: the bytes of the gyro-only patch.
    out = TS.deserialize_cdr(view.patched(0.1, 0.2, 0.3, (0.0,) * 3, False, None,
                                          (1.0, 1.0, 1.0)), IMU)
    assert _values(out)['linear_acceleration'] == before['linear_acceleration']
    assert view.patched(0.1, 0.2, 0.3, (1e-6,) * 3, True, None, None) == \
        view.patched(0.1, 0.2, 0.3, (1e-6,) * 3, True)
    # No accelerometer (covariance[0] == -1): the covariance stays "no data".
    msg.linear_acceleration_covariance[0] = -1.0
    raw = bytes(TS.serialize_cdr(msg, IMU))
    out = TS.deserialize_cdr(ImuView(raw, view.base).patched(
        0.0, 0.0, 0.0, (0.0,) * 3, False, None, (1.0, 1.0, 1.0)), IMU)
    np.testing.assert_array_equal(out.linear_acceleration_covariance,
                                  msg.linear_acceleration_covariance)


def test_locate_leaves_big_endian_to_the_general_path():
    raw = bytes(TS.serialize_cdr(_imu(np.random.default_rng(1), 'imu'), IMU, little_endian=False))
    assert layout_of(raw).big_endian
    assert locate(raw) is None


def _good():
    return bytes(TS.serialize_cdr(_imu(np.random.default_rng(2), 'imu_link'), IMU))


@pytest.mark.parametrize('damage, needle', [
    (lambda b: b'', 'at least 16 bytes'),
    (lambda b: b[:10], 'got 10 bytes'),
    (lambda b: b[:-8], 'got 316 bytes'),
    (lambda b: b + b'\0' * 8, 'got 332 bytes'),
    (lambda b: b'\x00\x02' + b[2:], 'representation'),
    (lambda b: b'\x01\x01' + b[2:], 'got 01 01'),
    (lambda b: b[:12] + (1000).to_bytes(4, 'little') + b[16:], 'got 1000'),
    (lambda b: b[:12] + (0).to_bytes(4, 'little') + b[16:], 'got 0'),
    (lambda b: b[:12] + (8).to_bytes(4, 'little') + b[16:], 'NUL'),
], ids=['empty', 'short', 'truncated', 'trailing', 'xcdr2', 'unknown', 'frame_len',
        'no_nul_len', 'no_nul'])
def test_bad_buffers_raise_a_clear_error(damage, needle):
    data = damage(_good())
    with pytest.raises(DatasetError, match=needle):
        layout_of(data)
    assert locate(data) is None or needle == 'NUL'   # the fast path only checks the length


def test_encode_rejects_a_flat_block():
    with pytest.raises(DatasetError, match=r'shape \(N, K\)'):
        encode([1], [2], 'imu', np.zeros(37))
