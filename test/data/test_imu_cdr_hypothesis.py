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
Hostile bytes through the serialized-Imu path (hypothesis): nothing raises, nothing implausible.

Random bytes and hostile variants of real messages (truncated, extended, a big-endian or
unknown header, ``frame_id`` lengths up to 2**32 - 1, overwritten bytes, NaN, Inf, 1e300 and
subnormal fields, covariance junk) go through :func:`~gyro_tdc.data.imu_cdr.layout_of`,
:func:`~gyro_tdc.data.imu_cdr.locate` and :class:`~gyro_tdc.data.imu_cdr.ImuView`, and through
the compensator's raw path as the node composes it (locate, view, ``CompensatorCore.process``,
``ImuView.patched``): each raises nothing but DatasetError where documented, and a sample that
comes out marked compensated is finite and corrected by a plausible drift.
"""

from __future__ import annotations

import math
import struct

from cdr_strategies import ANY_BYTES, FLOATS
from gyro_tdc.base import MAX_ACCEL_DRIFT_MPS2, MAX_DRIFT_RAD_S, MAX_RATE_RAD_S, model_path
from gyro_tdc.data.imu_cdr import (ANGULAR_VELOCITY, ANGULAR_VELOCITY_COV, CDR_BE, CDR_LE,
                                   encode, FRAME_ID, IMU_DOUBLES, IMU_FIELDS,
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
from synth import synth_run

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
