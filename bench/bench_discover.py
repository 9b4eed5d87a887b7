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
Discovery speed: a 2-hour, 50 Hz, three-axis bag analysed end to end (target: under 1 min).

A bag is simulated once (L3GD20 preset noise; heating and cooling between 0 and 40 degC with
soaks; ``dT2`` and a thermometer-to-die ``lag`` hidden; 360,000 IMU messages) and then
analysed ``--repeat`` times, each in a fresh process as a user would run it::

    python -m gyro_tdc discover BAG --json OUT.json --out MODEL.yaml

The median wall time of the whole command (interpreter start, imports, bag read, discovery
with the Allan deviation of the residual, model file, JSON) is the figure; the time of the
analysis alone (``load_runs`` + :func:`gyro_tdc.identify.discover.discover`, in this process) is
printed too, as is what was found. ``--report`` adds the markdown report with its PNGs::

    .venv/bin/python bench/bench_discover.py              # ~1 min
    .venv/bin/python bench/bench_discover.py --repeat 5 --report
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import argparse  # noqa: E402, I100
from pathlib import Path  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SCENARIO = {
    'format_version': 1, 'name': 'bench_discover', 'sensor': 'l3gd20', 'imu_rate_hz': 50.0,
    'profile': {'start_c': 0.0, 'segments': [
        {'kind': 'hold', 'duration_s': 600.0},
        {'kind': 'ramp', 'to_c': 40.0, 'rate_c_per_h': 80.0},
        {'kind': 'hold', 'duration_s': 900.0},
        {'kind': 'ramp', 'to_c': 0.0, 'rate_c_per_h': 60.0},
        {'kind': 'hold', 'duration_s': 1500.0}]},
    'duration_s': 7200.0,
    'thermal': {'tau_package_s': 60.0, 'tau_die_s': 150.0},
    'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.03,
                    'noise_c': 0.01},
    'gyro': {'effects': ['bias', 'dT', 'dT2', 'lag']},
}


def make_bag(path: Path) -> None:
    """Simulate the scenario and write it as a bag."""
    from gyro_tdc.data import write_bag
    from gyro_tdc.sim.simulator import simulate_run

    run = simulate_run(SCENARIO, seed=7)
    write_bag(path, imu_t=run.imu_t, gyro=run.gyro, accel=run.accel, temp_t=run.temp_t,
              temp_c=run.temp_c, temp_var=run.temp_var)
    print(f'bag: {len(run)} IMU messages at {run.rate_hz:g} Hz over '
          f'{(run.imu_t[-1] - run.imu_t[0]) / 3600.0:.2f} h, hidden dT2 and lag '
          f'(tau_die 150 s) -> {path}')


def main() -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--repeat', type=int, default=3, help='timed runs (default: 3)')
    parser.add_argument('--report', action='store_true', help='also write --report DIR')
    args = parser.parse_args()

    from gyro_tdc.data.dataset import load_runs
    from gyro_tdc.identify.discover import discover

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'bag'
        make_bag(bag)
        cli, inproc = [], []
        for i in range(args.repeat):
            out = Path(tmp) / f'out{i}'
            cmd = [sys.executable, '-m', 'gyro_tdc', 'discover', str(bag),
                   '--json', str(out / 'result.json'), '--out', str(out / 'model.yaml'),
                   '--no-progress']
            if args.report:
                cmd += ['--report', str(out / 'report')]
            start = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                                  env=dict(os.environ, MPLBACKEND='Agg'))
            cli.append(time.perf_counter() - start)
            if proc.returncode != 0:
                print(proc.stdout, proc.stderr)
                return 1
            start = time.perf_counter()
            res = discover(load_runs([bag]))
            inproc.append(time.perf_counter() - start)
        print(proc.stdout.rstrip())
        print(f'found: {", ".join(res.named) or "nothing"}; gap '
              f'{res.gap_dps / res.noise_floor_dps:.2f} x noise floor')
        print(f'discover CLI (fresh process, read + analyse + model + JSON'
              f'{" + report" if args.report else ""}): median {statistics.median(cli):.2f} s '
              f'over {len(cli)} runs (min {min(cli):.2f}, max {max(cli):.2f})')
        print(f'analysis in process (load_runs + discover): median '
              f'{statistics.median(inproc):.2f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
