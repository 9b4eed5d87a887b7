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
Tests of gyro_tdc.data.imu_cdr: the Imu wire layout against rosbags' CDR serialiser.

Hostile bytes (hypothesis): random bytes and hostile variants of real messages (truncated,
extended, a big-endian or unknown header, ``frame_id`` lengths up to 2**32 - 1, NaN, Inf,
1e300 and subnormal fields, covariance junk) go through ``layout_of``, ``locate``,
``ImuView`` and the compensator's raw path as the node composes it: each raises nothing but
DatasetError where documented, and a sample marked compensated is finite and plausible.
"""

from __future__ import annotations

import math
import struct

from cdr_strategies import ANY_BYTES, FLOATS
from gyro_tdc.base import MAX_ACCEL_DRIFT_MPS2, MAX_DRIFT_RAD_S, MAX_RATE_RAD_S, model_path
from gyro_tdc.data import imu_cdr
from gyro_tdc.data.imu_cdr import (ANGULAR_VELOCITY, ANGULAR_VELOCITY_COV, CDR_BE, CDR_LE,
                                   encode, field_slice, FRAME_ID, IMU_DOUBLES, IMU_FIELDS,
                                   ImuView, Layout, layout_of, LINEAR_ACCELERATION,
                                   LINEAR_ACCELERATION_COV, locate)
from gyro_tdc.data.mark import cov_marked
from gyro_tdc.errors import DatasetError
from gyro_tdc.identify import fit_model
from gyro_tdc.model import load_model
from gyro_tdc.runtime import CompensatorCore, PASSTHROUGH, Policy
from hostile_helpers import small_model
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores
from synth import synth_run

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
    assert raw[:4] == (CDR_LE if little else CDR_BE)
    rec = np.frombuffer(raw, dtype=lay.dtype)[0]
    assert (rec['sec'], rec['nanosec']) == (1_700_000_000, 123_456_789)
    assert rec['strlen'] == len(frame) and rec['frame'].tobytes() == frame
    order = '<' if little else '>'
    for name, want in _values(msg).items():
        np.testing.assert_array_equal(rec['data'][field_slice(name)], want)
        got = struct.unpack_from(f'{order}{len(want)}d', raw,
                                 lay.body + 8 * field_slice(name).start)
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


# ------------------------------------------------------------------------------------------
# Hostile bytes (hypothesis)
# ------------------------------------------------------------------------------------------

FAST = settings(max_examples=120, suppress_health_check=[HealthCheck.too_slow])


@settings(FAST)
@given(data=ANY_BYTES)
def test_layout_of_says_what_is_wrong_or_gives_a_layout_that_holds(data):
    try:
        lay = layout_of(data)
    except DatasetError as exc:
        assert str(exc) and '\n' not in str(exc)
        return
    assert lay.size == len(data) and data[FRAME_ID + lay.frame_len - 1] == 0
    assert data[:2] == (CDR_BE if lay.big_endian else CDR_LE)[:2]
    rec = np.frombuffer(data, dtype=lay.dtype)       # the layout reads the whole message
    assert rec['data'].shape == (1, IMU_DOUBLES)


@settings(FAST)
@given(data=ANY_BYTES)
def test_locate_and_the_view_never_raise_and_patch_only_their_fields(data):
    found = locate(data)
    if found is None:
        return
    sec, nanosec, base = found
    assert data[:2] == CDR_LE[:2] and base + 8 * IMU_DOUBLES == len(data)
    view = ImuView(data, base)
    w = view.angular_velocity()
    a = view.linear_acceleration()
    view.marked()
    out = view.patched(*w, (1e-6, 2e-6, math.nan), True, a, (1e300, -1.0, math.inf), 1e-6)
    assert len(out) == len(data)
    touched = set()
    for first, count in ((ANGULAR_VELOCITY, 3), (LINEAR_ACCELERATION, 3)):
        touched.update(range(base + first, base + first + 8 * count))
    for cov in (ANGULAR_VELOCITY_COV, LINEAR_ACCELERATION_COV):
        for k in (0, 4, 8):
            touched.update(range(base + cov + 8 * k, base + cov + 8 * k + 8))
    assert all(out[i] == data[i] for i in range(len(data)) if i not in touched)
    assert struct.unpack_from('<3d', out, base + ANGULAR_VELOCITY) == pytest.approx(
        w, nan_ok=True)


@settings(FAST)
@given(sec=st.integers(-2 ** 31, 2 ** 31 - 1), nanosec=st.integers(0, 2 ** 32 - 1),
       frame=st.text(max_size=40), big=st.booleans(),
       values=st.lists(FLOATS, min_size=IMU_DOUBLES, max_size=IMU_DOUBLES))
def test_encode_then_read_back_is_bit_for_bit(sec, nanosec, frame, big, values):
    data = encode([sec], [nanosec], frame, [values], big_endian=big)[0]
    lay = layout_of(data)
    assert lay == Layout(len(frame.encode('utf-8')) + 1, IMU_DOUBLES, big)
    rec = np.frombuffer(data, dtype=lay.dtype)
    assert rec['sec'][0] == sec and rec['nanosec'][0] == nanosec
    sent = np.asarray(values, dtype=np.float64)
    assert rec['data'][0].astype('<f8').tobytes() == sent.tobytes()
    found = locate(data)
    assert (found is None) == big
    if not big:
        assert found == (sec, nanosec, lay.body)
        first = IMU_FIELDS['angular_velocity'][0]
        got = ImuView(data, lay.body).angular_velocity()
        assert np.array(got).tobytes() == sent[first:first + 3].tobytes()


# -- the compensator's raw path ----------------------------------------------------------


@pytest.fixture(scope='module')
def cores():
    """
    Return the models under test: the shipped static one, a dTdt one and forged ones.

    The forged models are made in memory, never validated (as files they would be refused):
    a drift of 6 and -1e6 rad/s, or NaN, so only the core's output check stands between them
    and the output.
    """
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    dtdt = fit_model([run], features=('dT', 'dT2', 'dTdt'), n_centers=8, fit_params=False)
    return {'static': load_model(model_path('l3gd20_modified')), 'dtdt': dtdt,
            'forged': small_model(intercept=np.array([6.0, -1e6, 1e-3])),
            'forged_nan': small_model(intercept=np.array([1e-3, 1e-3, math.nan]))}


def raw_path(core, data):
    """Run ``data`` through the node's raw-bytes path; return (input rate, output) or None."""
    found = locate(data)
    if found is None:
        try:
            layout_of(data)          # the general way: the node deserialises or drops it
        except DatasetError:
            return None
        return None                  # big endian: deserialised, the Imu path (node tests)
    sec, nanosec, base = found
    view = ImuView(data, base)
    w = view.angular_velocity()
    a = view.linear_acceleration() if core.needs_accel else None
    try:
        wx, wy, wz, var, flags, aout, avar = core.process(sec + nanosec * 1e-9, *w, a)
    except Exception as exc:  # the node's edge: the raw sample goes out flagged
        var, flags = core.fail(exc), PASSTHROUGH
        wx, wy, wz = w
        aout, avar = None, None
    out = view.patched(wx, wy, wz, var, not flags & PASSTHROUGH, aout, avar,
                       core.policy.base_variance)
    return w, view.linear_acceleration(), out, base


def check_output(w_in, a_in, out, base):
    """Check that a sample marked compensated is finite and plausibly corrected."""
    if not cov_marked(out, base + ANGULAR_VELOCITY_COV):
        return False
    w = struct.unpack_from('<3d', out, base + ANGULAR_VELOCITY)
    cov = struct.unpack_from('<9d', out, base + ANGULAR_VELOCITY_COV)
    assert all(math.isfinite(v) for v in w + (cov[0], cov[4], cov[8])), (w, cov)
    assert all(abs(v) <= MAX_RATE_RAD_S for v in w_in)
    assert all(abs(o - i) <= MAX_DRIFT_RAD_S for o, i in zip(w, w_in)), (w, w_in)
    a = struct.unpack_from('<3d', out, base + LINEAR_ACCELERATION)
    if a_in is not None and np.array(a).tobytes() != np.array(a_in).tobytes():
        assert all(math.isfinite(v) and abs(v - u) <= MAX_ACCEL_DRIFT_MPS2
                   for v, u in zip(a, a_in))
    return True


@pytest.mark.parametrize('kind', ['static', 'dtdt', 'forged', 'forged_nan'])
def test_the_raw_path_never_raises_nor_marks_an_implausible_output(cores, kind):
    core = CompensatorCore(Policy(), cores[kind])
    seen = {'marked': 0, 'out': 0}

    @settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
    @given(data=ANY_BYTES, temps=st.lists(st.tuples(st.integers(-5, 5),
                                                    FLOATS | st.floats(15.0, 35.0)),
                                          max_size=3),
           good=st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0),
                                   st.floats(-1.0, 1.0)), min_size=1, max_size=3))
    def one(data, temps, good):
        # Hostile thermometer readings around the stamp, a hostile message, good ones around.
        found = locate(data)
        t = 1_700_000_000.0 if found is None else found[0] + found[1] * 1e-9
        for dt, temp_c in temps:
            core.add_temperature(t + dt, temp_c)
        for w in good:
            msg = encode([1_700_000_000], [0], 'imu_link', [[0.0, 0.0, 0.0, 1.0] + [0.0] * 9
                                                            + list(w) + [1e-6, 0, 0, 0, 1e-6,
                                                                         0, 0, 0, 1e-6]
                                                            + [0.0, 0.0, 9.81] + [1e-3] * 9])[0]
            done = raw_path(core, msg)
            seen['marked'] += check_output(*done)
        done = raw_path(core, data)
        if done is not None:
            seen['out'] += 1
            seen['marked'] += check_output(*done)

    core.add_temperature(1_700_000_000.0, 25.0)
    one()
    assert seen['out'] > 20                               # hostile messages came through
    if kind.startswith('forged'):
        assert seen['marked'] == 0 and core.flag_counts[PASSTHROUGH] > 100
    else:
        assert seen['marked'] > 100                       # the property was exercised
