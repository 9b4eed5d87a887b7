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
``python -m gyro_tdc train BAG... --out MODEL.yaml``: identify a model from recorded bags.

Parses the arguments into one :class:`~gyro_tdc.identify.TrainOptions` and one
:class:`~gyro_tdc.data.BagOptions`, runs :func:`gyro_tdc.identify.train.train` (or, with
``--still-only``, :func:`gyro_tdc.identify.train.train_still_only`) and prints the
choice of features, the training report and the coverage; bad input exits 2 with one line.
"""

from __future__ import annotations

import argparse
import math
from typing import Optional, Sequence

from gyro_tdc.base import atomic_json, DEG_PER_RAD, plain, start_imports
from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import (add_bag_options, ArgumentParser, bag_options, command_line,
                                 effect_listing, finite_float, positive_float,
                                 positive_int, refuse_driver_logs, run_command)
from gyro_tdc.errors import GyroTdcError
from gyro_tdc.evaluate import format_coverage, format_sessions, format_training
from gyro_tdc.identify import AUTO, train, train_still_only, TrainOptions, TrainResult
from gyro_tdc.model import KINDS
from gyro_tdc.signal import MAX_STILL_SE, MIN_STILL_S, MIN_STILL_SAMPLES

__all__ = ['add_train_options', 'build_parser', 'main', 'train_options', 'training_json']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``train``."""
    p = ArgumentParser(prog=f'{PROG} train', description='Identify a temperature-drift '
                       'compensation model from rosbag2 bags or flight logs (one run each) and '
                       'write it as a YAML model file.')
    p.add_argument('bags', nargs='+', metavar='BAG', help='rosbag2 directory (sqlite3 or mcap), a '
                   'PX4 .ulg / ArduPilot .bin flight log, or a folder: walked, subfolders too, '
                   'for its bags and logs; one found there that cannot be read is skipped with a '
                   'warning naming it and why (one named here is refused)')
    p.add_argument('-o', '--out', required=True, metavar='MODEL.yaml', help='model file to write')
    p.add_argument('--json', metavar='OUT',
                   help='also write what training produced as JSON (shape: doc/json.md)')
    p.add_argument('--sensor-id', default='', metavar='ID',
                   help="the recorded sensor's id (e.g. its serial number), written to the "
                        "model's sensor.sensor_id; compensator_node warns when its sensor_id "
                        'parameter differs (default: none)')
    p.help_tail = effect_listing     # --help ends with the effect ids
    add_train_options(p)
    g = p.add_argument_group('training from ordinary operation (no reference, no chamber)')
    g.add_argument('--still-only', action='store_true', help='train on the still stretches only '
                   '(bags recorded in normal operation: the rate is zero while still); the '
                   'thermal state runs over every sample; no reference is read')
    g.add_argument('--motion-topic', default='', metavar='TOPIC',
                   help='with --still-only: a geometry_msgs/Twist (cmd_vel), TwistStamped or '
                        'nav_msgs/Odometry topic; still only while it reports zero motion '
                        '(rejects slow constant turns the IMU cannot tell from rest)')
    g.add_argument('--min-still', type=positive_float, metavar='S',
                   help='training without a reference: shortest still stretch kept, in s '
                        f'(default: judged by its samples and its noise: {MIN_STILL_S:g} s, '
                        f'or two still-test windows (5 s at 8 Hz and up) and '
                        f'{MIN_STILL_SAMPLES} samples whose mean rate is known to '
                        f'{MAX_STILL_SE * DEG_PER_RAD:.2g} deg/s, e.g. 15 s at 8 or 25 Hz)')
    return p


def add_train_options(p: argparse.ArgumentParser) -> None:
    """Add every option of ``train`` but the bags and ``--out`` (``fleet`` shares them)."""
    p.add_argument('--features', default=AUTO, metavar='IDS',
                   help='auto, or comma-separated effect ids (default: %(default)s: the '
                        "paper's modified model dT,dT2 plus what discovery finds the data "
                        'support, each choice printed with its reason; dT,dT2 is exactly '
                        'the modified model, dT the conventional one; lag makes every '
                        'temperature term follow the lagged die temperature, tau fitted)')
    p.add_argument('--kind', default='rbf', choices=KINDS, help='rbf network with a linear tail, '
                   'or poly (linear in the features) (default: %(default)s)')
    p.add_argument('--centers', type=positive_int, default=12, metavar='K',
                   help='RBF centres (default: %(default)s)')
    p.add_argument('--refine', action='store_true',
                   help='refine RBF centres and widths by nonlinear least squares')
    p.add_argument('--t0', type=finite_float, metavar='C', help='reference temperature T0 in degC '
                   '(default: the stable initial temperature of the first bag)')
    p.add_argument('--seed', type=int, default=0, help='seed of the centre placement')
    p.add_argument('--bin', dest='bin_c', type=positive_float, default=5.0, metavar='C',
                   help='width of the coverage bins in degC (default: %(default)s)')
    p.add_argument('--no-accel', dest='accel', action='store_false',
                   help='do not read the accelerometer nor fit its part (default: fit the '
                        "accelerometer offset's change with temperature on still data when "
                        'the bags have accelerometer data)')
    add_bag_options(p, driver=True, sessions=True)


def train_options(args: argparse.Namespace, **more: object) -> TrainOptions:
    """
    Return the training options of arguments parsed with :func:`add_train_options`.

    ``more`` are the fields the command sets itself (``sensor_id``, ``min_still_s``); a bad
    choice (an unknown effect id) fails here, before any bag is read.
    """
    return TrainOptions(features=args.features, kind=args.kind, n_centers=args.centers,
                        refine=args.refine, t0=args.t0, seed=args.seed, bin_c=args.bin_c,
                        accel=args.accel, **more)


def training_json(result: TrainResult, warnings: Sequence[str] = ()) -> dict:
    """
    Return what ``train`` produced in the documented JSON shape (doc/json.md).

    Model file and id, kind, features, bags, samples, range, raw and training BS (deg/s)^2
    and RMS per axis, the constant axes (axis -> reading, rad/s), ``reanchor`` (the start-up
    shift the node takes per axis and its figures, ``model.metrics['reanchor']``), the
    accelerometer part (``fitted``, ``note``; null with ``--no-accel``) and the ``warnings``
    printed.
    """
    m, acc = result.model, result.accel
    nan3 = [math.nan] * 3
    return plain({'model_file': str(result.path), 'model_id': m.model_id, 'kind': m.kind,
                  'features': list(m.features), 'bags': [str(b) for b in result.bags],
                  'samples': int(result.samples), 'temp_range_c': m.temp_range_c,
                  **{k: m.metrics.get(key, nan3) for k, key in (
                      ('raw_bs', 'raw_bs_dps2'), ('train_bs', 'train_bs_dps2'),
                      ('train_rms_dps', 'train_rms_dps'))},
                  'constant_axes': result.constant, 'reanchor': m.metrics.get('reanchor'),
                  'accelerometer': None if acc is None else {'fitted': acc.part is not None,
                                                             'note': acc.note or None},
                  'warnings': list(warnings)}, nan_to_none=True)     # JSON has no NaN


def _lines(part: object) -> list:
    """Return the report lines of a part of the result (none when it is None)."""
    return [] if part is None else part.lines()


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``train`` with parsed arguments; print the report."""
    # Checked before any bag is read: a bad feature id fails at once.
    options = train_options(args, sensor_id=args.sensor_id, min_still_s=args.min_still)
    if args.motion_topic and not args.still_only:
        raise GyroTdcError('--motion-topic: only with --still-only.')
    bag = bag_options(args, motion_topic=args.motion_topic)
    refuse_driver_logs(bag, args.bags)     # a driver's own types are read by field
    fit = train_still_only if args.still_only else train     # still: no reference is read
    # Most of the start-up is scipy's import; the read mostly waits on the storage.
    start_imports(('scipy.special', 'scipy.optimize', 'scipy.cluster.vq'))
    result = fit(args.bags, args.out, options, bag, command=command_line('train', argv),
                 log=lambda line: print(line, flush=True))
    text, warns = format_training(result)
    print('\n'.join([*_lines(result.choice), *format_sessions(result), text,
                     *_lines(result.still), *_lines(result.accel)]))
    acc = result.accel
    if acc is not None and acc.part is not None and acc.coverage is not None:
        # The accelerometer's still samples against the gyro's: a chamber run is still
        # throughout for both (its own still test may find a few more or fewer).
        share = acc.samples / max(result.samples, 1)
        if 0.99 <= share <= 1.0:
            print(f"accelerometer coverage: the gyro's ({100.0 * share:.4g} % of the "
                  'samples still)')
        else:
            table, accel_warns = format_coverage(acc.coverage)
            print('accelerometer coverage (still data):\n' + table)
            warns = list(warns) + [f'accelerometer: {w}' for w in accel_warns]
    print(''.join(f'warning: {w}\n' for w in warns), end='')
    print(f'wrote {result.path} (model_id {result.model.model_id})', flush=True)
    if args.json is not None:
        path = atomic_json(args.json, training_json(result, warns), allow_nan=False)
        print(f'wrote {path}', flush=True)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``python -m gyro_tdc train``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('train', build_parser, _run, argv)
