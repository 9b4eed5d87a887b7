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
Read and patch a serialized sensor_msgs/Imu in place (pure; no rclpy).

The compensator changes three doubles and three covariance entries of each message. Taking
the message as CDR bytes (a raw subscription) and patching them saves the deserialisation
into a Python object and the serialisation back, which are most of a relay's cost. The
layout is fixed but for ``header.frame_id``: after the 4-byte encapsulation header come
``stamp`` (int32 sec, uint32 nanosec), the frame_id (uint32 length including the NUL, then
the bytes), then, aligned to 8 bytes from the start of the payload, ``orientation`` (4
doubles), ``orientation_covariance`` (9), ``angular_velocity`` (3),
``angular_velocity_covariance`` (9), ``linear_acceleration`` (3) and
``linear_acceleration_covariance`` (9): 296 bytes. Only little-endian plain CDR is handled;
anything else returns None so that the caller deserialises the message the usual way.
"""

from __future__ import annotations

import struct

__all__ = ['ImuView', 'locate']

_LE_CDR = (0x00, 0x01)        # encapsulation: plain CDR, little endian
_STAMP = struct.Struct('<iII')  # sec, nanosec, frame_id length
_VEC3 = struct.Struct('<3d')
_COV = struct.Struct('<9d')
_TAIL = 296                   # bytes from orientation to the end

# Offsets from the start of ``orientation``.
ANGULAR_VELOCITY = 4 * 8 + 9 * 8
ANGULAR_VELOCITY_COV = ANGULAR_VELOCITY + 3 * 8
LINEAR_ACCELERATION = ANGULAR_VELOCITY_COV + 9 * 8
LINEAR_ACCELERATION_COV = LINEAR_ACCELERATION + 3 * 8


def locate(data: bytes) -> tuple[int, int, int] | None:
    """
    Find the fields of a serialized Imu.

    Parameters
    ----------
    data : bytes
        The serialized message, encapsulation header included.

    Returns
    -------
    tuple of (int, int, int) or None
        ``(sec, nanosec, base)`` with ``base`` the byte offset of ``orientation`` in
        ``data``; None when ``data`` is not little-endian plain CDR of an Imu.

    """
    if len(data) < 4 + 12 + _TAIL or data[0] != _LE_CDR[0] or data[1] != _LE_CDR[1]:
        return None
    sec, nanosec, length = _STAMP.unpack_from(data, 4)
    payload = (12 + length + 7) & ~7
    if len(data) != 4 + payload + _TAIL:
        return None
    return sec, nanosec, 4 + payload


class ImuView:
    """
    Accessors for the fields of a serialized Imu found by :func:`locate`.

    Parameters
    ----------
    data : bytes
        The serialized message.
    base : int
        Offset of ``orientation`` (from :func:`locate`).

    """

    __slots__ = ('data', 'base')

    def __init__(self, data: bytes, base: int) -> None:
        self.data = data
        self.base = base

    def angular_velocity(self) -> tuple[float, float, float]:
        """Return ``angular_velocity`` (x, y, z), rad/s."""
        return _VEC3.unpack_from(self.data, self.base + ANGULAR_VELOCITY)

    def linear_acceleration(self) -> tuple[float, float, float] | None:
        """Return ``linear_acceleration``, m/s^2, or None when its covariance[0] is -1."""
        cov0 = struct.unpack_from('<d', self.data, self.base + LINEAR_ACCELERATION_COV)[0]
        if cov0 == -1.0:
            return None
        return _VEC3.unpack_from(self.data, self.base + LINEAR_ACCELERATION)

    def patched(self, wx: float, wy: float, wz: float,
                var: tuple[float, float, float]) -> bytes:
        """
        Return a copy with ``angular_velocity`` replaced and ``var`` added to its covariance.

        Parameters
        ----------
        wx, wy, wz : float, rad/s
            New angular velocity.
        var : tuple of 3 float, (rad/s)^2
            Added to the covariance diagonal unless its first element is -1.

        Returns
        -------
        bytes
            The serialized message, every other byte unchanged.

        """
        buf = bytearray(self.data)
        base = self.base
        _VEC3.pack_into(buf, base + ANGULAR_VELOCITY, wx, wy, wz)
        c = base + ANGULAR_VELOCITY_COV
        cov = _COV.unpack_from(buf, c)
        if cov[0] != -1.0:
            struct.pack_into('<d', buf, c, cov[0] + var[0])
            struct.pack_into('<d', buf, c + 32, cov[4] + var[1])
            struct.pack_into('<d', buf, c + 64, cov[8] + var[2])
        return bytes(buf)
