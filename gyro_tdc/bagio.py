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
Write and read rosbag2 bags of IMU, temperature and reference-rate messages, fast.

Pure rosbags + numpy (no rclpy). The three message types this package records all share
one shape on the wire: a ``std_msgs/Header`` followed by a flat run of float64 values
(``sensor_msgs/Imu``: 37, ``sensor_msgs/Temperature``: 2, ``geometry_msgs/Vector3Stamped``:
3). For a given ``frame_id`` length the CDR bytes of such a message have a fixed layout,
described once in :mod:`gyro_tdc.imu_cdr`, so all messages of a topic are written and read
as one numpy structured array (:attr:`gyro_tdc.imu_cdr.Layout.dtype`) instead of one Python
object per message. Every fast path checks itself against rosbags' own serialiser
(``serialize_cdr`` / ``deserialize_cdr``) and falls back to it, per chunk of messages,
whenever the layout does not hold (frame ids of different lengths, another encapsulation,
trailing bytes...).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
import shutil
import sqlite3
import struct
from typing import Any, Callable, Sequence

import apsw
from gyro_tdc import imu_cdr
from gyro_tdc.errors import DatasetError, one_line
from gyro_tdc.imu_cdr import field_slice, IMU_DOUBLES, IMU_FIELDS, layout_of
from gyro_tdc.yamlio import BAG_METADATA_LIMITS, load_yaml
import numpy as np
from numpy.typing import ArrayLike, NDArray
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness
from rosbags.interfaces import QosReliability, QosTime
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer, WriterError
from rosbags.serde import SerdeError
from rosbags.typesys import get_typestore, Stores
import yaml

__all__ = [
    'BagData',
    'IMU_TYPE',
    'REFERENCE_TYPE',
    'TEMPERATURE_TYPE',
    'read_bag',
    'write_bag',
]

IMU_TYPE = 'sensor_msgs/msg/Imu'
TEMPERATURE_TYPE = 'sensor_msgs/msg/Temperature'
REFERENCE_TYPE = 'geometry_msgs/msg/Vector3Stamped'

# Number of float64 values after the header, per message type.
_N_DOUBLES = {IMU_TYPE: IMU_DOUBLES, TEMPERATURE_TYPE: 2, REFERENCE_TYPE: 3}


def _columns(*names: str) -> tuple[int, ...]:
    """Return the float64-block columns of Imu fields (see gyro_tdc.imu_cdr.IMU_FIELDS)."""
    return tuple(k for name in names for k in range(IMU_DOUBLES)[field_slice(name)])


# Columns of that float64 block that read_bag keeps: Imu angular_velocity and
# linear_acceleration; Temperature temperature and variance; Vector3Stamped x, y, z.
_KEEP = {IMU_TYPE: _columns('angular_velocity', 'linear_acceleration'),
         TEMPERATURE_TYPE: (0, 1), REFERENCE_TYPE: (0, 1, 2)}

_WRITE_CHUNK = 1 << 16    # messages serialised per numpy call when writing
# Messages per block when reading: small enough that a block's raw bytes (~5 MB of Imu) are
# recycled by the allocator, large enough to amortise the per-block checks (1 << 14 read a
# 1 h, 1 kHz bag ~5 % faster than 1 << 13 or 1 << 15 in bench/bench_train.py).
_CHUNK = 1 << 14
_BAG_VERSION = 9          # rosbag2 metadata version written by Jazzy (rosbag2 0.26)
_STORAGES = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
# What rosbag2 (Jazzy) records for a reliable, volatile publisher with default deadlines.
_INFINITE = QosTime(9223372036, 854775807)
_QOS = Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, QosDurability.VOLATILE,
           _INFINITE, _INFINITE, QosLiveliness.AUTOMATIC, _INFINITE, False)
# rosbags' own errors, plus what its parsers let through on damaged files (found by fuzzing
# sqlite3 and mcap bags: huge record lengths raise OverflowError from seek, short reads
# struct.error).
_READ_ERRORS = (AnyReaderError, ReaderError, apsw.Error, OSError, SerdeError, yaml.YAMLError,
                UnicodeDecodeError, OverflowError, struct.error)

_TYPESTORE = None


def _jazzy() -> Any:
    """Return the (cached) ROS 2 Jazzy typestore."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


# --------------------------------------------------------------------------------------------
# Fixed CDR layout (gyro_tdc.imu_cdr) checked against rosbags
# --------------------------------------------------------------------------------------------

def _to_msg(msgtype: str, sec: int, nanosec: int, frame_id: str,
            row: NDArray[np.float64]) -> Any:
    """Build a rosbags message object of ``msgtype`` from a header and its float64 block."""
    ts = _jazzy()
    types = ts.types
    header = types['std_msgs/msg/Header'](
        types['builtin_interfaces/msg/Time'](int(sec), int(nanosec)), frame_id)
    row = [float(x) for x in row]
    if msgtype == IMU_TYPE:
        vec = types['geometry_msgs/msg/Vector3']
        f = {name: row[field_slice(name)] for name in IMU_FIELDS}
        return types[IMU_TYPE](
            header, types['geometry_msgs/msg/Quaternion'](*f['orientation']),
            np.array(f['orientation_covariance']), vec(*f['angular_velocity']),
            np.array(f['angular_velocity_covariance']), vec(*f['linear_acceleration']),
            np.array(f['linear_acceleration_covariance']))
    if msgtype == TEMPERATURE_TYPE:
        return types[TEMPERATURE_TYPE](header, row[0], row[1])
    return types[REFERENCE_TYPE](header, types['geometry_msgs/msg/Vector3'](*row[0:3]))


def _from_msg(msgtype: str, msg: Any) -> tuple[int, int, str, list[float]]:
    """Return (sec, nanosec, frame_id, float64 block) of a deserialised message."""
    stamp = msg.header.stamp
    if msgtype == IMU_TYPE:   # the fields in wire order (gyro_tdc.imu_cdr.IMU_FIELDS)
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        row = ([o.x, o.y, o.z, o.w, *msg.orientation_covariance, w.x, w.y, w.z,
                *msg.angular_velocity_covariance, a.x, a.y, a.z,
                *msg.linear_acceleration_covariance])
    elif msgtype == TEMPERATURE_TYPE:
        row = [msg.temperature, msg.variance]
    else:
        v = msg.vector
        row = [v.x, v.y, v.z]
    if len(row) != _N_DOUBLES[msgtype]:
        raise DatasetError(f'Expected {msgtype} to hold {_N_DOUBLES[msgtype]} float64 values '
                           f'after its header, got {len(row)}.')
    return int(stamp.sec), int(stamp.nanosec), str(msg.header.frame_id), row


def _encode_checked(msgtype: str, sec: NDArray[np.int64], nanosec: NDArray[np.int64],
                    frame_id: str, data: NDArray[np.float64]) -> list[bytes]:
    """Encode with numpy once verified against rosbags on the first message, else rosbags."""
    if not len(sec):
        return []
    out = imu_cdr.encode(sec, nanosec, frame_id, data)
    ref = bytes(_jazzy().serialize_cdr(
        _to_msg(msgtype, sec[0], nanosec[0], frame_id, data[0]), msgtype))
    if ref == out[0]:
        return out
    # The fixed layout disagrees with rosbags (should not happen): serialise one by one.
    ts = _jazzy()
    return [bytes(ts.serialize_cdr(_to_msg(msgtype, s, ns, frame_id, row), msgtype))
            for s, ns, row in zip(sec.tolist(), nanosec.tolist(), data)]


@dataclass(frozen=True)
class _Decoded:
    """Header stamps, first frame id and kept float64 columns of a block of messages."""

    sec: NDArray[np.int64]
    nanosec: NDArray[np.int64]
    frame_id: str
    values: NDArray[np.float64]
    fallback: int
    undecodable: NDArray[np.bool_] | None = None


def _decode_fast(raws: Sequence[bytes], msgtype: str,
                 keep: Sequence[int] | None = None) -> _Decoded | None:
    """
    Decode a block of raw CDR messages at once with numpy, or return None.

    None means the block does not share one fixed layout (lengths, encapsulation, frame id
    length or bytes differ) or a sampled message disagrees with rosbags' deserialiser.

    Parameters
    ----------
    raws : Sequence[bytes]
        Raw CDR messages of one message type.
    msgtype : str
        The message type.
    keep : sequence of int, optional
        Columns of the float64 block to return (default ``_KEEP[msgtype]``).

    Returns
    -------
    _Decoded or None
        The decoded block, or None when the caller must fall back.

    """
    n = len(raws)
    try:
        dt = layout_of(raws[0], _N_DOUBLES[msgtype]).dtype
    except DatasetError:
        return None
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=n)
    if np.any(lengths != dt.itemsize):
        return None
    buf = b''.join(raws)
    rec = np.frombuffer(buf, dtype=dt)
    # Encapsulation (word 0) and frame id length equal to the first message's, as raw
    # 32-bit words (itemsize is always a multiple of 4); then the frame id bytes.
    words = np.frombuffer(buf, dtype=np.uint32).reshape(n, dt.itemsize // 4)
    frame = rec['frame']
    k = imu_cdr.FRAME_ID_LENGTH // 4
    if (np.any(words[:, 0] != words[0, 0]) or np.any(words[:, k] != words[0, k])
            or np.any(frame != frame[0]) or frame[0, -1] != 0):
        return None
    try:
        frame_id = frame[0, :-1].tobytes().decode('utf-8')
    except UnicodeDecodeError:
        return None
    data = rec['data']
    # Check the layout against rosbags on a few messages of every block.
    ts = _jazzy()
    for i in sorted({0, n // 2, n - 1}):
        try:
            sec, nsec, fid, row = _from_msg(msgtype, ts.deserialize_cdr(raws[i], msgtype))
        except (SerdeError, AttributeError, DatasetError):
            return None
        if (sec != rec['sec'][i] or nsec != rec['nanosec'][i] or fid != frame_id
                or not np.array_equal(np.asarray(row, dtype=np.float64), data[i],
                                      equal_nan=True)):
            return None
    cols = list(_KEEP[msgtype] if keep is None else keep)
    values = data[:, cols].astype(np.float64, copy=False)
    return _Decoded(rec['sec'].astype(np.int64), rec['nanosec'].astype(np.int64), frame_id,
                    values, 0)


def _seconds(stamp_ns: NDArray[np.int64]) -> NDArray[np.float64]:
    """Return integer nanosecond stamps as float seconds (whole seconds added exactly)."""
    return (stamp_ns // 1_000_000_000) + (stamp_ns % 1_000_000_000) * 1e-9


def _decode_slow(raws: Sequence[bytes], msgtype: str, typestore: Any,
                 keep: Sequence[int] | None = None) -> _Decoded:
    """Decode a block message by message with rosbags (any layout, any frame ids)."""
    n = len(raws)
    keep = list(_KEEP[msgtype] if keep is None else keep)
    sec = np.zeros(n, dtype=np.int64)
    nsec = np.zeros(n, dtype=np.int64)
    values = np.full((n, len(keep)), np.nan)
    bad = np.zeros(n, dtype=bool)
    frame_id = None
    for i, raw in enumerate(raws):
        try:
            s, ns, fid, row = _from_msg(msgtype, typestore.deserialize_cdr(raw, msgtype))
        except (SerdeError, AttributeError):
            bad[i] = True
            continue
        sec[i], nsec[i] = s, ns
        values[i] = [row[k] for k in keep]
        if frame_id is None:
            frame_id = fid
    return _Decoded(sec, nsec, frame_id or '', values, n, bad if bad.any() else None)


def _decode(raws: Sequence[bytes], msgtype: str, typestore: Any,
            keep: Sequence[int] | None = None) -> _Decoded:
    """Decode a block with the numpy fast path, falling back to rosbags when needed."""
    return (_decode_fast(raws, msgtype, keep)
            or _decode_slow(raws, msgtype, typestore, keep))


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

def _times(name: str, t: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Return (sec, nanosec) of float seconds, checking shape, finiteness and sign."""
    arr = np.asarray(t, dtype=np.float64)
    if arr.ndim != 1:
        raise DatasetError(f'Expected `{name}` to have shape (N,), got {arr.shape}.')
    if not np.all(np.isfinite(arr)) or np.any(arr < 0) or np.any(arr >= 2.0 ** 31):
        raise DatasetError(f'Expected `{name}` to hold finite times in [0, 2**31) s, got '
                           f'values in [{np.nanmin(arr) if arr.size else 0}, '
                           f'{np.nanmax(arr) if arr.size else 0}].')
    sec = np.floor(arr)
    nsec = np.rint((arr - sec) * 1e9).astype(np.int64)
    sec = sec.astype(np.int64)
    carry = nsec >= 1_000_000_000
    sec[carry] += 1
    nsec[carry] -= 1_000_000_000
    return sec, nsec


def _values(name: str, a: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """Return ``a`` as float64 after checking its shape."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != shape:
        raise DatasetError(f'Expected `{name}` to have shape {shape}, got {arr.shape}.')
    return arr


def write_bag(path, *, imu_t, gyro, accel, temp_t, temp_c, temp_var=0.0, ref_t=None, ref=None,
              storage='sqlite3', frame_id='imu_link', imu_topic='/imu/data_raw',
              temperature_topic='/imu/temperature', reference_topic='/rate_table/reference',
              gyro_cov=None, accel_cov=None) -> None:
    """
    Write IMU, temperature and (optionally) reference-rate messages to a new rosbag2 bag.

    Messages of all topics are written in time order; header stamps and log times are the
    given times. Imu messages follow REP 145: identity orientation with
    ``orientation_covariance[0] = -1`` (no orientation estimate), diagonal rate and
    acceleration covariances. The bag embeds the ROS 2 Jazzy message definitions and uses
    metadata version 9 (what Jazzy's rosbag2 writes).

    Parameters
    ----------
    path : str or Path
        Bag directory to create; must not exist.
    imu_t : ArrayLike, shape (N,), s
        IMU stamps (seconds since any epoch, >= 0).
    gyro : ArrayLike, shape (N, 3), rad/s
        Angular velocity.
    accel : ArrayLike, shape (N, 3), m/s^2
        Linear acceleration.
    temp_t : ArrayLike, shape (M,), s
        Thermometer stamps.
    temp_c : ArrayLike, shape (M,), degC
        Temperature.
    temp_var : float or ArrayLike of shape (M,), degC^2
        Temperature variance (0 = unknown).
    ref_t : ArrayLike, shape (R,), s, optional
        Reference-rate stamps; no reference topic is written when None.
    ref : ArrayLike, shape (R, 3), rad/s, optional
        Reference (commanded) rate; required with ``ref_t``.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.
    frame_id : str
        Header frame id of every message.
    imu_topic, temperature_topic, reference_topic : str
        Topic names.
    gyro_cov, accel_cov : ArrayLike, shape (3,), optional
        Diagonals of ``angular_velocity_covariance`` and ``linear_acceleration_covariance``
        ((rad/s)^2 and (m/s^2)^2); zeros (unknown) when None. ``(-1, 0, 0)`` marks the
        quantity as absent (REP 145).

    Raises
    ------
    DatasetError
        When an argument has the wrong shape or the bag cannot be created.

    """
    if storage not in _STORAGES:
        raise DatasetError(f"Expected `storage` to be 'sqlite3' or 'mcap', got {storage!r}.")
    if not isinstance(frame_id, str):
        raise DatasetError(f'Expected `frame_id` to be a str, got {type(frame_id).__name__}.')
    imu_sec, imu_nsec = _times('imu_t', imu_t)
    n = len(imu_sec)
    gyro = _values('gyro', gyro, (n, 3))
    accel = _values('accel', accel, (n, 3))
    gcov = _values('gyro_cov', np.zeros(3) if gyro_cov is None else gyro_cov, (3,))
    acov = _values('accel_cov', np.zeros(3) if accel_cov is None else accel_cov, (3,))
    temp_sec, temp_nsec = _times('temp_t', temp_t)
    m = len(temp_sec)
    temp_c = _values('temp_c', temp_c, (m,))
    tvar = np.asarray(temp_var, dtype=np.float64)
    tvar = _values('temp_var', np.broadcast_to(tvar, (m,)) if tvar.ndim == 0 else tvar, (m,))
    if (ref_t is None) != (ref is None):
        raise DatasetError('Expected `ref_t` and `ref` to be given together, got only '
                           f"{'ref_t' if ref is None else 'ref'}.")
    if ref_t is not None:
        ref_sec, ref_nsec = _times('ref_t', ref_t)
        ref = _values('ref', ref, (len(ref_sec), 3))
    else:
        ref_sec = ref_nsec = np.zeros(0, dtype=np.int64)
        ref = np.zeros((0, 3))

    # The float64 blocks of every message, built lazily per chunk below.
    imu_const = np.zeros(IMU_DOUBLES)
    orientation = imu_const[field_slice('orientation')]
    orientation[3] = 1.0           # orientation w
    imu_const[field_slice('orientation_covariance').start] = -1.0  # no orientation (REP 145)
    imu_const[field_slice('angular_velocity_covariance')] = np.diag(gcov).ravel()
    imu_const[field_slice('linear_acceleration_covariance')] = np.diag(acov).ravel()
    gyro_cols, accel_cols = field_slice('angular_velocity'), field_slice('linear_acceleration')

    def imu_block(idx: NDArray[np.int64]) -> NDArray[np.float64]:
        block = np.broadcast_to(imu_const, (len(idx), IMU_DOUBLES)).copy()
        block[:, gyro_cols] = gyro[idx]
        block[:, accel_cols] = accel[idx]
        return block

    topics: list[tuple[str, str, NDArray[np.int64], NDArray[np.int64],
                       Callable[[NDArray[np.int64]], NDArray[np.float64]]]] = [
        (imu_topic, IMU_TYPE, imu_sec, imu_nsec, imu_block),
        (temperature_topic, TEMPERATURE_TYPE, temp_sec, temp_nsec,
         lambda idx: np.stack([temp_c[idx], tvar[idx]], axis=1)),
    ]
    if ref_t is not None:
        topics.append((reference_topic, REFERENCE_TYPE, ref_sec, ref_nsec, lambda idx: ref[idx]))
    names = [x[0] for x in topics]
    if len(set(names)) != len(names):
        raise DatasetError(f'Expected distinct topic names, got {names}.')

    # Global time order across topics (stable: IMU first on equal stamps).
    stamps = np.concatenate([x[2] * 1_000_000_000 + x[3] for x in topics])
    which = np.concatenate([np.full(len(x[2]), k, dtype=np.int64) for k, x in enumerate(topics)])
    index = np.concatenate([np.arange(len(x[2])) for x in topics])
    order = np.argsort(stamps, kind='stable')

    path = Path(path)
    if path.exists():
        raise DatasetError(f'Cannot create bag {str(path)!r}: the path exists already '
                           '(write_bag never overwrites).')
    writer = Writer(path, version=_BAG_VERSION, storage_plugin=_STORAGES[storage])
    try:
        writer.open()
    except (WriterError, OSError, sqlite3.Error) as err:
        raise DatasetError(f'Cannot create bag {str(path)!r}: {one_line(err)}') from err
    ok = False
    try:
        conns = [writer.add_connection(name, msgtype, typestore=_jazzy(),
                                       offered_qos_profiles=[_QOS])
                 for name, msgtype, *_ in topics]
        for k0 in range(0, len(order), _WRITE_CHUNK):
            sel = order[k0:k0 + _WRITE_CHUNK]
            sel_which = which[sel]
            payload: list[bytes] = [b''] * len(sel)
            for k, (_, msgtype, sec, nsec, block) in enumerate(topics):
                pos = np.flatnonzero(sel_which == k)
                if not pos.size:
                    continue
                idx = index[sel[pos]]
                encoded = _encode_checked(msgtype, sec[idx], nsec[idx], frame_id, block(idx))
                for p, raw in zip(pos.tolist(), encoded):
                    payload[p] = raw
            write = writer.write
            for cid, stamp, raw in zip(sel_which.tolist(), stamps[sel].tolist(), payload):
                write(conns[cid], stamp, raw)
        writer.close()
        ok = True
    except (WriterError, OSError, sqlite3.Error) as err:
        raise DatasetError(f'Cannot write bag {str(path)!r}: {one_line(err)}') from err
    finally:
        if not ok:
            if writer.storage is not None:
                writer.storage.abort()
            # writer.open() created the directory: leave no half-written bag behind.
            shutil.rmtree(path, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class BagData:
    """
    Arrays read from a bag, one entry per message that held finite values.

    Parameters
    ----------
    imu_t : NDArray[np.float64], shape (N,), s
        IMU header stamps (the log time where a header stamp is zero), in the order read
        (log-time order for a topic with one connection; not sorted by header stamp).
    gyro : NDArray[np.float64], shape (N, 3), rad/s
        Angular velocity; samples with a NaN or infinite component are rejected.
    accel : NDArray[np.float64], shape (N, 3), m/s^2, or None
        Linear acceleration (not checked: a missing accelerometer does not reject gyro
        data); None when read with ``accel=False``.
    frame_id : str
        Header frame id of the first IMU message.
    temp_t : NDArray[np.float64], shape (M,), s
        Thermometer stamps.
    temp_c : NDArray[np.float64], shape (M,), degC
        Temperature; non-finite samples rejected.
    temp_var : NDArray[np.float64], shape (M,), degC^2
        Temperature variance as recorded.
    ref_t : NDArray[np.float64], shape (R,), s, or None
        Reference-rate stamps; None when the bag has no (non-empty) reference topic.
    ref : NDArray[np.float64], shape (R, 3), rad/s, or None
        Reference rate.
    topics : dict[str, tuple[str, int]]
        Every topic of the bag: name -> (type, message count).
    rejected : dict[str, int]
        Counts of rejected messages: ``imu_nonfinite``, ``temp_nonfinite``,
        ``ref_nonfinite`` and ``undecodable`` (messages rosbags could not deserialise).
    storage : str
        Storage plugin of the bag ('sqlite3' or 'mcap').
    path : str
        The bag directory.
    fallback : dict[str, int]
        Messages per role ('imu', 'temperature', 'reference') decoded one by one with
        rosbags because the fixed-layout numpy decoder did not apply.

    """

    imu_t: NDArray[np.float64]
    gyro: NDArray[np.float64]
    accel: NDArray[np.float64] | None
    frame_id: str
    temp_t: NDArray[np.float64]
    temp_c: NDArray[np.float64]
    temp_var: NDArray[np.float64]
    ref_t: NDArray[np.float64] | None
    ref: NDArray[np.float64] | None
    topics: dict = field(default_factory=dict)
    rejected: dict = field(default_factory=dict)
    storage: str = ''
    path: str = ''
    fallback: dict = field(default_factory=dict, compare=False)


class _Sink:
    """Growable, preallocated output columns for one role: times plus value groups."""

    def __init__(self, capacity: int, widths: Sequence[int]) -> None:
        self.widths = list(widths)
        self.t = np.empty(capacity)
        self.v = [np.empty((capacity, w)) for w in self.widths]
        self.n = 0

    def add(self, t: NDArray[np.float64], values: NDArray[np.float64]) -> None:
        """Append a block (values: all groups side by side), growing when it must."""
        end = self.n + len(t)
        if end > len(self.t):
            cap = max(end, 2 * len(self.t))
            self.t = np.concatenate([self.t[:self.n], np.empty(cap - self.n)])
            self.v = [np.concatenate([v[:self.n], np.empty((cap - self.n, v.shape[1]))])
                      for v in self.v]
        self.t[self.n:end] = t
        col = 0
        for v, w in zip(self.v, self.widths):
            v[self.n:end] = values[:, col:col + w]
            col += w
        self.n = end

    def result(self, keep: NDArray[np.bool_] | None = None) -> list[NDArray[np.float64]]:
        """Return [t, *groups] of the filled rows (``keep`` selects rows)."""
        out = [self.t[:self.n]] + [v[:self.n] for v in self.v]
        if keep is not None and not keep.all():
            return [x[keep] for x in out]
        if self.n < 0.9 * len(self.t):
            return [x.copy() for x in out]
        return out


def _resolve(path: str | Path) -> Path:
    """Return the rosbag2 directory of ``path`` or raise DatasetError saying why not."""
    p = Path(path)
    if not p.exists():
        raise DatasetError(f'Bag {str(p)!r} does not exist.')
    if p.is_file():
        if p.suffix == '.bag':
            raise DatasetError(f'Bag {str(p)!r} is a ROS 1 bag; expected a rosbag2 directory '
                               '(convert it with rosbags-convert).')
        if p.suffix in ('.db3', '.mcap') and (p.parent / 'metadata.yaml').is_file():
            return p.parent
        raise DatasetError(f'Bag {str(p)!r} is a file, not a rosbag2 directory (a folder '
                           'with metadata.yaml and .db3 or .mcap files).')
    if not (p / 'metadata.yaml').is_file():
        found = sorted(x.name for x in p.iterdir())[:5]
        raise DatasetError(f'Bag {str(p)!r} is not a rosbag2 directory: no metadata.yaml '
                           f'(found {found or "nothing"}; `ros2 bag reindex` can rebuild it).')
    return p


def _storage_id(bag: Path) -> str:
    """Return the storage identifier recorded in metadata.yaml ('' when absent)."""
    meta_path = bag / 'metadata.yaml'
    meta = load_yaml(meta_path.read_text(encoding='utf-8'), BAG_METADATA_LIMITS,
                     source=str(meta_path), error=DatasetError)
    try:
        return str(meta['rosbag2_bagfile_information']['storage_identifier'])
    except (KeyError, TypeError):
        return ''


def _describe(topics: dict[str, tuple[str, int]]) -> str:
    """Return 'name (type, N msgs), ...' for error messages."""
    if not topics:
        return 'none'
    return ', '.join(f'{k} ({t}, {c} msgs)' for k, (t, c) in sorted(topics.items()))


def read_bag(path, *, imu_topic='/imu/data_raw', temperature_topic='/imu/temperature',
             reference_topic='/rate_table/reference', progress=False,
             accel=True) -> BagData:
    """
    Read IMU, temperature and reference-rate arrays from a rosbag2 bag, fast.

    The raw CDR bytes are collected in blocks and decoded with numpy (see the module
    docstring); rosbags' per-message deserialiser is used only where the fixed layout does
    not apply. Memory is bounded by the output arrays plus one block of raw messages.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or mcap); a path to its .db3/.mcap file also works.
    imu_topic : str
        ``sensor_msgs/msg/Imu`` topic (required, non-empty).
    temperature_topic : str
        ``sensor_msgs/msg/Temperature`` topic (required, non-empty).
    reference_topic : str or None
        ``geometry_msgs/msg/Vector3Stamped`` topic; optional (``ref`` is None when absent
        or empty); None skips it.
    progress : bool
        Show a tqdm progress bar (messages read).
    accel : bool
        Also extract the linear acceleration (``BagData.accel`` is None when False: the
        trainer does not need it, and skipping it saves 24 bytes per IMU message).

    Returns
    -------
    BagData
        The arrays, the topics of the bag and the counts of rejected samples.

    Raises
    ------
    DatasetError
        When the path does not exist, is not a rosbag2 directory, cannot be read or is
        corrupt, or when a topic is missing, empty or of the wrong type.

    """
    bag = _resolve(path)
    try:
        storage = _storage_id(bag)
        with AnyReader([bag], default_typestore=_jazzy()) as reader:
            topics = {name: (info.msgtype or '?', int(info.msgcount))
                      for name, info in reader.topics.items()}
            wanted = [('imu', imu_topic, IMU_TYPE, True),
                      ('temperature', temperature_topic, TEMPERATURE_TYPE, True)]
            if reference_topic is not None:
                wanted.append(('reference', reference_topic, REFERENCE_TYPE, False))
            conns: dict[str, list[Any]] = {}
            for role, topic, msgtype, required in wanted:
                if topic not in topics:
                    if required:
                        raise DatasetError(
                            f'Bag {str(bag)!r} has no topic {topic!r} ({role}); topics '
                            f'present: {_describe(topics)}.')
                    continue
                if topics[topic][0] != msgtype:
                    raise DatasetError(f'Topic {topic!r} in bag {str(bag)!r} has type '
                                       f'{topics[topic][0]!r}, expected {msgtype!r}.')
                if topics[topic][1] == 0 and required:
                    raise DatasetError(f'Topic {topic!r} in bag {str(bag)!r} has no messages.')
                conns[role] = [c for c in reader.connections if c.topic == topic]
            return _read_messages(reader, bag, storage, topics, conns, progress, accel)
    except _READ_ERRORS as err:
        raise DatasetError(f'Cannot read bag {str(bag)!r} (unreadable or corrupt): '
                           f'{one_line(err)}') from err


def _read_messages(reader: AnyReader, bag: Path, storage: str,
                   topics: dict[str, tuple[str, int]], conns: dict[str, list[Any]],
                   progress: bool, with_accel: bool = True) -> BagData:
    """Run the block-wise raw read and decode of ``read_bag``."""
    from tqdm import tqdm

    roles = list(conns)
    msgtypes = {'imu': IMU_TYPE, 'temperature': TEMPERATURE_TYPE, 'reference': REFERENCE_TYPE}
    role_of = {id(c): k for k, role in enumerate(roles) for c in conns[role]}
    all_conns = [c for role in roles for c in conns[role]]
    expected = {role: sum(int(c.msgcount) for c in conns[role]) for role in roles}
    widths = {'imu': (3, 3) if with_accel else (3,), 'temperature': (1, 1), 'reference': (3,)}
    keep = {'imu': None if with_accel else _KEEP[IMU_TYPE][:3], 'temperature': None,
            'reference': None}
    sinks = {role: _Sink(expected[role], widths[role]) for role in roles}
    frame_id = {role: None for role in roles}
    fallback = {'imu': 0, 'temperature': 0, 'reference': 0}
    undecodable = 0
    typestore = reader.typestore

    # Main-connection messages whose header stamp is zero: (index among the connection's
    # messages, row in the IMU sink). Their log times are fetched after the main pass.
    zero_stamped: list[tuple[NDArray[np.int64], NDArray[np.int64]]] = []

    def decode(role: str, raws: Sequence[bytes], logs: Sequence[int] | None,
               first: int = 0) -> None:
        """Decode one role's messages of a block into its sink (``logs``: log times)."""
        nonlocal undecodable
        dec = _decode(raws, msgtypes[role], typestore, keep[role])
        fallback[role] += dec.fallback
        if frame_id[role] is None and dec.frame_id:
            frame_id[role] = dec.frame_id
        stamp_ns = dec.sec * 1_000_000_000 + dec.nanosec
        good = None if dec.undecodable is None else ~dec.undecodable
        zero = stamp_ns == 0
        if zero.any():
            if logs is not None:
                stamp_ns[zero] = np.fromiter(logs, dtype=np.int64, count=len(logs))[zero]
            else:
                if good is not None:
                    zero &= good
                pos = np.flatnonzero(zero)
                rows = pos if good is None else np.cumsum(good)[pos] - 1
                zero_stamped.append((first + pos, sinks[role].n + rows))
        t = _seconds(stamp_ns)
        values = dec.values
        if good is not None:
            undecodable += int(dec.undecodable.sum())
            t, values = t[good], values[good]
        sinks[role].add(t, values)

    # Hot loop, one list comprehension per block: the raw bytes of the main IMU connection
    # are collected with nothing else done per message (no log time, no call); any other
    # message (temperature, reference, another IMU connection) is passed to
    # ``add_other``, which returns None and so also keeps it out of the list.
    main = conns['imu'][0]
    # read_bag opens one bag: iterate its rosbags Reader directly, without AnyReader's
    # heapq merge across bags (one generator step less per message).
    source = reader.readers[0] if len(reader.readers) == 1 else reader
    gen = source.messages(connections=all_conns)
    n_main = 0
    with tqdm(total=sum(expected.values()), unit='msg', unit_scale=True, desc=bag.name,
              disable=not progress, leave=False) as bar:
        while True:
            others: list[tuple[Any, int, bytes]] = []
            add_other = others.append
            main_raws = [raw for conn, log, raw in islice(gen, _CHUNK)
                         if conn is main or add_other((conn, log, raw))]
            if main_raws:
                decode('imu', main_raws, None, n_main)
                n_main += len(main_raws)
            if others:
                for k, role in enumerate(roles):
                    mine = [x for x in others if role_of[id(x[0])] == k]
                    if mine:
                        decode(role, [x[2] for x in mine], [x[1] for x in mine])
            done = len(main_raws) + len(others)
            if not done:
                break
            bar.update(done)
    if zero_stamped:
        # Rare (a driver that leaves the header stamp at zero): read the main connection's
        # log times in a second pass and use them for those messages.
        logs = np.fromiter((log for _, log, _ in source.messages(connections=[main])),
                           dtype=np.int64, count=n_main)
        index = np.concatenate([z[0] for z in zero_stamped])
        rows = np.concatenate([z[1] for z in zero_stamped])
        sinks['imu'].t[rows] = _seconds(logs[index])

    rejected = {'imu_nonfinite': 0, 'temp_nonfinite': 0, 'ref_nonfinite': 0,
                'undecodable': undecodable}
    sink = sinks['imu']
    finite = np.isfinite(sink.v[0][:sink.n]).all(axis=1)
    rejected['imu_nonfinite'] = int(np.count_nonzero(~finite))
    imu_t, gyro, *accel = sink.result(finite)
    sink = sinks['temperature']
    finite = np.isfinite(sink.v[0][:sink.n, 0])
    rejected['temp_nonfinite'] = int(np.count_nonzero(~finite))
    temp_t, temp_c, temp_var = sink.result(finite)
    ref_t = ref = None
    if 'reference' in sinks and sinks['reference'].n:
        sink = sinks['reference']
        finite = np.isfinite(sink.v[0][:sink.n]).all(axis=1)
        rejected['ref_nonfinite'] = int(np.count_nonzero(~finite))
        ref_t, ref = sink.result(finite)
    return BagData(
        imu_t=imu_t, gyro=gyro, accel=accel[0] if accel else None, frame_id=frame_id['imu'] or '',
        temp_t=temp_t, temp_c=temp_c[:, 0], temp_var=temp_var[:, 0], ref_t=ref_t, ref=ref,
        topics=topics,
        rejected=rejected, storage=storage, path=str(bag), fallback=fallback)
