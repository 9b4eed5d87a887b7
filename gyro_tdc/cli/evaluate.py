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
``gyro-tdc evaluate BAG... --model A.yaml [--model B.yaml ...]``: score models.

Reads the held-out bags (one :class:`~gyro_tdc.data.BagOptions`), scores every model with
:mod:`gyro_tdc.evaluate.score` (BS, BS/BS1, RMS, Allan deviation; the paper's tables with two
models; ``px4`` a cubic fitted on ``--train``) and prints or writes the tables, ``--json``,
``--plots`` and ``--export``. See ``doc/internals/cli.md``.
"""

from __future__ import annotations

import argparse
import math
from typing import Iterator, Optional, Sequence

from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import (add_bag_options, ArgumentParser, bag_options, comma_floats,
                                 non_negative_float, progress_bar, refuse_driver_logs,
                                 run_command, UsageError)
from gyro_tdc.data import find_bags
from gyro_tdc.evaluate import (AUTO_REANCHOR, BagEval, evaluate, format_bag, format_means,
                               format_still, imu_mismatch, load_models, model_description,
                               POLICY_WORDS, PX4, write_csv, write_json, write_plots)
from gyro_tdc.learn import read_model
from gyro_tdc.model import DEFAULT_OUT_OF_RANGE, OUT_OF_RANGE_POLICIES

__all__ = ['build_parser', 'main']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``evaluate``."""
    p = ArgumentParser(prog=f'{PROG} evaluate', description='Score compensation models on '
                       'held-out rosbag2 bags in the terms of the paper (BS, P ratios), plus RMS '
                       'and Allan deviation.')
    p.add_argument('bags', nargs='+', metavar='BAG',
                   help='held-out rosbag2 directory (sqlite3 or mcap), PX4 .ulg or '
                        'ArduPilot .bin log, or a folder of them (walked, subfolders too; '
                        'one found there that cannot be read is skipped with a warning)')
    p.add_argument('--model', dest='models', action='append', required=True, metavar='MODEL',
                   help='model file or learn_file (its learned model; repeat for several; '
                        'reported in this order), px4 for '
                        'a PX4-style cubic in T fitted on the --train bags, or px4-onboard / '
                        "ardupilot-onboard for the flight controller's own correction as each "
                        "held-out log's TC_G* / INS_TCALn_* parameters define it (its clamp)")
    p.add_argument('--train', nargs='+', metavar='BAG', help='bags to fit the px4 cubic on')
    p.add_argument('--baseline', metavar='MODEL', help='the conventional model of the paper '
                   'tables (one of the --model values, or another model file, evaluated too); '
                   'default: the first of exactly two models')
    p.add_argument('--reanchor', type=_reanchor, default=0.0, metavar='S|auto',
                   help='remove from each model the mean error over the first S s of every '
                        'session (the turn-on offset of each power cycle, as the compensator '
                        're-anchors at start-up while still); auto: over as long as the '
                        "compensator takes to know it to its tolerance (0.1 x the model's "
                        'residual std, 10 to 600 s); default 0: off (a log scored on its still '
                        'stretches is anchored on the first of each session instead)')
    p.add_argument('--out-of-range', dest='out_of_range', default=DEFAULT_OUT_OF_RANGE,
                   choices=OUT_OF_RANGE_POLICIES,
                   help=f"beyond a model's trained range: linear ({POLICY_WORDS['linear']}, "
                        'as the compensator node by default), clamp, or extrapolate (default: '
                        '%(default)s)')
    p.add_argument('--floor', type=_floor, metavar='X,Y,Z|V',
                   help='a known white-noise floor of the gyro per axis in (deg/s)^2 (one '
                        'value: all axes), e.g. ARW^2 x rate from the simulator or a '
                        'datasheet: adds BS / floor per model (BS/fl; bs_over_floor in --json)')
    p.add_argument('--accel-floor', dest='accel_floor', type=_floor,
                   metavar='X,Y,Z|V', help='likewise for the accelerometer, in (m/s^2)^2 (aBS/fl; '
                   'accel_bs_over_floor in --json)')
    p.add_argument('--json', metavar='OUT', help='write the scores as JSON (shape: doc/json.md)')
    p.add_argument('--plots', metavar='DIR', help='write PNGs per bag here')
    p.add_argument('--export', metavar='DIR', help='write a CSV per bag here: time, temperature, '
                   'raw, reference and compensated rates (rad/s) of the samples scored (of a '
                   'flight log: its still stretches)')
    add_bag_options(p, driver=True, sessions=True)
    return p


def _reanchor(text: str) -> float | str:
    """Parse ``--reanchor``: ``auto`` or a number of seconds >= 0 (argparse type)."""
    return AUTO_REANCHOR if text.strip().lower() == AUTO_REANCHOR else non_negative_float(text)


def _floor(text: str) -> tuple[float, float, float]:
    """Parse ``--floor``: one number > 0 for every axis, or three x,y,z (argparse type)."""
    values = comma_floats(text)
    if len(values) not in (1, 3) or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(
            f'expected one number > 0 or three x,y,z (a variance per axis), got {text!r}')
    return tuple(values * 3) if len(values) == 1 else tuple(values)


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``evaluate`` with parsed arguments; print the tables and write the outputs."""
    specs = list(args.models)
    if args.baseline is not None and args.baseline not in specs:
        specs.append(args.baseline)
    if PX4 in specs and not args.train:
        raise UsageError('--model px4 needs --train BAG... (the bags to fit the cubic on)')
    if args.train and PX4 not in specs:
        raise UsageError('--train is only used by --model px4; add --model px4 or drop --train')
    baseline = (specs.index(args.baseline) if args.baseline is not None
                else (0 if len(specs) == 2 else None))
    bag = bag_options(args)
    refuse_driver_logs(bag, [*args.bags, *(args.train or ())])   # read by field
    auto = args.reanchor == AUTO_REANCHOR
    # One description of the re-anchoring: the console line and the plot titles.
    how = ('re-anchored (auto): mean error removed over the head of each session, averaged '
           "until its standard error is 0.1 x the model's residual std or 600 s" if auto else
           f're-anchored: mean error over the first {args.reanchor:g} s of each session removed'
           if args.reanchor > 0 else 'no re-anchoring')
    found = find_bags(args.bags)
    place = {str(p): k + 1 for k, (p, _) in enumerate(found)}
    bar, log = progress_bar(len(found), 'bag', 'evaluate', bag.progress)
    models = load_models(specs, train_bags=args.train, bag=bag, log=log, held_out=args.bags,
                         loader=read_model)
    descriptions = [model_description(nm.name, nm.model) for nm in models]

    def each(b: BagEval) -> None:
        for line in [*(w for nm in models if (w := imu_mismatch(nm, b.run, b.label))),
                     *(_reanchor_lines(b) if auto else ()), *format_still(b)]:
            log(line)
        if b.still is not None and args.reanchor != 0:
            given = args.reanchor if auto else f'{args.reanchor:g}'
            log(f'{b.label}: --reanchor {given} does not apply to it (scored on its '
                'still stretches, each session anchored on its first)')
        log(format_bag(b, baseline, floor=args.floor, accel_floor=args.accel_floor))
        if args.plots is not None:
            bar.set_postfix_str(f'{b.label}: plots')
            for f in write_plots(b, args.plots, descriptions=descriptions, options=how,
                                 reanchor_s=0.0 if auto else args.reanchor):
                log(f'wrote {f}')
        if args.export is not None:
            bar.set_postfix_str(f'{b.label}: CSV')
            log(f'wrote {write_csv(b, args.export)}')
        bar.update(place[b.bag] - bar.n)       # past the logs skipped before it

    for nm, text in zip(models, descriptions):
        lo, hi = nm.model.temp_range_c
        log(f'model {nm.label} = {text}, trained {lo:.2f} .. {hi:.2f} degC')
    log(f"out-of-range policy: {args.out_of_range} (beyond a model's trained range of the "
        f'model temperature {POLICY_WORDS[args.out_of_range]}; --out-of-range '
        f'{"|".join(OUT_OF_RANGE_POLICIES)})')
    if args.reanchor:
        log(f'models {how} (raw data untouched)'
            + ('; per model: samples, seconds, standard error' if auto else ''))
    try:
        results = evaluate(args.bags, models, bag=bag, reanchor_s=args.reanchor, log=log,
                           each=each, out_of_range=args.out_of_range, found=found)
    finally:
        bar.close()
    if args.json is not None:
        path = write_json(results, args.json, floor=args.floor, accel_floor=args.accel_floor)
        print(f'wrote {path}')
    if len(results) > 1:
        print(format_means(results, floor=args.floor))
    return 0


def _reanchor_lines(b: BagEval) -> Iterator[str]:
    """Yield what the automatic re-anchoring did for each model on a bag (each session)."""
    for m in b.models:
        if m.reanchor is None:         # scored on still stretches: anchored on them
            continue
        records = m.reanchor.get('sessions') or [m.reanchor]
        for k, r in enumerate(records):
            where = f' session {k + 1}' if len(records) > 1 else ''
            yield (f'{b.label}: {m.label} re-anchored{where} on {r["samples"]} samples '
                   f'over {r["duration_s"]:.1f} s ({r["reason"]}): shift '
                   + ', '.join(f'{v:+.5f}' for v in r['shift_dps']) + ' deg/s, standard error '
                   + ', '.join(f'{v:.5f}' for v in r['se_dps']) + ' deg/s')


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``gyro-tdc evaluate``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('evaluate', build_parser, _run, argv)
