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
Bag -> aligned numpy arrays: one :class:`gyro_tdc.data.runs.Run` per recording.

How a bag is read is one :class:`gyro_tdc.data.options.BagOptions`; what is dropped and why
(implausible values, duplicate stamps, lost messages) is in ``doc/internals/data.md``.
"""

from __future__ import annotations

from dataclasses import replace
import math
import os
from pathlib import Path
import re
from tempfile import TemporaryDirectory
from typing import Callable, Iterable, Iterator

from gyro_tdc.base import (MAX_RATE_RAD_S, MAX_TEMP_SLEW_C_S, plausible_temperatures,
                           RESTART_BACK_S, TEMP_PLAUSIBLE_C)
from gyro_tdc.data.bag.metadata import (has_metadata, missing, storage_files,
                                        STORAGE_SUFFIXES)
from gyro_tdc.data.bag.reader import read_bag
from gyro_tdc.data.bag.storage_mcap import CUT_OFF
from gyro_tdc.data.dataflash import read_dataflash
from gyro_tdc.data.driver_bags import normalize_bag
from gyro_tdc.data.flightlog import detect_format, flight_log_data, is_flight_log
from gyro_tdc.data.options import BagOptions
from gyro_tdc.data.runs import float_array, Run
from gyro_tdc.data.ulog import read_ulog
from gyro_tdc.errors import DatasetError
from gyro_tdc.signal import has_accelerometer
import numpy as np
from numpy.typing import NDArray

__all__ = ['align_temperature', 'describe_read', 'expand_bags', 'find_bags',
           'FLIGHT_LOG_GAP_PERIODS', 'iter_runs', 'load_run', 'load_runs']

#: A flight log's thermometer is trusted up to this many of its own sample periods away
#: (at least ``BagOptions.max_gap_s``).
FLIGHT_LOG_GAP_PERIODS = 2.5


def _interp_sorted(imu_t: NDArray[np.float64], tt: NDArray[np.float64],
                   tc: NDArray[np.float64], gap: float) -> tuple[NDArray, NDArray[np.bool_]]:
    """
    Interpolate onto sorted IMU stamps, working on the knots rather than on every sample.

    One ``np.interp`` pass, then the invalid stretches -- before and after the thermometer's
    span, and the middle of every segment longer than ``2 * gap`` -- are located among the
    IMU stamps by binary search per knot instead of being tested per sample.
    """
    temp, valid = np.interp(imu_t, tt, tc), np.ones(len(imu_t), dtype=bool)
    valid[:np.searchsorted(imu_t, tt[0], side='left')] = False
    valid[np.searchsorted(imu_t, tt[-1], side='right'):] = False
    # In segment j a stamp is invalid when both distances exceed the gap:
    # t - tt[j] > gap and tt[j + 1] - t > gap.
    seg = np.flatnonzero(np.diff(tt) > 2.0 * gap)
    start = np.searchsorted(imu_t, tt[seg], side='right')
    stop = np.searchsorted(imu_t, tt[seg + 1], side='left')
    for a, b, j in zip(start.tolist(), stop.tolist(), seg.tolist()):
        part = imu_t[a:b]
        valid[a:b] &= ~((part - tt[j] > gap) & (tt[j + 1] - part > gap))
    temp[~valid] = np.nan
    return temp, valid


def align_temperature(imu_t, temp_t, temp_c, *, max_gap_s=5.0, return_counts=False):
    """
    Interpolate thermometer samples linearly onto IMU stamps.

    Thermometer samples with a NaN or infinite stamp or value are dropped, out-of-order
    samples are sorted and of samples sharing a stamp the last one given is kept (readings
    that disagree are counted, not averaged). An IMU sample is valid
    when it lies within the thermometer's time span and at most ``max_gap_s`` from the
    nearest thermometer sample; invalid samples get NaN.

    Parameters
    ----------
    imu_t : ArrayLike, shape (N,), s
        IMU stamps (any order).
    temp_t : ArrayLike, shape (M,), s
        Thermometer stamps (any order).
    temp_c : ArrayLike, shape (M,), degC
        Thermometer readings.
    max_gap_s : float, s
        Largest distance from an IMU stamp to the nearest thermometer sample.
    return_counts : bool
        Also return the counts of thermometer samples that were dropped or reordered.

    Returns
    -------
    temp_at_imu : NDArray[np.float64], shape (N,), degC
        Interpolated temperature (NaN where invalid).
    valid : NDArray[np.bool_], shape (N,)
        Where the interpolation is trusted.
    counts : dict[str, int]
        Only with ``return_counts``: ``nonfinite`` (dropped), ``out_of_order`` (backward
        steps before sorting), ``duplicates`` (samples dropped because a later one has the
        same stamp) and ``conflicting`` (stamps whose duplicate readings disagree).

    Raises
    ------
    DatasetError
        When shapes disagree or ``max_gap_s`` is not a positive number.

    """
    imu_t, temp_t, temp_c = (float_array('imu_t', imu_t), float_array('temp_t', temp_t),
                             float_array('temp_c', temp_c))
    if temp_c.shape != temp_t.shape:
        raise DatasetError(f'Expected `temp_c` to have shape {temp_t.shape} like `temp_t`, '
                           f'got {temp_c.shape}.')
    try:
        gap = float(max_gap_s)
    except (TypeError, ValueError):
        gap = float('nan')
    if not (np.isfinite(gap) and gap > 0):
        raise DatasetError(f'Expected `max_gap_s` to be a positive number, got {max_gap_s!r}.')

    finite = np.isfinite(temp_t) & np.isfinite(temp_c)
    counts = {'nonfinite': int(np.count_nonzero(~finite)), 'out_of_order': 0, 'duplicates': 0,
              'conflicting': 0}
    tt, tc = temp_t[finite], temp_c[finite]
    steps = np.diff(tt)
    if np.any(steps <= 0):
        counts['out_of_order'] = int(np.count_nonzero(steps < 0))
        order = np.argsort(tt, kind='stable')
        tt, tc = tt[order], tc[order]
        last = np.ones(len(tt), dtype=bool)      # the last sample given of each stamp
        last[:-1] = np.diff(tt) > 0
        if not last.all():
            differ = ~last & (tc != tc[np.searchsorted(tt, tt, side='right') - 1])
            counts['duplicates'] = int(np.count_nonzero(~last))
            counts['conflicting'] = int(np.unique(tt[differ]).size)
            tt, tc = tt[last], tc[last]

    if len(tt) < 2:
        valid = imu_t == tt[0] if len(tt) else np.zeros(imu_t.shape, dtype=bool)
        temp = np.where(valid, tc[0] if len(tt) else np.nan, np.nan)
    elif np.all(imu_t[1:] >= imu_t[:-1]):
        temp, valid = _interp_sorted(imu_t, tt, tc, gap)
    else:                                       # IMU stamps in any order: sorted and back
        order = np.argsort(imu_t, kind='stable')
        temp, valid = np.empty(len(imu_t)), np.empty(len(imu_t), dtype=bool)
        temp[order], valid[order] = _interp_sorted(imu_t[order], tt, tc, gap)
    return (temp, valid, counts) if return_counts else (temp, valid)


def _check_counts(bag: object, data: object, decoded: dict[str, int], max_loss: float,
                  warnings: list[str]) -> dict[str, list[int]]:
    """
    Compare the messages decoded per topic with the counts listed in the bag's metadata.

    Appends a warning per topic with missing messages; raises DatasetError when more than
    ``max_loss`` of a topic's listed messages are missing. Returns topic -> [decoded, listed].
    """
    out = {topic: [int(got), int(data.topics.get(topic, ('', 0))[1])]
           for topic, got in decoded.items()}
    cut = any(CUT_OFF in w for w in data.warnings)
    why = 'a storage file cut off at its end' if cut else 'a damaged file or undecodable messages'
    for topic, (got, listed) in out.items():
        lost = listed - got
        note = (f'{topic}: read {got} of {listed} messages listed in the bag metadata '
                f'({lost} lost: {100.0 * lost / max(listed, 1):.2g} %; {why})')
        if lost > max_loss * listed:
            raise DatasetError(f'Bag {str(bag)!r}: {note}, more than the '
                               f'{100.0 * max_loss:g} % allowed (--allow-loss accepts it)'
                               + ''.join(f'; {w}' for w in data.warnings) + '.')
        warnings += [note] if lost > 0 else []
    return out


def _follow_restarts(bag: object, data: object, gap: float) -> tuple[object, list]:
    """
    Move every restarted part's stamps to follow the previous part, ``gap`` s after it.

    A device whose clock restarts (stamps since boot) steps its IMU stamps back in the bag's
    order; its thermometer (and reference) stamps step back with them. Each part is moved,
    every topic by the same amount, so the parts follow one another in the bag's order;
    returns the data and, per restart, ``(first moved stamp, step back in s)``.
    """
    streams = {'imu_t': data.imu_t, 'temp_t': data.temp_t}
    if data.ref_t is not None and len(data.ref_t):
        streams['ref_t'] = data.ref_t
    # Part starts: where the stamps (bag order) step back by more than RESTART_BACK_S.
    cuts = {k: [0] + (np.flatnonzero(np.diff(v) < -RESTART_BACK_S) + 1).tolist() + [len(v)]
            for k, v in streams.items()}
    imu = cuts['imu_t']
    for key, c in cuts.items():
        if len(c) != len(imu):
            what = 'thermometer' if key == 'temp_t' else 'reference'
            raise DatasetError(
                f'Bag {str(bag)!r}: the IMU stamps step back {len(imu) - 2} time(s) (a device '
                f'clock restart) but the {what} stamps {len(c) - 2} time(s): the parts cannot '
                'be matched; split the bag at the restarts.')
    new = {k: v.astype(np.float64, copy=True) for k, v in streams.items()}
    out, end = [], -math.inf
    for p in range(len(imu) - 1):
        spans = [(new[k], slice(c[p], c[p + 1])) for k, c in cuts.items() if c[p + 1] > c[p]]
        shift = 0.0 if p == 0 else end + gap - min(float(v[sl].min()) for v, sl in spans)
        if p:
            out.append((float(new['imu_t'][imu[p]] + shift),
                        float(data.imu_t[imu[p] - 1] - data.imu_t[imu[p]])))
        for v, sl in spans:
            v[sl] += shift
        end = max(float(v[sl].max()) for v, sl in spans)
    return replace(data, **new), out


def _read_source(bag: str | os.PathLike, o: BagOptions, *,
                 read_reference: bool) -> tuple[object, dict]:
    """Read a rosbag2 bag, or a flight-controller log (one IMU, no reference topic)."""
    if (fmt := detect_format(bag, o.log_format)) == 'rosbag2':
        topics = dict(imu_topic=o.imu_topic, temperature_topic=o.temperature_topic)
        how = dict(reference_topic=o.reference_topic if read_reference else None,
                   progress=o.progress, accel=bool(o.accel))
        if o.driver is None or o.driver.plain:
            return read_bag(bag, **topics, **how), {}
        # A driver's types, read by field into a plain bag that lives as long as this read.
        notes: list[str] = []
        with TemporaryDirectory(prefix='gyro_tdc_driver_') as tmp:
            plain = normalize_bag(bag, o.driver, **topics, out=Path(tmp) / Path(bag).name,
                                  warn=notes.append)
            data = read_bag(plain, **topics, **how)
        return replace(data, path=str(bag), warnings=(*notes, *data.warnings)), {}
    if not Path(bag).is_file():
        raise DatasetError(f'Log {str(bag)!r} is not a file.')
    log = (read_ulog if fmt == 'ulog' else read_dataflash)(
        bag, instance=o.imu_instance, accel=bool(o.accel), temperature_source=o.temperature_source)
    return flight_log_data(bag, log, fmt, o)


def _gate_imu(data: object, rejected: dict[str, int]) -> tuple[NDArray, NDArray, NDArray | None]:
    """
    Drop implausible rates, sort by stamp and keep the first sample of each stamp.

    Returns stamps, rates and their rows in ``data.accel`` (None: all of them, in order).
    """
    t, omega, rows = data.imu_t, data.gyro, None
    plausible = np.abs(omega) <= MAX_RATE_RAD_S     # then column by column, not .all(axis=1)
    plausible = plausible[:, 0] & plausible[:, 1] & plausible[:, 2]
    if not plausible.all():
        rejected['imu_implausible'] = int(np.count_nonzero(~plausible))
        rows = np.flatnonzero(plausible)
        t, omega = t[rows], omega[rows]
    steps = np.diff(t)
    if np.any(steps <= 0):
        rejected['out_of_order'] = int(np.count_nonzero(steps < 0))
        order = np.argsort(t, kind='stable')
        first = np.ones(len(t), dtype=bool)
        first[1:] = np.diff(t[order]) > 0
        rejected['duplicate_stamps'] = int(np.count_nonzero(~first))
        order = order[first]
        t, omega, rows = t[order], omega[order], order if rows is None else rows[order]
    return t, omega, rows


def _reference_rates(data: object, const: NDArray | None, t: NDArray, shape: tuple,
                     keep: NDArray[np.bool_], rejected: dict[str, int]) -> tuple[str, NDArray]:
    """
    Return the reference source and rate per IMU stamp: constant, held from a topic or zero.

    Drops a topic's implausible rates and clears ``keep`` before its first message (counted).
    """
    if const is not None:
        return 'constant', np.broadcast_to(const, shape).copy()
    if data.ref_t is None:
        return 'zero', np.zeros(shape)
    plausible = np.all(np.abs(data.ref) <= MAX_RATE_RAD_S, axis=1)
    rejected['ref_implausible'] = int(np.count_nonzero(~plausible))
    order = np.argsort(data.ref_t[plausible], kind='stable')
    ref_t, ref = data.ref_t[plausible][order], data.ref[plausible][order]
    held = np.searchsorted(ref_t, t, side='right') - 1
    has_ref = held >= 0
    rejected['no_reference'] = int(np.count_nonzero(keep & ~has_ref))
    keep &= has_ref
    return 'topic', ref[held.clip(0)]


def load_run(bag: str | os.PathLike, options: BagOptions | None = None) -> Run:
    """
    Read one bag into a :class:`~gyro_tdc.data.runs.Run` aligned on the IMU stamps.

    IMU samples are sorted by stamp; of samples sharing a stamp the first in the bag is
    kept. Samples with a non-finite rate, without a trusted temperature (see
    :func:`align_temperature`) or before the first reference message are dropped, and so
    are physically impossible values (a temperature the plausibility gate refuses, outside
    ``TEMP_PLAUSIBLE_C`` or jumping faster than ``MAX_TEMP_SLEW_C_S`` from the last plausible
    reading, :mod:`gyro_tdc.base.plausible`; a rate above ``MAX_RATE_RAD_S`` in magnitude).
    Every drop is counted in
    ``run.info['rejected']``: ``imu_nonfinite``, ``temp_nonfinite``, ``ref_nonfinite``,
    ``undecodable``, ``temp_before_imu`` (Float readings before the first IMU message),
    ``imu_implausible``, ``temp_implausible``, ``ref_implausible``, ``duplicate_stamps``,
    ``temp_duplicate_stamps``, ``out_of_order``, ``no_temperature``, ``no_reference``.
    Messages missing against the bag's metadata and conflicting thermometer readings are
    reported in ``run.info['warnings']``.

    Parameters
    ----------
    bag : str or Path
        rosbag2 directory (sqlite3 or mcap), or a PX4 ULog / ArduPilot DataFlash log (as
        ``options.log_format`` says; see :mod:`gyro_tdc.data.flightlog`).
    options : BagOptions, optional
        Topics, reference rate, temperature gap, loss allowed, accelerometer (default
        :class:`~gyro_tdc.data.options.BagOptions`: the accelerometer is not read).

    Returns
    -------
    Run
        ``name`` is the bag path; ``info`` holds ``rejected``, ``warnings``, ``reference``
        ('constant', 'topic' or 'zero'), ``frame_id``, ``storage``, ``topics``,
        ``samples_read`` and ``messages`` (topic -> [decoded, listed in the metadata]); for a
        flight log also what :func:`gyro_tdc.data.flightlog.flight_log_data` adds
        (``log_format``, ``log``, ``params``, ``onboard_compensated``...).

    Raises
    ------
    DatasetError
        When the bag cannot be read, a topic is missing, empty or of the wrong type, more
        than ``options.max_loss`` of a topic's messages are missing, or no sample survives.

    """
    o = BagOptions() if options is None else options
    const = None if o.reference is None else np.asarray(o.reference, dtype=np.float64)
    data, extra = _read_source(bag, o, read_reference=const is None)
    rejected = {k: data.rejected.get(k, 0) for k in _DROPPED}
    warnings: list[str] = [*extra.pop('warnings', ()), *data.warnings]
    messages = {} if extra else _check_counts(bag, data, {
        o.imu_topic: len(data.imu_t) + data.rejected['imu_nonfinite'],
        o.temperature_topic: (len(data.temp_t) + data.rejected['temp_nonfinite']
                              + data.rejected.get('temp_before_imu', 0)),
        **({o.reference_topic: len(data.ref_t) + data.rejected['ref_nonfinite']}
           if data.ref_t is not None else {})}, o.max_loss, warnings)

    restarts: list = []
    if len(data.imu_t) > 1 and np.any(np.diff(data.imu_t) < -RESTART_BACK_S):
        data, restarts = _follow_restarts(bag, data, 2.0 * o.max_gap_s + 1.0)
    t, omega, rows = _gate_imu(data, rejected)
    temp_t, temp_c = data.temp_t, data.temp_c
    plausible = plausible_temperatures(temp_t, temp_c)     # the node's and driver's gate
    if not plausible.all():
        rejected['temp_implausible'] = int(np.count_nonzero(~plausible))
        temp_t, temp_c = temp_t[plausible], temp_c[plausible]

    gap = o.max_gap_s
    if extra and len(temp_t) > 1:
        # A flight log's thermometer runs at its own rate (PX4 logs sensor_gyro, the
        # barometer at 1 Hz or less): a gap is one of several of its periods.
        gap = max(gap, FLIGHT_LOG_GAP_PERIODS * float(np.median(np.diff(np.sort(temp_t)))))
    temp, keep, counts = align_temperature(t, temp_t, temp_c, max_gap_s=gap, return_counts=True)
    rejected['temp_nonfinite'] += counts['nonfinite']
    rejected['temp_duplicate_stamps'] = counts['duplicates']
    if counts['conflicting']:
        warnings.append(f'{o.temperature_topic}: {counts["conflicting"]} stamp(s) carry '
                        'conflicting temperature readings; kept the last reading of each')
    rejected['no_temperature'] = int(np.count_nonzero(~keep))

    source, omega_ref = _reference_rates(data, const, t, omega.shape, keep, rejected)

    if not np.any(keep):
        raise DatasetError(
            f'{str(bag)!r} has no usable sample: {len(data.imu_t)} IMU samples read, '
            f'{len(temp_t)} temperature samples spanning '
            + (f'[{temp_t.min():.3f}, {temp_t.max():.3f}] s' if len(temp_t) else 'nothing')
            + (f' vs IMU [{t.min():.3f}, {t.max():.3f}] s' if len(t) else '')
            + '; rejected: ' + (', '.join(f'{v} {k}' for k, v in rejected.items() if v)
                                or 'none') + '.')
    info = {'rejected': rejected, 'warnings': warnings, 'reference': source,
            'frame_id': data.frame_id, 'storage': data.storage, 'topics': data.topics,
            'samples_read': int(len(data.imu_t) + data.rejected['imu_nonfinite']),
            'messages': messages, 'decoded_by_rosbags': data.fallback, **extra}
    if restarts:     # the first sample of each restarted part in the final stamps
        info['restarts'] = [[int(np.searchsorted(t[keep], at)), back] for at, back in restarts]
    if not keep.all():
        kept = _as_slice(keep)    # the usual case (before the first reading): views, no copy
        t, temp, omega, omega_ref = t[kept], temp[kept], omega[kept], omega_ref[kept]
        rows = kept if rows is None else rows[kept]
    if (acc := data.accel) is not None:
        acc = np.ascontiguousarray(acc if rows is None else acc[_as_slice(rows)])
        acc = acc if has_accelerometer(acc) else None    # no accelerometer (REP 145: zeros)
    return Run(t, temp, np.ascontiguousarray(omega), np.ascontiguousarray(omega_ref),
               str(bag), info, acc)


def _as_slice(index: NDArray) -> slice | NDArray:
    """
    Return ``index`` (a boolean mask, sorted row numbers or a slice) as a slice where it can.

    Indexing by a slice gives views instead of copies of the full-length columns; the values
    are the same either way.
    """
    if isinstance(index, slice):
        return index
    if index.dtype == bool:          # one run: its first True and the count of them
        n, a = int(np.count_nonzero(index)), int(np.argmax(index))
        return slice(a, a + n) if n and index[a:a + n].all() else index
    if len(index) and int(index[-1]) - int(index[0]) + 1 == len(index) and np.all(
            np.diff(index) == 1):
        return slice(int(index[0]), int(index[-1]) + 1)
    return index


def _is_bag(path: Path) -> bool:
    """Return True when ``path`` is a rosbag2 directory (metadata.yaml, or storage files only)."""
    return path.is_dir() and (has_metadata(path) or bool(storage_files(path)))


def _natural_key(path: Path) -> list:
    """Sort key comparing digit runs as numbers."""
    return [int(s) if s.isdigit() else s for s in re.split(r'(\d+)', path.name)]


def find_bags(paths: Iterable[str | os.PathLike]) -> list[tuple[Path, bool]]:
    """
    Return the bags to read as ``(path, walked)``: ``walked`` when a folder's walk found it.

    A rosbag2 directory, a flight log or anything else given is kept as it is (reading
    reports what is wrong); a directory without ``metadata.yaml`` is walked into its bags
    and flight logs (``.ulg``, ``.bin``), down its subfolders (an SD card's ``log/DATE/``),
    in natural order (``run_2`` before ``run_10``); one where nothing is found is kept.
    Raises DatasetError when a path does not exist or two paths are the same bag: a run read
    twice would weigh double in training and escape discovery's leave-one-run-out.
    """
    out: list[tuple[Path, bool]] = []
    for p in map(Path, paths):
        if not p.exists():
            raise DatasetError(f'Bag {str(p)!r} does not exist.')
        subs = _walk(p) if p.is_dir() and not _is_bag(p) else []
        out.extend([(c, True) for c in subs] or [(p, False)])
    seen: dict[Path, Path] = {}
    for p, _ in out:
        real = Path(os.path.realpath(p))
        # A bag's storage file names the bag (a file without metadata.yaml is one).
        real = real.parent if p.is_file() and p.suffix in STORAGE_SUFFIXES and not missing(
            p.parent) else real
        if real in seen:
            raise DatasetError(f'Bag {str(p)!r} is given twice (also as {str(seen[real])!r}); '
                               'give each run once.')
        seen[real] = p
    return out


def _walk(folder: Path) -> list[Path]:
    """Return the bags and flight logs under ``folder`` (not inside a bag), naturally sorted."""
    out = []
    for c in sorted(folder.iterdir(), key=_natural_key):
        if _is_bag(c) or is_flight_log(c):
            out.append(c)
        elif c.is_dir() and not c.is_symlink():
            out.extend(_walk(c))
    return out


def expand_bags(paths: Iterable[str | os.PathLike]) -> list[Path]:
    """Return the bags to read, folders walked (:func:`find_bags`)."""
    return [p for p, _ in find_bags(paths)]


# What each count of ``run.info['rejected']`` means, as a reader would say it.
_DROPPED = {
    'imu_nonfinite': 'IMU samples with a NaN or infinite rate',
    'temp_nonfinite': 'temperature readings that are NaN or infinite',
    'ref_nonfinite': 'reference messages that are NaN or infinite',
    'undecodable': 'messages that could not be decoded',
    'temp_before_imu': 'Float temperature readings before the first IMU message',
    'imu_implausible': f'IMU samples above {MAX_RATE_RAD_S:g} rad/s',
    'temp_implausible': (f'temperature readings outside {TEMP_PLAUSIBLE_C[0]:g} .. '
                         f'{TEMP_PLAUSIBLE_C[1]:g} degC or jumping faster than '
                         f'{MAX_TEMP_SLEW_C_S:g} degC/s'),
    'ref_implausible': f'reference messages above {MAX_RATE_RAD_S:g} rad/s',
    'duplicate_stamps': 'IMU samples repeating an earlier stamp',
    'temp_duplicate_stamps': 'temperature readings repeating a stamp (the last one kept)',
    'out_of_order': 'IMU samples out of order (sorted, not dropped)',
    'no_temperature': 'IMU samples with no temperature reading near them (ends or gaps)',
    'no_reference': 'IMU samples before the first reference message'}


def describe_read(bag: str | os.PathLike, run: Run, reference_topic: str) -> str:
    """
    Return the one line that says what :func:`load_run` read from ``bag``, in words.

    ``read BAG: N samples over M min, reference rate ...; dropped ...``; ``reference_topic``
    is named when it was used.
    """
    source, log = run.info.get('reference', '?'), run.info.get('log')
    reference = {'topic': f'reference rate from {reference_topic}'
                          + ('' if np.any(run.omega_ref) else ' (zero throughout)'),
                 'constant': 'constant reference rate (--reference)',
                 'zero': 'reference rate zero (' + ('a flight log has none' if log else
                                                    f'no {reference_topic} in the bag') + ')'
                 }.get(source, f'reference {source}')
    dropped = '; '.join(f'{v} {_DROPPED.get(k, k)}'
                        for k, v in run.info.get('rejected', {}).items() if v)
    return (f'read {bag}: {len(run)} samples over {run.duration_s / 60.0:.1f} min, '
            + (f'{log}; ' if log else '') + reference
            + (f'; dropped {dropped}' if dropped else ''))


def load_runs(bags: Iterable[str | os.PathLike] | str | os.PathLike,
              options: BagOptions | None = None, *,
              log: Callable[[str], None] | None = None) -> list[Run]:
    """
    Load bags (or folders of them, :func:`find_bags`) with :func:`load_run`, one run each.

    Runs come in the given order, all read with ``options``; what cannot be read is skipped
    or refused as :func:`iter_runs` says.
    """
    return list(iter_runs(bags, options, log=log))


def iter_runs(bags: Iterable[str | os.PathLike] | str | os.PathLike,
              options: BagOptions | None = None, *, log: Callable[[str], None] | None = None,
              found: list[tuple[Path, bool]] | None = None) -> Iterator[Run]:
    """
    Yield the runs of bags (or folders of them, :func:`find_bags`) one at a time.

    ``found``: what :func:`find_bags` returned for ``bags``, when the caller has it (one walk).
    ``log`` receives one line per bag (samples, minutes, reference, what was dropped) and its
    warnings. A bag or log that a folder's walk found and that cannot be read is skipped with
    one warning naming it and why, and a last line counts what was read and skipped; one
    named itself is refused (DatasetError), and so is a set of which nothing can be read.
    """
    options = BagOptions() if options is None else options
    log = log or (lambda _line: None)
    if found is None:
        found = find_bags([bags] if isinstance(bags, (str, os.PathLike)) else bags)
    skipped, read = [], 0
    for bag, walked in found:
        try:
            run = load_run(bag, options)
        except DatasetError as exc:
            if not walked:
                raise
            skipped.append(f'{bag}: {exc}')
            log(f'warning: skipped {bag}: {exc}')
            continue
        log(describe_read(bag, run, options.reference_topic))
        for warning in run.info.get('warnings', ()):
            log(f'warning: {bag}: {warning}')
        read += 1
        yield run
    if skipped and not read:
        raise DatasetError(f'None of the {len(skipped)} bags and logs found can be read '
                           f'(the first: {skipped[0]}).')
    if skipped:
        log(f'read {read} of the {len(found)} bags and logs, skipped {len(skipped)} '
            'that cannot be read (each named above)')
