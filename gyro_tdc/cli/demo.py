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
``gyro-tdc demo``: the whole pipeline on simulated data, in a few minutes.

The steps are :data:`STEPS`; each prints the command a user would type and runs that
command's ``main``. Everything lands in ``--out`` (:data:`OUTPUTS`), which a later demo
clears (marker :data:`MARKER`). See ``doc/internals/cli.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
from pathlib import Path
import shlex
import shutil
import textwrap
import time
from typing import Sequence

from gyro_tdc.base import atomic_json, model_path
from gyro_tdc.cli import load_main, PROG
from gyro_tdc.cli.common import ArgumentParser, key_listing, positive_float, run_command
from gyro_tdc.errors import GyroTdcError
from gyro_tdc.evaluate import is_coverage_line

__all__ = ['MARKER', 'OUTPUTS', 'STEPS', 'build_parser', 'live_counts_explained', 'main',
           'prepare_out', 'run_demo']

DEFAULT_MODEL = 'l3gd20_modified'
MARKER = '.gyro_tdc-demo'

#: The demo's steps, in order; the last one is left out by ``--skip-live``.
STEPS = (
    'Simulate the paper campaign: L3GD20, 5 runs, -40 -> 85 degC at 18 degC/h, 8.1 h each '
    'at 10 Hz',
    'Train on run 1: conventional f(dT) and modified f(dT, dT^2) polynomials (eq. 18 and 16) '
    'and the modified RBF network',
    'Evaluate on held-out runs 2-5: the paper tables 3-7 (BS1 raw, BS2 conventional, BS3 '
    'modified, P1-P3)',
    'Compare on run 2: modified RBF, modified polynomial and a PX4-style cubic (fitted on run '
    '1), with start-up re-anchoring, with plots',
    'Simulate a sensor whose MEMS die lags its thermometer by 180 s (heating and cooling, 2 runs)',
    'Discover what the datasheet model f(dT) misses, from the bags alone',
    'Train on its run 1: datasheet f(dT), modified f(dT, dT^2) and the default options '
    '(--features auto)',
    'Evaluate on its held-out run 2: datasheet, modified, PX4 cubic, default-options and '
    'discovered models, with plots',
    'Live: compensator_node, then driver_node (simulated, 50x accelerated) as two processes '
    'over DDS on loopback, with the shipped model',
)

#: What ``--out`` holds afterwards (relative path -> what it is).
OUTPUTS = {
    'bags/l3gd20_paper/run1 .. run5': 'the simulated paper campaign (rosbag2, sqlite3)',
    'bags/lag_heat_cool/run1, run2': 'the simulated lagging-die sensor',
    'models/*.yaml': 'every model trained or discovered (model files compensator_node loads)',
    'report/paper_tables.json': 'step 3, the paper tables (evaluate --json)',
    'report/comparison.json': 'step 4 (evaluate --json)',
    'report/evaluate/*.png': 'step 4 plots: time series with a zoom, residual vs temperature, '
                             'Allan deviation',
    'report/discovery.json': 'step 6 (discover --json)',
    'report/discovery/report.md': 'step 6 report, with its PNG residual maps',
    'report/lag_comparison.json': 'step 8 (evaluate --json)',
    'report/evaluate_lag/*.png': 'step 8 plots',
    'report/live.json': 'step 9, the live counts and bias stability (not with --skip-live)',
}


def _description() -> str:
    """Return ``--help``'s description: the steps and the outputs."""
    lines = ['Run the whole pipeline on simulated data, printing each command as a user would '
             'type it:', '']
    for i, title in enumerate(STEPS, 1):
        lines += textwrap.wrap(title, 92, initial_indent=f'  {i}. ', subsequent_indent='     ')
    lines += ['', 'Writes into --out (a folder an earlier demo wrote is cleared first; any '
              'other existing folder is refused):']
    return '\n'.join(lines + key_listing(OUTPUTS))


def _run_step(n: int, command: str, argv: Sequence[str], covered: set) -> None:
    """
    Print ``$ gyro-tdc COMMAND ARGV`` and run the command's ``main`` (step ``n``).

    ``train`` prints a bag's coverage report only the first time (``covered`` holds the bags
    printed): later, its coverage lines are left out and one line says so.
    """
    print(f'$ {PROG} {command} {shlex.join(argv)}', flush=True)
    bag = str(argv[0]) if command == 'train' else None
    seen, buffer = bag is not None and bag in covered, io.StringIO()
    with contextlib.redirect_stdout(buffer) if seen else contextlib.nullcontext():
        rc = load_main(command)(list(argv))
    if seen:
        lines = buffer.getvalue().splitlines()
        kept = [line for line in lines if not is_coverage_line(line)]
        if len(kept) < len(lines):
            kept.append(f'(coverage of {bag}: as printed above)')
        print('\n'.join(kept), flush=True)
    if bag is not None:
        covered.add(bag)
    if rc != 0:
        raise GyroTdcError(f'step {n} ({command}) failed with exit code {rc}')


def prepare_out(out: Path) -> None:
    """
    Clear ``out`` when an earlier demo wrote it; refuse any other existing content.

    Created when missing, cleared when it holds :data:`MARKER`, used as is when empty; then
    marked. Raises GyroTdcError for a file, a symlink or a non-empty folder without marker.
    """
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise GyroTdcError(f'--out: {str(out)!r} exists and is not a folder; choose another')
    if out.is_dir() and any(out.iterdir()):
        if not (out / MARKER).is_file():
            raise GyroTdcError(f'--out: {str(out)!r} exists and was not written by the demo; '
                               'choose another folder or remove it')
        print(f'removing the previous demo output in {out}', flush=True)
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).write_text('written by gyro-tdc demo; the next demo clears this folder\n')


def run_demo(out: Path, *, live_seconds: float = 20.0, skip_live: bool = False) -> int:
    """
    Run the demo into ``out``.

    Parameters
    ----------
    out : Path
        Output folder (bags, models, report); cleared first when an earlier demo wrote it.
    live_seconds : float, s
        Length of the live driver -> compensator stream.
    skip_live : bool
        Leave out the live ROS step.

    Returns
    -------
    int
        0 on success.

    Raises
    ------
    GyroTdcError
        When ``out`` holds something the demo did not write, or a step's command fails (it
        has printed its own error line).

    """
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    out = Path(out)
    prepare_out(out)
    bags, models, report = out / 'bags', out / 'models', out / 'report'
    for d in (bags, models, report):
        d.mkdir(parents=True, exist_ok=True)
    l3, lag = bags / 'l3gd20_paper', bags / 'lag_heat_cool'
    held_out = [str(l3 / f'run{i}') for i in range(2, 6)]

    def yaml(name: str) -> str:
        return str(models / f'{name}.yaml')

    def train(bag: Path, name: str, opts: list[str]) -> tuple[str, list[str]]:
        return 'train', [str(bag), *opts, '--out', yaml(name), '--no-progress']

    plan = [   # one entry per step of STEPS but the live one: the commands it runs
        [('simulate', ['--scenario', 'l3gd20_paper', '--out', str(l3), '--seed', '1',
                       '--no-progress'])],
        [train(l3 / 'run1', name, ['--features', feats, '--kind', kind])
         for name, kind, feats in (('conventional', 'poly', 'dT'),
                                   ('modified', 'poly', 'dT,dT2'),
                                   ('modified_rbf', 'rbf', 'dT,dT2'))],
        [('evaluate', held_out + ['--model', yaml('conventional'), '--model', yaml('modified'),
                                  '--json', str(report / 'paper_tables.json'), '--no-progress'])],
        [('evaluate', held_out[:1] + ['--model', yaml('modified_rbf'), '--model', yaml('modified'),
                                      '--model', 'px4', '--train', str(l3 / 'run1'),
                                      '--reanchor', '300',
                                      '--json', str(report / 'comparison.json'),
                                      '--plots', str(report / 'evaluate'), '--no-progress'])],
        [('simulate', ['--scenario', 'lag_heat_cool', '--out', str(lag), '--seed', '3',
                       '--no-progress'])],
        [('discover', [str(lag / 'run1'), str(lag / 'run2'), '--base', 'bias,dT',
                       '--json', str(report / 'discovery.json'),
                       '--report', str(report / 'discovery'), '--out', yaml('discovered')])],
        [train(lag / 'run1', name, opts)
         for name, opts in (('datasheet', ['--features', 'dT', '--kind', 'poly']),
                            ('modified_lag_run', ['--features', 'dT,dT2', '--kind', 'poly']),
                            ('default_lag_run', []))],
        [('evaluate', [str(lag / 'run2'), '--model', yaml('datasheet'),
                       '--model', yaml('modified_lag_run'), '--model', 'px4',
                       '--train', str(lag / 'run1'), '--model', yaml('default_lag_run'),
                       '--model', yaml('discovered'),
                       '--json', str(report / 'lag_comparison.json'),
                       '--plots', str(report / 'evaluate_lag'), '--no-progress'])],
    ]
    start, covered, total = time.monotonic(), set(), len(STEPS) - (1 if skip_live else 0)

    def begin(n: int) -> None:
        print(f'\n[{n}/{total}] {STEPS[n - 1]}  (t = {time.monotonic() - start:.0f} s)',
              flush=True)

    for n, commands in enumerate(plan, 1):
        begin(n)
        for command, argv in commands:
            _run_step(n, command, argv, covered)
            if command == 'discover':
                _print_discovery(report / 'discovery.json')
    if not skip_live:
        begin(len(STEPS))
        _live(model_path(DEFAULT_MODEL), live_seconds, report)
    print(f'\ndemo finished in {time.monotonic() - start:.0f} s; everything is in {out} '
          f'(report: {report})')
    return 0


def _print_discovery(path: Path) -> None:
    """Print what discovery named, step by step, from its JSON."""
    found = json.loads(path.read_text())
    named = [s['effect'] for s in found['steps']]
    print(f'discovered: {", ".join(named) or "nothing"}; final effects '
          f'{", ".join(found["final_effects"])}')
    for s in found['steps']:
        print(f'  + {s["effect"]}: gap {s["gap_before_dps"]:.4f} -> {s["gap_after_dps"]:.4f} '
              f'deg/s (held out {s["heldout_gap_before_dps"]:.4f} -> '
              f'{s["heldout_gap_after_dps"]:.4f}); noise floor '
              f'{found["noise_floor_dps"]:.4f} deg/s')


def _node_lines(model_stem: str) -> list[str]:
    """Return the two node commands, as a pip-venv user and as an apt ROS user types them."""
    comp = f'--ros-args --params-file config/compensator.yaml -p model_file:={model_stem}'
    drv = ('--ros-args --params-file config/driver_sim.yaml -p scenario:=demo_fast '
           '-p seed:=7 -p sim_rate_hz:=10.0 -p time_scale:=50.0')
    return ["# this repository's venv (make venv), from the repository root:",
            f'$ .venv/bin/compensator_node {comp}',
            f'$ .venv/bin/driver_node {drv}',
            '# the same with an apt-installed ROS 2 Jazzy (colcon-built package, sourced):',
            f'$ ros2 run gyro_tdc compensator_node {comp}',
            f'$ ros2 run gyro_tdc driver_node {drv}']


def _live(model: Path, seconds: float, report: Path) -> None:
    """Run the live driver -> compensator step and explain its counts."""
    print('\n'.join(_node_lines(model.stem)))
    print(f'(run here as two processes for {seconds:g} s; the compensator starts first, the '
          'driver once the compensator publishes)', flush=True)
    from gyro_tdc.nodes import run_live
    result = run_live(model, scenario='demo_fast', seed=7, sim_rate_hz=10.0, time_scale=50.0,
                      seconds=seconds)
    print('\n'.join([*result.lines(), *live_counts_explained(
        result.raw_received, result.compensated_received, result.raw_in_window,
        result.compensated_in_window)]))
    atomic_json(report / 'live.json', result.__dict__)


def live_counts_explained(raw: int, compensated: int, raw_in_window: int,
                          compensated_in_window: int) -> list[str]:
    """
    Return the lines explaining the live counts: one out per in, and why the totals differ.

    ``raw`` and ``compensated`` are the messages the monitor received, the ``_in_window``
    ones those stamped inside the window where it heard both streams.
    """
    same = raw_in_window == compensated_in_window
    lines = [f'{"one out per in" if same else "not one out per in"}: while both streams were '
             f'heard, {raw_in_window} raw messages went in and {compensated_in_window} '
             'compensated came out'
             + ('' if same or compensated_in_window > raw_in_window else
                f" ({raw_in_window - compensated_in_window} lost on the compensator's "
                'best-effort input queue)')]
    if raw != raw_in_window or compensated != compensated_in_window:
        lines.append(
            f'the totals ({raw} raw, {compensated} compensated) differ because DDS discovery '
            'matches each subscription a moment after the driver starts publishing, at its '
            "own pace: a raw message sent before the compensator's input was matched is never "
            'compensated, a compensated one sent before the monitor heard the raw stream has '
            'no raw twin here')
    return lines


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``demo``."""
    parser = ArgumentParser(prog=f'{PROG} demo', description=_description(),
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('-o', '--out', type=Path, default=Path('out/demo'),
                        help='output folder (default: out/demo)')
    parser.add_argument('--live-seconds', type=positive_float, default=20.0,
                        help='length of the live ROS step in s (default 20)')
    parser.add_argument('--skip-live', action='store_true',
                        help=f'leave out the live ROS step (step {len(STEPS)})')
    return parser


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run the demo with parsed arguments."""
    return run_demo(args.out, live_seconds=args.live_seconds, skip_live=args.skip_live)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gyro-tdc demo``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('demo', build_parser, _run, argv)
