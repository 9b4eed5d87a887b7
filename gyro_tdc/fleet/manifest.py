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
The fleet manifest: ``sensor_id,train,test`` rows, sensor ids, and the resume key of a sensor.

The resume key hashes the path, size and modification time (ns) of every file of a sensor's
bags, the training options and the gyro_tdc version; a bag's *content* is not hashed (an hour
at 1 kHz is 1.4 GB of sqlite3), so a bag rewritten with the same size and mtime is not noticed.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
import hashlib
import io
import json
import os
from pathlib import Path
import re

from gyro_tdc import __version__
from gyro_tdc.errors import FleetError

__all__ = ['COLUMNS', 'KEY_FORMAT', 'SensorSpec', 'check_sensor_id', 'input_key', 'read_manifest']

COLUMNS = ('sensor_id', 'train', 'test')
KEY_FORMAT = 1               # bump when the key's recipe changes: every sensor retrains
_SENSOR_ID = re.compile(r'[A-Za-z0-9][A-Za-z0-9._-]{0,127}')


@dataclass(frozen=True)
class SensorSpec:
    """One manifest row: a sensor and its bags, the input of one fleet task."""

    #: Sensor identifier, a valid file name (letters, digits, ``.``, ``_``, ``-``).
    sensor_id: str
    #: Training bags (absolute or relative to the working directory).
    train: tuple[str, ...]
    #: Held-out bags (may be empty).
    test: tuple[str, ...] = ()
    #: Line of the manifest (for messages).
    line: int = 0


def check_sensor_id(text: str, where: str = 'sensor_id') -> str:
    """
    Return ``text`` when it can name the model file ``<sensor_id>.yaml``.

    1-128 letters, digits, ``.``, ``_`` or ``-``, starting with a letter or digit; else a
    FleetError naming ``where``.
    """
    if not _SENSOR_ID.fullmatch(text):
        raise FleetError(f'{where}: {text!r} cannot be a file name; expected 1-128 letters, '
                         f'digits, ".", "_" or "-", starting with a letter or digit')
    return text


def _bags(cell: str, base: Path) -> tuple[str, ...]:
    """Split a ``;``-separated cell into bag paths, relative ones anchored at ``base``."""
    return tuple(str(base / p.strip()) for p in cell.split(';') if p.strip())


def read_manifest(path: str | os.PathLike) -> list[SensorSpec]:
    """
    Read a fleet manifest (CSV ``sensor_id,train,test``).

    Parameters
    ----------
    path : str or PathLike
        The manifest; relative bag paths are taken relative to its folder.

    Returns
    -------
    list of SensorSpec
        One per data row, in file order, bag paths absolute.

    Raises
    ------
    FleetError
        When the file cannot be read, the header is not ``sensor_id,train,test``, a row has
        another number of fields, a sensor id is invalid or repeated (case-insensitively, as
        on a case-insensitive file system), a row has no training bag, or there is no row.

    """
    p = Path(path)
    try:
        text = p.read_text(encoding='utf-8-sig')
    except (OSError, UnicodeDecodeError) as exc:
        raise FleetError(f'manifest {str(p)!r}: cannot read it: '
                         f'{getattr(exc, "strerror", None) or exc}') from exc
    base = p.absolute().parent
    rows = list(csv.reader(io.StringIO(text)))
    numbered = [(i + 1, r) for i, r in enumerate(rows) if any(c.strip() for c in r)]
    if not numbered:
        raise FleetError(f'manifest {str(p)!r} is empty; expected the header '
                         f'{",".join(COLUMNS)} and one row per sensor')
    line, header = numbered[0]
    if [c.strip() for c in header] != list(COLUMNS):
        raise FleetError(f'manifest {str(p)!r} line {line}: expected the header '
                         f'{",".join(COLUMNS)}, got {",".join(header)!r}')
    specs: list[SensorSpec] = []
    seen: dict[str, int] = {}
    for line, row in numbered[1:]:
        where = f'manifest {str(p)!r} line {line}'
        if len(row) != len(COLUMNS):
            raise FleetError(f'{where}: expected {len(COLUMNS)} fields '
                             f'({",".join(COLUMNS)}), got {len(row)}')
        sid = check_sensor_id(row[0].strip(), f'{where}: sensor_id')
        if sid.lower() in seen:
            raise FleetError(f'{where}: sensor_id {sid!r} repeats line {seen[sid.lower()]} '
                             f'(ids must differ, also in letter case)')
        seen[sid.lower()] = line
        if not (train_bags := _bags(row[1], base)):
            raise FleetError(f'{where}: sensor {sid!r} has no training bag')
        specs.append(SensorSpec(sid, train_bags, _bags(row[2], base), line))
    if not specs:
        raise FleetError(f'manifest {str(p)!r} lists no sensor (only the header)')
    return specs


def _fingerprint(bag: str) -> list:
    """Return the path, size and mtime (ns) of every file of a bag (a file or a folder)."""
    p = Path(bag)
    if not p.exists():
        return [bag, 'missing']
    files = sorted(f for f in p.rglob('*') if f.is_file()) if p.is_dir() else [p]
    stats = [(f, f.stat()) for f in files]
    return [bag] + [[f.relative_to(p).as_posix() if f != p else '', st.st_size, st.st_mtime_ns]
                    for f, st in stats]


def input_key(spec: SensorSpec, options: dict) -> str:
    """
    Return the resume key of a sensor: a hash of its inputs and the training options.

    SHA-256 (hex) of the sensor id, the gyro_tdc version, ``options`` (of
    :func:`gyro_tdc.identify.train.train`) and the path, size and modification time (ns) of
    every train and test bag.
    """
    blob = json.dumps({'format': KEY_FORMAT, 'version': __version__,
                       'sensor_id': spec.sensor_id,
                       'options': {k: v for k, v in options.items() if k != 'progress'},
                       'train': [_fingerprint(b) for b in spec.train],
                       'test': [_fingerprint(b) for b in spec.test]},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()
