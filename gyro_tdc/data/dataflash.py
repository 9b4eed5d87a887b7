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
ArduPilot DataFlash (``.bin``) -> one IMU as a :class:`gyro_tdc.data.flightlog.FlightLog`.

pymavlink's ``DFReader`` indexes the records and their FMT formats; the ``IMU`` records (with
``T``, or ``Temp`` in ArduCopter 3.4, per instance), ``BARO`` (a proxy thermometer with
``--temperature-source baro``) and ``PARM`` are decoded here column-wise with numpy. Where the
log holds the gyro at the sensor rate as a stream (``GYR``, with ``ACC``: ``INS_RAW_LOG_OPT``
or ``LOG_BITMASK``'s raw-IMU bit), it is read instead of ``IMU``'s, the IMU's thermometer on
its own stamps beside it; the batch sampler's ``ISBD`` bursts are no stream and not read.
"""

from __future__ import annotations

from functools import partial
import io
import os
from pathlib import Path
import re

from gyro_tdc.data.flightlog import (captured, columns, FlightLog, no_instance, no_temperature,
                                     on_stamps, rate_words, seconds, sensor_stream, thermometer)
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import onboard_status
import numpy as np

__all__ = ['DATAFLASH_TYPES', 'read_dataflash', 'TEMPERATURE_FIELDS']

#: DataFlash format characters -> numpy dtypes (little-endian, packed).
DATAFLASH_TYPES = {
    'a': ('<i2', (32,)), 'b': 'i1', 'B': 'u1', 'h': '<i2', 'H': '<u2', 'i': '<i4', 'I': '<u4',
    'f': '<f4', 'd': '<f8', 'n': 'S4', 'N': 'S16', 'Z': 'S64', 'c': '<i2', 'C': '<u2',
    'e': '<i4', 'E': '<u4', 'L': '<i4', 'M': 'u1', 'q': '<i8', 'Q': '<u8', 'g': '<f2'}
#: The temperature field of ``IMU`` and ``BARO`` records: ``T``, or ``Temp`` (ArduCopter 3.4).
TEMPERATURE_FIELDS = ('T', 'Temp')
#: Records decoded at once (bounds the memory of a long log's decoding).
_CHUNK = 1 << 16
#: Scaled format characters (centi-units; degE7 for ``L``).
_SCALE = {'c': 0.01, 'C': 0.01, 'e': 0.01, 'E': 0.01, 'L': 1e-7}
#: A record type's stamps in s: ``TimeUS`` (or ``TimeMS``, see :func:`_records`); a
#: sensor-rate sample's when it was taken (``SampleUS``).
#: ArduPilot's boot message naming the board: its name and three words of its unique id.
_BOARD = re.compile(r'\S+( [0-9A-F]{8}){3}')
_seconds = partial(seconds, field='TimeUS')
_stamps = partial(seconds, field='TimeUS', sample='SampleUS')


def _records(reader, mtype: int, instance: int | None = None) -> dict[str, np.ndarray]:
    """
    Decode every whole record of one message type into columns.

    ``instance``: only the records whose ``I`` (a uint8) is that one, picked by their ``I``
    byte before decoding (a sensor-rate ``GYR`` of three IMUs would take gigabytes); a
    message without ``I`` is instance 0's.
    """
    fmt = reader.formats[mtype]
    offs = np.asarray(reader.offsets[mtype], dtype=np.int64)
    offs = offs[offs + fmt.len <= reader.data_len]
    names = list(fmt.columns)
    dt = np.dtype([(n, DATAFLASH_TYPES[c]) for n, c in zip(names, fmt.format)])
    if dt.itemsize != fmt.len - 3:
        raise DatasetError(f'{fmt.name}: format {fmt.format!r} is {dt.itemsize} bytes, the '
                           f'FMT record says {fmt.len - 3}.')
    buf = np.frombuffer(reader.data_map, dtype=np.uint8)
    if instance is not None:
        at = (dt.fields or {}).get('I')
        offs = (offs[buf[offs + 3 + at[1]] == instance] if at and at[0] == np.uint8
                else offs[:len(offs) * (instance == 0)])
    cols = 3 + np.arange(dt.itemsize)
    # Gathered in chunks: the byte index of a whole long log would take 8 bytes per byte.
    rec = np.concatenate([np.ascontiguousarray(buf[offs[a:a + _CHUNK, None] + cols])
                          .view(dt).ravel() for a in range(0, len(offs), _CHUNK)]
                         or [np.zeros(0, dtype=dt)])
    out = {n: rec[n] * _SCALE[c] if c in _SCALE else rec[n] for n, c in zip(names, fmt.format)}
    if 'TimeUS' not in out and 'TimeMS' in out:     # ArduPilot up to 3.3 stamps in ms
        out['TimeUS'] = np.asarray(out['TimeMS'], dtype=np.float64) * 1e3
    return out


def _named(reader, name: str) -> dict[str, np.ndarray]:
    """Return the records of the message type ``name`` ({} when the log has none)."""
    mtype = reader.name_to_id.get(name)
    return _records(reader, mtype) if mtype is not None and len(reader.offsets[mtype]) else {}


def _truncated(reader) -> int:
    """Return the bytes of a record cut short at the end of the log (0: none)."""
    last, end = -1, 0
    for mtype, offs in enumerate(reader.offsets):
        if len(offs) and mtype in reader.formats and offs[-1] > last:
            last, end = int(offs[-1]), int(offs[-1]) + reader.formats[mtype].len
    # A record cut short, or the head of one too short for the indexer to see.
    return 0 if last < 0 else reader.data_len - (last if end > reader.data_len else end)


def _params(reader) -> dict[str, float]:
    """Return the first value of every PARM record's parameter."""
    cols, out = _named(reader, 'PARM'), {}
    for name, value in zip(cols.get('Name', ()), cols.get('Value', ())):
        out.setdefault(name.split(b'\0')[0].decode('ascii', 'replace'), float(value))
    return out


def _board(reader) -> str:
    """Return the board's boot line (``Pixhawk6C 00490034 30315109 34373938``), or ''."""
    for text in _named(reader, 'MSG').get('Message', [])[:32]:
        line = bytes(text).split(b'\0')[0].decode('ascii', 'replace').strip()
        if _BOARD.fullmatch(line):
            return line
    return ''


def _imu(reader, kind: str = 'IMU') -> tuple[dict[int, dict[str, np.ndarray]], list[int]]:
    """
    Return the records per instance (the ``I`` field, or IMU/IMU2/IMU3 of old logs).

    And the instances left out: a single record beside an instance with more is damaged bytes
    read as a record (a log with 6,705 damaged headers showed IMU instances 45 and 48).
    """
    out: dict[int, dict[str, np.ndarray]] = {}
    for base, name in enumerate((kind, kind[:3] + '2', kind[:3] + '3')):   # IMU2, BAR2...
        if cols := _named(reader, name):
            parts = _instances(cols)
            out.update({base: cols} if parts is None else parts)
    lone = [i for i, d in out.items() if len(next(iter(d.values()))) < 2]
    if len(lone) == len(out):             # none beside another: the log's only records
        lone = []
    return {i: d for i, d in out.items() if i not in lone}, lone


def _fast(reader, kind: str, instance: int) -> dict[str, np.ndarray] | str | None:
    """
    Return one instance's sensor-rate records (``GYR``/``ACC``; ``GYR1``..3 of older firmware).

    None when the log has none of ``kind`` at all; ``{}`` when only other instances'; why
    not, in words, when they cannot be decoded (the log is still read, from ``IMU``).
    ``INS_RAW_LOG_OPT``'s pre- and post-filter option logs the post-filter copy as instance
    ``I`` + the gyro count: ``I`` = the IMU instance is the pre-filter one.
    """
    ids = {n: m for n in (kind, f'{kind}1', f'{kind}2', f'{kind}3')
           if (m := reader.name_to_id.get(n)) is not None and len(reader.offsets[m])}
    name = kind if kind in ids else f'{kind}{instance + 1}'
    try:
        return (_records(reader, ids[name], instance if name == kind else None)
                if name in ids else {} if ids else None)
    except (DatasetError, KeyError, ValueError, TypeError) as exc:
        return f'{kind} not used: its records cannot be decoded ({exc})'


def _gyro_accel(d: dict, gyr: dict | str | None, acc: dict | str | None, accel: bool,
                instance: int) -> tuple:
    """
    Return (stamps, gyro, accelerometer, source, what in words) of one IMU instance.

    ``gyr``, ``acc``: what :func:`_fast` found. ``GYR``'s gyro where it is a stream beside
    ``IMU`` (:func:`gyro_tdc.data.flightlog.sensor_stream`), else ``IMU``'s. On ``GYR``'s
    stamps the accelerometer is ``ACC``'s where the log has it for the instance, else
    ``IMU``'s, interpolated.
    """
    acc_xyz, imu_t = ('AccX', 'AccY', 'AccZ'), _seconds(d)
    ok, said = False, gyr if isinstance(gyr, str) else ''
    if isinstance(gyr, dict):
        gyro = columns(gyr, ('GyrX', 'GyrY', 'GyrZ'))
        if gyro is None or 'TimeUS' not in gyr or not len(gyro):
            said = f'GYR not used: it has no instance {instance}'
        else:
            t = _stamps(gyr)
            ok, said = sensor_stream(t, gyro, imu_t, 'GYR', 'IMU')
    if not ok:
        return (imu_t, columns(d, ('GyrX', 'GyrY', 'GyrZ')),
                columns(d, acc_xyz) if accel else None, 'IMU', said)
    if not accel:
        return t, gyro, None, 'GYR', said
    a = columns(acc, acc_xyz) if isinstance(acc, dict) and 'TimeUS' in acc else None
    if a is not None and len(a) > 1:
        return t, gyro, on_stamps(t, _stamps(acc), a), 'GYR', said + ', accelerometer from ACC'
    return (t, gyro, on_stamps(t, imu_t, columns(d, acc_xyz)), 'GYR',
            said + ', accelerometer from IMU')


def _instances(cols: dict[str, np.ndarray]) -> dict[int, dict[str, np.ndarray]] | None:
    """Return a message type's records per instance; None when its ``I`` is no instance number."""
    if 'I' not in cols or np.asarray(cols['I']).dtype != np.uint8:
        return None
    return {int(i): {k: v[cols['I'] == i] for k, v in cols.items()}
            for i in np.unique(cols['I']).tolist()}


def _temperature(cols: dict[str, np.ndarray], fields: tuple[str, ...] = TEMPERATURE_FIELDS
                 ) -> tuple[str, np.ndarray] | None:
    """Return (field, degC) of a record type's thermometer, None when it has none."""
    return next(((n, v) for n in fields if (v := thermometer(cols.get(n))) is not None), None)


def _inventory(imus: dict, baros: dict) -> str:
    """Return what each IMU instance of the log carries, in words (for a refusal)."""
    parts = [f'{i}: {len(d["TimeUS"])} samples at {rate_words(_seconds(d))}, temperature '
             + (f'IMU.{temp[0]}' if (temp := _temperature(d)) else 'none')
             for i, d in sorted(imus.items())]
    baro = [i for i, d in sorted(baros.items()) if _temperature(d) is not None]
    return '; '.join(parts) + (f'; barometer temperature: BARO instance '
                               f'{", ".join(map(str, baro))}' if baro else '')


def read_dataflash(path: str | os.PathLike, *, instance: int = 0,
                   accel: bool = False, temperature_source: str = 'imu') -> FlightLog:
    """
    Read one IMU of an ArduPilot DataFlash log.

    Parameters
    ----------
    path : str or PathLike
        The ``.bin`` file.
    instance : int
        IMU instance (0-based, the ``I`` field).
    accel : bool
        Also read ``AccX..Z`` (``ACC``'s or ``IMU``'s on ``GYR``'s stamps).
    temperature_source : str
        ``'imu'`` (``IMU.T`` / ``IMU.Temp``), ``'baro'`` (``BARO.T`` / ``BARO.Temp``, a
        proxy) or ``'MSG.Field'`` (another thermometer of the board, a proxy).

    Returns
    -------
    FlightLog
        The gyro of ``GYR`` where :func:`_gyro_accel` finds it a stream, else ``IMU``'s.
        Never ``raw``: both are logged after the offsets and the temperature correction;
        ``compensated`` when ``INS_TCALn_ENABLE`` is 1.

    Raises
    ------
    DatasetError
        The file is no DataFlash log, has no ``IMU`` records or not the instance asked for.

    """
    from pymavlink.DFReader import DFReader_binary

    p = Path(path)
    chatter = io.StringIO()        # DFReader prints what it skips; the count is reported
    try:
        with captured(chatter):
            reader = DFReader_binary(str(p), zero_time_base=False)
    # pymavlink raises a bare Exception for a FMT record it cannot use (DFFormat): caught
    # here, at the library's edge, so that a damaged log is one line like any bad input.
    except Exception as exc:  # noqa: B902
        raise DatasetError(f'Log {str(p)!r} is not a readable DataFlash log: {exc}') from None
    msg, _, fld = temperature_source.partition('.')
    try:
        if not any(len(offs) for offs in reader.offsets):
            raise DatasetError(f'Log {str(p)!r} is not a DataFlash log: not one record in '
                               f'its {reader.data_len} bytes.')
        params, (imus, lone), (baros, _), cut = (_params(reader), _imu(reader),
                                                 _imu(reader, 'BARO'), _truncated(reader))
        board = _board(reader)
        gyr = _fast(reader, 'GYR', instance)
        # ACC is only read beside this instance's GYR (a sensor-rate stream is large).
        acc = _fast(reader, 'ACC', instance) if accel and isinstance(gyr, dict) and gyr else None
        bursts = 'ISBD' in reader.name_to_id and len(reader.offsets[reader.name_to_id['ISBD']])
        other = _named(reader, msg) if fld else {}
    except (KeyError, ValueError, TypeError, UnicodeDecodeError) as exc:
        raise DatasetError(f'Log {str(p)!r}: a record cannot be decoded ({exc}).') from None
    finally:
        reader.data_map.close()
        reader.filehandle.close()
    if not imus:
        raise DatasetError(f'Log {str(p)!r} has no IMU records.')
    if any('TimeUS' not in d for d in imus.values()):
        raise DatasetError(f'Log {str(p)!r}: its IMU records carry no time stamp (neither '
                           'TimeUS nor TimeMS).')
    if instance not in imus:
        raise no_instance(p, 'IMU', instance, imus, _inventory(imus, baros))
    d = imus[instance]
    t, gyro, acc, source, said = _gyro_accel(d, gyr, acc, accel, instance)
    b_inst = instance if instance in baros else 0       # BARO, BAR2...: per instance
    # A message with an instance field (I, a uint8: BARO, MAG... in ArduPilot 4; HEAT.I is a
    # float, its heater's integrator) interleaves its instances: this IMU's where it has it,
    # else its first; a message without is one.
    parts = _instances(other) or {0: other}
    o_inst = instance if instance in parts else min(parts)
    other = parts[o_inst]
    src = {'imu': d, 'baro': baros.get(b_inst, {})}.get(temperature_source, other)
    found = _temperature(src, (fld,) if fld else TEMPERATURE_FIELDS)
    if found is None or 'TimeUS' not in src:
        raise no_temperature(p, f'IMU instance {instance}', temperature_source,
                             _inventory(imus, baros),
                             others=sum(_temperature(v) is not None
                                        for k, v in imus.items() if k != instance),
                             baro=any(_temperature(b) is not None for b in baros.values()))
    temp_t = None if temperature_source == 'imu' and source != 'GYR' else _seconds(src)
    inst = {'imu': 0, 'baro': b_inst}.get(temperature_source, o_inst)
    name = {'imu': f'IMU.{found[0]}', 'baro': f'BARO.{found[0]}'}.get(
        temperature_source, temperature_source) + (f' instance {inst}' if inst else '')
    active, words = onboard_status(params, 'ardupilot', instance=instance)
    skipped = chatter.getvalue().count('\n')
    notes = [f'pymavlink skipped damaged bytes ({skipped} reports)'] if skipped else []
    notes += [f"IMU instance{'s' * (len(lone) > 1)} {', '.join(map(str, lone))} left out "
              '(one record each: damaged bytes)'] if lone else []
    notes += [said] if said else []
    notes += (['ISBD batch samples not read (bursts, not a stream)']
              if bursts and source == 'IMU' else [])
    return FlightLog(imu_t=t, gyro=gyro, temp_c=found[1], accel=acc, params=params,
                     firmware='ardupilot', source=source, instance=int(instance),
                     instances=tuple(sorted(imus)), raw=False, compensated=active,
                     onboard=words, truncated_bytes=cut, notes=notes,
                     temp_t=temp_t, temperature=name, proxy=temperature_source != 'imu',
                     damage=f'pymavlink skipped {skipped} damaged headers' if skipped else '',
                     board=board)
