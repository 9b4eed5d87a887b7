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
``gyro-tdc simulate``: simulate a thermal-chamber scenario into rosbag2 bags.

One bag at ``--out``, or ``OUT/run1 ... OUT/runN`` for a multi-run scenario; the topics of
the Imu, the temperature and, when used, the rate table (a vehicle scenario: the truth and
``/cmd_vel``). ``--force`` replaces an earlier output of ``simulate`` only.
See ``doc/internals/cli.md``.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import textwrap
import time
from typing import Callable, Optional, Sequence

from gyro_tdc.base import atomic_dir, check_sim_samples, clean_leftovers, scenario_names
from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import ArgumentParser, progress, progress_bar, run_command
from gyro_tdc.errors import GyroTdcError
from gyro_tdc.sim import CMD_VEL_TOPIC, load_scenario, SimRun, simulate_run, TRUTH_TOPIC
import numpy as np

__all__ = ['build_parser', 'main', 'simulate']


def scenario_listing(width: int = 92) -> str:
    """
    Return the shipped scenarios as help text: name, runs, length and rate, description.

    Parameters
    ----------
    width : int
        Line width of the wrapped descriptions.

    Returns
    -------
    str
        Multi-line text; a scenario that cannot be read is listed with its error.

    """
    lines = ['shipped scenarios (--scenario NAME; config/scenarios/NAME.yaml):']
    for name in scenario_names():
        try:
            sc = load_scenario(name)
        except GyroTdcError as exc:
            lines.append(f'  {name}: cannot be read: {exc}')
            continue
        runs = f'{sc.runs.count} runs' if sc.runs.count > 1 else '1 run'
        lines.append(f'  {name}: {runs} of {sc.duration_s / 3600.0:.2f} h at '
                     f'{sc.imu_rate_hz:g} Hz')
        lines += textwrap.wrap(' '.join(str(sc.description).split()), width,
                               initial_indent='      ', subsequent_indent='      ')
    return '\n'.join(lines)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``simulate``."""
    parser = ArgumentParser(prog=f'{PROG} simulate', description='Simulate a gyro in a thermal '
                            'chamber on a rate table and write rosbag2 bags (one per run).')
    parser.add_argument('--scenario', required=True, metavar='NAME|FILE',
                        help='shipped scenario name (listed below) or a YAML file')
    parser.add_argument('-o', '--out', required=True, metavar='BAG', help='bag directory to '
                        'create; for a multi-run scenario a directory holding run1 ... runN')
    parser.add_argument('--force', action='store_true',
                        help='replace --out when it exists and holds what simulate writes (a '
                             'bag, or a folder of run bags); anything else is refused')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                        help='rosbag2 storage plugin (default: sqlite3)')
    parser.add_argument('--seed', type=int, default=0, metavar='N',
                        help='random seed (default: 0)')
    parser.add_argument('--rate-hz', type=float, metavar='F',
                        help="IMU rate in Hz (default: the scenario's)")
    parser.help_tail = scenario_listing      # read only when --help asks for it
    parser.add_argument('--no-progress', dest='progress', action='store_false', default=None,
                        help='no progress bar over the runs (default: shown on a terminal)')
    return parser


def _is_bag(path: Path) -> bool:
    """Return True when ``path`` is a rosbag2 directory (it holds ``metadata.yaml``)."""
    return path.is_dir() and not path.is_symlink() and (path / 'metadata.yaml').is_file()


def _check_replaceable(out: Path) -> None:
    """Raise unless ``out`` is a bag or a folder of ``runN`` bags (what simulate writes)."""
    entries = list(out.iterdir()) if out.is_dir() and not out.is_symlink() else []
    if not (_is_bag(out) or entries and all(e.name.startswith('run') and e.name[3:].isdigit()
                                            and _is_bag(e) for e in entries)):
        raise GyroTdcError(f'--out: {str(out)!r} exists and is not a bag or a folder of run bags '
                           'written by simulate; --force replaces only those. Choose a new path.')


def _summary(run: SimRun, path: Path, seconds: float) -> str:
    lo, hi = float(np.min(run.temp_c)), float(np.max(run.temp_c))
    span_h = (run.imu_t[-1] - run.imu_t[0]) / 3600.0
    if run.vehicle is not None:
        v = run.vehicle
        drives = sum(leg.kind == 'drive' for leg in v.legs)
        ref = (f'{drives} drives, parked {100.0 * float(v.parked.mean()):.0f} % of the time, '
               f'true rate on {TRUTH_TOPIC}, {v.cmd_t.size} {CMD_VEL_TOPIC} messages')
    else:
        ref = f'{run.ref_t.size if run.moving else 0} reference messages'
    return (f'{run.name}: {len(run)} IMU samples at {run.rate_hz:g} Hz ({span_h:.2f} h), '
            f'{run.temp_t.size} temperature readings {lo:.2f}..{hi:.2f} degC, '
            f'{ref}, {seconds:.2f} s -> {path}')


def simulate(scenario: str, out: str, *, storage: str = 'sqlite3', seed: int = 0,
             rate_hz: Optional[float] = None, force: bool = False, progress: bool = False,
             log: Callable[[str], None] = print) -> list[Path]:
    """
    Simulate every run of a scenario and write one bag per run.

    Parameters
    ----------
    scenario : str
        Shipped scenario name or YAML path.
    out : str
        Bag directory (single run) or directory of ``run1 ... runN`` (several runs); must
        not exist unless ``force``.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.
    seed : int
        Random seed, >= 0.
    rate_hz : float, optional
        IMU rate overriding the scenario's.
    force : bool
        Replace ``out`` when it exists and is a bag or a folder of run bags; the old one
        stays at ``out`` until the new one is complete (and when the simulation fails).
    progress : bool
        Show a progress bar over the runs on stderr.
    log : callable
        Receives one summary line per run.

    Returns
    -------
    list of pathlib.Path
        The bags written, in run order.

    Raises
    ------
    GyroTdcError
        ScenarioError for a bad scenario, seed or rate; DatasetError when a bag cannot be
        written; GyroTdcError when ``out`` exists (without ``force``, or when it is not
        an output of simulate).

    """
    sc = load_scenario(scenario)
    out_path = Path(out)
    clean_leftovers(out_path)     # what killed runs left; may put a replaced bag back
    if os.path.lexists(out_path):
        if not force:
            raise GyroTdcError(f'--out: {str(out_path)!r} already exists; choose a new path, '
                               'or add --force to replace it.')
        _check_replaceable(out_path)
    if seed < 0:
        raise GyroTdcError(f'--seed: expected an integer >= 0, got {seed}.')
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise GyroTdcError(f'--rate-hz: expected a number > 0, got {rate_hz}.')
    check_sim_samples(sc.duration_s, sc.imu_rate_hz if rate_hz is None else rate_hz,
                      option='imu_rate_hz' if rate_hz is None else '--rate-hz')
    # One bag, or a folder of run1..runN: built out of sight and renamed when complete, so
    # a failure (full disk, Ctrl-C, a bad run) leaves nothing behind. With --force the old
    # output stays at its path until the new one is complete, then the two are swapped; a
    # run killed at any point leaves the old or the new output there, never neither.
    names = [f'run{i + 1}' for i in range(sc.runs.count)] if sc.runs.count > 1 else ['']
    from gyro_tdc.data import DEFAULT_REFERENCE_TOPIC, encode_twists, TWIST_TYPE, write_bag
    bar, above = progress_bar(len(names), 'run', 'simulate', progress and len(names) > 1)
    log = log if bar.disable else above     # summary lines above the bar
    with atomic_dir(out_path, what='bag', replace=force) as build:
        if sc.runs.count > 1:
            build.mkdir()
        for index, name in enumerate(names):
            start = time.perf_counter()
            run = simulate_run(sc, seed=seed, run_index=index, rate_hz=rate_hz)
            accel_var = (np.asarray(sc.accel.noise_mps2_per_rt_hz) ** 2) * run.rate_hz
            ref_topic, extra = DEFAULT_REFERENCE_TOPIC, []
            ref_t, ref = (run.ref_t, run.ref) if run.moving else (None, None)
            if run.vehicle is not None:      # no rate table: the true rate, for evaluation only
                ref_topic, ref_t, ref = TRUTH_TOPIC, run.imu_t, run.ref
                if run.vehicle.cmd_t.size:
                    extra = [(CMD_VEL_TOPIC, TWIST_TYPE, run.vehicle.cmd_t,
                              encode_twists(run.vehicle.cmd))]
            write_bag(build / name, imu_t=run.imu_t, gyro=run.gyro, accel=run.accel,
                      temp_t=run.temp_t, temp_c=run.temp_c, temp_var=run.temp_var, ref_t=ref_t,
                      ref=ref, storage=storage, reference_topic=ref_topic,
                      gyro_cov=run.truth.noise_std ** 2, accel_cov=accel_var, extra=extra)
            log(_summary(run, out_path / name, time.perf_counter() - start))
            bar.update(1)
        bar.close()
    return [out_path / n for n in names]


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``simulate`` with parsed arguments (one summary line per run)."""
    simulate(args.scenario, args.out, storage=args.storage, seed=args.seed,
             rate_hz=args.rate_hz, force=args.force, progress=progress(args))
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``gyro-tdc simulate``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('simulate', build_parser, _run, argv)
