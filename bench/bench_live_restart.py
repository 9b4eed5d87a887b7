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
Restart a learning compensator again and again inside test_field_live's rig: lost streams.

The rig is test_field_live's ``Live``: a feeder, a learning compensator (``learn:=true``,
reliable input) and a draining subscriber on one executor, in one process. Each restart
destroys the compensator, starts a new one resuming its learn_file and streams the next
``--chunk`` messages of vehicle day 1 (seed 1, 2 Hz); it fails when the outputs do not all
come within ``--wait`` s (a failure starts a new rig). ``--hogs`` busy processes load the
machine while it runs (ended at exit), the rig ``--nice`` below them; ``--tree`` takes the
rig from another checkout, to compare with the main branch's.

::

    .venv/bin/python bench/bench_live_restart.py --restarts 300 --hogs 2
    .venv/bin/python bench/bench_live_restart.py --restarts 300 --hogs 2 --tree /work/main
"""

import argparse
import importlib.util
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _rig_module(tree: Path):
    """Return ``tree``'s test/system/test_field_live.py as a module (its support first)."""
    sys.path[:0] = [str(tree / 'test' / 'support')]
    spec = importlib.util.spec_from_file_location(
        'field_live', tree / 'test' / 'system' / 'test_field_live.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def restarts(live_mod, day, n, chunk, wait_s, tmp):
    """Restart and stream ``n`` times; print each failure; return how many failed."""
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration

    live_mod.Live.spin_until.__defaults__ = (wait_s,)
    context = Context()
    rclpy.init(context=context)
    live, pos, failed = live_mod.Live(context, tmp / 'rig0.json'), 0, 0
    try:
        for k in range(n):
            if pos + chunk > len(day[0]):
                live.close()
                live, pos = live_mod.Live(context, tmp / f'rig{k}.json'), 0
            live.stop()
            live.start()
            try:
                live.stream(day, start=pos, stop=pos + chunk)
                pos += chunk
            except AssertionError as exc:
                failed += 1
                acked = live.imu_pub.wait_for_all_acked(Duration(seconds=5.0))
                print(f'restart {k + 1}: {exc}; the feeder IMU writer acknowledged: {acked}',
                      flush=True)
                live.close()
                live, pos = live_mod.Live(context, tmp / f'rig{k}.json'), 0
    finally:
        live.close()
        rclpy.try_shutdown(context=context)
    return failed


def main():
    """Run the restarts and print how many failed."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--restarts', type=int, default=100)
    parser.add_argument('--chunk', type=int, default=400, help='messages after each restart')
    parser.add_argument('--wait', type=float, default=10.0, help='longest wait of a step [s]')
    parser.add_argument('--hogs', type=int, default=0, help='busy processes beside it')
    parser.add_argument('--nice', type=int, default=10, help="the rig's niceness over the hogs'")
    parser.add_argument('--tree', type=Path, default=ROOT, help='checkout of the rig')
    args = parser.parse_args()
    sys.path[:0] = [str(ROOT), str(ROOT / 'test' / 'support')]
    import ros_domain
    domain, _ = ros_domain.run_domain(os.environ.get('ROS_DOMAIN_ID'), os.getpid())
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    live_mod = _rig_module(args.tree.resolve())
    from gyro_tdc.sim import simulate_run
    day = live_mod.serialised(simulate_run('vehicle_day1', seed=1, rate_hz=2.0), 0.0)
    from cpu_load import cpu_hogs
    start = time.monotonic()
    with cpu_hogs(args.hogs), tempfile.TemporaryDirectory() as tmp:
        os.nice(args.nice)  # the rig below the hogs: a starved test, as on a loaded CI runner
        failed = restarts(live_mod, day, args.restarts, args.chunk, args.wait, Path(tmp))
    print(f'{failed} of {args.restarts} restarts failed (rig of {args.tree}, {args.hogs} '
          f'hogs, nice +{args.nice}, {args.chunk} messages each, wait {args.wait:g} s; '
          f'{time.monotonic() - start:.0f} s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
