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
PX4 ULog (``.ulg``) -> one IMU as a :class:`gyro_tdc.data.flightlog.FlightLog` (via pyulog).

``sensor_gyro`` (raw, with its ``temperature``, per multi-id instance) where the log has it,
else ``sensor_combined`` (corrected on board) with the temperature of ``vehicle_imu_status``.
"""

from __future__ import annotations

import contextlib
import io
import mmap
import os
from pathlib import Path
import struct

from gyro_tdc.data.flightlog import FlightLog
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import onboard_status
import numpy as np
from numpy.typing import NDArray

__all__ = ['read_ulog', 'ulog_truncated_bytes']

_TOPICS = ['sensor_gyro', 'sensor_accel', 'sensor_combined', 'vehicle_imu_status']
_HEADER_BYTES = 16
#: ULog message types (FLAG_BITS, FORMAT, INFO, INFO_MULTIPLE, PARAMETER, PARAMETER_DEFAULT,
#: ADD_LOGGED, REMOVE_LOGGED, DATA, LOGGING, LOGGING_TAGGED, DROPOUT, SYNC).
_KINDS = frozenset(b'BFIMPQARDLCOS')


def ulog_truncated_bytes(path: str | os.PathLike) -> int:
    """
    Return how many bytes follow the last whole message of a ULog (0: it ends cleanly).

    Parameters
    ----------
    path : str or PathLike
        The ULog.

    Returns
    -------
    int
        Bytes of a message cut short at the end (the whole file past the header when even
        the header is incomplete); 0 also when the walk meets a damaged message first.

    """
    size = os.path.getsize(path)
    if size < _HEADER_BYTES:
        return size
    with open(path, 'rb') as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as m:
        ofs = _HEADER_BYTES
        unpack = struct.Struct('<HB').unpack_from
        while ofs + 3 <= size:
            length, kind = unpack(m, ofs)
            if kind not in _KINDS:
                return 0            # damaged, not cut: pyulog resynchronises and says so
            end = ofs + 3 + length
            if end > size:
                return size - ofs
            ofs = end
        return size - ofs


def _seconds(d: dict) -> NDArray[np.float64]:
    """Return a topic's sample stamps in s (``timestamp_sample`` where it has one)."""
    us = d.get('timestamp_sample', d['timestamp'])
    return np.asarray(us, dtype=np.float64) * 1e-6


def _xyz(d: dict, names: tuple[str, str, str]) -> NDArray[np.float64]:
    """Return three fields side by side as an (N, 3) float64 array."""
    return np.column_stack([np.asarray(d[n], dtype=np.float64) for n in names])


def _on(t: NDArray[np.float64], t_src: NDArray[np.float64],
        v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Interpolate ``v`` (stamps ``t_src``) onto ``t`` per column (NaN outside)."""
    order = np.argsort(t_src, kind='stable')
    ts, vs = t_src[order], v[order]
    cols = [np.interp(t, ts, vs[:, j], left=np.nan, right=np.nan) for j in range(v.shape[1])]
    return np.column_stack(cols)


def read_ulog(path: str | os.PathLike, *, instance: int = 0, accel: bool = False) -> FlightLog:
    """
    Read one IMU of a PX4 ULog.

    Parameters
    ----------
    path : str or PathLike
        The ``.ulg`` file.
    instance : int
        ``sensor_gyro`` multi-id instance (0-based).
    accel : bool
        Also read ``sensor_accel`` of the same instance, interpolated onto the gyro stamps.

    Returns
    -------
    FlightLog
        ``raw`` with ``sensor_gyro``; ``compensated`` when only ``sensor_combined`` exists
        and ``TC_G_ENABLE`` is 1.

    Raises
    ------
    DatasetError
        The file is no ULog pyulog can parse, has neither ``sensor_gyro`` nor
        ``sensor_combined``, or not the instance asked for.

    """
    from pyulog import ULog
    from pyulog.core import ULogException

    p = Path(path)
    cut = ulog_truncated_bytes(p)
    chatter = io.StringIO()        # pyulog prints what it finds corrupt; the count is reported
    try:
        with contextlib.redirect_stdout(chatter):
            ulog = ULog(str(p), _TOPICS)
    except (ULogException, struct.error, UnicodeDecodeError, ValueError, IndexError,
            KeyError, TypeError, OSError) as exc:     # OSError: a seek past a damaged start
        raise DatasetError(f'Log {str(p)!r} is not a readable ULog: {exc}') from None
    params = {k: float(v) for k, v in ulog.initial_parameters.items()
              if isinstance(v, (int, float, np.number))}
    topics: dict[str, dict[int, dict]] = {}
    for d in ulog.data_list:
        topics.setdefault(d.name, {})[int(d.multi_id)] = d.data
    active, words = onboard_status(params, 'px4')
    notes: list[str] = []
    if ulog.file_corruption or chatter.getvalue():
        notes.append('pyulog found damaged messages (skipped)')
    if 'sensor_gyro' in topics:
        found = topics['sensor_gyro']
        source, raw, compensated = 'sensor_gyro', True, False
    elif 'sensor_combined' in topics:
        found = topics['sensor_combined']
        source, raw, compensated = 'sensor_combined', False, active
        notes.append('no sensor_gyro in the log: sensor_combined (rotated, calibrated on '
                     'board) is all there is')
    else:
        what = ', '.join(sorted({d.name for d in ulog.data_list})) or 'no logged topic'
        raise DatasetError(f'Log {str(p)!r} has neither sensor_gyro nor sensor_combined '
                           f'(it has {what}).')
    if instance not in found:
        raise DatasetError(f'Log {str(p)!r}: {source} has no instance {instance} (it has '
                           f'{", ".join(map(str, sorted(found)))}; --imu-instance N).')
    d = found[instance]
    t = _seconds(d)
    if raw:
        gyro = _xyz(d, ('x', 'y', 'z'))
        temp = np.asarray(d.get('temperature', np.full(len(t), np.nan)), dtype=np.float64)
        device = int(d['device_id'][0]) if 'device_id' in d and len(t) else 0
        acc_topic, acc_names = topics.get('sensor_accel', {}).get(instance), ('x', 'y', 'z')
        if not np.isfinite(temp).any() and acc_topic is not None and 'temperature' in acc_topic:
            temp = _on(t, _seconds(acc_topic),
                       np.asarray(acc_topic['temperature'], dtype=np.float64)[:, None])[:, 0]
            notes.append('temperature from sensor_accel of the same instance')
    else:
        gyro = _xyz(d, tuple(f'gyro_rad[{i}]' for i in range(3)))
        device = 0
        temp = np.full(len(t), np.nan)
        status = topics.get('vehicle_imu_status', {}).get(instance)
        if status is not None:
            for name in ('temperature_gyro', 'temperature_accel'):
                if name in status:
                    temp = _on(t, _seconds(status),
                               np.asarray(status[name], dtype=np.float64)[:, None])[:, 0]
                    notes.append(f'temperature from vehicle_imu_status.{name}')
                    break
        acc_topic, acc_names = d, tuple(f'accelerometer_m_s2[{i}]' for i in range(3))
    acc = None
    if accel and acc_topic is not None and all(n in acc_topic for n in acc_names):
        acc = (_xyz(acc_topic, acc_names) if acc_topic is d
               else _on(t, _seconds(acc_topic), _xyz(acc_topic, acc_names)))
    return FlightLog(imu_t=t, gyro=gyro, temp_c=temp, accel=acc, params=params,
                     firmware='px4', source=source, instance=int(instance),
                     instances=tuple(sorted(found)), raw=raw, compensated=compensated,
                     onboard=words, device_id=device, truncated_bytes=cut, notes=notes)
