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
Small flight-controller logs written by the tests: PX4 ULog and ArduPilot DataFlash.

Both are written from their specifications with numpy (pyulog writes a ULog only back from
one it has read, record by record): ULog = header, FLAG_BITS, FORMAT, INFO, PARAMETER,
ADD_LOGGED and DATA messages; DataFlash = FMT records, then PARM and IMU records, and where
asked the sensor-rate GYR / ACC records and the batch sampler's ISBH / ISBD bursts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import struct

from gyro_tdc.data import write_bag
import numpy as np

# --------------------------------------------------------------------------------------------
# ULog
# --------------------------------------------------------------------------------------------

_ULOG_TYPES = {'uint64_t': '<u8', 'uint32_t': '<u4', 'uint16_t': '<u2', 'uint8_t': 'u1',
               'float': '<f4', 'int32_t': '<i4', 'int16_t': '<i2'}
SENSOR_GYRO = [('uint64_t', 'timestamp'), ('uint64_t', 'timestamp_sample'),
               ('uint32_t', 'device_id'), ('float', 'x'), ('float', 'y'), ('float', 'z'),
               ('float', 'temperature'), ('uint32_t', 'error_count')]
SENSOR_ACCEL = SENSOR_GYRO
SENSOR_COMBINED = [('uint64_t', 'timestamp'), ('float[3]', 'gyro_rad'),
                   ('uint32_t', 'gyro_integral_dt'), ('float[3]', 'accelerometer_m_s2')]
VEHICLE_IMU = [('uint64_t', 'timestamp'), ('uint64_t', 'timestamp_sample'),
               ('float[3]', 'delta_angle'), ('float[3]', 'delta_velocity'),
               ('uint16_t', 'delta_angle_dt'), ('uint16_t', 'delta_velocity_dt')]
#: PX4's ``msg/SensorGyroFifo.msg`` (and ``SensorAccelFifo.msg``), 1.12-1.15, as its logger
#: lays the fields out (by size, padded).
SENSOR_FIFO = [('uint64_t', 'timestamp'), ('uint64_t', 'timestamp_sample'),
               ('uint32_t', 'device_id'), ('float', 'dt'), ('float', 'scale'),
               ('int16_t[32]', 'x'), ('int16_t[32]', 'y'), ('int16_t[32]', 'z'),
               ('uint8_t', 'samples'), ('uint8_t[3]', '_padding0')]
VEHICLE_IMU_STATUS = [('uint64_t', 'timestamp'), ('uint32_t', 'gyro_device_id'),
                      ('float', 'temperature_gyro')]


@dataclass
class Topic:
    """One logged ULog topic instance: its fields (type, name) and its columns."""

    name: str
    fields: list
    data: dict
    multi_id: int = 0


def _ulog_dtype(fields: list) -> np.dtype:
    """Return the packed numpy dtype of a ULog format's fields."""
    out = []
    for typ, name in fields:
        if typ.endswith(']'):
            base, n = typ[:-1].split('[')
            out.append((name, _ULOG_TYPES[base], (int(n),)))
        else:
            out.append((name, _ULOG_TYPES[typ]))
    return np.dtype(out)


def _msg(kind: bytes, payload: bytes) -> bytes:
    """Return one ULog message: uint16 size, uint8 type, payload."""
    return struct.pack('<HB', len(payload), kind[0]) + payload


def _key_value(key: str, value: bytes) -> bytes:
    """Return an INFO / PARAMETER payload: uint8 key length, key, value."""
    k = key.encode()
    return bytes([len(k)]) + k + value


def write_ulog(path: Path, topics: list, params: dict | None = None, *,
               info: dict | None = None) -> Path:
    """
    Write a ULog (version 1) holding ``topics`` and the initial ``params``.

    Integer-valued ``int`` parameters are written as ``int32_t``, the rest as ``float``;
    data messages are interleaved by timestamp in blocks, as a logger writes them.
    """
    out = [b'ULog\x01\x125' + bytes([1]) + struct.pack('<Q', 0)]
    out.append(_msg(b'B', bytes(16) + struct.pack('<3Q', 0, 0, 0)))
    formats = {}
    for tp in topics:
        if tp.name not in formats:
            formats[tp.name] = tp.fields
            spec = ''.join(f'{typ} {name};' for typ, name in tp.fields)
            out.append(_msg(b'F', f'{tp.name}:{spec}'.encode()))
    for key, value in (info or {'sys_name': 'PX4'}).items():
        v = value.encode()
        out.append(_msg(b'I', _key_value(f'char[{len(v)}] {key}', v)))
    for name, value in (params or {}).items():
        if isinstance(value, int) and not isinstance(value, bool):
            out.append(_msg(b'P', _key_value(f'int32_t {name}', struct.pack('<i', value))))
        else:
            out.append(_msg(b'P', _key_value(f'float {name}', struct.pack('<f', value))))
    blocks = []
    for msg_id, tp in enumerate(topics):
        out.append(_msg(b'A', struct.pack('<BH', tp.multi_id, msg_id) + tp.name.encode()))
        body = tp.fields[:-1] if tp.fields[-1][1].startswith('_padding') else tp.fields
        dt = _ulog_dtype(body)                  # PX4's logger leaves a trailing pad out
        n = len(tp.data['timestamp'])
        rec = np.zeros(n, dtype=np.dtype([('size', '<u2'), ('kind', 'u1'), ('id', '<u2'),
                                          ('body', dt)]))
        rec['size'] = 2 + dt.itemsize
        rec['kind'] = ord('D')
        rec['id'] = msg_id
        for _, name in body:
            rec['body'][name] = tp.data.get(name, 0)
        blocks.append((np.asarray(tp.data['timestamp'], dtype=np.uint64), rec))
    edges = np.unique(np.concatenate([t for t, _ in blocks] or [np.zeros(0, np.uint64)]))
    edges = edges[::max(1, len(edges) // 50)]
    for lo, hi in zip(edges, list(edges[1:]) + [np.iinfo(np.uint64).max]):
        for t, rec in blocks:
            out.append(rec[(t >= lo) & (t < hi)].tobytes())
    Path(path).write_bytes(b''.join(out))
    return Path(path)


@dataclass
class Imu:
    """One simulated IMU as a flight controller logs it (per sample temperature)."""

    t: np.ndarray
    gyro: np.ndarray
    temp: np.ndarray
    accel: np.ndarray | None = None
    device_id: int = 2293768
    extra: dict = field(default_factory=dict)


def _us(t: np.ndarray) -> np.ndarray:
    """Return stamps in s as whole microseconds."""
    return np.round(np.asarray(t) * 1e6).astype(np.uint64)


def px4_topics(imus: list, *, combined: bool = False, temperature: bool = True) -> list:
    """
    Return the ULog topics of IMUs: ``sensor_gyro`` + ``sensor_accel`` per instance.

    ``combined``: ``sensor_combined`` (of IMU 0) and ``vehicle_imu_status`` instead;
    ``temperature=False`` leaves every temperature out (NaN, as a driver without one).
    """
    out = []
    for k, imu in enumerate(imus):
        us = _us(imu.t)
        temp = imu.temp if temperature else np.full(len(us), np.nan)
        if combined:
            if k == 0:
                acc = imu.accel if imu.accel is not None else np.zeros((len(us), 3))
                out.append(Topic('sensor_combined', SENSOR_COMBINED,
                                 {'timestamp': us, 'gyro_rad': imu.gyro,
                                  'accelerometer_m_s2': acc}))
            if temperature:
                out.append(Topic('vehicle_imu_status', VEHICLE_IMU_STATUS,
                                 {'timestamp': us, 'gyro_device_id': imu.device_id,
                                  'temperature_gyro': temp}, multi_id=k))
            continue
        g = {'timestamp': us, 'timestamp_sample': us, 'device_id': imu.device_id,
             'x': imu.gyro[:, 0], 'y': imu.gyro[:, 1], 'z': imu.gyro[:, 2], 'temperature': temp}
        out.append(Topic('sensor_gyro', SENSOR_GYRO, g, multi_id=k))
        if imu.accel is not None:
            a = dict(g, x=imu.accel[:, 0], y=imu.accel[:, 1], z=imu.accel[:, 2],
                     device_id=imu.device_id + 1)
            out.append(Topic('sensor_accel', SENSOR_ACCEL, a, multi_id=k))
    return out


def fifo_topic(name: str, t: np.ndarray, v: np.ndarray, device_id: int, *, block: int = 8,
               scale: float | None = None, multi_id: int = 0) -> Topic:
    """
    Return samples ``v`` (N, 3) at even stamps ``t`` (s) as PX4 FIFO blocks (``name``).

    ``block`` samples a block (the last one fewer), stamped as PX4's drivers stamp it:
    ``timestamp_sample`` the newest sample's, ``dt`` the spacing in us. The counts are
    ``v / scale`` as int16; ``scale`` by default the ICM-42688-P's fine one (1/131 deg/s, or
    g/8192 for an accelerometer), coarser where a sample would not fit.
    """
    v = np.asarray(v, dtype=np.float64)
    fine = np.radians(1 / 131) if 'gyro' in name else 9.80665 / 8192
    scale = scale or max(fine, float(np.abs(v).max(initial=0.0)) / 32767)
    starts = np.arange(0, len(t), block)
    counts = np.minimum(block, len(t) - starts)
    at = np.minimum(starts[:, None] + np.arange(32), len(t) - 1)
    used = (np.arange(32) < counts[:, None])[..., None]
    raw = np.where(used, np.clip(np.round(v[at] / scale), -32768, 32767), 0).astype(np.int16)
    us = _us(t)
    dt = float(np.mean(np.diff(t))) * 1e6 if len(t) > 1 else 1000.0
    return Topic(name, SENSOR_FIFO, {
        'timestamp': us[starts + counts - 1], 'timestamp_sample': us[starts + counts - 1],
        'device_id': device_id, 'dt': dt, 'scale': scale, 'samples': counts,
        'x': raw[..., 0], 'y': raw[..., 1], 'z': raw[..., 2]}, multi_id=multi_id)


# --------------------------------------------------------------------------------------------
# DataFlash
# --------------------------------------------------------------------------------------------

_DF = {'Q': '<u8', 'B': 'u1', 'f': '<f4', 'I': '<u4', 'H': '<u2', 'N': 'S16', 'n': 'S4',
       'Z': 'S64', 'a': ('<i2', (32,))}
IMU_FORMAT = ('IMU', 'QBffffffIIfBBHH', 'TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,'
              'GHz,AHz')
IMU_FORMAT_NO_T = ('IMU', 'QBffffffIIBBHH', 'TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,GH,AH,'
                   'GHz,AHz')
PARM_FORMAT = ('PARM', 'QNf', 'TimeUS,Name,Value')
#: ArduPilot's sensor-rate records (``libraries/AP_InertialSensor/LogStructure.h``).
GYR_FORMAT = ('GYR', 'QBQfff', 'TimeUS,I,SampleUS,GyrX,GyrY,GyrZ')
ACC_FORMAT = ('ACC', 'QBQfff', 'TimeUS,I,SampleUS,AccX,AccY,AccZ')
ISBH_FORMAT = ('ISBH', 'QHBBHHQf', 'TimeUS,N,type,instance,mul,smp_cnt,SampleUS,smp_rate')
ISBD_FORMAT = ('ISBD', 'QHHaaa', 'TimeUS,N,seqno,x,y,z')


def _df_records(mtype: int, fmt: str, columns: str, data: dict) -> np.ndarray:
    """Return DataFlash records (head bytes, type, body) of one message type."""
    names = columns.split(',')
    body = np.dtype([(n, _DF[c]) for n, c in zip(names, fmt)])
    n = len(next(iter(data.values())))
    rec = np.zeros(n, dtype=np.dtype([('h1', 'u1'), ('h2', 'u1'), ('type', 'u1'),
                                      ('body', body)]))
    rec['h1'], rec['h2'], rec['type'] = 0xA3, 0x95, mtype
    for name in names:
        if name in data:
            rec['body'][name] = data[name]
    return rec


def _fmt_record(mtype: int, name: str, fmt: str, columns: str) -> bytes:
    """Return one FMT record describing a message type."""
    length = 3 + _df_records(mtype, fmt, columns, {columns.split(',')[0]: [0]}).dtype[
        'body'].itemsize
    return (bytes([0xA3, 0x95, 0x80, mtype, length]) + name.encode().ljust(4, b'\0')
            + fmt.encode().ljust(16, b'\0') + columns.encode().ljust(64, b'\0'))


def write_dataflash(path: Path, imus: list, params: dict | None = None, *,
                    temperature: bool = True, temp_field: str = 'T',
                    stamp: str = 'TimeUS', fast: dict | None = None, bursts: int = 0,
                    gyr_format: tuple = GYR_FORMAT, board: str = '') -> Path:
    """
    Write an ArduPilot DataFlash log: FMT records, PARM, then IMU records of every instance.

    ``temperature=False`` uses an IMU format without ``T``; ``temp_field='Temp'`` names it as
    ArduCopter 3.4 does; ``stamp='TimeMS'`` stamps in ms as ArduPilot up to 3.3 does.
    ``fast`` {instance: :class:`Imu`}: that instance's gyro at the sensor rate as ``GYR``
    records (``SampleUS`` = ``t``; ``TimeUS`` when written, the next 2.5 ms tick), its
    ``accel`` as ``ACC``; ``gyr_format`` another ``GYR`` layout. ``bursts``: that many batch
    sampler bursts of instance 0's gyro (an ``ISBH`` + 32 ``ISBD`` each). Records go
    interleaved by time, ``GYR`` last in each stretch. ``board``: a ``MSG`` record of that text
    after the firmware's (the boot line naming the board).
    """
    name, fmt, cols = IMU_FORMAT if temperature else IMU_FORMAT_NO_T
    cols = cols.replace(',T,', f',{temp_field},')
    if stamp == 'TimeMS':
        fmt, cols = 'I' + fmt[1:], cols.replace('TimeUS', 'TimeMS', 1)
    kinds = [(64, *PARM_FORMAT), (65, name, fmt, cols), (66, *ACC_FORMAT),
             (67, *ISBH_FORMAT), (68, *ISBD_FORMAT), (69, *gyr_format)]
    out = [_fmt_record(0x80, 'FMT', 'BBnNZ', 'Type,Length,Name,Format,Columns')]
    out += [_fmt_record(*k) for k in kinds[:2 if not (fast or bursts) else len(kinds)]]
    if board:
        out.append(_fmt_record(70, 'MSG', 'QZ', 'TimeUS,Message'))
        out.append(_df_records(70, 'QZ', 'TimeUS,Message', {
            'TimeUS': np.zeros(2, dtype=np.uint64),
            'Message': [b'ArduCopter V4.5.4 (fd1bcc61)', board.encode()]}).tobytes())
    if params:
        keys = list(params)
        out.append(_df_records(64, PARM_FORMAT[1], PARM_FORMAT[2], {
            'TimeUS': np.zeros(len(keys), dtype=np.uint64),
            'Name': [k.encode() for k in keys],
            'Value': [float(params[k]) for k in keys]}).tobytes())
    recs = []
    for k, imu in enumerate(imus):
        acc = imu.accel if imu.accel is not None else np.zeros((len(imu.t), 3))
        recs.append(_df_records(65, fmt, cols, {
            stamp: _us(imu.t) // (1000 if stamp == 'TimeMS' else 1),
            'I': np.full(len(imu.t), k), 'GyrX': imu.gyro[:, 0],
            'GyrY': imu.gyro[:, 1], 'GyrZ': imu.gyro[:, 2], 'AccX': acc[:, 0],
            'AccY': acc[:, 1], 'AccZ': acc[:, 2], temp_field: imu.temp, 'GH': 1, 'AH': 1}))
    blocks = [(np.concatenate(recs), stamp)] if recs else []
    blocks += _fast_records(fast or {}, gyr_format) + _bursts(imus[0] if imus else None, bursts)
    blocks = [(r[np.argsort(r['body'][st], kind='stable')], st) for r, st in blocks]
    if blocks:
        ends = [float(r['body'][st][-1]) * (1000 if st == 'TimeMS' else 1)
                for r, st in blocks if len(r)]
        edges = np.linspace(0.0, max(ends, default=0.0) + 1.0, 51)[1:-1]
        for lo, hi in zip(np.r_[-1.0, edges], np.r_[edges, np.inf]):
            for r, st in blocks:
                us = r['body'][st].astype(np.float64) * (1000 if st == 'TimeMS' else 1)
                out.append(r[(us > lo) & (us <= hi)].tobytes())
    Path(path).write_bytes(b''.join(out))
    return Path(path)


def _fast_records(fast: dict, gyr_format: tuple) -> list:
    """Return the ``ACC`` and ``GYR`` records of the instances at the sensor rate."""
    out = []
    for mtype, (name, fmt, cols), what in ((66, ACC_FORMAT, 'accel'), (69, gyr_format, 'gyro')):
        for k, imu in sorted(fast.items()):
            v = getattr(imu, what)
            if v is None:
                continue
            us = _us(imu.t)
            axes = [c for c in cols.split(',') if c[-1] in 'XYZ']
            rec = _df_records(mtype, fmt, cols, {
                'TimeUS': (us // 2500 + 1) * 2500, 'I': np.full(len(us), k), 'SampleUS': us,
                **{a: v[:, j] for j, a in enumerate(axes)}})
            out.append((rec, 'TimeUS'))
    return out


def _bursts(imu: Imu | None, count: int) -> list:
    """Return ``count`` batch-sampler bursts of ``imu``'s gyro: ISBH + 4 ISBD of 32 samples."""
    if imu is None or not count:
        return []
    n = len(imu.t)
    starts = np.linspace(0, max(0, n - 128), count).astype(int)
    head = _df_records(67, ISBH_FORMAT[1], ISBH_FORMAT[2], {
        'TimeUS': _us(imu.t[starts]), 'N': np.arange(count), 'type': 1, 'mul': 1000,
        'smp_cnt': 128, 'SampleUS': _us(imu.t[starts]), 'smp_rate': 1000.0})
    rows = np.minimum(starts[:, None] + np.arange(128), n - 1).reshape(count * 4, 32)
    g = np.clip(np.round(imu.gyro[rows] * 1000), -32768, 32767).astype(np.int16)
    body = _df_records(68, ISBD_FORMAT[1], ISBD_FORMAT[2], {
        'TimeUS': _us(imu.t[rows[:, -1]]), 'N': np.repeat(np.arange(count), 4),
        'seqno': np.tile(np.arange(4), count), 'x': g[..., 0], 'y': g[..., 1], 'z': g[..., 2]})
    return [(head, 'TimeUS'), (body, 'TimeUS')]


# --------------------------------------------------------------------------------------------
# A simulated session in every format
# --------------------------------------------------------------------------------------------

def imu_from_sim(sim, *, t_offset: float = 100.0, device_id: int = 2293768) -> Imu:
    """
    Return a simulated run as a flight controller logs it, in float32 like the logs.

    The temperature at each sample is the latest thermometer reading (zero-order hold).
    """
    idx = np.clip(np.searchsorted(sim.temp_t, sim.imu_t, side='right') - 1, 0,
                  sim.temp_t.size - 1)
    f32 = lambda a: np.asarray(a, dtype=np.float32).astype(np.float64)  # noqa: E731
    t = np.round((sim.imu_t + t_offset) * 1e6) * 1e-6
    return Imu(t=t, gyro=f32(sim.gyro), temp=f32(sim.temp_c[idx]), accel=f32(sim.accel),
               device_id=device_id)


def bag_from_imu(imu: Imu, path: Path) -> Path:
    """Write the same samples as a bag (temperature on the IMU stamps)."""
    t = _us(imu.t).astype(np.float64) * 1e-6
    acc = imu.accel if imu.accel is not None else np.zeros((len(t), 3))
    write_bag(path, imu_t=t, gyro=imu.gyro, accel=acc, temp_t=t, temp_c=imu.temp)
    return path


# --------------------------------------------------------------------------------------------
# Flight-controller-like logs: flights between still stretches (tests and bench/)
# --------------------------------------------------------------------------------------------

@dataclass
class FlightDay:
    """One simulated power cycle of a flight controller and where it was truly still."""

    imu: Imu
    still: np.ndarray            # (N,) bool: truly still samples
    offset: np.ndarray           # (3,) rad/s: this power cycle's turn-on offset
    drift: np.ndarray            # (2, 3): rad/s per degC and per degC^2 about 35 degC
    glitch: np.ndarray | None = None     # (N,) bool: the samples that read a spike


def flight_day(seed: int, *, rate_hz: float = 25.0, still_s: tuple = (10.0, 60.0),
               flight_s: tuple = (20.0, 120.0), legs: int = 8, t_start: float = 20.0,
               t_end: float = 50.0, tau_s: float = 400.0, resolution_c: float = 0.0625,
               noise_dps: float = 0.05, drift: np.ndarray | None = None,
               glitches: int = 0, drift_sd: np.ndarray | None = None,
               boot_calibrated: bool = False) -> FlightDay:
    """
    Return a flight log's IMU: still stretches and flights in turn while the board warms.

    The gyro reads ``offset + drift(T) + noise`` while still, plus the vehicle's rotation
    (tens of deg/s) and vibration in flight; the thermometer is quantised to
    ``resolution_c``; ``glitches`` single samples read a spike. Each seed is its own power
    cycle (its own turn-on offset); ``drift`` (2, 3) is the board's (shared across seeds).
    ``drift_sd`` (2, 3): this power cycle's drift departs from the board's by a normal draw of
    that spread per term and axis (a curve that does not carry from one power cycle to the
    next); ``boot_calibrated``: the offset is the one that zeroes the rate at boot, as a
    flight controller's gyro calibration does, within 0.01 deg/s. ``t_start > t_end`` cools.
    """
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    parts, still = [], []
    for k in range(legs):
        n_still = max(2, int(rng.uniform(*still_s) * rate_hz))
        n_fly = max(2, int(rng.uniform(*flight_s) * rate_hz))
        parts += [n_still, n_fly] if k < legs - 1 else [n_still]
        still += [True, False] if k < legs - 1 else [True]
    n = int(sum(parts))
    t = 100.0 + np.arange(n) * dt
    is_still = np.repeat(np.array(still), parts)
    temp_true = t_end + (t_start - t_end) * np.exp(-(t - t[0]) / tau_s)
    temp = np.round(temp_true / resolution_c) * resolution_c
    d = np.array([[0.004, -0.002, 0.003], [3e-5, 4e-5, -2e-5]]) if drift is None else drift
    dT = (temp_true - 35.0)[:, None]
    offset = np.radians(rng.normal(0.0, 0.1, 3))
    if drift_sd is not None or boot_calibrated:     # a second stream: the seeds above stay
        cycle = np.random.default_rng([seed, 1])
        if drift_sd is not None:
            d = d + cycle.normal(0.0, 1.0, (2, 3)) * np.asarray(drift_sd)
        if boot_calibrated:
            offset = -np.radians(dT[0] * d[0] + dT[0] ** 2 * d[1] + cycle.normal(0.0, 0.01, 3))
    d = np.radians(d)
    noise = np.radians(noise_dps)
    gyro = offset + dT * d[0] + dT ** 2 * d[1] + rng.normal(0.0, noise, (n, 3))
    accel = np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.02, (n, 3))
    fly = ~is_still
    m = int(fly.sum())
    if m:
        # Smooth manoeuvres (a random walk low-passed) and motor vibration.
        steps = rng.normal(0.0, 1.0, (m, 3)).cumsum(axis=0) * np.radians(2.0) * np.sqrt(dt)
        gyro[fly] += steps - steps.mean(axis=0) + rng.normal(0.0, np.radians(3.0), (m, 3))
        accel[fly] += rng.normal(0.0, 1.5, (m, 3))
    glitch = np.zeros(n, dtype=bool)
    if glitches:
        at = rng.choice(n, size=glitches, replace=False)
        gyro[at] += rng.choice([-1.0, 1.0], size=(glitches, 3)) * 3.0
        glitch[at] = True
    f32 = lambda a: np.asarray(a, dtype=np.float32).astype(np.float64)  # noqa: E731
    imu = Imu(t=np.round(t * 1e6) * 1e-6, gyro=f32(gyro), temp=f32(temp), accel=f32(accel))
    return FlightDay(imu, is_still, offset, d, glitch)


def flight_logs(root: Path, n: int, *, legs: int) -> tuple[list, list]:
    """Return ``n`` power cycles of one board (seeds 0..n-1) and their DataFlash logs."""
    days = [flight_day(seed, legs=legs) for seed in range(n)]
    return days, [write_dataflash(root / f'day{k}.bin', [d.imu]) for k, d in enumerate(days)]


def still_drift(days: list, corrected: list | None = None) -> np.ndarray:
    """
    Return the within-log drift of still stretches per axis, rad/s (3,).

    Per log, the mean rate of each truly still stretch less the log's mean of them (its
    power cycle's offset re-anchored away); the RMS of those over every log. ``corrected``
    gives per log the rate to judge instead of the raw one.
    """
    dev = []
    for k, day in enumerate(days):
        rate = day.imu.gyro if corrected is None else corrected[k]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], day.still.astype(np.int8), [0]])))
        means = np.array([rate[a:b].mean(axis=0) for a, b in zip(edges[::2], edges[1::2])])
        if len(means) > 1:
            dev.append(means - means.mean(axis=0))
    return np.sqrt(np.mean(np.concatenate(dev) ** 2, axis=0))


def sd_card(root: Path) -> tuple[list, list]:
    """
    Write an SD card's folder of logs under ``root``: (readable logs, unreadable logs).

    Two heat-cool chamber runs, one as a ULog in ``log/DATE/`` (PX4's layout), one as a
    DataFlash log; beside them a ULog damaged inside, an empty ``.BIN`` (the power cut
    before its first byte) and a text file that is no log.
    """
    from gyro_tdc.sim import simulate_scenario
    imus = [imu_from_sim(s) for s in simulate_scenario('l3gd20_heat_cool', seed=3,
                                                       rate_hz=1.0)]
    day = root / 'log' / '2024-05-01'
    day.mkdir(parents=True)
    good = [write_ulog(day / 'run0.ulg', px4_topics([imus[0]]), {'TC_G_ENABLE': 0}),
            write_dataflash(root / 'run1.bin', [imus[1]], {'INS_TCAL1_ENABLE': 0})]
    empty = root / 'empty.BIN'
    empty.write_bytes(b'')
    data = bytearray(good[0].read_bytes())
    data[len(data) // 2:len(data) // 2 + 40] = bytes(40)
    damaged = day / 'run2.ulg'
    damaged.write_bytes(bytes(data))
    (root / 'notes.txt').write_text('not a log')
    return good, [damaged, empty]
