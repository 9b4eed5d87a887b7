#!/usr/bin/env python3
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
Convert the PAN CubeSat thermal-vacuum CSV into a rosbag2 bag.

Usage: ``python tools/pan_cubesat_to_bag.py [--csv PATH] [--out BAG] [--storage mcap] [--force]``.
The conversion itself is :func:`gyro_tdc.data.realdata.pan_cubesat_to_bag`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(ROOT))

from gyro_tdc.data.realdata import default_pan_csv, pan_cubesat_to_bag  # noqa: E402
from gyro_tdc.errors import GyroTdcError  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Run the converter on ``argv`` (``sys.argv[1:]`` when None); return 0, or 2 on bad input."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--csv', type=Path, default=default_pan_csv(),
                        help='TVCtest3_7_20.csv (default: %(default)s)')
    parser.add_argument('--out', type=Path, default=ROOT / 'out' / 'pan_cubesat_tvac',
                        help='bag directory to create (default: %(default)s)')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                        help='rosbag2 storage plugin (default: %(default)s)')
    parser.add_argument('--force', action='store_true',
                        help='replace --out when it is a bag (a folder with metadata.yaml)')
    args = parser.parse_args(argv)
    try:
        if args.force and (args.out / 'metadata.yaml').is_file() and not args.out.is_symlink():
            shutil.rmtree(args.out)
        data = pan_cubesat_to_bag(args.csv, args.out, storage=args.storage)
    except GyroTdcError as err:
        print(f'pan_cubesat_to_bag: error: {err}', file=sys.stderr)
        return 2
    print(f'{args.out}: {len(data.t)} samples ({data.rows_read} rows read, '
          f'{data.rows_removed} spike rows removed at t = '
          f'{", ".join(f"{x:.3f}" for x in data.removed_t)} s), '
          f'{data.t[-1] - data.t[0]:.0f} s, temperature {data.temp_c[0]:.2f} -> '
          f'{data.temp_c[-1]:.2f} degC (range {data.temp_c.min():.2f}..'
          f'{data.temp_c.max():.2f}), storage {args.storage}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
