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
``python -m gyro_tdc simulate``: simulate a thermal-chamber scenario into rosbag2 bags.

A single-run scenario writes one bag at ``--out``; a multi-run scenario writes the directory
``OUT/run1 ... OUT/runN``. Topics: ``/imu/data_raw`` (sensor_msgs/Imu, frame ``imu_link``),
``/imu/temperature`` (sensor_msgs/Temperature) and, when the rate table is ever non-zero,
``/rate_table/reference`` (geometry_msgs/Vector3Stamped, one message per change).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time
from typing import Callable, Optional, Sequence

from gyro_tdc.atomicio import atomic_dir
from gyro_tdc.cli.common import ArgumentParser, run_command
from gyro_tdc.errors import GyroTdcError
from gyro_tdc.limits import check_sim_samples
from gyro_tdc.sim import load_scenario, SimRun, simulate_run
import numpy as np

__all__ = ['build_parser', 'main', 'simulate']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``simulate``."""
    parser = ArgumentParser(
        prog='python -m gyro_tdc simulate',
        description='Simulate a gyro in a thermal chamber on a rate table and write rosbag2 '
                    'bags (one per run).')
    parser.add_argument('--scenario', required=True, metavar='NAME|FILE',
                        help='shipped scenario name (config/scenarios) or a YAML file')
    parser.add_argument('--out', required=True, metavar='BAG',
                        help='bag directory to create; for a multi-run scenario a directory '
                             'holding run1 ... runN')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                        help='rosbag2 storage plugin (default: sqlite3)')
    parser.add_argument('--seed', type=int, default=0, metavar='N',
                        help='random seed (default: 0)')
    parser.add_argument('--rate-hz', type=float, default=None, metavar='F',
                        help="IMU rate in Hz (default: the scenario's)")
    return parser


def _summary(run: SimRun, path: Path, seconds: float) -> str:
    lo, hi = float(np.min(run.temp_c)), float(np.max(run.temp_c))
    span_h = (run.imu_t[-1] - run.imu_t[0]) / 3600.0
    return (f'{run.name}: {len(run)} IMU samples at {run.rate_hz:g} Hz ({span_h:.2f} h), '
            f'{run.temp_t.size} temperature readings {lo:.2f}..{hi:.2f} degC, '
            f'{run.ref_t.size if run.moving else 0} reference messages, '
            f'{seconds:.2f} s -> {path}')


def simulate(scenario: str, out: str, *, storage: str = 'sqlite3', seed: int = 0,
             rate_hz: Optional[float] = None,
             log: Callable[[str], None] = print) -> list[Path]:
    """
    Simulate every run of a scenario and write one bag per run.

    Parameters
    ----------
    scenario : str
        Shipped scenario name or YAML path.
    out : str
        Bag directory (single run) or directory of ``run1 ... runN`` (several runs); must
        not exist.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.
    seed : int
        Random seed, >= 0.
    rate_hz : float, optional
        IMU rate overriding the scenario's.
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
        written; GyroTdcError when ``out`` exists.

    """
    sc = load_scenario(scenario)
    out_path = Path(out)
    if out_path.exists():
        raise GyroTdcError(f'--out: {str(out_path)!r} already exists; choose a new path.')
    if seed < 0:
        raise GyroTdcError(f'--seed: expected an integer >= 0, got {seed}.')
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise GyroTdcError(f'--rate-hz: expected a number > 0, got {rate_hz}.')
    check_sim_samples(sc.duration_s, sc.imu_rate_hz if rate_hz is None else rate_hz,
                      option='imu_rate_hz' if rate_hz is None else '--rate-hz')
    # One bag, or a folder of run1..runN: built out of sight and renamed when complete, so
    # a failure (full disk, Ctrl-C, a bad run) leaves nothing behind.
    names = [f'run{i + 1}' for i in range(sc.runs.count)] if sc.runs.count > 1 else ['']
    with atomic_dir(out_path, what='bag') as build:
        if sc.runs.count > 1:
            build.mkdir()
        _simulate_runs(sc, [build / n for n in names], [out_path / n for n in names],
                       storage, seed, rate_hz, log)
    return [out_path / n for n in names]


def _simulate_runs(sc, paths, shown, storage, seed, rate_hz, log) -> None:
    """Simulate run k of ``sc`` into ``paths[k]`` (logged as ``shown[k]``)."""
    from gyro_tdc.bagio import write_bag

    for index, (path, name) in enumerate(zip(paths, shown)):
        start = time.perf_counter()
        run = simulate_run(sc, seed=seed, run_index=index, rate_hz=rate_hz)
        accel_var = (np.asarray(sc.accel.noise_mps2_per_rt_hz) ** 2) * run.rate_hz
        write_bag(path, imu_t=run.imu_t, gyro=run.gyro, accel=run.accel, temp_t=run.temp_t,
                  temp_c=run.temp_c, temp_var=run.temp_var,
                  ref_t=run.ref_t if run.moving else None,
                  ref=run.ref if run.moving else None, storage=storage,
                  frame_id='imu_link', imu_topic='/imu/data_raw',
                  temperature_topic='/imu/temperature', reference_topic='/rate_table/reference',
                  gyro_cov=run.truth.noise_std ** 2, accel_cov=accel_var)
        log(_summary(run, name, time.perf_counter() - start))


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``simulate`` with parsed arguments (one summary line per run)."""
    simulate(args.scenario, args.out, storage=args.storage, seed=args.seed,
             rate_hz=args.rate_hz)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``python -m gyro_tdc simulate``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('simulate', build_parser, _run, argv)


if __name__ == '__main__':
    sys.exit(main())
