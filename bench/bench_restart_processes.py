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
Restart a compensator process beside a live driver process: does the stream come back.

test_restart_across_processes's rig (``test/support/restart_rig.py``): the driver at a steady
200 Hz (sim back-end, reliable keep last 100) and a compensator, two processes under
``/rover``, remapped, from parameter files. The compensator is stopped with SIGINT and
started again ``--restarts`` times per input QoS mode (best effort, the default, and
``input_reliability: reliable``; the modes take turns), each life running a seeded random
0.5-3 s after its first output. Printed per mode: restarts, how many resumed, the median
and worst time from the process start to its first output (and to its model loaded, the
start-up's share: the rest is creating the topics and discovery), and the inputs lost
between a life's first and last output, with ``--hogs`` busy processes beside it.

::

    .venv/bin/python bench/bench_restart_processes.py --restarts 30 --hogs 0
    .venv/bin/python bench/bench_restart_processes.py --restarts 30 --hogs 2
"""

import argparse
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


class _Parser(argparse.ArgumentParser):
    """Bad options: one line on stderr and exit status 2 (no usage dump)."""

    def error(self, message):
        """Print ``message`` in one line and exit 2."""
        self.exit(2, f'{self.prog}: error: {message}\n')


def count(text):
    """Return a count >= 0 (ValueError otherwise)."""
    value = int(text)
    if value < 0:
        raise ValueError(text)
    return value


def seconds(text):
    """Return a duration > 0 s (ValueError otherwise)."""
    value = float(text)
    if not value > 0:
        raise ValueError(text)
    return value


def bench(restarts, seed, first_timeout_s, tmp):
    """Run the lives, the modes in turn; return {mode: [Verdict]} and the driver's exit code."""
    import numpy as np
    from restart_rig import judge, MODES, Probe, Restarter

    rng = np.random.default_rng(seed)
    probe = Probe()
    driver = Restarter(probe, tmp, 'best_effort', seed=seed)
    comps = {mode: Restarter(probe, tmp, mode, seed=seed) for mode in MODES}
    try:
        driver.start_driver()
        for mode, comp in comps.items():     # the first start: not a restart, not counted
            comp.life(0.5, first_timeout_s)
        for _ in range(restarts):
            for comp in comps.values():
                comp.life(float(rng.uniform(0.5, 3.0)), first_timeout_s)
    finally:
        code = driver.close()
        probe.close()
    inputs = probe.input_stamps()
    return {mode: [judge(run, inputs) for run in comp.runs[1:]]
            for mode, comp in comps.items()}, code


def main():
    """Run the restarts and print one line per mode."""
    parser = _Parser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--restarts', type=count, default=30, help='restarts per mode')
    parser.add_argument('--hogs', type=count, default=0, help='busy processes beside it')
    parser.add_argument('--seed', type=int, default=0, help='life lengths and the simulator')
    parser.add_argument('--first-timeout', type=seconds, default=30.0,
                        help='longest wait for a first output [s]; none by then: not resumed')
    args = parser.parse_args()
    sys.path[:0] = [str(ROOT), str(ROOT / 'test' / 'support')]
    import ros_domain
    domain, _ = ros_domain.run_domain(os.environ.get('ROS_DOMAIN_ID'), os.getpid())
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    from cpu_load import cpu_hogs
    from restart_rig import RATE_HZ
    start = time.monotonic()
    with cpu_hogs(args.hogs), tempfile.TemporaryDirectory() as tmp:
        verdicts, code = bench(args.restarts, args.seed, args.first_timeout, Path(tmp))
    print(f'{args.hogs} hogs, seed {args.seed}, driver at {RATE_HZ:g} Hz; driver exit '
          f'{code}; {time.monotonic() - start:.0f} s')
    for mode, vs in verdicts.items():
        firsts = [v.first_output_s for v in vs if v.resumed]
        median = f'{statistics.median(firsts):.2f}' if firsts else '-'
        worst = f'{max(firsts):.2f}' if firsts else '-'
        loaded = [v.loaded_s for v in vs if v.loaded_s == v.loaded_s]
        loads = (f'{statistics.median(loaded):.2f} s, worst {max(loaded):.2f} s' if loaded
                 else '-')
        answered, lost = sum(v.answered for v in vs), sum(v.lost for v in vs)
        print(f'{mode}: {len(vs)} restarts, {sum(v.resumed for v in vs)} resumed, first output '
              f'median {median} s, worst {worst} s (model loaded: median {loads}); '
              f'lost while running {lost} of '
              f'{answered + lost}; unmatched {sum(v.unmatched for v in vs)}, duplicated '
              f'{sum(v.duplicated for v in vs)}, non-finite {sum(v.nonfinite for v in vs)}, '
              f'unclean stops {sum(not v.clean for v in vs)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
