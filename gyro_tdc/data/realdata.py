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
Real recordings -> rosbag2 bags.

``pan_cubesat``: the Cornell PAN CubeSat engineering unit cooling in a thermal-vacuum
chamber, converted as the authors' analysis script does. See ``doc/internals/data.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path

from gyro_tdc.data.bag.writer import write_bag
from gyro_tdc.errors import DatasetError
import numpy as np
from numpy.typing import NDArray

__all__ = ['PAN_CSV_COLUMNS', 'PanCubesat', 'default_pan_csv', 'pan_cubesat_to_bag',
           'read_pan_cubesat_csv']

PAN_CSV_COLUMNS = ('time (ms)', 'mag1x [T]', 'mag1y [T]', 'mag1z [T]', 'gyrox rad/s',
                   'gyroy rad/s', 'gyroz rad/s', 'temp')
PAN_GYRO_CORRECTION = 0.5          # the authors' "error in driver script" factor
PAN_SPIKE_GYROX = -0.08            # rad/s as logged: rows at or below are spikes
LSM6DSM_LSB_PER_C = 256.0          # OUT_TEMP sensitivity; 0 LSB at 25 degC
# Quantisation noise of a 1/256 degC register: uniform over one LSB -> LSB^2 / 12.
LSM6DSM_TEMP_VARIANCE = (1.0 / LSM6DSM_LSB_PER_C) ** 2 / 12.0


@dataclass(frozen=True)
class PanCubesat:
    """The PAN CubeSat TVAC recording after the authors' corrections, ready for a bag."""

    #: Time since boot (N,), s.
    t: NDArray[np.float64]
    #: Corrected angular rate (N, 3), rad/s (logged x 0.5).
    gyro: NDArray[np.float64]
    #: Die temperature from the raw register (N,), degC.
    temp_c: NDArray[np.float64]
    #: Data rows in the CSV.
    rows_read: int
    #: Times of the spike rows that were removed (K,), s.
    removed_t: NDArray[np.float64]

    @property
    def rows_removed(self) -> int:
        """Return the number of spike rows removed."""
        return int(len(self.removed_t))


def default_pan_csv() -> Path:
    """Return the recording's CSV path: ``data/pan_cubesat_tvac`` in the repository."""
    root = Path(os.path.realpath(__file__)).parents[2]
    return root / 'data' / 'pan_cubesat_tvac' / 'TVCtest3_7_20.csv'


def read_pan_cubesat_csv(path: str | Path) -> PanCubesat:
    """
    Parse ``TVCtest3_7_20.csv`` and apply the authors' corrections.

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    PanCubesat
        Corrected samples and what was removed.

    Raises
    ------
    DatasetError
        When the file is missing, has other columns, non-numeric cells, a temperature
        register outside 0..65535 or non-increasing times.

    """
    path = Path(path)
    try:
        with path.open(encoding='utf-8-sig') as f:
            header = f.readline()
            rows = np.loadtxt(f, delimiter=',', dtype=np.float64, ndmin=2)
    except OSError as err:
        raise DatasetError(f'Cannot read PAN CubeSat CSV {str(path)!r}: '
                           f'{err.strerror or err}.') from err
    except ValueError as err:
        raise DatasetError(f'Expected numbers in PAN CubeSat CSV {str(path)!r}: '
                           f'{" ".join(str(err).split())}') from err
    columns = tuple(x.strip() for x in header.strip().split(','))
    if tuple(x.lower() for x in columns) != tuple(x.lower() for x in PAN_CSV_COLUMNS):
        raise DatasetError(f'Expected PAN CubeSat CSV columns {list(PAN_CSV_COLUMNS)}, '
                           f'got {list(columns)} in {str(path)!r}.')
    if rows.shape[1] != len(PAN_CSV_COLUMNS) or not len(rows):
        raise DatasetError(f'Expected {len(PAN_CSV_COLUMNS)} columns and at least one row in '
                           f'{str(path)!r}, got shape {rows.shape}.')
    if not np.all(np.isfinite(rows)):
        raise DatasetError(f'Expected finite numbers in {str(path)!r}, got '
                           f'{int(np.count_nonzero(~np.isfinite(rows)))} NaN/Inf cells.')
    raw = rows[:, 7]
    if np.any(raw != np.round(raw)) or raw.min() < 0 or raw.max() > 65535:
        raise DatasetError(f'Expected `temp` to be the raw 16-bit register (integers in '
                           f'0..65535), got values in [{raw.min()}, {raw.max()}].')
    t = rows[:, 0] / 1000.0
    if np.any(np.diff(t) <= 0):
        raise DatasetError(f'Expected strictly increasing `time (ms)` in {str(path)!r}.')
    keep = rows[:, 4] > PAN_SPIKE_GYROX
    temp_c = 25.0 + raw.astype(np.int64).astype(np.uint16).view(np.int16) / LSM6DSM_LSB_PER_C
    return PanCubesat(t=t[keep], gyro=PAN_GYRO_CORRECTION * rows[keep, 4:7],
                      temp_c=temp_c[keep], rows_read=int(len(rows)), removed_t=t[~keep])


def pan_cubesat_to_bag(csv_path: str | Path, out: str | Path, *,
                       storage: str = 'sqlite3') -> PanCubesat:
    """
    Convert the PAN CubeSat TVAC CSV (``TVCtest3_7_20.csv``) into the rosbag2 bag ``out``.

    One ``sensor_msgs/Imu`` per row on ``/imu/data_raw`` (no accelerometer in the file:
    ``linear_acceleration_covariance[0] = -1``, REP 145), a ``sensor_msgs/Temperature`` on
    ``/imu/temperature`` (variance: quantisation of the 1/256 degC register) and a zero
    reference rate, all on the same stamps. Returns what was written and removed; raises
    DatasetError for a malformed CSV or a bag that cannot be created.
    """
    data = read_pan_cubesat_csv(csv_path)
    write_bag(out, imu_t=data.t, gyro=data.gyro, accel=np.zeros_like(data.gyro), temp_t=data.t,
              temp_c=data.temp_c, temp_var=LSM6DSM_TEMP_VARIANCE, ref_t=data.t,
              ref=np.zeros_like(data.gyro), storage=storage, accel_cov=(-1.0, 0.0, 0.0))
    return data
