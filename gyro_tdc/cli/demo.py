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
``python -m gyro_tdc demo``: the whole pipeline on simulated data, in a few minutes.

1. simulate the paper's L3GD20 campaign (five runs, -40 -> 85 degC at 18 degC/h);
2. train the conventional f(dT) and modified f(dT, dT^2) models on run 1;
3. evaluate them on runs 2-5 (the paper's tables 3-7), with the RBF models and a PX4-style
   cubic beside them;
4. run ``discover`` on a sensor whose die lags its thermometer (the effect is hidden: the
   workflow sees only the bag) and show the effect named and the gap shrinking; train on it
   with default options (``--features auto`` finds the thermal state by itself) and evaluate
   that model beside the datasheet, modified, PX4 and discovered ones on the held-out run;
5. stream a held-out simulated run live through ``driver_node`` -> ``compensator_node`` (two
   processes, real DDS on loopback) with the shipped default model and print the live raw
   and compensated bias stability.

Each step prints the command a user would type for it and runs that command's ``main``, so
the demo shows exactly what the commands print. Everything lands in ``--out``: bags, models,
JSON, CSV and a report folder with the plots.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import shlex
import sys
import time
from typing import Callable, Sequence

from gyro_tdc.atomicio import atomic_write
from gyro_tdc.cli.common import ArgumentParser, positive_float, run_command
from gyro_tdc.errors import GyroTdcError
from gyro_tdc.resources import model_path

__all__ = ['build_parser', 'main', 'run_demo']

DEFAULT_MODEL = 'l3gd20_modified'


class _Steps:
    """Print numbered steps with their command line and elapsed time."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.n = 0
        self.start = time.monotonic()

    def run(self, title: str, command: str, argv: Sequence[str],
            fn: Callable[[list[str]], int]) -> None:
        self.n += 1
        print(f'\n[{self.n}/{self.total}] {title}  (t = {time.monotonic() - self.start:.0f} s)',
              flush=True)
        print(f'$ python -m gyro_tdc {command} {shlex.join(argv)}', flush=True)
        rc = fn(list(argv))
        if rc != 0:
            raise GyroTdcError(f'step {self.n} ({command}) failed with exit code {rc}')


def run_demo(out: Path, *, live_seconds: float = 20.0, skip_live: bool = False) -> int:
    """
    Run the demo into ``out``.

    Parameters
    ----------
    out : Path
        Output folder (bags, models, report).
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
        When a step's command fails (it has printed its own error line).

    """
    from gyro_tdc.cli import discover, evaluate, simulate, train

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    out = Path(out)
    bags, models, report = out / 'bags', out / 'models', out / 'report'
    for d in (bags, models, report):
        d.mkdir(parents=True, exist_ok=True)
    l3 = bags / 'l3gd20_paper'
    lag = bags / 'lag_heat_cool'
    steps = _Steps(total=8 if not skip_live else 7)
    steps.run('Simulate the paper campaign: L3GD20, 5 runs, -40 -> 85 degC at 18 degC/h',
              'simulate', ['--scenario', 'l3gd20_paper', '--out', str(l3), '--seed', '1'],
              simulate.main)
    train_args = []
    for name, kind, feats in (('conventional', 'poly', 'dT'), ('modified', 'poly', 'dT,dT2'),
                              ('modified_rbf', 'rbf', 'dT,dT2')):
        train_args.append((name, [str(l3 / 'run1'), '--features', feats, '--kind', kind,
                                  '--out', str(models / f'{name}.yaml'), '--no-progress']))
    steps.run('Train on run 1: conventional f(dT) and modified f(dT, dT^2) (polynomial), and '
              'the modified RBF network', 'train', train_args[0][1], train.main)
    for _name, argv in train_args[1:]:
        print(f'$ python -m gyro_tdc train {shlex.join(argv)}', flush=True)
        if train.main(argv) != 0:
            raise GyroTdcError('training failed')
    held_out = [str(l3 / f'run{i}') for i in range(2, 6)]
    steps.run('Evaluate on held-out runs 2-5: the paper tables 3-7 (BS1 raw, BS2 conventional, '
              'BS3 modified)', 'evaluate',
              held_out + ['--model', str(models / 'conventional.yaml'),
                          '--model', str(models / 'modified.yaml'),
                          '--json', str(report / 'paper_tables.json'), '--no-progress'],
              evaluate.main)
    steps.run('Compare on the same held-out runs: modified RBF, PX4-style cubic (fitted on run '
              '1), with and without start-up re-anchoring', 'evaluate',
              held_out[:1] + ['--model', str(models / 'modified_rbf.yaml'),
                              '--model', str(models / 'modified.yaml'), '--model', 'px4',
                              '--train', str(l3 / 'run1'), '--reanchor', '300',
                              '--json', str(report / 'comparison.json'),
                              '--plots', str(report / 'evaluate'), '--no-progress'],
              evaluate.main)
    steps.run('Simulate a sensor whose MEMS die lags its thermometer (heating and cooling)',
              'simulate', ['--scenario', 'lag_heat_cool', '--out', str(lag), '--seed', '3'],
              simulate.main)
    steps.run('Discover what the datasheet model f(dT) misses, from the bag alone', 'discover',
              [str(lag / 'run1'), str(lag / 'run2'), '--base', 'bias,dT',
               '--json', str(report / 'discovery.json'), '--report', str(report / 'discovery'),
               '--out', str(models / 'discovered.yaml')], discover.main)
    found = json.loads((report / 'discovery.json').read_text())
    named = [s['effect'] for s in found['steps']]
    print(f'discovered: {", ".join(named) or "nothing"}; final effects '
          f'{", ".join(found["final_effects"])}')
    for s in found['steps']:
        print(f'  + {s["effect"]}: gap {s["gap_before_dps"]:.4f} -> {s["gap_after_dps"]:.4f} '
              f'deg/s (held out {s["heldout_gap_before_dps"]:.4f} -> '
              f'{s["heldout_gap_after_dps"]:.4f}); noise floor '
              f'{found["noise_floor_dps"]:.4f} deg/s')
    for name, feats in (('datasheet', 'dT'), ('modified_lag_run', 'dT,dT2'),
                        ('default_lag_run', None)):
        opts = [] if feats is None else ['--features', feats, '--kind', 'poly']
        argv = [str(lag / 'run1'), *opts, '--out', str(models / f'{name}.yaml'),
                '--no-progress']
        print(f'$ python -m gyro_tdc train {shlex.join(argv)}', flush=True)
        if train.main(argv) != 0:
            raise GyroTdcError('training failed')
    steps.run('Evaluate on the held-out run 2: datasheet f(dT), modified f(dT, dT^2), PX4 cubic, '
              'train with default options (all fitted on run 1) and the discovered model',
              'evaluate',
              [str(lag / 'run2'), '--model', str(models / 'datasheet.yaml'),
               '--model', str(models / 'modified_lag_run.yaml'), '--model', 'px4',
               '--train', str(lag / 'run1'), '--model', str(models / 'default_lag_run.yaml'),
               '--model', str(models / 'discovered.yaml'),
               '--json', str(report / 'lag_comparison.json'),
               '--plots', str(report / 'evaluate_lag'), '--no-progress'], evaluate.main)
    if not skip_live:
        default_model = model_path(DEFAULT_MODEL)
        _live(steps, default_model, live_seconds, report)
    print(f'\ndemo finished in {time.monotonic() - steps.start:.0f} s; report in {report}')
    return 0


def _live(steps: _Steps, model: Path, seconds: float, report: Path) -> None:
    """Run the live driver -> compensator step."""
    steps.n += 1
    print(f'\n[{steps.n}/{steps.total}] Live: driver_node (sim, demo_fast seed 7, 50x '
          f'accelerated) -> compensator_node with the shipped model {model.name}  '
          f'(t = {time.monotonic() - steps.start:.0f} s)', flush=True)
    print('$ ros2 run gyro_tdc compensator_node --ros-args --params-file config/compensator.yaml'
          f' -p model_file:={model.stem}')
    print('$ ros2 run gyro_tdc driver_node --ros-args --params-file config/driver_sim.yaml '
          '-p scenario:=demo_fast -p seed:=7 -p sim_rate_hz:=10.0 -p time_scale:=50.0')
    from gyro_tdc.nodes.live import run_live
    result = run_live(model, scenario='demo_fast', seed=7, sim_rate_hz=10.0, time_scale=50.0,
                      seconds=seconds)
    for line in result.lines():
        print(line)
    atomic_write(report / 'live.json', json.dumps(result.__dict__, indent=1) + '\n',
                 what='JSON file')


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``demo``."""
    parser = ArgumentParser(prog='python -m gyro_tdc demo', description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', type=Path, default=Path('out/demo'),
                        help='output folder (default: out/demo)')
    parser.add_argument('--live-seconds', type=positive_float, default=20.0,
                        help='length of the live ROS step in s (default 20)')
    parser.add_argument('--skip-live', action='store_true', help='leave out the live ROS step')
    return parser


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run the demo with parsed arguments."""
    return run_demo(args.out, live_seconds=args.live_seconds, skip_live=args.skip_live)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``python -m gyro_tdc demo``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('demo', build_parser, _run, argv)


if __name__ == '__main__':
    sys.exit(main())
