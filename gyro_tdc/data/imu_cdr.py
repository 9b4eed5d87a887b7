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
The wire layout of a serialized ``sensor_msgs/Imu`` (plain CDR), in one place.

Pure (numpy and struct). :class:`Layout` gives the fixed field offsets for a ``frame_id``
length (also of Temperature and Vector3Stamped), :func:`locate` finds them in one message and
:class:`ImuView` patches its rates in place. See ``doc/internals/data.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
import itertools
import struct

from gyro_tdc.data.mark import cov_marked, MARK, UNKNOWN_MARK
from gyro_tdc.errors import DatasetError
import numpy as np
from numpy.typing import ArrayLike

__all__ = ['ANGULAR_VELOCITY', 'ANGULAR_VELOCITY_COV', 'CDR_BE', 'CDR_LE', 'FRAME_ID',
           'FRAME_ID_LENGTH', 'IMU_DOUBLES', 'IMU_FIELDS', 'ImuView', 'LINEAR_ACCELERATION',
           'LINEAR_ACCELERATION_COV', 'Layout', 'STAMP_NANOSEC', 'STAMP_SEC', 'body_offset',
           'encode', 'field_slice', 'layout_of', 'locate']

#: Encapsulation headers of plain CDR (representation id 00 01 / 00 00, options 00 00).
CDR_LE = b'\x00\x01\x00\x00'
CDR_BE = b'\x00\x00\x00\x00'
#: Byte offsets of the header fields from the start of the message (encapsulation included).
STAMP_SEC = 4
STAMP_NANOSEC = 8
FRAME_ID_LENGTH = 12
FRAME_ID = 16
_ALIGN_ORIGIN = 4            # CDR alignment counts from the end of the encapsulation header

# The float64 fields of sensor_msgs/Imu in wire order, with their number of values.
_IMU_ORDER = (('orientation', 4), ('orientation_covariance', 9), ('angular_velocity', 3),
              ('angular_velocity_covariance', 9), ('linear_acceleration', 3),
              ('linear_acceleration_covariance', 9))


_STARTS = [0, *itertools.accumulate(count for _, count in _IMU_ORDER)]
#: Imu field name -> (index of its first value in the float64 block, number of values).
IMU_FIELDS: dict[str, tuple[int, int]] = {
    name: (k, count) for (name, count), k in zip(_IMU_ORDER, _STARTS)}
#: Number of float64 values after the header of an Imu.
IMU_DOUBLES = _STARTS[-1]
#: Byte offsets of the fields the compensator touches, from the start of the float64 block.
ANGULAR_VELOCITY = 8 * IMU_FIELDS['angular_velocity'][0]
ANGULAR_VELOCITY_COV = 8 * IMU_FIELDS['angular_velocity_covariance'][0]
LINEAR_ACCELERATION = 8 * IMU_FIELDS['linear_acceleration'][0]
LINEAR_ACCELERATION_COV = 8 * IMU_FIELDS['linear_acceleration_covariance'][0]


def field_slice(name: str) -> slice:
    """
    Return the columns of an Imu field in the float64 block after the header.

    Parameters
    ----------
    name : str
        A key of :data:`IMU_FIELDS` (e.g. ``'angular_velocity'``).

    Returns
    -------
    slice
        ``block[:, field_slice(name)]`` holds the field (covariances row-major, 3 x 3).

    """
    first, count = IMU_FIELDS[name]
    return slice(first, first + count)


def body_offset(frame_len: int) -> int:
    """
    Return the float64 block's byte offset after a header (4 more than a multiple of 8).

    ``frame_len`` is the serialized ``frame_id`` length, NUL included; the offset counts
    from the start of the message, encapsulation included.
    """
    return _ALIGN_ORIGIN + (FRAME_ID + frame_len - _ALIGN_ORIGIN + 7) // 8 * 8


@dataclass(frozen=True)
class Layout:
    """
    The fixed layout of a header-plus-float64 message for one ``frame_id`` length.

    Parameters
    ----------
    frame_len : int
        Serialized ``frame_id`` length, terminating NUL included (>= 1).
    n_doubles : int
        Float64 values after the header (37 for an Imu).
    big_endian : bool
        Byte order of the encapsulation (CDR_BE when True).

    """

    frame_len: int
    n_doubles: int = IMU_DOUBLES
    big_endian: bool = False

    @property
    def body(self) -> int:
        """Return the byte offset of the float64 block from the start of the message."""
        return body_offset(self.frame_len)

    @property
    def size(self) -> int:
        """Return the length of the serialized message in bytes."""
        return self.body + 8 * self.n_doubles

    @cached_property
    def dtype(self) -> np.dtype:
        """
        Return the structured dtype of one message; ``itemsize`` is the message length.

        Fields ``encap`` (4 x u1), ``sec`` (i4), ``nanosec`` (u4), ``strlen`` (u4),
        ``frame`` (``frame_len`` x u1, NUL included) and ``data`` (``n_doubles`` x f8),
        in the byte order of the message.
        """
        order = '>' if self.big_endian else '<'
        return np.dtype({
            'names': ['encap', 'sec', 'nanosec', 'strlen', 'frame', 'data'],
            'formats': [('u1', (4,)), order + 'i4', order + 'u4', order + 'u4',
                        ('u1', (self.frame_len,)), (order + 'f8', (self.n_doubles,))],
            'offsets': [0, STAMP_SEC, STAMP_NANOSEC, FRAME_ID_LENGTH, FRAME_ID, self.body],
            'itemsize': self.size})


def layout_of(data: bytes, n_doubles: int = IMU_DOUBLES) -> Layout:
    """
    Return the layout (byte order, ``frame_id`` length) of one serialized message, checked.

    ``data`` includes the encapsulation header; ``n_doubles`` float64 values follow the
    header (37 for an Imu). Raises DatasetError when ``data`` is too short, not plain CDR (the
    option bytes are not checked), its ``frame_id`` length impossible or not NUL-terminated,
    or its length not the layout's.
    """
    n = len(data)
    if n < FRAME_ID:
        raise DatasetError(f'Expected a serialized message of at least {FRAME_ID} bytes '
                           f'(encapsulation and header), got {n} bytes.')
    if (rep := bytes(data[:2])) not in (CDR_LE[:2], CDR_BE[:2]):
        raise DatasetError(f'Expected the encapsulation header to start with the plain CDR '
                           f'representation {CDR_LE[:2].hex(" ")} (little endian) or '
                           f'{CDR_BE[:2].hex(" ")} (big endian), got {rep.hex(" ")}.')
    big = rep == CDR_BE[:2]
    frame_len = int.from_bytes(data[FRAME_ID_LENGTH:FRAME_ID], 'big' if big else 'little')
    if not 1 <= frame_len <= n - FRAME_ID:
        raise DatasetError(f'Expected a frame_id length (NUL included) between 1 and '
                           f'{n - FRAME_ID} bytes in a {n}-byte message, got {frame_len}.')
    if data[FRAME_ID + frame_len - 1] != 0:
        raise DatasetError('Expected the frame_id to end with a NUL byte.')
    lay = Layout(frame_len, n_doubles, big)
    if n != lay.size:
        raise DatasetError(f'Expected {lay.size} bytes for a message of {n_doubles} float64 '
                           f'values after a {frame_len}-byte frame_id, got {n} bytes.')
    return lay


def encode(sec: ArrayLike, nanosec: ArrayLike, frame_id: str, values: ArrayLike, *,
           big_endian: bool = False) -> list[bytes]:
    """
    Serialize header-plus-float64 messages that share one frame id, one per row of ``values``.

    ``values`` (N, K): K = 37 for an Imu, in :data:`IMU_FIELDS` order. The bytes are exactly
    what rosbags' ``serialize_cdr`` writes.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 2:
        raise DatasetError(f'Expected `values` to have shape (N, K), got {values.shape}.')
    frame = frame_id.encode('utf-8') + b'\x00'
    lay = Layout(len(frame), values.shape[1], big_endian)
    rec = np.zeros(values.shape[0], dtype=lay.dtype)
    for name, value in (('encap', np.frombuffer(CDR_BE if big_endian else CDR_LE, np.uint8)),
                        ('sec', sec), ('nanosec', nanosec), ('strlen', len(frame)),
                        ('frame', np.frombuffer(frame, dtype=np.uint8)), ('data', values)):
        rec[name] = value
    buf, size = rec.tobytes(), lay.size
    return [buf[i:i + size] for i in range(0, len(buf), size)]


# --------------------------------------------------------------------------------------------
# In-place access for the compensator (little endian only: the hot path of every message)
# --------------------------------------------------------------------------------------------

_HEAD = struct.Struct('<iII')   # sec, nanosec, frame_id length (little endian)
_VEC3 = struct.Struct('<3d')
_COV = struct.Struct('<9d')
_F64 = struct.Struct('<d')
_TAIL = 8 * IMU_DOUBLES         # bytes of the float64 block
_LE0, _LE1 = CDR_LE[0], CDR_LE[1]
_INF = float('inf')
_U16_INTO = struct.Struct('<H').pack_into
_MARK16 = int.from_bytes(MARK, 'little')


def locate(data: bytes) -> tuple[int, int, int] | None:
    """
    Find ``(sec, nanosec, base)`` of a serialized little-endian Imu (None: not one).

    ``base`` is the byte offset of ``orientation`` (the float64 block) in ``data``; on None
    the caller deserialises the message the general way.
    """
    if len(data) < FRAME_ID + _TAIL or data[0] != _LE0 or data[1] != _LE1:
        return None
    sec, nanosec, length = _HEAD.unpack_from(data, STAMP_SEC)
    base = body_offset(length)
    return (sec, nanosec, base) if len(data) == base + _TAIL else None


class ImuView:
    """
    Accessors for the fields of a serialized little-endian Imu found by :func:`locate`.

    Parameters
    ----------
    data : bytes
        The serialized message.
    base : int
        Offset of ``orientation`` (from :func:`locate`).

    """

    __slots__ = ('data', 'base')

    def __init__(self, data: bytes, base: int) -> None:
        self.data, self.base = data, base

    def angular_velocity(self) -> tuple[float, float, float]:
        """Return ``angular_velocity`` (x, y, z), rad/s."""
        return _VEC3.unpack_from(self.data, self.base + ANGULAR_VELOCITY)

    def linear_acceleration(self) -> tuple[float, float, float] | None:
        """Return ``linear_acceleration``, m/s^2, or None when its covariance[0] is -1."""
        return (None if _F64.unpack_from(self.data, self.base + LINEAR_ACCELERATION_COV)[0] == -1.0
                else _VEC3.unpack_from(self.data, self.base + LINEAR_ACCELERATION))

    def marked(self) -> bool:
        """Return whether the angular velocity covariance carries the compensation mark."""
        return cov_marked(self.data, self.base + ANGULAR_VELOCITY_COV)

    def patched(self, wx: float, wy: float, wz: float,
                var: tuple[float, float, float], mark: bool = False,
                accel: tuple[float, float, float] | None = None,
                accel_var: tuple[float, float, float] | None = None,
                base_variance: float = 0.0) -> bytes:
        """
        Return a copy with ``angular_velocity`` replaced and ``var`` added to its covariance.

        Rates rad/s, variances (rad/s)^2; every other byte is unchanged. ``var`` is not added to
        a covariance marked absent (-1, REP 145), nor to an all-zero (unknown) one unless
        ``base_variance`` > 0 makes its diagonal ``base_variance + var``. ``mark`` writes
        :mod:`gyro_tdc.data.mark`'s mark into a positive finite diagonal, or -0.0 into one that
        stays unknown. ``accel`` (m/s^2) replaces ``linear_acceleration``; ``accel_var`` is
        added to its covariance unless marked absent (None: left as is; never marked).
        """
        buf, base = bytearray(self.data), self.base
        _VEC3.pack_into(buf, base + ANGULAR_VELOCITY, wx, wy, wz)
        c = base + ANGULAR_VELOCITY_COV
        cov = _COV.unpack_from(buf, c)
        b = 0.0
        if cov[0] == 0.0 and not any(cov):  # REP 145 unknown: stays so without a base
            b = base_variance if base_variance > 0.0 else None
        if cov[0] != -1.0 and b is not None:
            v0, v4, v8 = cov[0] + (b + var[0]), cov[4] + (b + var[1]), cov[8] + (b + var[2])
            _F64.pack_into(buf, c, v0)
            _F64.pack_into(buf, c + 32, v4)
            _F64.pack_into(buf, c + 64, v8)
            if mark and 0.0 < v0 < _INF and 0.0 < v4 < _INF and 0.0 < v8 < _INF:
                _U16_INTO(buf, c, _MARK16)   # (not a bytearray slice assignment: slower)
                _U16_INTO(buf, c + 32, _MARK16)
                _U16_INTO(buf, c + 64, _MARK16)
        elif mark and b is None:             # unknown stays unknown: -0.0 diagonal marks it
            buf[c:c + 8] = buf[c + 32:c + 40] = buf[c + 64:c + 72] = UNKNOWN_MARK
        if accel is not None:
            _VEC3.pack_into(buf, base + LINEAR_ACCELERATION, *accel)
        if accel_var is not None:
            c = base + LINEAR_ACCELERATION_COV
            cov = _COV.unpack_from(buf, c)
            if cov[0] != -1.0:
                for k, v in enumerate(accel_var):     # the diagonal: entries 0, 4 and 8
                    _F64.pack_into(buf, c + 32 * k, cov[4 * k] + v)
        return bytes(buf)
