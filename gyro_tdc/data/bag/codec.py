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
The fixed-layout numpy CDR codec of the three recorded message types, checked against rosbags.

Imu, Temperature and Vector3Stamped blocks are encoded (:func:`encode_checked`) and decoded
(:func:`decode_joined`) as numpy structured arrays; every fast path checks itself against
rosbags' serialiser and falls back to it (:func:`decode_slow`). Temperatures published as a
bare ``std_msgs/msg/Float32`` or ``Float64`` (no header) are decoded by
:func:`decode_float`. See ``doc/internals/data.md``.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import functools
from typing import Any, Callable, Sequence, Union

from gyro_tdc.data import imu_cdr
from gyro_tdc.data.imu_cdr import CDR_LE, field_slice, IMU_DOUBLES, IMU_FIELDS, layout_of
from gyro_tdc.errors import DatasetError
import numpy as np
from numpy.typing import NDArray
from rosbags.serde import SerdeError
from rosbags.typesys import get_typestore, Stores

__all__ = ['Decoded', 'FLOAT_TYPES', 'IMU_TYPE', 'KEEP', 'Logs', 'N_DOUBLES', 'REFERENCE_TYPE',
           'TEMPERATURE_TYPE', 'TEMPERATURE_TYPES', 'decode_float', 'decode_joined',
           'decode_slow', 'encode_checked', 'from_msg', 'jazzy', 'to_msg']

IMU_TYPE = 'sensor_msgs/msg/Imu'
TEMPERATURE_TYPE = 'sensor_msgs/msg/Temperature'
REFERENCE_TYPE = 'geometry_msgs/msg/Vector3Stamped'
#: Bare temperature readings (degC, no header), as the compensator node also takes them: the
#: little-endian numpy dtype of the value after the 4-byte CDR encapsulation.
FLOAT_TYPES = {'std_msgs/msg/Float32': '<f4', 'std_msgs/msg/Float64': '<f8'}
#: The message types a temperature topic may have, the stamped one first.
TEMPERATURE_TYPES = (TEMPERATURE_TYPE, *FLOAT_TYPES)

# Number of float64 values after the header, per message type.
N_DOUBLES = {IMU_TYPE: IMU_DOUBLES, TEMPERATURE_TYPE: 2, REFERENCE_TYPE: 3}


# Columns of that float64 block that read_bag keeps: Imu angular_velocity and
# linear_acceleration (gyro_tdc.data.imu_cdr.IMU_FIELDS); Temperature temperature and
# variance; Vector3Stamped x, y, z.
KEEP = {IMU_TYPE: tuple(k for name in ('angular_velocity', 'linear_acceleration')
                        for k in range(IMU_DOUBLES)[field_slice(name)]),
        TEMPERATURE_TYPE: (0, 1), REFERENCE_TYPE: (0, 1, 2)}


#: Log times of a block, or a function that fetches them when a message needs them.
Logs = Union[NDArray[np.int64], Callable[[], NDArray[np.int64]]]


@functools.lru_cache(maxsize=None)
def jazzy() -> Any:
    """Return the (cached) ROS 2 Jazzy typestore."""
    return get_typestore(Stores.ROS2_JAZZY)


def to_msg(msgtype: str, sec: int, nanosec: int, frame_id: str,
           row: NDArray[np.float64]) -> Any:
    """Build a rosbags message object of ``msgtype`` from a header and its float64 block."""
    types = jazzy().types
    header = types['std_msgs/msg/Header'](
        types['builtin_interfaces/msg/Time'](int(sec), int(nanosec)), frame_id)
    row = [float(x) for x in row]
    vec = types['geometry_msgs/msg/Vector3']
    if msgtype == TEMPERATURE_TYPE:
        return types[TEMPERATURE_TYPE](header, row[0], row[1])
    if msgtype != IMU_TYPE:
        return types[REFERENCE_TYPE](header, vec(*row[0:3]))
    f = {name: row[field_slice(name)] for name in IMU_FIELDS}
    return types[IMU_TYPE](
        header, types['geometry_msgs/msg/Quaternion'](*f['orientation']),
        np.array(f['orientation_covariance']), vec(*f['angular_velocity']),
        np.array(f['angular_velocity_covariance']), vec(*f['linear_acceleration']),
        np.array(f['linear_acceleration_covariance']))


def from_msg(msgtype: str, msg: Any) -> tuple[int, int, str, list[float]]:
    """Return (sec, nanosec, frame_id, float64 block) of a deserialised message."""
    if msgtype in FLOAT_TYPES:    # no header: the value and an unknown (0) variance
        return 0, 0, '', [float(msg.data), 0.0]
    stamp = msg.header.stamp
    if msgtype == IMU_TYPE:   # the fields in wire order (gyro_tdc.data.imu_cdr.IMU_FIELDS)
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        row = [o.x, o.y, o.z, o.w, *msg.orientation_covariance, w.x, w.y, w.z,
               *msg.angular_velocity_covariance, a.x, a.y, a.z,
               *msg.linear_acceleration_covariance]
    else:
        v = msg.vector if msgtype == REFERENCE_TYPE else None
        row = [msg.temperature, msg.variance] if v is None else [v.x, v.y, v.z]
    if len(row) != N_DOUBLES[msgtype]:
        raise DatasetError(f'Expected {msgtype} to hold {N_DOUBLES[msgtype]} float64 values '
                           f'after its header, got {len(row)}.')
    return int(stamp.sec), int(stamp.nanosec), str(msg.header.frame_id), row


def encode_checked(msgtype: str, sec: NDArray[np.int64], nanosec: NDArray[np.int64],
                   frame_id: str, data: NDArray[np.float64]) -> list[bytes]:
    """Encode with numpy once verified against rosbags on the first message, else rosbags."""
    if not len(sec):
        return []
    out = imu_cdr.encode(sec, nanosec, frame_id, data)
    ts = jazzy()
    if bytes(ts.serialize_cdr(to_msg(msgtype, sec[0], nanosec[0], frame_id, data[0]),
                              msgtype)) == out[0]:
        return out
    # The fixed layout disagrees with rosbags (should not happen): serialise one by one.
    return [bytes(ts.serialize_cdr(to_msg(msgtype, s, ns, frame_id, row), msgtype))
            for s, ns, row in zip(sec.tolist(), nanosec.tolist(), data)]


@dataclass(frozen=True)
class Decoded:
    """Header stamps, first frame id and kept float64 columns of a block of messages."""

    sec: NDArray[np.int64]
    nanosec: NDArray[np.int64]
    frame_id: str
    values: NDArray[np.float64]
    fallback: int
    undecodable: NDArray[np.bool_] | None = None


def _decode_records(buf: bytes | memoryview, sizes: NDArray[np.int64], msgtype: str,
                    typestore: Any, keep: Sequence[int] | None) -> Decoded | None:
    """
    Decode messages of ``sizes`` bytes stored end to end in ``buf`` with numpy, or return None.

    None: the messages do not share one fixed layout (size, encapsulation, frame id) or a
    sampled message disagrees with rosbags' deserialiser of ``typestore`` (the one that
    decodes them otherwise).
    """
    n = len(sizes)
    try:
        if not n or np.any(sizes != sizes[0]):
            return None
        size = int(sizes[0])
        dt = layout_of(bytes(buf[:size]), N_DOUBLES[msgtype]).dtype   # of size bytes
        rec = np.frombuffer(buf[:n * size], dtype=dt)
        # Encapsulation (word 0), frame id length, frame id and its padding equal to the first
        # message's, compared as raw 32-bit words column by column (one strided pass each).
        words = np.frombuffer(buf[:n * size], dtype=np.uint32).reshape(n, size // 4)
        frame, data = rec['frame'], rec['data']
        cols = [0, *range(imu_cdr.FRAME_ID_LENGTH // 4, dt.fields['data'][1] // 4)]
        if frame[0, -1] != 0 or any(np.any(words[:, k] != words[0, k]) for k in cols):
            return None
        frame_id = frame[0, :-1].tobytes().decode('utf-8')
        for i in sorted({0, n // 2, n - 1}):    # the layout checked against rosbags
            raw = bytes(buf[i * size:(i + 1) * size])
            sec, nsec, fid, row = from_msg(msgtype, typestore.deserialize_cdr(raw, msgtype))
            if (sec != rec['sec'][i] or nsec != rec['nanosec'][i] or fid != frame_id or not
                    np.array_equal(np.asarray(row, dtype=np.float64), data[i], equal_nan=True)):
                return None
    except (SerdeError, AttributeError, DatasetError, UnicodeDecodeError):
        return None
    keep = list(KEEP[msgtype] if keep is None else keep)
    return Decoded(rec['sec'].astype(np.int64), rec['nanosec'].astype(np.int64), frame_id,
                   data[:, keep].astype(np.float64, copy=False), 0)


def decode_joined(buf: bytes | memoryview, lengths: Sequence[int], msgtype: str,
                  typestore: Any, keep: Sequence[int] | None = None) -> Decoded:
    """
    Decode a block of messages stored end to end: numpy where they share one fixed layout.

    ``buf`` holds the messages (``lengths`` bytes each, in order; nothing returned refers to
    it), so the storage reads copy no message on its own. Where the layout does not hold, or a
    sampled message disagrees with rosbags, the ``typestore`` decodes message by message
    (``fallback`` of the result counts them). ``keep``: float64 columns returned (default
    ``KEEP[msgtype]``).
    """
    sizes = np.asarray(lengths, dtype=np.int64)
    return (_decode_records(buf, sizes, msgtype, typestore, keep)
            or decode_slow(buf, sizes, msgtype, typestore, keep))


def decode_slow(buf: bytes | memoryview, lengths: Sequence[int], msgtype: str, typestore: Any,
                keep: Sequence[int] | None = None) -> Decoded:
    """Decode a block stored end to end message by message with rosbags (any layout)."""
    ends = np.cumsum(lengths).tolist()
    raws = [bytes(buf[a:b]) for a, b in zip([0] + ends[:-1], ends)]
    n = len(raws)
    keep = list(KEEP[msgtype] if keep is None else keep)
    sec, nsec = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    values, bad, frame_id = np.full((n, len(keep)), np.nan), np.zeros(n, dtype=bool), None
    for i, raw in enumerate(raws):
        try:
            s, ns, fid, row = from_msg(msgtype, typestore.deserialize_cdr(raw, msgtype))
        except (SerdeError, AttributeError, TypeError, ValueError):
            bad[i] = True
            continue
        sec[i], nsec[i] = s, ns
        values[i] = [row[k] for k in keep]
        if frame_id is None:
            frame_id = fid
    return Decoded(sec, nsec, frame_id or '', values, n, bad if bad.any() else None)


def decode_float(buf: bytes | memoryview, lengths: Sequence[int], msgtype: str,
                 typestore: Any) -> Decoded:
    """
    Decode a block of ``std_msgs/msg/Float32`` or ``Float64`` temperatures (degC, variance 0).

    The messages (stored end to end in ``buf``) have no header: ``sec`` and ``nanosec`` are
    zero (the reader stamps each reading with the latest IMU message, as the node does live);
    the variance is 0 (unknown, as ``sensor_msgs/msg/Temperature`` says). Plain little-endian
    CDR of one fixed size is read with numpy, checked against rosbags on its first, middle and
    last message; anything else by rosbags (``undecodable`` marks what it could not read).
    """
    n, sizes = len(lengths), np.asarray(lengths, dtype=np.int64)
    dtype = np.dtype(FLOAT_TYPES[msgtype])
    size = len(CDR_LE) + dtype.itemsize
    raw = np.frombuffer(buf, dtype=np.uint8)
    if n and np.all(sizes == size) and np.all(raw.reshape(n, size)[:, :4] == list(CDR_LE)):
        value = np.ndarray((n,), dtype=dtype, buffer=buf, offset=len(CDR_LE), strides=(size,))
        with contextlib.suppress(SerdeError, AttributeError):
            if all(np.array_equal(np.float64(typestore.deserialize_cdr(
                    bytes(buf[i * size:(i + 1) * size]), msgtype).data), np.float64(value[i]),
                    equal_nan=True) for i in sorted({0, n // 2, n - 1})):
                zeros = np.zeros(n, dtype=np.int64)
                return Decoded(zeros, zeros.copy(), '', np.column_stack([value, zeros * 0.0]), 0)
    return decode_slow(buf, sizes, msgtype, typestore, (0, 1))
