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
What learning adds to the compensator's per-message cost at 1 kHz.

A synthetic 1 kHz stream (``--minutes`` of it: still 2 min, moving 30 s, the temperature
between 15 and 20 degC at 1 degC a minute, a thermometer at 1 Hz, an accelerometer in every
sample) goes through :class:`gyro_tdc.runtime.core.CompensatorCore` with a static
``dT, dT2`` model, one message at a time, twice per trial (ABBA over ``--trials``): plain,
and with a :class:`gyro_tdc.learn.learner.Learner` attached, stepped every 100 messages
(:meth:`~gyro_tdc.runtime.core.CompensatorCore.learn_step`: the node's 0.1 s timer at
1 kHz), its swapped models scheduled and installed at their stamps. Printed side by side,
per message (median over trials): the plain core; the learning core's message path (the
append); and its total with the timer's work amortised
over the messages (the still test, binning, refits, installs). Then the same at the node:
``compensator_node``'s IMU callback (``raw_cdr``: the serialized message patched and
published, no subscriber) called directly on the serialized stream, with ``learn`` off and
on (its learner timer callback run every 100 messages and counted), which is the
compensator's per-message cost the issue bounds (10 %). Last, the cost of one learned-model
swap on the thread that compensates (:meth:`~gyro_tdc.runtime.core.CompensatorCore.schedule`,
due at once) in a core whose thermometer history is full (3 h at 1 Hz): a static model
(``dT, dT2``, what the learner fits) as installed now, beside the replay of the history
every swap did before (``prepare`` over the full history, then ``install``), and a model
with time terms (lag, warm-up), which replays at most ``HISTORY_LENGTH`` readings. Times
are this process's CPU time (``time.process_time``: other load on the host does not
count)::

    .venv/bin/python bench/bench_learning.py                 # ~1 min
    .venv/bin/python bench/bench_learning.py --minutes 20 --trials 5
"""

import argparse
import gc
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.learn.learner import learned_model, Learner  # noqa: E402
from gyro_tdc.runtime import CompensatorCore, Policy  # noqa: E402
import numpy as np  # noqa: E402

RATE = 1000.0
STEP = 100              # messages between learner steps: the node's 0.1 s timer at 1 kHz
MODEL = learned_model(np.array([[0.01, 0.0, 0.0], [1e-3, 0, 0], [1e-6, 0, 0]]), ('dT', 'dT2'),
                      20.0, (0.0, 60.0), np.full(3, 1e-6))


def make_stream(minutes: float, seed: int = 0):
    """Return stamps, rates, accelerations (lists) and the thermometer (lists)."""
    rng = np.random.default_rng(seed)
    n = int(minutes * 60 * RATE)
    t = np.arange(n) / RATE
    temp = _temp(t)
    moving = (t % 150.0) >= 120.0
    bias = 0.01 + 1e-3 * (temp - 20.0)
    w = 1e-3 * rng.standard_normal((n, 3)) + bias[:, None]
    w[moving] += 0.3 * rng.standard_normal((int(moving.sum()), 3))
    a = np.array([0.0, 0.0, 9.81]) + 0.01 * rng.standard_normal((n, 3))
    a[moving] += 0.5 * rng.standard_normal((int(moving.sum()), 3))
    tt = np.arange(0.0, t[-1] + 1.0, 1.0)
    return t.tolist(), w.tolist(), a.tolist(), tt.tolist(), _temp(tt).tolist()


def _temp(t):
    """Return the temperature: 15 -> 20 degC and back, 1 degC a minute."""
    return 15.0 + 5.0 - np.abs((t / 60.0) % 10.0 - 5.0)


def run(stream, learn: bool) -> tuple[float, float, float]:
    """Stream once; return s/message total, s/message in steps, swaps."""
    t, w, a, tt, tc = stream
    core = CompensatorCore(Policy(), MODEL)
    learner = Learner() if learn else None
    core.learner = learner
    j, m = 0, len(tt)
    step_s = 0.0
    process, add = core.process, core.add_temperature
    gc.collect()
    t0 = time.process_time()
    for k, (ts, wi, ai) in enumerate(zip(t, w, a)):
        while j < m and tt[j] <= ts:
            add(tt[j], tc[j])
            j += 1
        process(ts, wi[0], wi[1], wi[2], ai)
        if learner is not None and k % STEP == STEP - 1:
            s0 = time.process_time()
            core.learn_step()
            step_s += time.process_time() - s0
    total = time.process_time() - t0
    return total / len(t), step_s / len(t), 0 if learner is None else learner.swaps


def run_node(stream, learn: bool, model_file: str, context) -> float:
    """Call compensator_node's raw IMU callback over the stream; return s/message."""
    from gyro_tdc.nodes.compensator_node import CompensatorNode
    from rclpy.parameter import Parameter
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu, Temperature

    t, w, a, tt, tc = stream
    node = CompensatorNode(context=context, parameter_overrides=[
        Parameter('model_file', value=model_file), Parameter('learn', value=learn)])
    try:
        data = []
        for ts, wi, ai in zip(t, w, a):
            m = Imu()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(round(ts * 1e9)), 10 ** 9)
            m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = wi
            m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = ai
            data.append(serialize_message(m))
        temps = []
        for ts, c in zip(tt, tc):
            m = Temperature()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(round(ts * 1e9)), 10 ** 9)
            m.temperature = c
            temps.append(m)
        on_imu, on_temp = node._on_imu_raw, node._on_temperature
        on_learn = node.learning.on_timer if learn else None
        j, m = 0, len(tt)
        gc.collect()
        t0 = time.process_time()
        for k, (ts, d) in enumerate(zip(t, data)):
            while j < m and tt[j] <= ts:
                on_temp(temps[j])
                j += 1
            on_imu(d)
            if on_learn is not None and k % STEP == STEP - 1:
                on_learn()
        return (time.process_time() - t0) / len(t)
    finally:
        node.destroy_node()


def bench_node(stream, trials: int) -> tuple[float, float] | None:
    """Return the node's median s/message, plain and learning (None: no ROS here)."""
    try:
        import rclpy
        from rclpy.context import Context
    except ImportError:
        return None
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    from gyro_tdc.model.modelfile import save_model
    context = Context()
    rclpy.init(context=context, args=['--ros-args', '--log-level', 'error'])
    plain, learn = [], []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            path = str(save_model(MODEL, Path(tmp) / 'model.yaml'))
            for i in range(trials):
                for flag in ((False, True) if i % 2 == 0 else (True, False)):
                    (learn if flag else plain).append(run_node(stream, flag, path, context))
    finally:
        context.try_shutdown()
    return statistics.median(plain), statistics.median(learn)


def bench_swap(trials: int) -> dict[str, float]:
    """Return the median CPU s of one swap: static now, static as before, with time terms."""
    from gyro_tdc.identify import fit_model
    from gyro_tdc.runtime.priming import prepare
    sys.path.insert(0, str(ROOT / 'test' / 'support'))
    from synth import synth_run
    timed = fit_model([synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)],
                      features=('dT', 'dT2', 'lag', 'warmup'), n_centers=6, fit_params=False)
    other = learned_model(np.array([[0.02, 0.0, 0.0], [9e-4, 0, 0], [2e-6, 0, 0]]),
                          ('dT', 'dT2'), 20.0, (0.0, 60.0), np.full(3, 1e-6))
    core = CompensatorCore(Policy(reanchor_on_start=False), MODEL)
    for k in range(3 * 3600):
        core.add_temperature(k - 0.25, 15.0 + 10.0 * k / 10800.0)
        core.process(float(k), 0.01, 0.0, 0.0)
    got: dict[str, list[float]] = {'static now': [], 'static before': [], 'time terms': []}
    for i in range(trials):
        for name in ('static now', 'static before', 'time terms'):
            model = other if i % 2 else MODEL        # a different model every swap
            c0 = time.process_time()
            if name == 'static now':
                core.schedule(model, None)
            elif name == 'static before':
                core.install(prepare(model, core.policy, core.priming()))
            else:
                core.schedule(timed, None)
            got[name].append(time.process_time() - c0)
    return {k: statistics.median(v) for k, v in got.items()}


def main(argv=None) -> int:
    """Print plain vs learn per-message cost."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    p.add_argument('--minutes', type=float, default=5.0, help='stream length (default 5)')
    p.add_argument('--trials', type=int, default=3, help='ABBA trials (default 3)')
    args = p.parse_args(argv)
    if not (args.minutes > 0 and args.trials > 0):
        print('bench_learning: error: --minutes and --trials must be > 0', file=sys.stderr)
        return 2
    stream = make_stream(args.minutes)
    plain, learn, steps, swaps = [], [], [], 0
    for i in range(args.trials):
        order = (False, True) if i % 2 == 0 else (True, False)
        for flag in order:
            per, step, sw = run(stream, flag)
            if flag:
                learn.append(per)
                steps.append(step)
                swaps = sw
            else:
                plain.append(per)
    p_us = statistics.median(plain) * 1e6
    l_us = statistics.median(learn) * 1e6
    s_us = statistics.median(steps) * 1e6
    print(f'{len(stream[0])} messages at 1 kHz ({args.minutes:g} min), {args.trials} trials, '
          f'median per message; the learner swapped models {swaps} times')
    print(f'  {"":<36}{"us/msg":>10}{"vs plain":>10}')
    print(f'  {"plain CompensatorCore.process":<36}{p_us:>10.3f}{"":>10}')
    print(f'  {"learn: message path (append)":<36}{l_us - s_us:>10.3f}'
          f'{100 * (l_us - s_us - p_us) / p_us:>+9.1f}%')
    print(f'  {"learn: total (timer amortised)":<36}{l_us:>10.3f}'
          f'{100 * (l_us - p_us) / p_us:>+9.1f}%')
    node = bench_node(stream, args.trials)
    if node is None:
        print('  (no rclpy here: the node figures are skipped)')
    else:
        np_us, nl_us = node[0] * 1e6, node[1] * 1e6
        print(f'  {"compensator_node callback, plain":<36}{np_us:>10.3f}')
        print(f'  {"compensator_node callback, learn":<36}{nl_us:>10.3f}'
              f'{100 * (nl_us - np_us) / np_us:>+9.1f}%')
    swap = bench_swap(max(args.trials, 5))
    print(f'one learned-model swap on the compensating thread, history full '
          f'({CompensatorCore.HISTORY_LENGTH} readings), median CPU ms:')
    print(f'  static model, now (no replay)      {swap["static now"] * 1e3:10.3f}')
    print(f'  static model, before (replay)      {swap["static before"] * 1e3:10.3f}'
          f'   ({swap["static before"] / max(swap["static now"], 1e-9):.0f}x)')
    print(f'  lag + warm-up model (replay)       {swap["time terms"] * 1e3:10.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
