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
``python -m gyro_tdc discover BAG...``: name the thermal effect a model is missing.

Reads the bags (one :class:`~gyro_tdc.data.BagOptions`), runs
:func:`gyro_tdc.identify.discover.discover` (``--sensor accel``: on the accelerometer's still
data), prints the summary and writes ``--json``, ``--report DIR`` and ``--out MODEL.yaml``.
See ``doc/internals/cli.md``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys
from typing import Optional, Sequence

from gyro_tdc.base import atomic_json
from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import (add_bag_options, ArgumentParser, bag_options, command_line,
                                 effect_listing, finite_float, positive_float, positive_int,
                                 probability, progress_bar, run_command, UsageError)
from gyro_tdc.data import load_runs, split_sessions
from gyro_tdc.errors import DatasetError, FitError
from gyro_tdc.identify import (ACCEL_EFFECTS, build_model, constant_gyro_axes, constant_note,
                               discover, discovery_runs, format_summary, still_only_runs,
                               write_report)
from gyro_tdc.model import KINDS, normalise_ids, save_model

__all__ = ['build_parser', 'main']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``discover``."""
    p = ArgumentParser(prog=f'{PROG} discover', description='Fit the drift model with the base '
                       'effects to measured bags, show where it disagrees with them, name the '
                       'missing effect, add it and repeat until the residual is noise.')
    p.add_argument('bags', nargs='+', metavar='BAG', help='rosbag2 directory (sqlite3 or mcap), '
                   'or a PX4 .ulg / ArduPilot .bin flight log')
    p.help_tail = effect_listing     # --help ends with the effect ids
    p.add_argument('--base', default='bias,dT', metavar='IDS',
                   help='effects of the starting model (default: %(default)s, the conventional '
                        'model of eq. 18; bias is always included, one offset per bag)')
    p.add_argument('--candidates', metavar='IDS',
                   help='effects to try (default: every catalog effect not in --base)')
    p.add_argument('--json', dest='json_out', metavar='OUT',
                   help='write the machine-readable result to OUT (shape: doc/json.md)')
    p.add_argument('--report', metavar='DIR',
                   help='write report.md with PNG residual maps and Allan deviation to DIR')
    p.add_argument('-o', '--out', metavar='MODEL.yaml', help='write a model file of the '
                   'discovered effects (compensator_node loads it)')
    p.add_argument('--kind', default='poly', choices=KINDS, help='model of --out: poly (linear in '
                   'the features of the model temperature, what discovery validated; with lag '
                   'every temperature term is of the lagged state) or rbf (default: poly)')
    p.add_argument('--block-s', type=positive_float, default=10.0, metavar='S',
                   help='block length in s; gaps and the noise floor are RMS of block means '
                        '(default: %(default)s)')
    p.add_argument('--t0', type=finite_float, metavar='C', help='reference temperature T0 in '
                   'degC (default: the stable initial temperature of the first bag)')
    p.add_argument('--alpha', type=probability, default=0.01, metavar='P',
                   help='family-wise significance level per step (default: %(default)s)')
    p.add_argument('--max-steps', type=positive_int, default=6, metavar='N',
                   help='most effects to add (default: %(default)s)')
    p.add_argument('--sensor', choices=('gyro', 'accel'), default='gyro',
                   help='gyro, or accel: search the accelerometer offset on the still data (one '
                        'offset per bag and orientation; candidates among '
                        f'{", ".join(ACCEL_EFFECTS)}; figures in mg) (default: %(default)s)')
    add_bag_options(p, sessions=True)
    return p


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``discover`` with parsed arguments; print the summary, write the outputs."""
    base = normalise_ids(args.base)            # fail on a bad id before reading any bag
    cands = None if args.candidates is None else normalise_ids(args.candidates)
    for opt, value in (('--json', args.json_out), ('--out', args.out)):
        if value is not None and Path(value).is_dir():
            raise UsageError(f'{opt}: expected a file path, got the directory {value!r}')
    accel = args.sensor == 'accel'
    if accel:
        cands = _accel_options(args, base, cands)
    bag = bag_options(args, accel=accel)
    runs = load_runs(args.bags, bag, log=lambda s: print(s, flush=True))
    bags = [r.name for r in runs]
    split = split_sessions(runs, bag.sessions, bag.session_gap_s)
    if split.breaks:            # one offset per run: a bag cut at its restarts (auto)
        print('\n'.join(split.lines()))
    runs, still = split.runs, None
    # A sensor constant on every axis has nothing to discover: refused before the search, in
    # train's words (a gyro), or in the accelerometer part's.
    if accel:
        if note := constant_note(runs):
            raise DatasetError('Expected an accelerometer to discover on: '
                               f'{note.split("; treated as absent")[0]}.')
        n_bags, runs = len(runs), discovery_runs(runs)
        print(f'accelerometer: the still data of {n_bags} bag(s) as {len(runs)} run(s) (one '
              'offset per bag and orientation); figures in mg (1 mg = 9.80665e-3 m/s^2)')
    else:
        constant_gyro_axes(runs)
        runs, still = still_only_runs(runs)     # no reference and moving: the still stretches
        if still is not None:
            print(still)
    bar = progress_bar(None, 'candidate', 'discover', bag.progress)[0]

    def progress(step: int, eid: str) -> None:
        bar.set_postfix_str(f'step {step + 1}: scoring {eid}')
        bar.update(1)

    try:
        result = discover(runs, base=base, candidates=cands, block_s=args.block_s, t0=args.t0,
                          alpha=args.alpha, max_steps=args.max_steps, progress=progress)
    except FitError as err:
        if still is None:
            raise
        raise FitError(f'on the still stretches only (no reference rate, the IMU moves): '
                       f'{err}') from None
    finally:
        bar.close()
    text = format_summary(result)
    sys.stdout.write(text.replace('deg/s', 'mg') if accel else text)
    model_file = None
    if args.out is not None:
        model = build_model(result, runs, kind=args.kind, created={
            'command': command_line('discover', argv), 'bags': bags})
        model_file = str(save_model(model, args.out))
        print(f'wrote model {model_file} ({model.kind}, features '
              f'{", ".join(model.features)}, model_id {model.model_id})')
    if args.report is not None:
        print(f'wrote report {write_report(result, args.report)}')
    if args.json_out is not None:
        doc = {**result.to_json(model_file), **(dict(sensor='accel', unit='mg') if accel else {})}
        atomic_json(args.json_out, doc)
        print(f'wrote {args.json_out}')
    return 0


def _accel_options(args: argparse.Namespace, base: tuple, cands: tuple | None) -> tuple:
    """Check the options of ``--sensor accel``; return its candidates."""
    for opt, value in (('--out', args.out), ('--report', args.report)):
        if value is not None:
            raise UsageError(f'{opt} is for the gyro; with --sensor accel, train fits the '
                             'accelerometer part and --json holds the search')
    allowed = ('bias',) + ACCEL_EFFECTS
    if bad := [e for e in base + (cands or ()) if e not in allowed]:
        raise UsageError(f'--sensor accel: {", ".join(bad)} cannot be an accelerometer '
                         f'effect; expected some of {", ".join(allowed)}')
    return cands if cands is not None else tuple(e for e in ACCEL_EFFECTS if e not in base)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``python -m gyro_tdc discover``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('discover', build_parser, _run, argv)
