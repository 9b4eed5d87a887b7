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
Write rosbag2 bags of IMU, temperature and reference-rate messages (:func:`write_bag`).

Messages are encoded a chunk at a time with the fixed-layout codec of
:mod:`gyro_tdc.data.bag.codec` (checked against rosbags' serialiser) and written with rosbags'
``Writer``, in time order across topics, as Jazzy's rosbag2 would record them.
"""

from __future__ import annotations

from pathlib import Path
import shutil
import sqlite3
from typing import Any, Callable, NamedTuple, Sequence

from gyro_tdc.data.bag.codec import (encode_checked, IMU_TYPE, jazzy, REFERENCE_TYPE,
                                     TEMPERATURE_TYPE)
from gyro_tdc.data.imu_cdr import field_slice, IMU_DOUBLES
from gyro_tdc.data.runs import float_array
from gyro_tdc.errors import DatasetError, one_line
import numpy as np
from numpy.typing import ArrayLike, NDArray
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness
from rosbags.interfaces import QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError

__all__ = ['write_bag']

_WRITE_CHUNK = 1 << 16    # messages serialised per numpy call when writing
_BAG_VERSION = 9          # rosbag2 metadata version written by Jazzy (rosbag2 0.26)
_STORAGES = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
# What rosbag2 (Jazzy) records for a reliable, volatile publisher with default deadlines.
_INFINITE = QosTime(9223372036, 854775807)
_QOS = Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, QosDurability.VOLATILE,
           _INFINITE, _INFINITE, QosLiveliness.AUTOMATIC, _INFINITE, False)


def _times(name: str, t: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Return (sec, nanosec) of float seconds, checking shape, finiteness and sign."""
    arr = float_array(name, t)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0) or np.any(arr >= 2.0 ** 31):
        raise DatasetError(f'Expected `{name}` to hold finite times in [0, 2**31) s, got '
                           f'values in [{np.nanmin(arr) if arr.size else 0}, '
                           f'{np.nanmax(arr) if arr.size else 0}].')
    sec = np.floor(arr)
    return np.divmod(sec.astype(np.int64) * 1_000_000_000
                     + np.rint((arr - sec) * 1e9).astype(np.int64), 1_000_000_000)


def write_bag(path, *, imu_t, gyro, accel, temp_t, temp_c, temp_var=0.0, ref_t=None, ref=None,
              storage='sqlite3', frame_id='imu_link', imu_topic='/imu/data_raw',
              temperature_topic='/imu/temperature', reference_topic='/rate_table/reference',
              gyro_cov=None, accel_cov=None, extra=()) -> None:
    """
    Write IMU, temperature and (optionally) reference-rate messages to a new rosbag2 bag.

    ``path`` must not exist. Stamps are s (>= 0), ``gyro``/``ref`` rad/s (N, 3), ``accel``
    m/s^2, ``temp_c`` degC, ``temp_var`` degC^2 (0 = unknown); no reference topic without
    ``ref_t`` and ``ref`` (given together). Messages are written in time order, header stamps
    = log times; Imu messages follow REP 145 (identity orientation, ``orientation_covariance[0]
    = -1``, diagonal covariances ``gyro_cov``/``accel_cov``: zeros = unknown, ``(-1, 0, 0)`` =
    absent). ``extra``: further serialised topics ``(topic, msgtype, t, messages)``, e.g.
    :func:`gyro_tdc.data.bag.motion.encode_twists`. The bag embeds the Jazzy message
    definitions, metadata version 9. Raises DatasetError on a wrong shape or a bag that cannot
    be created.
    """
    if storage not in _STORAGES:
        raise DatasetError(f"Expected `storage` to be 'sqlite3' or 'mcap', got {storage!r}.")
    if not isinstance(frame_id, str):
        raise DatasetError(f'Expected `frame_id` to be a str, got {type(frame_id).__name__}.')
    streams = [_imu_stream(imu_topic, imu_t, gyro, accel, gyro_cov, accel_cov)]
    temp_sec, temp_nsec = _times('temp_t', temp_t)
    m = len(temp_sec)
    tvar = np.asarray(temp_var, dtype=np.float64)
    temps = np.stack([float_array('temp_c', temp_c, (m,)), float_array(
        'temp_var', np.broadcast_to(tvar, (m,)) if tvar.ndim == 0 else tvar, (m,))], axis=1)
    streams.append(_Stream(temperature_topic, TEMPERATURE_TYPE, temp_sec, temp_nsec,
                           lambda idx: temps[idx]))
    if (ref_t is None) != (ref is None):
        raise DatasetError('Expected `ref_t` and `ref` to be given together, got only '
                           f"{'ref_t' if ref is None else 'ref'}.")
    if ref_t is not None:
        ref_sec, ref_nsec = _times('ref_t', ref_t)
        ref = float_array('ref', ref, (len(ref_sec), 3))
        streams.append(_Stream(reference_topic, REFERENCE_TYPE, ref_sec, ref_nsec,
                               lambda idx: ref[idx]))
    for topic, msgtype, t_x, msgs in extra:
        sec_x, nsec_x = _times(f'extra {topic} t', t_x)
        if len(msgs) != len(sec_x):
            raise DatasetError(f'Expected as many messages as stamps for {topic!r}, got '
                               f'{len(msgs)} and {len(sec_x)}.')
        streams.append(_Stream(topic, msgtype, sec_x, nsec_x,
                               lambda idx, msgs=msgs: [msgs[i] for i in idx.tolist()], True))
    names = [x.topic for x in streams]
    if len(set(names)) != len(names):
        raise DatasetError(f'Expected distinct topic names, got {names}.')
    _write(Path(path), storage, frame_id, streams)


class _Stream(NamedTuple):
    """One topic to write: stamps, and its messages' float64 blocks (or raw messages)."""

    topic: str
    msgtype: str
    sec: NDArray[np.int64]
    nsec: NDArray[np.int64]
    block: Callable[[NDArray[np.int64]], Any]     # message indices -> blocks or messages
    raw: bool = False


def _imu_stream(topic: str, imu_t: ArrayLike, gyro: ArrayLike, accel: ArrayLike,
                gyro_cov: ArrayLike | None, accel_cov: ArrayLike | None) -> _Stream:
    """Return the Imu stream after checking its arrays (REP 145 orientation and covariances)."""
    imu_sec, imu_nsec = _times('imu_t', imu_t)
    n = len(imu_sec)
    gyro, accel = float_array('gyro', gyro, (n, 3)), float_array('accel', accel, (n, 3))
    imu_const = np.zeros(IMU_DOUBLES)
    imu_const[field_slice('orientation').start + 3] = 1.0             # orientation w
    imu_const[field_slice('orientation_covariance').start] = -1.0  # no orientation (REP 145)
    for arg, cov, name in (('gyro_cov', gyro_cov, 'angular_velocity_covariance'),
                           ('accel_cov', accel_cov, 'linear_acceleration_covariance')):
        cov = float_array(arg, np.zeros(3) if cov is None else cov, (3,))
        imu_const[field_slice(name)] = np.diag(cov).ravel()

    def imu_block(idx: NDArray[np.int64]) -> NDArray[np.float64]:
        block = np.broadcast_to(imu_const, (len(idx), IMU_DOUBLES)).copy()
        block[:, field_slice('angular_velocity')] = gyro[idx]
        block[:, field_slice('linear_acceleration')] = accel[idx]
        return block
    return _Stream(topic, IMU_TYPE, imu_sec, imu_nsec, imu_block)


def _write(path: Path, storage: str, frame_id: str, streams: Sequence[_Stream]) -> None:
    """Write the streams' messages in time order across topics (IMU first on equal stamps)."""
    stamps = np.concatenate([x.sec * 1_000_000_000 + x.nsec for x in streams])
    which = np.repeat(np.arange(len(streams)), [len(x.sec) for x in streams])
    index = np.concatenate([np.arange(len(x.sec)) for x in streams])
    order = np.argsort(stamps, kind='stable')
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
        conns = [writer.add_connection(x.topic, x.msgtype, typestore=jazzy(),
                                       offered_qos_profiles=[_QOS]) for x in streams]
        for k0 in range(0, len(order), _WRITE_CHUNK):
            sel = order[k0:k0 + _WRITE_CHUNK]
            sel_which = which[sel]
            payload = np.empty(len(sel), dtype=object)
            for k, x in enumerate(streams):
                pos = np.flatnonzero(sel_which == k)
                idx = index[sel[pos]]
                if pos.size:
                    payload[pos] = (x.block(idx) if x.raw else encode_checked(
                        x.msgtype, x.sec[idx], x.nsec[idx], frame_id, x.block(idx)))
            for cid, stamp, raw in zip(sel_which.tolist(), stamps[sel].tolist(), payload):
                writer.write(conns[cid], stamp, raw)
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
