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
Held-out evaluation on the PAN CubeSat TVAC recording, leaving one block of bursts out.

Usage: ``python tools/pan_holdout.py [--csv PATH] [--blocks 5] [--json OUT]``. Prints, per
model and per held-out block, BS in (deg/s)^2, RMS in deg/s and the ratio to the white-noise
floor, interior (interpolation) and end (extrapolation) blocks apart, then the same for
leave-one-burst-out. The evaluation is :func:`gyro_tdc.evaluate.realdata.pan_holdout`; the
method and its caveats are in ``doc/real_data.md``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
from typing import Any, Callable, Mapping

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(ROOT))

from gyro_tdc.base import atomic_write  # noqa: E402
from gyro_tdc.data.realdata import default_pan_csv  # noqa: E402
from gyro_tdc.errors import GyroTdcError  # noqa: E402
from gyro_tdc.evaluate.realdata import format_holdout, pan_holdout  # noqa: E402


def run_tool(prog: str, compute: Callable[[], Mapping[str, Any]],
             fmt: Callable[[Mapping[str, Any]], str], json_path: Path | None) -> int:
    """
    Run a real-data tool: compute, print the table, write the JSON; one line on failure.

    ``compute`` returns the figures, ``fmt`` formats them, ``json_path`` (optional) receives
    them atomically. Returns 0, or 2 after ``PROG: error: ...`` on bad input or an
    unwritable ``json_path``.
    """
    try:
        result = compute()
        print(fmt(result))
        if json_path is not None:
            atomic_write(json_path, json.dumps(result, indent=1) + '\n', what='JSON file')
            print(f'\nwrote {json_path}')
    except GyroTdcError as err:
        print(f'{prog}: error: {err}', file=sys.stderr)
        return 2
    return 0


def _blocks(text: str) -> int:
    """Parse ``--blocks``: an integer of at least 2."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected an integer, got {text!r}') from None
    if value < 2:
        raise argparse.ArgumentTypeError(f'expected at least 2 blocks, got {value}')
    return value


def main(argv: list[str] | None = None) -> int:
    """Run the evaluation on ``argv`` (``sys.argv[1:]`` when None); return 0, or 2 on bad input."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--csv', type=Path, default=default_pan_csv(),
                        help='TVCtest3_7_20.csv (default: %(default)s)')
    parser.add_argument('--blocks', type=_blocks, default=5, metavar='N',
                        help='contiguous blocks of bursts (default: %(default)s); '
                        'leave-one-burst-out is always added')
    parser.add_argument('--json', type=Path, default=None, metavar='OUT',
                        help='write the figures as JSON (keys in doc/real_data.md)')
    args = parser.parse_args(argv)
    return run_tool('pan_holdout', lambda: pan_holdout(args.csv, n_blocks=args.blocks),
                    format_holdout, args.json)


if __name__ == '__main__':
    sys.exit(main())
