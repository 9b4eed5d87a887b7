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
Flight-controller logs beside bags: which format a path is, and one IMU read from it.

PX4 ULog (:mod:`gyro_tdc.data.ulog`) and ArduPilot DataFlash (:mod:`gyro_tdc.data.dataflash`)
give one :class:`FlightLog`; :func:`flight_log_data` turns it into the arrays a bag gives,
refusing data the flight controller already compensated (see ``doc/internals/data.md``).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import io
import os
from pathlib import Path
import sys
import tempfile
from typing import Any, Iterator, Mapping

from gyro_tdc.data.bag.reader import BagData
from gyro_tdc.data.options import BagOptions, LOG_FORMATS
from gyro_tdc.errors import DatasetError
import numpy as np
from numpy.typing import NDArray

__all__ = ['captured', 'columns', 'DATAFLASH_MAGIC', 'describe_log', 'detect_format',
           'flight_log_data', 'FlightLog', 'imu_of', 'is_flight_log', 'no_instance',
           'no_temperature', 'on_stamps', 'PLAUSIBLE_C', 'rate_hz', 'rate_words', 'seconds',
           'sensor_stream', 'thermometer', 'ULOG_MAGIC']

#: A ULog starts with these 7 bytes (then the version byte).
ULOG_MAGIC = b'ULog\x01\x125'
#: A DataFlash log starts with a FMT record: the two head bytes, then message type 0x80.
DATAFLASH_MAGIC = b'\xa3\x95\x80'
_SUFFIXES = {'.ulg': 'ulog', '.bin': 'dataflash'}
#: Readings outside this range (degC) are no temperature of a working board.
PLAUSIBLE_C = (-80.0, 200.0)
#: A sensor-rate stream replaces a log's gyro when at least this many times as fast...
STREAM_RATIO = 2.0
#: ...and every sample of that gyro (but one in a thousand) has one of the stream's within
#: this many seconds: no gap the log's own gyro does not share.
STREAM_GAP_S = 1.0


@dataclass(frozen=True)
class FlightLog:
    """
    One IMU of a flight-controller log, as its reader found it.

    The samples, and what the log says about them (firmware, source, on-board corrections,
    thermometer, damage), for the reader's line and its refusals.
    """

    #: Sample stamps (N,), s (the log's boot clock).
    imu_t: NDArray[np.float64]
    #: Angular rate (N, 3), rad/s.
    gyro: NDArray[np.float64]
    #: The temperature at each sample (N,) (NaN where the log has none), or at ``temp_t``
    #: (M,), degC.
    temp_c: NDArray[np.float64]
    #: Specific force at each sample (N, 3), m/s^2; None when not read or absent.
    accel: NDArray[np.float64] | None
    #: The log's parameters (the values at its start), name -> value.
    params: dict
    #: ``'px4'`` or ``'ardupilot'``.
    firmware: str
    #: Where the samples came from (``sensor_gyro``, ``sensor_combined``, ``IMU``).
    source: str
    #: The IMU instance read (0-based).
    instance: int
    #: Every instance the log holds.
    instances: tuple
    #: True when the samples precede every on-board correction.
    raw: bool
    #: True when the flight controller's thermal compensation was applied to the samples.
    compensated: bool
    #: What the parameters say about on-board thermal compensation, in words.
    onboard: str
    #: The sensor's device id where the log gives one (0 otherwise).
    device_id: int = 0
    #: Bytes after the last whole message (a log cut short), 0 when none.
    truncated_bytes: int = 0
    #: Further facts for the reader's line (e.g. the temperature's source).
    notes: list = field(default_factory=list)
    #: The thermometer's own stamps (M,), s (its rate, e.g. 1 Hz beside a 200 Hz gyro);
    #: None: ``temp_c`` is on ``imu_t``.
    temp_t: NDArray[np.float64] | None = None
    #: The thermometer read (``IMU.T``, ``sensor_gyro.temperature``, ``BARO.Temp``...).
    temperature: str = ''
    #: True when the thermometer is not the IMU's own (``--temperature-source``).
    proxy: bool = False
    #: What the reader skipped of damaged bytes inside the log (not at its end), in words;
    #: '' when nothing was.
    damage: str = ''
    #: The board the log was written on (its name and unique id as the firmware logs them),
    #: '' when the log does not say.
    board: str = ''


def thermometer(values: object) -> NDArray[np.float64] | None:
    """
    Return a thermometer's readings as float64, None when it is no thermometer.

    A field that is missing, reads NaN throughout or a constant 0 (a driver that fills the
    field without a sensor behind it) is no thermometer; NaN readings of a real one stay. A
    reading outside :data:`PLAUSIBLE_C` is none (PX4 fills ``differential_pressure``'s
    with -1000 where the sensor has no thermometer): NaN.
    """
    if values is None:
        return None
    v = _float64(values).reshape(-1)
    with np.errstate(invalid='ignore'):
        v = np.where((v >= PLAUSIBLE_C[0]) & (v <= PLAUSIBLE_C[1]), v, np.nan)
    return v if np.any(np.abs(v) > 0.0) else None      # NaN compares False: none or all 0


def _float64(values: object) -> NDArray[np.float64]:
    """Return a log's field as float64; a signalling NaN (damaged bytes) is a NaN, silently."""
    with np.errstate(invalid='ignore'):
        return np.asarray(values, dtype=np.float64)


def columns(d: dict, names: tuple[str, ...]) -> NDArray[np.float64] | None:
    """Return a log's fields side by side as an (N, k) float64 array, None when one is missing."""
    return (np.column_stack([_float64(d[n]) for n in names])
            if all(n in d for n in names) else None)


def on_stamps(t: NDArray[np.float64], t_src: NDArray[np.float64],
              v: NDArray[np.float64] | None) -> NDArray[np.float64] | None:
    """Interpolate ``v`` (stamps ``t_src``) onto ``t`` per column (NaN outside; None: none)."""
    if v is None or not len(t_src):
        return None
    order = np.argsort(t_src, kind='stable')
    return np.column_stack([np.interp(t, t_src[order], v[order, j], left=np.nan, right=np.nan)
                            for j in range(v.shape[1])])


def rate_hz(t: NDArray[np.float64]) -> float:
    """
    Return the mean sample rate of stamps ``t`` (s, in log order), Hz (0 without two apart).

    Over the middle 98 % of the stamps where the whole span is over twice theirs: one stamp a
    damaged byte threw years away (no checksum guards a log's payload) would make the fastest
    gyro look the slowest. Where the stamps go back (damage, a reset), over the time their
    runs cover, each instant once: the gaps the jumps leave between runs are no pause.
    """
    t = np.asarray(t, dtype=np.float64)
    t = t[np.isfinite(t)]
    s = np.sort(t)
    n, k = len(s), len(s) // 100
    if k and s[-1] - s[0] > 2.0 * float(s[n - 1 - k] - s[k]) * (n - 1) / (n - 1 - 2 * k):
        t = t[(t >= s[k]) & (t <= s[n - 1 - k])]
    if len(t) < 2:
        return 0.0
    cut = np.flatnonzero(np.diff(t) < 0) + 1
    starts, ends = t[np.r_[0, cut]], t[np.r_[cut - 1, len(t) - 1]]
    order = np.argsort(starts, kind='stable')
    starts, ends = starts[order], ends[order]
    before = np.r_[-np.inf, np.maximum.accumulate(ends)[:-1]]
    span = float(np.sum(np.clip(ends - np.maximum(starts, before), 0.0, None)))
    return (len(t) - 1) / span if span > 0 else 0.0


def rate_words(t: NDArray[np.float64]) -> str:
    """
    Return the rate of stamps ``t`` (s) in words for an inventory: its mean rate.

    A log that records only while armed pauses (steps over ten times the median): its mean
    rate (:func:`rate_hz`) counts the pauses, so where that is under 0.8 times the rate
    between them both are said (e.g. ``50 Hz (26.8 Hz over the log: it pauses)``).
    """
    mean = rate_hz(t)
    steps = np.diff(np.unique(np.asarray(t, dtype=np.float64)))
    run = steps[steps <= 10.0 * np.median(steps)] if steps.size else steps
    typical = run.size / float(run.sum()) if run.size else 0.0
    return (f'{typical:.3g} Hz ({mean:.3g} Hz over the log: it pauses)' if mean < 0.8 * typical
            else f'{mean:.3g} Hz')


def sensor_stream(t: NDArray[np.float64], v: NDArray[np.float64], slow_t: NDArray[np.float64],
                  name: str, beside: str, what: str = 'gyro') -> tuple[bool, str]:
    """
    Return whether samples ``v`` at ``t`` (s) can stand in for ``beside``'s at ``slow_t``, and why.

    They can when their finite samples come at least :data:`STREAM_RATIO` times as fast and
    leave no ``beside`` sample (but one in a thousand) :data:`STREAM_GAP_S` away: a stream
    beside it over the whole log, its gaps the log's own (a sensor's FIFO, ArduPilot's ``GYR``).
    """
    ts = np.sort(t[np.isfinite(v).all(axis=1)])
    fast, slow = rate_hz(ts), rate_hz(slow_t)
    if len(ts) < 2 or fast < STREAM_RATIO * slow:
        return False, (f'{name} not used: {len(ts)} samples at {fast:.4g} Hz, not twice as '
                       f'fast as {beside}')
    at = np.clip(np.searchsorted(ts, slow_t), 1, len(ts) - 1)
    near = np.minimum(np.abs(ts[at] - slow_t), np.abs(ts[at - 1] - slow_t))
    far = int(np.count_nonzero(~(near <= STREAM_GAP_S)))
    if far > len(slow_t) // 1000:
        return False, (f'{name} at {fast:.4g} Hz not used: none within {STREAM_GAP_S:g} s of '
                       f'{far} of {len(slow_t)} {beside} samples (gaps, or it ends early)')
    return True, f'{what} from {name} at {fast:.4g} Hz beside {beside} at {slow:.3g} Hz'


def seconds(d: dict, field: str, sample: str = '') -> NDArray[np.float64]:
    """
    Return a record's stamps (microseconds in the log) in s: ``sample`` where it has one.

    ``sample`` is when each sample was taken (``timestamp_sample``, ``SampleUS``), ``field``
    when it was logged; a driver that leaves ``sample`` 0 would stack every sample on one
    stamp, so such a record is stamped by ``field``.
    """
    us = d.get(sample)
    if us is None or not np.all(np.asarray(us) > 0):
        us = d[field]
    return np.asarray(us, dtype=np.float64) * 1e-6


@contextlib.contextmanager
def captured(sink: io.StringIO) -> Iterator[None]:
    """
    Send what is printed meanwhile to ``sink``, at the file descriptors too.

    pyulog prints what it finds corrupt, pymavlink's compiled indexer every damaged header
    to the process's stderr; a damaged log must stay one line (the error, or a count in the
    reader's line).
    """
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile(mode='w+b') as tmp:
        try:
            for fd in (1, 2):
                os.dup2(tmp.fileno(), fd)
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            for fd, old in zip((1, 2), saved):
                os.dup2(old, fd)
                os.close(old)
            tmp.seek(0)
            sink.write(tmp.read().decode('utf-8', 'replace'))


def no_instance(path: Path, kind: str, instance: int, has: object, inventory: str) -> DatasetError:
    """Return the refusal of an IMU instance the log does not hold (``has``: the ones it does)."""
    return DatasetError(f'Log {str(path)!r}: {kind} has no instance {instance} (it has '
                        f'{", ".join(map(str, sorted(has)))}; what each instance carries: '
                        f'{inventory}; --imu-instance N).')


def no_temperature(path: Path, what: str, source: str, inventory: str, *, others: int,
                   baro: bool) -> DatasetError:
    """
    Return the refusal of a log without the thermometer ``source`` (``--temperature-source``).

    ``what``: the IMU read, in words; ``inventory``: what each instance carries; ``others``:
    how many other IMUs of the log have a thermometer (``--imu-instance`` is proposed only
    then); ``baro``: whether it has a barometer's thermometer.
    """
    if source != 'imu':
        return DatasetError(f'Log {str(path)!r}: no usable thermometer for --temperature-source '
                            f'{source} (what each instance carries: {inventory}).')
    hint = ('--imu-instance N, or --temperature-source baro' if others and baro else
            "--temperature-source baro takes the barometer's as a proxy" if baro else
            '--imu-instance N' if others else 'the log has no other thermometer')
    return DatasetError(f'Log {str(path)!r}: {what} carries no temperature (no thermometer '
                        'reads other than a constant 0 or NaN; what each instance carries: '
                        f'{inventory}; {hint}).')


def is_flight_log(path: str | os.PathLike) -> bool:
    """Return True when ``path`` is a file that looks like a ULog or DataFlash log."""
    return detect_format(path) != 'rosbag2'


def detect_format(path: str | os.PathLike, requested: str = 'auto') -> str:
    """
    Return how to read ``path``: ``'rosbag2'``, ``'ulog'`` or ``'dataflash'``.

    ``requested`` (``--log-format``) is the format, or ``'auto'``: magic bytes, then the
    suffix ``.ulg`` / ``.bin``; a directory or anything else is a bag. Raises DatasetError for
    an unknown ``requested``.
    """
    if requested not in LOG_FORMATS:
        raise DatasetError(f'Expected the log format to be one of {", ".join(LOG_FORMATS)}, '
                           f'got {requested!r}.')
    p = Path(path)
    if requested != 'auto' or not p.is_file():
        return 'rosbag2' if requested == 'auto' else requested
    head = b''
    with contextlib.suppress(OSError), open(p, 'rb') as f:
        head = f.read(8)
    return next((fmt for magic, fmt in ((ULOG_MAGIC, 'ulog'), (DATAFLASH_MAGIC, 'dataflash'))
                 if head.startswith(magic)), _SUFFIXES.get(p.suffix.lower(), 'rosbag2'))


def describe_log(log: FlightLog) -> str:
    """Return what was read from a log, in words (for the reader's line)."""
    kind = {'px4': 'PX4 ULog', 'ardupilot': 'ArduPilot DataFlash'}[log.firmware]
    dev = f' (device id {log.device_id})' if log.device_id else ''
    data = ('raw (before any on-board correction)' if log.raw else
            'corrected on board (thermal compensation included)' if log.compensated else
            'calibrated on board (no thermal compensation active)')
    return (f'{kind}, {log.source} instance {log.instance} of {len(log.instances)}{dev}: '
            f'{data}; {log.onboard}' + ''.join(f'; {n}' for n in log.notes)
            + (f'; temperature from {log.temperature}' if log.temperature else '')
            + (" (a proxy of the IMU's)" if log.temperature and log.proxy else ''))


def flight_log_data(path: str | os.PathLike, log: FlightLog, fmt: str,
                    options: BagOptions) -> tuple[BagData, dict]:
    """
    Return one IMU of a ULog or DataFlash log as the arrays a bag gives, or refuse it.

    Parameters
    ----------
    path : str or PathLike
        The log file.
    log : FlightLog
        What :func:`gyro_tdc.data.ulog.read_ulog` or
        :func:`gyro_tdc.data.dataflash.read_dataflash` read from it.
    fmt : str
        ``'ulog'`` or ``'dataflash'`` (see :func:`detect_format`).
    options : BagOptions
        ``imu_instance``, ``accel``, ``max_loss`` (damaged bytes inside the log are refused
        below 1.0; a log cut off at its end is read with a warning) and
        ``allow_onboard_corrected``.

    Returns
    -------
    (BagData, dict)
        The arrays (the temperature on the IMU stamps, no reference), and the run's extra
        ``info``: ``log_format``, ``log`` (what was read, in words), ``firmware``,
        ``source``, ``instance``, ``raw``, ``onboard_compensated``, ``params`` (the
        thermal-calibration ones), ``temperature`` (the thermometer read),
        ``temperature_proxy`` and ``warnings``.

    Raises
    ------
    DatasetError
        The log has no temperature, holds damaged bytes (unless ``max_loss`` is 1.0) or
        was compensated on board (unless allowed).

    """
    p = Path(path)
    warnings: list[str] = []
    if log.damage:
        note = f'damaged bytes inside the log ({log.damage})'
        if options.max_loss < 1.0:
            raise DatasetError(f'Log {str(p)!r}: {note}; --allow-loss reads the whole '
                               'messages around them.')
        warnings.append(note)
    if log.truncated_bytes:
        # Every SD-card log whose power goes ends so: the whole messages before are read.
        warnings.append(f'the log ends inside a message (cut short: the last '
                        f'{log.truncated_bytes} bytes, less than one message, are lost)')
    if log.compensated and not options.allow_onboard_corrected:
        raise DatasetError(
            f'Log {str(p)!r}: the {log.source} data were already thermally compensated on '
            f'board ({log.onboard}), a model of them would compensate twice; record the raw '
            'sensor data (PX4: log sensor_gyro) or turn the on-board compensation off, or '
            'pass --allow-onboard-corrected to use them as they are.')
    ok = np.isfinite(log.gyro).all(axis=1)
    temp_t = log.imu_t if log.temp_t is None else np.asarray(log.temp_t, dtype=np.float64)
    if not (warm := np.isfinite(log.temp_c) & np.isfinite(temp_t)).any():
        raise DatasetError(f'Log {str(p)!r}: {log.source} instance {log.instance} carries no '
                           'temperature; a drift model needs the IMU temperature.')
    data = BagData(imu_t=log.imu_t[ok], gyro=log.gyro[ok],
                   accel=None if log.accel is None else log.accel[ok], frame_id='',
                   temp_t=temp_t[warm], temp_c=log.temp_c[warm],
                   temp_var=np.zeros(int(warm.sum())), ref_t=None, ref=None, storage=fmt,
                   path=str(p), rejected={'imu_nonfinite': int(np.count_nonzero(~ok)),
                                          'temp_nonfinite': int(np.count_nonzero(~warm)),
                                          'ref_nonfinite': 0, 'undecodable': 0})
    return data, {
        'log_format': fmt, 'log': describe_log(log), 'firmware': log.firmware,
        'source': log.source, 'instance': log.instance, 'device_id': log.device_id,
        'raw': log.raw, 'onboard_compensated': log.compensated,
        'params': {k: v for k, v in log.params.items()
                   if k.startswith(('TC_', 'INS_TCAL')) or k.endswith('_CALTEMP')},
        'temperature': log.temperature, 'temperature_proxy': log.proxy, 'warnings': warnings,
        'board': log.board}


def imu_of(info: Mapping[str, Any]) -> str | None:
    """Return the IMU a run's ``info`` names, ``'<board> IMU <instance>'`` (None: no board)."""
    board = info.get('board')
    return f"{board} IMU {info.get('instance') or 0}" if board else None
