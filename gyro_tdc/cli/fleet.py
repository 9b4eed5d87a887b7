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
``python -m gyro_tdc fleet MANIFEST.csv --out DIR``: calibrate many sensors on Dask.

One model per manifest row, trained with the options and defaults of ``train`` (one
``TrainOptions`` and one ``BagOptions`` for every sensor) and evaluated on the row's test
bags; exit 1 when any sensor failed. See :mod:`gyro_tdc.fleet` and ``doc/internals/cli.md``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Optional, Sequence

from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import (ArgumentParser, bag_options, command_line, positive_float,
                                 positive_int, run_command, UsageError)
from gyro_tdc.cli.train import add_train_options, train_options
from gyro_tdc.fleet import (DEFAULT_OUTLIER_Z, format_table, open_engine, read_manifest, run_fleet,
                            sigterm_as_interrupt)

__all__ = ['build_parser', 'main']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``fleet``."""
    p = ArgumentParser(prog=f'{PROG} fleet', description='Calibrate a fleet of IMUs on Dask: one '
                       'model per row of a manifest CSV (sensor_id,train,test; bags separated by '
                       '";", relative to the manifest), evaluated on its test bags, with '
                       'fleet-outlier flags on the drift coefficients; the training options are '
                       'those of train.')
    p.add_argument('manifest', metavar='MANIFEST.csv', help='the fleet manifest')
    p.add_argument('-o', '--out', required=True, metavar='DIR',
                   help='output folder: <sensor_id>.yaml, summary.json, summary.csv')
    eng = p.add_argument_group('Dask engine').add_mutually_exclusive_group()
    eng.add_argument('--workers', type=positive_int, metavar='N',
                     help='worker processes of the embedded LocalCluster (default: the '
                          "machine's cores)")
    eng.add_argument('--scheduler', metavar='ADDRESS',
                     help='use a running Dask cluster (tcp://HOST:PORT) instead; its workers '
                          'must read the bags at the paths of the manifest')
    p.add_argument('--connect-timeout', type=positive_float, default=30.0, metavar='S',
                   help='seconds to wait for --scheduler and its first worker, and for a '
                        'worker when the cluster has lost them all (default: %(default)s)')
    p.add_argument('--force', action='store_true', help='retrain sensors whose bags and options '
                   'are unchanged (default: skip them, keeping their models)')
    p.add_argument('--outlier-z', type=positive_float, default=DEFAULT_OUTLIER_Z, metavar='Z',
                   help='flag a drift coefficient whose robust z-score against the fleet '
                        'exceeds Z (default: %(default)s)')
    add_train_options(p)
    return p


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``fleet`` with parsed arguments; print the table; 1 when a sensor failed."""
    options = train_options(args)     # a bad feature id fails before any worker starts
    bag = bag_options(args)
    specs = read_manifest(args.manifest)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f'--out: {str(out)!r} exists and is not a folder')
    workers = min(args.workers or os.cpu_count() or 1, len(specs))   # no idle processes
    with sigterm_as_interrupt(), open_engine(workers=workers, scheduler=args.scheduler,
                                             timeout_s=args.connect_timeout) as engine:
        print(f'fleet: {len(specs)} sensor(s) on {engine.workers} Dask worker(s) '
              f'({engine.scheduler}) -> {out}', flush=True)
        result = run_fleet(specs, out, options, engine, bag=bag, force=args.force,
                           outlier_z=args.outlier_z, progress=bag.progress,
                           command=command_line('fleet', argv),
                           log=None if bag.progress else (lambda line: print(line, flush=True)))
    print(format_table(result))
    print(f'wrote {out / "summary.json"} and {out / "summary.csv"}', flush=True)
    return 1 if result.failed else 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Run ``python -m gyro_tdc fleet``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the command name (``sys.argv[1:]`` when None).

    Returns
    -------
    int
        0 when every sensor was calibrated, 1 when any failed, 2 on bad input.

    """
    return run_command('fleet', build_parser, _run, argv)
