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
Fleet on Dask: 32 sensors, 1 h at 100 Hz each, with 1 and 2 local worker processes.

Writes (once, cached in ``--data``) a train and a test bag per sensor with
:func:`gyro_tdc.data.write_bag`: a chamber cycle (soak 20 degC, heat to 60 at 1.5 degC/min,
hold, cool), drift slopes and curvatures spread by 10 % between units, white noise
0.03 deg/s/sqrt(Hz). Then measures

* ``train alone``: :func:`gyro_tdc.identify.train.train` on one sensor's train bag plus
  :func:`gyro_tdc.evaluate.score.evaluate` on its test bag, in this process (median of
  ``--repeat`` sensors): the work a fleet task does, without Dask;
* ``plain processes``: the same, over ``2 * --repeat`` sensors in a plain two-process pool
  (no Dask), one after the other and two at a time: what this machine gives a second process
  at that moment, the ceiling of the fleet's speed-up;
* ``paired``: the same ``2 * --repeat`` sensors two at a time, alternately in that plain pool
  and in a two-worker fleet, ``--rounds`` times (both see the same load): the fleet's cost
  against plain processes, free of the load drifting between measurements;
* ``fleet``: :func:`gyro_tdc.fleet.run_fleet` over every sensor (``force``, a fresh output
  folder) on an embedded ``LocalCluster`` with each worker count of ``--workers``, wall time
  including the cluster's start and stop;

and prints the wall times (cluster start, run, stop), the speed-up between the first two
worker counts, the run time per sensor, the mean task time on a worker and the per-sensor
overhead of the fleet over ``train alone`` (1 worker). The figures feed doc/benchmarks.md's
10,000-sensor estimate::

    .venv/bin/python bench/bench_fleet.py                        # 32 sensors, 1 h, 100 Hz
    .venv/bin/python bench/bench_fleet.py --sensors 4 --hours 0.1  # a quick run
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import argparse  # noqa: E402, I100
from pathlib import Path  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

DEG = np.pi / 180.0


def _profile_c(t, duration):
    """Chamber cycle (degC) scaled to ``duration`` s: soak 20, heat to 60, hold, cool to 27."""
    k = duration / 3600.0
    return np.interp(t, np.array([0.0, 300.0, 1900.0, 2300.0, 3600.0]) * k,
                     [20.0, 20.0, 60.0, 60.0, 27.0])


def make_sensor_bag(path, *, unit, seed, hours, rate_hz):
    """
    Write one bag of a simulated unit (IMU at ``rate_hz``, thermometer at 1 Hz).

    Parameters
    ----------
    path : Path
        Bag directory to create.
    unit : dict
        ``a1`` (deg/s/degC) and ``a2`` (deg/s/degC^2) per axis, ``b0`` (deg/s).
    seed : int
        Noise seed.
    hours : float
        Duration.
    rate_hz : float
        IMU rate.

    """
    from gyro_tdc.data import write_bag
    from gyro_tdc.model.effects import first_order_lag

    rng = np.random.default_rng(seed)
    duration = hours * 3600.0
    n = int(round(duration * rate_hz))
    t = np.arange(n) / rate_hz
    t_temp = np.arange(int(duration) + 1, dtype=np.float64)
    package = first_order_lag(t_temp, _profile_c(t_temp, duration), 120.0)
    reading = np.round((package + rng.normal(0, 0.01, package.shape)) / 0.03) * 0.03
    d = np.interp(t, t_temp, package) - 25.0
    gyro = (unit['b0'] + d[:, None] * unit['a1'] + d[:, None] ** 2 * unit['a2']) * DEG
    gyro += rng.normal(0.0, 0.03 * np.sqrt(rate_hz) * DEG, size=gyro.shape)
    accel = np.zeros((n, 3))
    accel[:, 2] = 9.80665
    write_bag(path, imu_t=t + 1.0, gyro=gyro, accel=accel, temp_t=t_temp + 1.0,
              temp_c=reading)


def make_fleet(data, *, sensors, hours, rate_hz):
    """Write (or reuse) every sensor's bags under ``data``; return the manifest path."""
    data.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2026)
    rows = ['sensor_id,train,test']
    written = 0
    start = time.perf_counter()
    for i in range(sensors):
        sid = f'imu-{i:04d}'
        unit = {'a1': np.array([0.02, -0.015, 0.01]) * (1 + 0.1 * rng.standard_normal(3)),
                'a2': np.array([2e-4, 1.5e-4, -1e-4]) * (1 + 0.1 * rng.standard_normal(3)),
                'b0': rng.normal(0.0, 0.5, 3)}
        for j, kind in enumerate(('train', 'test')):
            bag = data / sid / kind
            if not (bag / 'metadata.yaml').exists():
                shutil.rmtree(bag, ignore_errors=True)
                make_sensor_bag(bag, unit=unit, seed=2 * i + j, hours=hours, rate_hz=rate_hz)
                written += 1
        rows.append(f'{sid},{sid}/train,{sid}/test')
    manifest = data / 'manifest.csv'
    manifest.write_text('\n'.join(rows) + '\n')
    if written:
        print(f'wrote {written} bag(s) in {time.perf_counter() - start:.0f} s under {data}')
    return manifest


def train_alone(spec, options, out):
    """Train and evaluate one sensor in this process, as a fleet task does; return seconds."""
    from gyro_tdc.data import BagOptions
    from gyro_tdc.evaluate.score import evaluate, NamedModel
    from gyro_tdc.identify.train import train

    start = time.perf_counter()
    result = train(list(spec.train), out, options, BagOptions())
    evaluate(list(spec.test), [NamedModel(str(out), spec.sensor_id, result.model)],
             bag=BagOptions())
    return time.perf_counter() - start


def _warm():
    """Import what a task needs (so that a pool's timing excludes the imports)."""
    import gyro_tdc.evaluate.score  # noqa: F401
    import gyro_tdc.identify.train  # noqa: F401


def plain_processes(specs, options, tmp):
    """
    Return the seconds of :func:`train_alone` over ``specs``: one after the other, two at a time.

    Both in two already started, already warm worker processes of a plain
    ``ProcessPoolExecutor`` (no Dask): the capacity of this machine for a second process.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context('spawn')) as pool:
        list(pool.map(_warm_wait, [0.5, 0.5]))
        start = time.perf_counter()
        for s in specs:
            pool.submit(train_alone, s, options, tmp / f'seq_{s.sensor_id}.yaml').result()
        t_seq = time.perf_counter() - start
        start = time.perf_counter()
        list(pool.map(train_alone, specs, [options] * len(specs),
                      [tmp / f'par_{s.sensor_id}.yaml' for s in specs]))
        t_par = time.perf_counter() - start
    return t_seq, t_par


def paired(specs, options, tmp, rounds):
    """
    Alternate a plain two-process pool and a two-worker fleet on the same sensors.

    Both are started and warm before the first round; each round times the pool, then the
    fleet, on ``specs``, so that both see the same load of a shared machine. Returns the
    seconds per round of each.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from gyro_tdc.fleet import open_engine, run_fleet

    plain, fleet = [], []
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context('spawn')) as pool, \
            open_engine(workers=2) as engine:
        list(pool.map(_warm_wait, [0.5, 0.5]))
        engine.client.run(_warm)
        for r in range(rounds):
            start = time.perf_counter()
            list(pool.map(train_alone, specs, [options] * len(specs),
                          [tmp / f'pair{r}_{s.sensor_id}.yaml' for s in specs]))
            plain.append(time.perf_counter() - start)
            start = time.perf_counter()
            run_fleet(specs, tmp / f'pair{r}', options, engine, force=True)
            fleet.append(time.perf_counter() - start)
    return plain, fleet


def _warm_wait(seconds):
    """Warm a pool process and hold it busy a moment, so that both processes get one."""
    _warm()
    time.sleep(seconds)


def main(argv=None):
    """Run the benchmark and print its figures."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--sensors', type=int, default=32)
    p.add_argument('--hours', type=float, default=1.0, help='duration of each bag')
    p.add_argument('--rate-hz', type=float, default=100.0)
    p.add_argument('--workers', default='1,2', help='worker counts to time (default: 1,2)')
    p.add_argument('--repeat', type=int, default=3, help='sensors timed by train alone')
    p.add_argument('--rounds', type=int, default=3,
                   help='alternating rounds of the paired pool / fleet comparison')
    p.add_argument('--data', type=Path, default=None,
                   help='folder of the cached bags (default: under the temporary folder)')
    args = p.parse_args(argv)

    from gyro_tdc.cli.train import build_parser, train_options
    from gyro_tdc.fleet import open_engine, read_manifest, run_fleet

    data = args.data or Path(tempfile.gettempdir()) / (
        f'gyro_tdc_bench_fleet_{args.sensors}x{args.hours:g}h_{args.rate_hz:g}Hz')
    manifest = make_fleet(data, sensors=args.sensors, hours=args.hours, rate_hz=args.rate_hz)
    specs = read_manifest(manifest)
    options = train_options(build_parser().parse_args(['b', '--out', 'm', '--no-progress']))
    n = len(specs)
    samples = int(round(args.hours * 3600 * args.rate_hz))
    print(f'fleet bench: {n} sensors, train + test bag of {args.hours:g} h at '
          f'{args.rate_hz:g} Hz ({samples} IMU messages) each; {os.cpu_count()} CPU(s)')

    with tempfile.TemporaryDirectory(prefix='gyro_tdc_bench_fleet_') as tmp:
        alone = [train_alone(s, options, Path(tmp) / f'{s.sensor_id}.yaml')
                 for s in specs[:max(1, min(args.repeat, n))]]
        t_alone = statistics.median(alone)
        print(f'train alone (train + evaluate, one process): {t_alone:.2f} s per sensor '
              f'(median of {len(alone)})')
        batch = specs[:max(2, min(2 * args.repeat, n))]
        t_seq, t_par = plain_processes(batch, options, Path(tmp))
        print(f'plain processes, no Dask, {len(batch)} sensors: one after the other '
              f'{t_seq:.1f} s, two at a time {t_par:.1f} s: {t_seq / t_par:.2f}x (what this '
              f'machine gives a second process now)')
        plain, fleet = paired(batch, options, Path(tmp), args.rounds)
        print(f'paired, {len(batch)} sensors two at a time, {args.rounds} alternating rounds: '
              f'plain pool {statistics.median(plain):.1f} s, Dask fleet with 2 workers '
              f'{statistics.median(fleet):.1f} s (medians): fleet / plain '
              f'{statistics.median(f / q for f, q in zip(fleet, plain)):.2f}')
        walls, runs, tasks_mean = {}, {}, {}
        for w in [int(x) for x in args.workers.split(',')]:
            t0 = time.perf_counter()
            with open_engine(workers=w) as engine:
                t1 = time.perf_counter()
                result = run_fleet(specs, Path(tmp) / f'out{w}', options, engine, force=True)
                t2 = time.perf_counter()
            t3 = time.perf_counter()
            walls[w], runs[w] = t3 - t0, t2 - t1
            tasks = [s.seconds for s in result.sensors if s.status == 'ok']
            tasks_mean[w] = statistics.mean(tasks)
            print(f'fleet, {w} worker(s): {t3 - t0:.1f} s wall = {t1 - t0:.1f} s cluster start '
                  f'+ {t2 - t1:.1f} s run + {t3 - t2:.1f} s stop; {(t2 - t1) / n:.2f} s of run '
                  f'per sensor; mean task {statistics.mean(tasks):.2f} s on a worker; '
                  f'{len(result.failed)} failed')
    counts = sorted(walls)
    if len(counts) >= 2:
        a, b = counts[:2]
        print(f'speed-up {a} -> {b} workers: {walls[a] / walls[b]:.2f}x wall, '
              f'{runs[a] / runs[b]:.2f}x run')
    if 1 in runs:
        per = runs[1] / n
        print(f"Dask's own cost per sensor (1 worker: run per sensor - mean task): "
              f'{per - tasks_mean[1]:.3f} s')
        print(f'per-sensor overhead of the fleet (1 worker, run time per sensor) over train '
              f'alone: {per - t_alone:+.2f} s ({per / t_alone - 1:+.0%})')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
