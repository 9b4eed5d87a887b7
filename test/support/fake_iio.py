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

"""Fake Linux IIO devices in a folder: one file per sysfs attribute."""

from __future__ import annotations

import math
from pathlib import Path

# st_gyro L3GD20 at 250 dps full scale: 8.75 mdps/digit in rad/s.
L3GD20_SCALE = 8.75e-3 * math.pi / 180.0


def make_device(root: Path, files: dict[str, object], dirname: str = 'iio:device0') -> Path:
    """Write a fake IIO device directory with one file per entry (value + newline)."""
    device = root / dirname
    device.mkdir(parents=True)
    for name, value in files.items():
        (device / name).write_text(f'{value}\n')
    return device


def l3gd20_files() -> dict[str, object]:
    """Return the sysfs files of an st_gyro L3GD20 (no accelerometer, raw thermometer)."""
    return {
        'name': 'l3gd20',
        'in_anglvel_x_raw': 100, 'in_anglvel_y_raw': -200, 'in_anglvel_z_raw': 0,
        'in_anglvel_scale': f'{L3GD20_SCALE:.9f}',
        'in_temp_raw': 25, 'in_temp_scale': '1000.000000', 'in_temp_offset': 0,
    }
