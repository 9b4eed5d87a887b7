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

The gyro is the highest-rate one the log has for the instance: ``sensor_gyro`` (raw) where it
is logged at full rate, else ``sensor_combined`` (its rows where ``sensor_selection`` names
this IMU) or ``vehicle_imu`` (calibrated on board); where the log holds the sensor's FIFO
(``sensor_gyro_fifo``, every raw sample in blocks) as a stream at least twice as fast, that.
The temperature is the IMU's own thermometer wherever the log has it (``sensor_gyro``,
``vehicle_imu_status``, ``sensor_accel``), on its own stamps, or a proxy the user names
(``--temperature-source baro``: ``sensor_combined.baro_temp_celcius``, ``vehicle_air_data``,
``sensor_baro``).
"""

from __future__ import annotations

from functools import partial
import io
import mmap
import os
from pathlib import Path
import struct

from gyro_tdc.data.flightlog import (captured, columns, FlightLog, no_instance, no_temperature,
                                     on_stamps, rate_hz, rate_words, seconds,
                                     sensor_stream, thermometer)
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import onboard_status
import numpy as np
from numpy.typing import NDArray

__all__ = ['read_ulog', 'ulog_truncated_bytes']

_TOPICS = ['sensor_gyro', 'sensor_accel', 'sensor_combined', 'vehicle_imu',
           'vehicle_imu_status', 'sensor_baro', 'vehicle_air_data', 'sensor_selection',
           'sensor_gyro_fifo', 'sensor_accel_fifo']
#: Where each topic of an instance names its gyro's (accelerometer's) device id.
_DEVICE_FIELDS = {kind: ((f'sensor_{kind}', 'device_id'), ('vehicle_imu', f'{kind}_device_id'),
                         ('vehicle_imu_status', f'{kind}_device_id'))
                  for kind in ('gyro', 'accel')}
#: A FIFO block holds at most this many samples (``msg/SensorGyroFifo.msg``: ``int16[32] x``).
FIFO_SAMPLES = 32
#: The IMU's own thermometers, in the order they are tried: (topic, field).
_IMU_THERMOMETERS = (('sensor_gyro', 'temperature'), ('vehicle_imu_status', 'temperature_gyro'),
                     ('vehicle_imu_status', 'temperature_accel'), ('sensor_accel', 'temperature'))
#: The barometer's thermometers (``--temperature-source baro``), in the order they are tried.
_BARO_THERMOMETERS = (('sensor_combined', 'baro_temp_celcius'),
                      ('vehicle_air_data', 'baro_temp_celcius'), ('sensor_baro', 'temperature'))
#: ``sensor_gyro`` counts as logged at full rate at this fraction of the fastest gyro's rate.
FULL_RATE_FRACTION = 0.5
_HEADER_BYTES = 16
#: ULog message types (FLAG_BITS, FORMAT, INFO, INFO_MULTIPLE, PARAMETER, PARAMETER_DEFAULT,
#: ADD_LOGGED, REMOVE_LOGGED, DATA, LOGGING, LOGGING_TAGGED, DROPOUT, SYNC).
_KINDS = frozenset(b'BFIMPQARDLCOS')
#: A topic's sample stamps in s (``timestamp_sample``, else ``timestamp``).
_seconds = partial(seconds, field='timestamp', sample='timestamp_sample')


def ulog_truncated_bytes(path: str | os.PathLike) -> int:
    """
    Return how many bytes of ``path`` follow its last whole message (0: it ends cleanly).

    The bytes of a message cut short at the end (the whole file past the header when even
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
            if ofs + 3 + length > size:
                break
            ofs += 3 + length
        return size - ofs


def _vec(name: str) -> tuple[str, str, str]:
    """Return the field names of a logged array of three (``name[0]`` ...)."""
    return (f'{name}[0]', f'{name}[1]', f'{name}[2]')


def _rate(d: dict) -> float:
    """Return a topic's mean sample rate, Hz."""
    return rate_hz(_seconds(d))


def _delta_rate(d: dict, what: str) -> NDArray[np.float64] | None:
    """Return ``vehicle_imu``'s integrated ``delta_angle``/``delta_velocity`` as a rate."""
    if (v := columns(d, (*_vec(what), f'{what}_dt'))) is None:
        return None
    with np.errstate(invalid='ignore', divide='ignore'):
        return v[:, :3] / (v[:, 3:] * 1e-6)


#: The gyro topics and the fields each needs to hold rates.
_GYRO_FIELDS = {'sensor_gyro': ('x', 'y', 'z'), 'sensor_combined': ('gyro_rad[0]',),
                'vehicle_imu': ('delta_angle[0]', 'delta_angle_dt')}


def _device(topics: dict, instance: int, kind: str = 'gyro') -> int:
    """Return the device id of an instance's gyro (``kind``) as its topics name it (0: unknown)."""
    for tp, f in _DEVICE_FIELDS[kind]:
        ids = np.asarray(topics.get(tp, {}).get(instance, {}).get(f, []))
        if (ids := ids[ids != 0]).size:
            return int(ids[0])
    return 0


def _combined_rows(topics: dict, instance: int, kind: str = 'gyro') -> NDArray[np.bool_] | None:
    """
    Return which ``sensor_combined`` rows carry the gyro (``kind``) of ``instance``.

    ``sensor_combined`` is the selected IMU (``sensor_selection.gyro_device_id``, its
    accelerometer ``accel_device_id``): instance 0 when the log names no selection or no
    device id to match (PX4's default; for the accelerometer None: the gyro's rows). Where the
    selection changes, each row is the IMU selected at its stamp (before any selection: none).
    """
    c = topics.get('sensor_combined', {}).get(0, {})
    n = len(c.get('timestamp', ()))
    s = topics.get('sensor_selection', {}).get(0, {})
    sel = np.asarray(s.get(f'{kind}_device_id', []), dtype=np.int64)
    ids = sorted({i for name in _GYRO_FIELDS for i in topics.get(name, {})})
    known = {_device(topics, i, kind): i for i in ids} | {0: 0}
    if not (picked := set(sel.tolist()) - {0}) or len(known) == 1:
        return np.full(n, instance == 0) if kind == 'gyro' else None
    if len(picked) == 1:
        return np.full(n, known.get(picked.pop()) == instance)
    order = np.argsort(np.asarray(s['timestamp'], dtype=np.uint64), kind='stable')
    at = np.searchsorted(np.asarray(s['timestamp'], dtype=np.uint64)[order],
                         np.asarray(c['timestamp'], dtype=np.uint64), side='right') - 1
    owner = np.array([known.get(int(d), -1) if d else -1 for d in sel[order]])
    return (at >= 0) & (owner[np.maximum(at, 0)] == instance)


def _combined_note(topics: dict, instance: int, rows: NDArray[np.bool_]) -> str:
    """Return what ``sensor_combined`` carries when it is not all this instance's, else ''."""
    if rows.all():
        return ''
    ids = {i for name in _GYRO_FIELDS for i in topics.get(name, {})}
    if rows.any():
        rest = {k: int(_combined_rows(topics, k).sum()) for k in sorted(ids - {instance})}
        most = max(rest, key=rest.get, default=None)
        return (f'sensor_combined carries this IMU in {int(rows.sum())} of {len(rows)} '
                'samples (the selection changed, sensor_selection): those are its own' + (
                    f'; instance {most} has {rest[most]} (--imu-instance {most})'
                    if most is not None and rest[most] > rows.sum() else ''))
    owners = {k for k in ids if _combined_rows(topics, k).any()}
    if owners == {0}:          # the first IMU's, as PX4 selects by default: nothing to say
        return ''
    which = f'instance {owners.pop()}' if len(owners) == 1 else 'other IMUs'
    return f'sensor_combined carries {which} (sensor_selection), not this one'


def _gyros(topics: dict, instance: int, rows: NDArray[np.bool_] | None = None) -> dict[str, dict]:
    """
    Return the gyro topics of an instance that hold rates: name -> columns (its own rows).

    ``rows``: :func:`_combined_rows` of the instance, when the caller has them already.
    """
    out = {}
    for k, need in _GYRO_FIELDS.items():
        d = topics.get(k, {}).get(0 if k == 'sensor_combined' else instance)
        if d is None or not all(n in d for n in need):
            continue
        if k == 'sensor_combined':
            rows = _combined_rows(topics, instance) if rows is None else rows
            if rows.sum() < 2:
                continue
            d = d if rows.all() else {f: np.asarray(v)[rows] for f, v in d.items()}
        out[k] = d
    return out


def _stream(topics: dict, kind: str, device: int, instance: int,
            slow_t: NDArray[np.float64], beside: str) -> tuple:
    """
    Return (stamps, samples, words) of the FIFO where it stands in for ``beside`` at ``slow_t``.

    Else (None, None, why not in words; '' without the FIFO): see
    :func:`gyro_tdc.data.flightlog.sensor_stream`. The FIFO is one IMU's
    ``sensor_{kind}_fifo`` blocks of its ``device`` (of ``instance`` where the log names
    none). Sample k of a block of n is ``timestamp_sample - (n - 1 - k) * dt`` (PX4's drivers
    stamp a block by its newest sample), its value ``x[k] * scale``. A block whose ``samples``
    is 0 or beyond 32, ``dt`` not in (0, 1 s] or ``scale`` not finite and non-zero is skipped
    and counted (and any sample whose value overflows).
    """
    name = f'sensor_{kind}_fifo'
    if not (inst := topics.get(name)):
        return None, None, ''
    own = [d for i, d in sorted(inst.items())
           if ((np.asarray(d.get('device_id', [])) == device).any() if device else i == instance)]
    k = np.arange(FIFO_SAMPLES)
    axes = [columns(d, tuple(f'{a}[{j}]' for j in k)) for d in own for a in 'xyz']
    need = ('device_id', 'dt', 'scale', 'samples')
    head = [columns(d, need) for d in own]
    if not own or any(a is None for a in axes + head):
        ids = sorted({int(i) for d in inst.values() for i in np.unique(d.get('device_id', []))})
        mine = f'not {device}' if device else f'none of instance {instance}'
        lack = next((f for d in own for f in need if f not in d), 'x[0..31], y or z')
        return None, None, (f'{name} not used: ' + (
            f'its blocks are of device {", ".join(map(str, ids))}, {mine}' if not own
            else f'its format has no {lack}'))
    dev, dt, scale, n = np.concatenate(head).T
    mine = dev == device if device else np.ones(len(dev), dtype=bool)
    stamp = np.concatenate([_seconds(d) for d in own])
    ok = (mine & (n >= 1) & (n <= FIFO_SAMPLES) & (dt > 0) & (dt <= 1e6) & np.isfinite(scale)
          & (scale != 0))
    with np.errstate(invalid='ignore', over='ignore'):
        t = stamp[:, None] - (n[:, None] - 1 - k) * dt[:, None] * 1e-6
        v = np.stack([np.concatenate(axes[j::3]) * scale[:, None] for j in range(3)], axis=-1)
    keep = ok[:, None] & (k < n[:, None]) & np.isfinite(v).all(axis=-1)
    order = np.argsort(t[keep], kind='stable')
    t, v, bad = t[keep][order], v[keep][order], int(np.count_nonzero(mine & ~ok))
    used, said = sensor_stream(t, v, slow_t, name, beside,
                               'accelerometer' if kind == 'accel' else 'gyro')
    return (t, v, said + (f', {bad} of {int(mine.sum())} blocks skipped (samples, dt or scale '
                          'out of range)' if bad else '')) if used else (None, None, said)


def _gyro_accel(topics: dict, instance: int, gyros: dict, source: str,
                rows: NDArray[np.bool_] | None, accel: bool) -> tuple:
    """
    Return (stamps, gyro, accelerometer stamps, accelerometer, words) of the gyro ``source``.

    ``sensor_combined``'s accelerometer is its rows where ``sensor_selection`` names this
    IMU's accelerometer (NaN in the others), whichever IMU gives the gyro there.
    """
    d = gyros[source]
    t = _seconds(d)
    if source == 'sensor_gyro':
        a = topics.get('sensor_accel', {}).get(instance)
        v = columns(a, ('x', 'y', 'z')) if accel and a is not None else None
        return t, columns(d, ('x', 'y', 'z')), _seconds(a) if v is not None else t, v, ''
    if source == 'vehicle_imu':
        return (t, _delta_rate(d, 'delta_angle'), t,
                _delta_rate(d, 'delta_velocity') if accel else None,
                f'vehicle_imu (integrated, calibrated on board) at {_rate(d):.3g} Hz is the '
                'fastest gyro')
    acc = columns(d, _vec('accelerometer_m_s2')) if accel else None
    a_rows = _combined_rows(topics, instance, 'accel') if acc is not None else None
    if a_rows is not None:
        acc[~a_rows[rows]] = np.nan
    return t, columns(d, _vec('gyro_rad')), t, acc, (
        f'sensor_gyro at {_rate(gyros["sensor_gyro"]):.3g} Hz beside sensor_combined '
        f'(rotated, calibrated on board) at {_rate(d):.3g} Hz: the faster one is read'
        if 'sensor_gyro' in gyros else 'no sensor_gyro in the log: sensor_combined (rotated, '
        'calibrated on board) is all there is')


def _pick_gyro(gyros: dict[str, dict], fastest: float = 0.0) -> str:
    """
    Return the gyro to read: ``sensor_gyro`` at full rate, else the fastest one.

    Full rate is judged against ``fastest``, the fastest gyro topic of the whole log, as
    well: a ``sensor_gyro`` at the logger's 1 Hz default is not full rate beside a 2 Hz
    ``vehicle_imu`` because the other topic happens to be that slow too.
    """
    rates = {k: _rate(d) for k, d in gyros.items()}
    full = FULL_RATE_FRACTION * max(fastest, *rates.values())
    return ('sensor_gyro' if 'sensor_gyro' in rates and rates['sensor_gyro'] >= full
            else max(rates, key=lambda k: rates[k]))


def _inventory(topics: dict) -> str:
    """Return what each instance of the log carries, in words (for a refusal)."""
    ids = sorted({i for name in (*_GYRO_FIELDS, 'vehicle_imu_status', 'sensor_accel')
                  for i in topics.get(name, {})})

    def found(pairs: tuple, i: int) -> str:
        return ', '.join(f'{tp}.{f}' for tp, f in pairs
                         if thermometer(topics.get(tp, {}).get(i, {}).get(f)) is not None)
    parts = [f'{i}: ' + ', '.join([f'{k} {rate_words(_seconds(d))}'
                                   for k, d in _gyros(topics, i).items()]
                                  + [f'temperature: {found(_IMU_THERMOMETERS, i) or "none"}'])
             for i in ids]
    baro = found(_BARO_THERMOMETERS, 0)
    return ('; '.join(parts) or 'no IMU') + (f'; barometer temperature: {baro}' if baro else '')


def _thermometer(topics: dict, instance: int, source: str) -> tuple | None:
    """Return (name, stamps s, degC) of the thermometer ``source`` asks for, None if none."""
    tp, _, f = source.partition('.')
    cands = {'imu': [(tp, f, instance) for tp, f in _IMU_THERMOMETERS],
             'baro': [(tp, f, 0) for tp, f in _BARO_THERMOMETERS]
             }.get(source, [(tp, f, instance), (tp, f, 0)])
    for tp, f, i in cands:
        d = topics.get(tp, {}).get(i) or {}
        if (v := thermometer(d.get(f))) is not None:
            return f'{tp}.{f}' + (f' instance {i}' if i else ''), _seconds(d), v
    return None


def read_ulog(path: str | os.PathLike, *, instance: int = 0, accel: bool = False,
              temperature_source: str = 'imu') -> FlightLog:
    """
    Read one IMU of a PX4 ULog.

    Parameters
    ----------
    path : str or PathLike
        The ``.ulg`` file.
    instance : int
        Multi-id instance of the IMU (0-based).
    accel : bool
        Also read the accelerometer of the same instance, on the gyro stamps.
    temperature_source : str
        ``'imu'`` (the IMU's own thermometer), ``'baro'`` or ``'TOPIC.FIELD'`` (a proxy).

    Returns
    -------
    FlightLog
        ``raw`` with ``sensor_gyro``; ``compensated`` when the gyro read is calibrated on
        board and ``TC_G_ENABLE`` is 1; ``temp_t`` the thermometer's own stamps.

    Raises
    ------
    DatasetError
        The file is no ULog pyulog can parse, has no gyro, or not the instance asked for.

    """
    from pyulog import ULog
    from pyulog.core import ULogException

    p = Path(path)
    cut = ulog_truncated_bytes(p)
    chatter = io.StringIO()        # pyulog prints what it finds corrupt; the count is reported
    asked = temperature_source.partition('.')[0]        # TOPIC.FIELD: any topic of the log
    try:
        with captured(chatter):
            ulog = ULog(str(p), _TOPICS + ([asked] if '.' in temperature_source else []))
    except (ULogException, struct.error, UnicodeDecodeError, ValueError, IndexError,
            KeyError, TypeError, OSError) as exc:     # OSError: a seek past a damaged start
        raise DatasetError(f'Log {str(p)!r} is not a readable ULog: {exc}') from None
    params = {k: float(v) for k, v in ulog.initial_parameters.items()
              if isinstance(v, (int, float, np.number))}
    topics: dict[str, dict[int, dict]] = {}
    for d in ulog.data_list:
        topics.setdefault(d.name, {})[int(d.multi_id)] = d.data
    active, words = onboard_status(params, 'px4')
    damaged = bool(ulog.file_corruption)
    notes = ['pyulog found damaged messages (skipped)'] if damaged or chatter.getvalue() else []
    if not (found := {i for name in _GYRO_FIELDS for i in topics.get(name, {})}):
        what = ', '.join(sorted({d.name for d in ulog.data_list})) or 'no logged topic'
        raise DatasetError(f'Log {str(p)!r} has neither sensor_gyro nor sensor_combined '
                           f'nor vehicle_imu (it has {what})' + (
                               ': the log is damaged (pyulog skipped messages it could not '
                               'decode or attribute)' if notes else '') + '.')
    rows = _combined_rows(topics, instance) if 'sensor_combined' in topics else None
    if not (gyros := _gyros(topics, instance, rows)):
        kind = next(k for k in _GYRO_FIELDS if k in topics)
        raise no_instance(p, kind, instance, topics[kind], _inventory(topics))
    source = _pick_gyro(gyros, max(_rate(d) for name in _GYRO_FIELDS
                                   for d in topics.get(name, {}).values()))
    device = _device(topics, instance)
    if rows is not None and (said := _combined_note(topics, instance, rows)):
        notes.append(said)
    t, gyro, acc_t, acc, said = _gyro_accel(topics, instance, gyros, source, rows, accel)
    acc_from = 'sensor_accel' if source == 'sensor_gyro' and acc is not None else source
    fast_t, fast, why = _stream(topics, 'gyro', device, instance, t, source)
    if fast_t is not None:
        t, gyro, source, said, why = fast_t, fast, 'sensor_gyro_fifo', why, ''
    notes += [n for n in (said, why) if n]
    if accel:
        fast_t, fast, why = _stream(topics, 'accel', _device(topics, instance, 'accel'),
                                    instance, acc_t, acc_from)
        notes += [why] if why else []
        acc_t, acc = (fast_t, fast) if fast_t is not None else (acc_t, acc)
        acc = acc if acc_t is t else on_stamps(t, acc_t, acc)
    raw = source in ('sensor_gyro', 'sensor_gyro_fifo')
    if (therm := _thermometer(topics, instance, temperature_source)) is None:
        raise no_temperature(p, f'{source} instance {instance}', temperature_source,
                             _inventory(topics),
                             others=sum(_thermometer(topics, k, 'imu') is not None
                                        for k in found if k != instance),
                             baro=_thermometer(topics, instance, 'baro') is not None)
    name, temp_t, temp = therm
    return FlightLog(imu_t=t, gyro=gyro, temp_c=temp, accel=acc, params=params,
                     firmware='px4', source=source, instance=int(instance),
                     instances=tuple(sorted(found)), raw=raw, compensated=active and not raw,
                     onboard=words, device_id=device, truncated_bytes=cut, notes=notes,
                     temp_t=temp_t, temperature=name, proxy=temperature_source != 'imu',
                     damage='pyulog resynchronised past damaged messages' if damaged else '',
                     board=' '.join(str(ulog.msg_info_dict[k]) for k in ('ver_hw', 'sys_uuid')
                                    if k in ulog.msg_info_dict))
