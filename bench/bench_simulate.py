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
Time the simulator on a 7 h run at 100 Hz (2.52 M IMU samples), every effect and noise on.

The profile is the paper's: 200 s soak at -40 degC, then the 0.1 degC / 20 s staircase to
85 degC (25,000 s), 25,200 s = 7 h in all. Prints the median wall time of several runs::

    .venv/bin/python bench/bench_simulate.py [--repeat 5] [--rate-hz 100]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from gyro_tdc.sim import EFFECT_IDS, Scenario, simulate_run  # noqa: E402

SCENARIO = {
    'name': 'bench_7h',
    'sensor': 'l3gd20',
    'imu_rate_hz': 100.0,
    'profile': {'start_c': -40.0, 'segments': [
        {'kind': 'hold', 'duration_s': 200.0},
        {'kind': 'staircase', 'to_c': 85.0, 'step_c': 0.1, 'hold_s': 20.0},
    ]},
    'thermal': {'tau_package_s': 120.0, 'tau_die_s': 60.0},
    'thermometer': {'rate_hz': 10.0, 'resolution_c': 0.03, 'noise_c': 0.01},
    'gyro': {'effects': list(EFFECT_IDS)},
    'rate_table': [{'t_s': 0.0, 'rate_dps': [10.0, 5.0, 20.0]},
                   {'t_s': 12600.0, 'rate_dps': [-10.0, -5.0, -20.0]}],
}


def main(argv: list[str] | None = None) -> int:
    """
    Run the benchmark and print its figures.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (``--repeat``, ``--rate-hz``).

    Returns
    -------
    int
        0.

    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--repeat', type=int, default=5, help='timed runs (default 5)')
    parser.add_argument('--rate-hz', type=float, default=100.0, help='IMU rate (default 100)')
    args = parser.parse_args(argv)
    scenario = Scenario.from_dict(SCENARIO)
    simulate_run(scenario, seed=0, rate_hz=10.0)  # warm-up (imports, caches)
    times = []
    n = 0
    for i in range(args.repeat):
        start = time.perf_counter()
        run = simulate_run(scenario, seed=i, rate_hz=args.rate_hz)
        times.append(time.perf_counter() - start)
        n = len(run)
        del run
    hours = scenario.duration_s / 3600.0
    print(f'simulate_run: {hours:.2f} h at {args.rate_hz:g} Hz = {n} IMU samples, all effects '
          f'and noise on; {args.repeat} runs')
    print(f'median {statistics.median(times):.3f} s, min {min(times):.3f} s, '
          f'max {max(times):.3f} s ({n / statistics.median(times) / 1e6:.2f} M samples/s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
