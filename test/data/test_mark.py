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

"""The compensation mark (no rclpy): where it lives, what it changes, what it leaves alone."""

from __future__ import annotations

import math

from gyro_tdc.data.imu_cdr import ImuView, locate
from gyro_tdc.data.mark import cov_marked, diagonal_marked, MARK
from marks import is_marked, mark
import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores


@pytest.mark.parametrize('value', [1e-6, 2.5e-5, 0.25, 1.0, 3.0e3, 5e-324 * 2 ** 60])
def test_mark_changes_a_variance_by_less_than_2_to_the_minus_36(value):
    marked = mark(value)
    assert is_marked(marked) and not is_marked(np.nextafter(marked, 1.0))
    assert marked > 0.0 and abs(marked - value) <= value * 2.0 ** -36
    assert mark(marked) == marked


@pytest.mark.parametrize('value', [0.0, -1.0, -0.5, math.inf, math.nan])
def test_no_data_unknown_and_non_finite_are_never_marked(value):
    assert mark(value) is value or (math.isnan(value) and math.isnan(mark(value)))
    assert not is_marked(mark(value))


def test_a_covariance_is_marked_on_its_whole_diagonal_or_not_at_all():
    cov = np.array([1e-6, 1e-9, 0.0, 0.0, 2e-6, 0.0, 0.0, 0.0, 3e-6])
    assert not diagonal_marked(cov)
    cov[[0, 4]] = mark(cov[0]), mark(cov[4])
    assert not diagonal_marked(cov)                 # two of three: not the mark
    cov[8] = mark(cov[8])
    assert diagonal_marked(cov) and cov[1] == 1e-9
    assert not diagonal_marked(np.array([-1.0] + [0.0] * 8))


def imu_bytes(cov0=1e-6):
    store = get_typestore(Stores.ROS2_JAZZY)
    Imu = store.types['sensor_msgs/msg/Imu']
    Header = store.types['std_msgs/msg/Header']
    Time = store.types['builtin_interfaces/msg/Time']
    Quaternion = store.types['geometry_msgs/msg/Quaternion']
    Vector3 = store.types['geometry_msgs/msg/Vector3']
    cov = np.zeros(9)
    cov[[0, 4, 8]] = cov0, 2e-6, 3e-6
    msg = Imu(Header(Time(1, 2), 'imu_link'), Quaternion(0, 0, 0, 1), np.full(9, -1.0),
              Vector3(0.1, 0.2, 0.3), cov, Vector3(0, 0, 9.81), np.eye(3).ravel() * 1e-3)
    return bytes(store.serialize_cdr(msg, 'sensor_msgs/msg/Imu')), store


@pytest.mark.parametrize('cov0,marks', [(1e-6, True), (-1.0, False), (0.0, False)])
def test_imu_view_marks_only_what_it_may(cov0, marks):
    data, store = imu_bytes(cov0)
    sec, nanosec, base = locate(data)
    view = ImuView(data, base)
    assert not view.marked()
    var = (0.0, 0.0, 0.0) if cov0 == 0.0 else (1e-7, 1e-7, 1e-7)
    out = view.patched(0.5, 0.6, 0.7, var, mark=True)
    assert ImuView(out, base).marked() is marks
    plain = view.patched(0.5, 0.6, 0.7, var)
    assert not ImuView(plain, base).marked()
    # Only the two lowest bytes of the three diagonal entries differ from the plain patch.
    diff = [i for i, (a, b) in enumerate(zip(out, plain)) if a != b]
    assert len(diff) <= 6 and (not marks or diff)
    msg = store.deserialize_cdr(out, 'sensor_msgs/msg/Imu')
    assert diagonal_marked(msg.angular_velocity_covariance) is marks
    if marks:
        np.testing.assert_allclose(msg.angular_velocity_covariance[[0, 4, 8]],
                                   np.array([1e-6, 2e-6, 3e-6]) + 1e-7, rtol=2.0 ** -36)
        assert cov_marked(out, base + 8 * 16) and out.count(MARK) >= 3


def test_an_unknown_covariance_is_marked_by_the_sign_of_its_zeros():
    """REP 145 unknown (all zero) stays all zero to every reader, yet carries the mark."""
    cov = [-0.0, 0.0, 0.0, 0.0, -0.0, 0.0, 0.0, 0.0, -0.0]
    assert cov == [0.0] * 9 and diagonal_marked(cov)      # -0.0 == 0.0: nothing invented
    assert not diagonal_marked([0.0] * 9)                  # a driver's plain zeros
    assert not diagonal_marked(cov[:1] + [1e-9] + cov[2:])     # only all zero is marked so
    known = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6]
    assert not diagonal_marked(known)
    # Serialized: the patch writes the same zeros, and a relay (deserialise, serialise)
    # keeps them.
    store = get_typestore(Stores.ROS2_JAZZY)
    data, _ = imu_bytes(0.0)
    data = bytearray(data)
    _, _, base = locate(bytes(data))
    for k in (4, 8):
        data[base + 8 * 16 + 8 * k:base + 8 * 16 + 8 * k + 8] = bytes(8)
    view = ImuView(bytes(data), base)
    out = view.patched(0.5, 0.6, 0.7, (1e-7,) * 3, mark=True)
    assert ImuView(out, base).marked() and not ImuView(
        view.patched(0.5, 0.6, 0.7, (1e-7,) * 3), base).marked()
    msg = store.deserialize_cdr(out, 'sensor_msgs/msg/Imu')
    assert not any(msg.angular_velocity_covariance)
    assert diagonal_marked(msg.angular_velocity_covariance)
    assert [math.copysign(1.0, v) for v in msg.angular_velocity_covariance] == [
        -1, 1, 1, 1, -1, 1, 1, 1, -1]
    again = bytes(store.serialize_cdr(msg, 'sensor_msgs/msg/Imu'))
    assert again == out and cov_marked(again, base + 8 * 16)
