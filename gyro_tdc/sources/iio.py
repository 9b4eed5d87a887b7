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
Linux industrial-I/O (IIO) gyro back-end reading sysfs.

:class:`IioSource` reads ``(raw + offset) * scale`` of each channel (st_gyro, BMI160,
MPU-6050) and re-reads the scales every ``rescale_every`` samples; every file-system error
becomes a :class:`~gyro_tdc.errors.DeviceError` naming the file; a thermometer reading the
plausibility gate (:mod:`gyro_tdc.base.plausible`) refuses is dropped and counted.
:func:`find_iio_device` finds the device. See ``doc/internals/sources.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
import os
from pathlib import Path
import stat
import time
from typing import Callable

from gyro_tdc.base import AXES, TemperatureGate
from gyro_tdc.errors import DeviceError
from gyro_tdc.sources.base import ImuSample, PolledSource, Vec3

DEFAULT_IIO_ROOT = '/sys/bus/iio/devices'


def _exists(path: Path, *, directory: bool = False) -> bool:
    """Return whether ``path`` exists (as a directory); raise DeviceError when it cannot say."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return False
    except OSError as exc:       # PermissionError (an unreadable directory), EIO...
        raise DeviceError(f'Cannot access IIO path {str(path)!r}: '
                          f'{exc.strerror or exc}.') from None
    return not directory or stat.S_ISDIR(mode)


def _read_text(path: Path) -> str:
    """Return the stripped content of one sysfs file, or raise DeviceError."""
    try:
        with open(path, 'rb') as stream:
            data = stream.read(128)
    except FileNotFoundError:
        if not _exists(path.parent, directory=True):
            raise DeviceError(
                f'IIO device directory {str(path.parent)!r} disappeared '
                f'(while reading {path.name!r}).') from None
        raise DeviceError(f'IIO file {str(path)!r} is missing.') from None
    except OSError as exc:
        raise DeviceError(f'Cannot read IIO file {str(path)!r}: {exc.strerror or exc}.') from None
    return data.decode('ascii', errors='replace').strip()


def _read_number(path: Path) -> float:
    """Return the finite number held by one sysfs file, or raise DeviceError."""
    text = _read_text(path)
    try:
        value = float(text)
    except ValueError:
        raise DeviceError(f'IIO file {str(path)!r} holds {text[:32]!r}, expected a number.'
                          ) from None
    if not math.isfinite(value):
        raise DeviceError(f'IIO file {str(path)!r} holds {text[:32]!r}, expected a finite number.')
    return value


def find_iio_device(name: str, *, root: str | os.PathLike = DEFAULT_IIO_ROOT) -> Path:
    """
    Return the directory of the IIO device whose ``name`` file reads ``name``.

    Parameters
    ----------
    name : str
        Device name as the kernel driver reports it (e.g. ``l3gd20``, ``bmi160``).
    root : path-like
        Where the ``iio:deviceN`` directories live.

    Returns
    -------
    pathlib.Path
        The first matching device directory in sorted order.

    Raises
    ------
    DeviceError
        No device with that name exists under ``root``.

    """
    base = Path(root)
    try:
        entries = sorted(base.iterdir())
    except OSError as exc:
        raise DeviceError(f'Cannot list IIO devices in {str(base)!r}: '
                          f'{exc.strerror or exc}.') from None
    seen = []
    for entry in entries:
        try:
            if not _exists(entry / 'name'):
                continue
            found = _read_text(entry / 'name')
        except DeviceError as exc:
            # An unreadable device that may not be the wanted one: skip it, say so.
            seen.append(f'{entry.name} unreadable ({str(exc).rsplit(": ", 1)[-1].rstrip(".")})')
            continue
        seen.append(found)
        if found == name:
            return entry
    raise DeviceError(f'No IIO device named {name!r} under {str(base)!r} '
                      f'(found: {", ".join(seen) or "none"}).')


@dataclass(slots=True)
class _Channel:
    """
    One scaled channel: ``(raw + offset) * scale * factor``.

    ``scale_file`` / ``offset_file`` (None: constant) are re-read by :meth:`refresh`; the
    factor folds the unit (1 for rad/s and m/s^2, 1/1000 for milli-degrees Celsius).
    """

    path: Path
    scale_file: Path | None = None
    offset_file: Path | None = None
    factor: float = 1.0
    scale: float = 1.0
    offset: float = 0.0

    def refresh(self, read: Callable[[Path], float]) -> None:
        """Re-read the scale and offset files with ``read`` (shared files: read once)."""
        self.scale = self.factor * (1.0 if self.scale_file is None else read(self.scale_file))
        if self.offset_file is not None:
            self.offset = read(self.offset_file)

    def read(self) -> float:
        return (_read_number(self.path) + self.offset) * self.scale


class IioSource(PolledSource):
    """
    Read a gyro (and its accelerometer and thermometer) from a Linux IIO device.

    Parameters
    ----------
    device_dir : path-like
        The device's sysfs directory, e.g. ``/sys/bus/iio/devices/iio:device0``.
    read_accel : bool
        Read ``in_accel_{x,y,z}_raw`` when present (ignored when absent).
    read_temperature : bool
        Read the thermometer when present.
    require_temperature : bool
        Raise when the device has no thermometer instead of publishing none.
    temp_every : int
        Read the temperature on one sample out of ``temp_every`` (it changes slowly,
        and a sysfs read costs tens of microseconds).
    rescale_every : int
        Re-read the scale and offset files once every ``rescale_every`` samples (a
        full-scale change takes effect within that many samples; one or two sysfs reads).
    clock : callable returning float, s
        Source of sample times; ``time.monotonic`` by default.

    Attributes
    ----------
    temperatures_rejected : int
        Thermometer readings dropped as implausible (outside the plausible range, or jumping
        faster than the slew bound from the last plausible one): the sample carries none.

    Raises
    ------
    DeviceError
        The directory does not exist or cannot be read, a required file is missing,
        unreadable or garbled.

    """

    def __init__(self, device_dir: str | os.PathLike, *, read_accel: bool = True,
                 read_temperature: bool = True, require_temperature: bool = False,
                 temp_every: int = 1, rescale_every: int = 100,
                 clock: Callable[[], float] = time.monotonic) -> None:
        for name, every in (('temp_every', temp_every), ('rescale_every', rescale_every)):
            if int(every) < 1:
                raise ValueError(f'Expected `{name}` >= 1, got {every!r}.')
        if require_temperature and not read_temperature:
            raise ValueError('Expected `read_temperature` with `require_temperature`: a '
                             'thermometer not read cannot be required.')
        self.device_dir = Path(device_dir)
        if not _exists(self.device_dir, directory=True):
            raise DeviceError(f'IIO device directory {str(self.device_dir)!r} does not exist.')
        name_file = self.device_dir / 'name'
        self.name = _read_text(name_file) if _exists(name_file) else self.device_dir.name
        self._clock, self._count, self._temp_gate = clock, 0, TemperatureGate()
        self._temp_every, self._rescale_every = int(temp_every), int(rescale_every)
        self._gyro = self._vector('anglvel', required=True)
        self._accel = self._vector('accel', required=False) if read_accel else None
        self._temp = self._temperature(required=require_temperature) if read_temperature else None
        self._channels = tuple(c for c in (*self._gyro, *(self._accel or ()), self._temp) if c)
        self.rescale()
        for channel in self._channels:      # a garbled file fails here, not at the first read
            channel.read()
        #: Whether samples carry acceleration, and temperature.
        self.has_accel, self.has_temperature = self._accel is not None, self._temp is not None

    def _shared_or_own(self, kind: str, axis: str, what: str) -> Path | None:
        """Return the file ``in_<kind>_<axis>_<what>``, else ``in_<kind>_<what>``, or None."""
        own, shared = (self.device_dir / f'in_{kind}{name}_{what}' for name in (f'_{axis}', ''))
        return next((path for path in (own, shared) if _exists(path)), None)

    def _vector(self, kind: str, *, required: bool) -> tuple[_Channel, ...] | None:
        raws = [self.device_dir / f'in_{kind}_{axis}_raw' for axis in AXES]
        missing = [path for path in raws if not _exists(path)]
        if missing and (required or len(missing) < len(raws)):
            raise DeviceError(f'IIO file {str(missing[0])!r} is missing.')
        if missing:
            return None
        channels = []
        for axis, path in zip(AXES, raws):
            if (scale_file := self._shared_or_own(kind, axis, 'scale')) is None:
                raise DeviceError(f'IIO file {str(self.device_dir / f"in_{kind}_scale")!r} is '
                                  f'missing (nor is there in_{kind}_{axis}_scale).')
            channels.append(_Channel(path, scale_file, self._shared_or_own(kind, axis, 'offset')))
        return tuple(channels)

    def _temperature(self, *, required: bool) -> _Channel | None:
        raw, processed, scale_file, offset_file = (
            self.device_dir / f'in_temp_{what}' for what in ('raw', 'input', 'scale', 'offset'))
        if _exists(raw):
            if not _exists(scale_file):
                raise DeviceError(f'IIO file {str(scale_file)!r} is missing '
                                  '(needed to convert in_temp_raw).')
            return _Channel(raw, scale_file, offset_file if _exists(offset_file) else None,
                            factor=1.0 / 1000.0)
        if _exists(processed):
            return _Channel(processed, factor=1.0 / 1000.0)
        if required:
            raise DeviceError(f'IIO file {str(raw)!r} is missing (nor is there in_temp_input).')
        return None

    def rescale(self) -> None:
        """
        Re-read every scale and offset file now (each shared file once).

        Raises
        ------
        DeviceError
            A scale or offset file vanished, is unreadable or not a finite number.

        """
        read = functools.cache(_read_number)
        for channel in self._channels:
            channel.refresh(read)

    def read(self) -> ImuSample:
        """
        Read one sample from sysfs, stamped by ``clock``.

        Rate in rad/s, acceleration in m/s^2 (or None), temperature in degC (None when
        skipped or implausible).

        Raises
        ------
        DeviceError
            A file vanished or holds something that is not a finite number.

        """
        if self._count and self._count % self._rescale_every == 0:
            self.rescale()
        t = self._clock()
        omega: Vec3 = tuple(c.read() for c in self._gyro)
        accel = None if self._accel is None else tuple(c.read() for c in self._accel)
        temp_c = None
        if self._temp is not None and self._count % self._temp_every == 0:
            temp_c = self._temp.read()
            if not self._temp_gate.accept(t, temp_c):
                temp_c = None             # a glitch is never published
        self._count += 1
        return ImuSample(t, omega, accel, temp_c)

    @property
    def temperatures_rejected(self) -> int:
        """Return the thermometer readings dropped as implausible."""
        return self._temp_gate.rejected

    def close(self) -> None:
        """Release the device (sysfs files are opened per read; nothing is held)."""
        self._count = 0

    def __repr__(self) -> str:
        return f'IioSource({str(self.device_dir)!r}, name={self.name!r})'
