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
A real compensator_node fed at a steady rate: in, out, lost, and what it said about it.

The node is its own process (``python -m gyro_tdc.nodes.compensator_node``: its main(), the
EventsExecutor); a publisher process sends Imu on a steady schedule at ``--rate`` (driver_node's
QoS: reliable, keep last 100; stamps ``1/rate`` apart, or a 5 Hz day replayed for ``learn``)
with 10 Hz temperatures (1 Hz of stamps in the replay); this process drains
``imu/data_compensated`` and ``/diagnostics`` on an executor in its own thread. Per case it
prints what was sent, what came out, what was lost (by sequence number), and the node's own
figures: messages in, ``input missing`` (by stamp), ``input lost`` (DDS), the largest
``queue age max s``, callback median and max, its CPU, and every WARN it published. Cases:
``small`` (a 12-centre dT, dT2 model), ``dtdt10k`` (a valid 10,000-centre dTdt model: its
per-sample cost is about the 2 kHz budget) and ``learn`` (``learn:=true``, no model, a
learn_file: a 5 Hz vehicle day replayed at 2,000 msg/s, still and moving, so windows end, fits
run and the state is saved about twice a second). ``--hog N`` adds N busy-looping processes
competing for the cores; ``--tree`` runs the node of another source tree::

    .venv/bin/python bench/bench_node_rate.py                      # ~1.5 min
    .venv/bin/python bench/bench_node_rate.py --cases learn --hog 1 --repeats 3
    git worktree add /tmp/before HEAD~3      # any older tree: the same cases, its node
    .venv/bin/python bench/bench_node_rate.py --cases learn --hog 1 --tree /tmp/before
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 60))

import argparse  # noqa: E402, I100
import math  # noqa: E402
from pathlib import Path  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for _p in (ROOT, ROOT / 'test' / 'support'):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from cpu_load import cpu_hogs  # noqa: E402

T0 = 1_700_000_000.0
#: This run's namespace: another run on the domain (or any other /bench node) is not heard.
NS = f'/bench_{os.getpid()}'
CASES = ('small', 'dtdt10k', 'learn')
#: The learn case's stamps: a 5 Hz IMU (a vehicle day replayed far faster than real time).
LEARN_STEP_S = 0.2


# -- the publisher (a child process) --------------------------------------------------


def publisher_main(ns: str, rate: float, count: int, step: float, learn: bool) -> int:
    """Publish ``count`` Imu at ``rate`` in namespace ``ns`` once stdin says ``go``."""
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu, Temperature
    import numpy as np
    rclpy.init()
    node = rclpy.create_node('bench_publisher', namespace=ns)
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                     reliability=ReliabilityPolicy.RELIABLE)
    imu_pub = node.create_publisher(Imu, 'imu/data_raw', qos)
    temp_pub = node.create_publisher(Temperature, 'imu/temperature', qos)
    deadline = time.monotonic() + 30.0
    while (imu_pub.get_subscription_count() < 1 or temp_pub.get_subscription_count() < 1) \
            and time.monotonic() < deadline:
        time.sleep(0.01)  # discovery, polled with a deadline
    print('matched', flush=True)
    if sys.stdin.readline().strip() != 'go':
        return 1
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((count, 3))
    msg = Imu()
    msg.header.frame_id = 'imu_link'
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
    msg.angular_velocity_covariance[8] = 1e-6
    msg.linear_acceleration.z = 9.81
    msg.linear_acceleration_covariance[0] = -1.0 if learn else 1e-3
    temp = Temperature()
    temp.header.frame_id = 'imu_link'
    temp.variance = 1e-4
    # 10 Hz of stamps live; 1 Hz in the replay (400 readings a second at 2,000 msg/s)
    temp_every = max(1, int(round((1.0 if learn else 0.1) / step)))
    span = count * step
    start = time.monotonic()
    late_max = 0.0
    for k in range(count):
        due = start + k / rate
        now = time.monotonic()
        if due > now:
            time.sleep(due - now)        # pacing of the producer, not a wait for the node
        else:
            late_max = max(late_max, now - due)
        t = T0 + k * step
        temp_c = 20.0 + 10.0 * (t - T0) / span
        if k % temp_every == 0:
            temp.header.stamp.sec, temp.header.stamp.nanosec = divmod(int(round(t * 1e9)),
                                                                      10 ** 9)
            temp.temperature = temp_c
            temp_pub.publish(temp)
        moving = learn and (t - T0) % 330.0 >= 300.0      # 300 s still, 30 s moving
        scale = 0.3 if moving else 1e-4
        bias = 1e-3 * (temp_c - 20.0)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(round(t * 1e9)), 10 ** 9)
        w = msg.angular_velocity
        w.x = 0.01 + bias + scale * noise[k, 0]
        w.y = -0.02 + scale * noise[k, 1]
        w.z = 0.005 + scale * noise[k, 2]
        msg.orientation.x = float(k)
        imu_pub.publish(msg)
    print(f'published {count} {time.monotonic() - start:.3f} {late_max:.4f}', flush=True)
    sys.stdin.read()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


# -- the drain (this process, its own executor thread) --------------------------------


class Drain:
    """Take every output and every /diagnostics status of the node, on an executor thread."""

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from gyro_tdc.nodes.executors import make_executor
        from rclpy.context import Context
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('bench_drain', namespace=NS, context=self.context)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20000,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.seq: list[int] = []
        self.status: list = []
        self.node.create_subscription(Imu, 'imu/data_compensated', self._on_imu, qos)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)
        self.executor = make_executor('events', self.context)
        self.executor.add_node(self.node)
        self._halt = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_imu(self, msg):
        self.seq.append(int(msg.orientation.x))

    def _on_diag(self, msg):
        self.status.extend(s for s in msg.status if s.name.startswith(f'{NS}/')
                           and 'gyro compensation' in s.name)

    def _spin(self):
        while not self._halt.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def matched(self):
        return self.node.count_publishers('imu/data_compensated') >= 1

    def close(self):
        import rclpy
        self._halt.set()
        self.thread.join(5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# -- one case ---------------------------------------------------------------------------


def wait(predicate, timeout_s, what):
    """Poll ``predicate`` (another thread's state) until true, or fail naming ``what``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f'{what} not within {timeout_s:g} s')
        time.sleep(0.05)


def node_args(case: str, tmp: Path, models: dict) -> list[str]:
    """Return the compensator_node --ros-args of ``case``."""
    args = ['-r', f'__ns:={NS}', '-p', 'temperature_timeout:=5.0']
    if case == 'learn':
        return args + ['-p', 'learn:=true', '-p', f'learn_file:={tmp / "learn.json"}']
    return args + ['-p', f'model_file:={models[case]}']


def run_case(case: str, args, tmp: Path, models: dict) -> dict:
    """Feed one node for ``--duration`` s at ``--rate``; return the figures."""
    import psutil
    count = int(args.rate * args.duration)
    step = LEARN_STEP_S if case == 'learn' else 1.0 / args.rate
    drain = Drain()
    env = dict(os.environ)
    if args.tree:                       # the node of another source tree (old code)
        env['PYTHONPATH'] = str(Path(args.tree).resolve())
    node = subprocess.Popen([sys.executable, '-m', 'gyro_tdc.nodes.compensator_node',
                             '--ros-args', *node_args(case, tmp, models)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env, cwd=args.tree or ROOT)   # python -m: cwd first on path
    log: list[str] = []
    threading.Thread(target=lambda: log.extend(node.stdout), daemon=True).start()
    pub = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), '--publisher', NS,
                            str(args.rate), str(count), repr(step), str(int(case == 'learn'))],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(pub.stdout), daemon=True).start()
    try:
        wait(lambda: any('matched' in x for x in lines) and drain.matched(), 60.0,
             'discovery')
        wait(lambda: drain.status, 10.0, 'a first /diagnostics report')
        reports0 = len(drain.status)
        time.sleep(1.0)      # both ends of every match settled: nothing lost to discovery
        proc = psutil.Process(node.pid)
        cpu0 = sum(proc.cpu_times()[:2])
        pub.stdin.write('go\n')
        pub.stdin.flush()
        wait(lambda: any(x.startswith('published') for x in lines), args.duration * 3 + 60,
             'the publisher')
        cpu_s = sum(proc.cpu_times()[:2]) - cpu0
        last, quiet = -1, time.monotonic()
        while time.monotonic() - quiet < 2.0:      # drained: nothing new for 2 s
            time.sleep(0.1)
            if len(drain.seq) != last:
                last, quiet = len(drain.seq), time.monotonic()
        n = len(drain.status)
        wait(lambda: len(drain.status) >= n + 2, 10.0, 'two more reports')
    finally:
        pub.stdin.close()
        pub.wait(timeout=30)
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=30)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait()
        drain.close()
    published = next(x for x in lines if x.startswith('published')).split()
    reports = drain.status[reports0:]
    final = {kv.key: kv.value for kv in reports[-1].values}
    per = [{kv.key: kv.value for kv in s.values} for s in reports]

    def top(key):
        vals = [float(v[key]) for v in per if v.get(key)]
        return max(vals) if vals else math.nan

    warns = []
    for s in reports:
        if s.level[0] >= 1:
            for part in s.message.split('; '):
                head = part.split(' (')[0].split(': a sample')[0].split(': ')[0]
                if head not in warns:
                    warns.append(head)
    got = set(drain.seq)
    gone = sorted(set(range(count)) - got)
    ranges = []                            # the sequence numbers lost, as [first, last] runs
    for k in gone:
        if ranges and ranges[-1][1] == k - 1:
            ranges[-1][1] = k
        else:
            ranges.append([k, k])
    return {'case': case, 'hog': args.hog, 'sent': count, 'out': len(drain.seq),
            'lost': count - len(got), 'node_in': int(final['messages in']),
            'node_out': int(final['messages out']),
            'missing': int(final.get('input missing', '0')),
            'dds_lost': int(final['input lost']),
            'age_max_s': top('queue age max s'), 'cb_median_us': top('callback median us'),
            'cb_max_us': top('callback max us'), 'load_max': top('callback load %'),
            'warn': warns, 'publish_s': float(published[2]), 'node_cpu_s': cpu_s,
            'late_s': float(published[3]),
            'log_errors': sum(1 for x in log if '[ERROR]' in x), 'lost_runs': ranges}


def make_models(tmp: Path) -> dict:
    """Fit the small model; make the 10,000-centre dTdt model from a fitted one (both valid)."""
    import numpy as np
    from gyro_tdc.identify import fit_model
    from gyro_tdc.model.modelfile import save_model
    from gyro_tdc.nodes.compensator_node import read_model
    from gyro_tdc.sim import simulate_run, to_run
    run = to_run(simulate_run('demo_fast', seed=0))
    small = save_model(fit_model([run], features=('dT', 'dT2'), n_centers=12),
                       tmp / 'small.yaml')
    base = fit_model([run], features=('dT', 'dT2', 'dTdt'), n_centers=10, fit_params=False)
    k = 10_000
    rng = np.random.default_rng(0)
    pick = rng.integers(0, base.centers.shape[0], k)
    big = base.replace(
        centers=base.centers[pick] + 0.01 * rng.standard_normal((k, base.centers.shape[1])),
        widths=base.widths[pick], weights=base.weights[pick] / (k / base.centers.shape[0]))
    path = save_model(big, tmp / 'dtdt10k.yaml')
    read_model(str(path))                           # valid: the node's loader accepts it
    return {'small': small, 'dtdt10k': path}


def main(argv=None) -> int:
    """Run the cases asked for and print the figures; return the exit status."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--cases', default=','.join(CASES))
    p.add_argument('--rate', type=float, default=2000.0, help='messages per second')
    p.add_argument('--duration', type=float, default=10.0, help='seconds per case')
    p.add_argument('--hog', type=int, default=0, help='busy-looping processes competing')
    p.add_argument('--tree', help='run the node of this source tree (e.g. a git worktree of '
                   'older code: its figures without the keys it does not publish)')
    p.add_argument('--repeats', type=int, default=1, help='runs of each case')
    p.add_argument('--publisher', nargs=5, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.publisher:
        ns, rate, count, step, learn = args.publisher
        return publisher_main(ns, float(rate), int(count), float(step), learn == '1')
    print(f'bench_node_rate: node of {args.tree or ROOT}, '
          f'{args.rate:g} msg/s for {args.duration:g} s per case, '
          f'{args.hog} CPU hog(s), {os.cpu_count()} CPUs, ROS_DOMAIN_ID '
          f'{os.environ["ROS_DOMAIN_ID"]}', flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        models = make_models(Path(tmp))
        with cpu_hogs(args.hog):
            for case in [c for _ in range(args.repeats) for c in args.cases.split(',')]:
                row = run_case(case, args, Path(tmp), models)
                rows.append(row)
                print(f'  {case:8s} hog {row["hog"]}: sent {row["sent"]} (in '
                      f'{row["publish_s"]:.2f} s, publisher late up to {row["late_s"]:.3f} s), '
                      f'out {row["out"]}, lost {row["lost"]}; node: in {row["node_in"]}, '
                      f'out {row["node_out"]}, input missing {row["missing"]}, input lost '
                      f'(DDS) {row["dds_lost"]}, queue age max {row["age_max_s"]:.3f} s, '
                      f'callback median {row["cb_median_us"]:.0f} us max '
                      f'{row["cb_max_us"]:.0f} us, load up to {row["load_max"]:.0f} %, node '
                      f'CPU {100 * row["node_cpu_s"] / row["publish_s"]:.0f} % of a core, '
                      f'ERROR log lines {row["log_errors"]}', flush=True)
                if row['lost_runs']:
                    runs = ', '.join(f'{a}..{b}' for a, b in row['lost_runs'][:6])
                    more = len(row['lost_runs']) - 6
                    print(f'           lost sequence numbers: {runs}'
                          + (f' and {more} more runs' if more > 0 else ''), flush=True)
                for w in row['warn']:
                    print(f'           WARN {w}', flush=True)
    print('\ncase      hog     sent      out     lost  node in  missing  DDS lost  unreported'
          '  age max s')
    for r in rows:
        unreported = max(0, r['lost'] - r['missing'] - r['dds_lost'])
        print(f'{r["case"]:8s} {r["hog"]:4d} {r["sent"]:8d} {r["out"]:8d} {r["lost"]:8d} '
              f'{r["node_in"]:8d} {r["missing"]:8d} {r["dds_lost"]:9d} {unreported:11d} '
              f'{r["age_max_s"]:10.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
