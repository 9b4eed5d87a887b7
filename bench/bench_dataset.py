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
Benchmark: reading a 1 h, 1 kHz bag (3.6 M Imu + 1 Hz Temperature) vs its raw bytes.

Measured, each in a fresh subprocess (so that every peak RSS is its own), median of
``--repeats`` runs:

- ``raw bytes``: iterate ``AnyReader.messages`` over the two topics, touching ``rawdata``
  only (the physical limit of any reader built on rosbags);
- ``raw bytes, kept``: the same, collecting every ``rawdata`` in a list;
- ``read_bag``: gyro_tdc.data.read_bag (numpy decode of the CDR bytes);
- ``load_run``: gyro_tdc.data.dataset.load_run (read_bag + temperature alignment + checks);
- ``rosbags deserialise``: raw bytes + ``deserialize_cdr`` per message, timed on a subset of
  ``--subset`` messages and extrapolated to the whole bag.

The bag is written once with gyro_tdc.data.write_bag and cached (``--bag`` to choose where).
Run: ``.venv/bin/python bench/bench_dataset.py [--storage mcap] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import resource
import statistics
import subprocess
import sys
import tempfile
import time

# Habit: set before anything that could start DDS is imported (nothing here does).
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MEASURES = ('raw', 'raw_kept', 'read_bag', 'load_run', 'deserialise')
LABELS = {'raw': 'raw bytes', 'raw_kept': 'raw bytes, kept', 'read_bag': 'read_bag',
          'load_run': 'load_run', 'deserialise': 'rosbags deserialise (extrap.)'}
IMU_TOPIC, TEMP_TOPIC = '/imu/data_raw', '/imu/temperature'


def make_bag(path: Path, *, duration_s: float, rate_hz: float, storage: str) -> float:
    """
    Write the benchmark bag (a slowly drifting still gyro and a 1 Hz thermometer).

    Parameters
    ----------
    path : Path
        Bag directory to create.
    duration_s : float, s
        Length of the recording.
    rate_hz : float, Hz
        IMU rate.
    storage : str
        'sqlite3' or 'mcap'.

    Returns
    -------
    float
        Seconds spent writing.

    """
    import numpy as np

    from gyro_tdc.data import write_bag

    rng = np.random.default_rng(0)
    n = int(round(duration_s * rate_hz))
    imu_t = 1.7e9 + np.arange(n) / rate_hz
    temp_t = 1.7e9 + np.arange(int(duration_s) + 1, dtype=np.float64)
    temp_c = 25.0 + 20.0 * np.sin(2 * np.pi * (temp_t - temp_t[0]) / duration_s)
    gyro = 1e-3 * rng.standard_normal((n, 3)) + 1e-4 * np.interp(imu_t, temp_t, temp_c)[:, None]
    accel = np.tile([0.0, 0.0, 9.81], (n, 1)) + 1e-2 * rng.standard_normal((n, 3))
    start = time.perf_counter()
    write_bag(path, imu_t=imu_t, gyro=gyro, accel=accel, temp_t=temp_t, temp_c=temp_c,
              temp_var=1e-4, storage=storage)
    return time.perf_counter() - start


def measure(kind: str, bag: Path, subset: int) -> dict:
    """
    Run one measurement in this process and return its figures.

    Parameters
    ----------
    kind : str
        One of MEASURES.
    bag : Path
        The bag.
    subset : int
        Messages deserialised for the extrapolated rosbags figure.

    Returns
    -------
    dict
        ``seconds`` (wall), ``cpu`` (process CPU time), ``messages`` and ``rss_mb`` (peak
        resident set of this process).

    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    from gyro_tdc.data import BagOptions, read_bag
    from gyro_tdc.data.dataset import load_run

    start, cpu_start = time.perf_counter(), time.process_time()
    if kind in ('raw', 'raw_kept', 'deserialise'):
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic in (IMU_TOPIC, TEMP_TOPIC)]
            if kind == 'raw_kept':
                kept = [raw for _, _, raw in reader.messages(connections=conns)]
                messages = len(kept)
            else:
                messages = nbytes = 0
                for _, _, raw in reader.messages(connections=conns):
                    nbytes += len(raw)
                    messages += 1
            seconds = time.perf_counter() - start
            cpu = time.process_time() - cpu_start
            if kind == 'deserialise':
                imu = [c for c in conns if c.topic == IMU_TOPIC]
                sample = []
                for _, _, raw in reader.messages(connections=imu):
                    sample.append(raw)
                    if len(sample) >= subset:
                        break
                t0, c0 = time.perf_counter(), time.process_time()
                for raw in sample:
                    reader.deserialize(raw, 'sensor_msgs/msg/Imu')
                seconds += (time.perf_counter() - t0) / len(sample) * messages
                cpu += (time.process_time() - c0) / len(sample) * messages
    elif kind == 'read_bag':
        data = read_bag(bag, imu_topic=IMU_TOPIC, temperature_topic=TEMP_TOPIC)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        messages = len(data.imu_t) + len(data.temp_t)
    else:
        run = load_run(bag, BagOptions(imu_topic=IMU_TOPIC, temperature_topic=TEMP_TOPIC))
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        messages = len(run) + run.info['topics'][TEMP_TOPIC][1]
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {'seconds': seconds, 'cpu': cpu, 'messages': messages, 'rss_mb': rss_mb}


def _decode_blocks(repeats: int, n: int = 16384) -> int:
    """Time ``decode_joined`` of one block as the trainer reads it (gyro only); print it."""
    from gyro_tdc.data.bag import codec
    from gyro_tdc.data.imu_cdr import encode
    import numpy as np

    rng = np.random.default_rng(0)
    raws = encode(np.arange(n) + 1_700_000_000, np.arange(n) * 1000, 'imu_link',
                  rng.normal(size=(n, 37)))
    buf, lengths = b''.join(raws), np.full(n, len(raws[0]))
    keep, ts = codec.KEEP[codec.IMU_TYPE][:3], codec.jazzy()
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        dec = codec.decode_joined(buf, lengths, codec.IMU_TYPE, ts, keep)
        times.append(time.process_time() - t0)
    assert dec.fallback == 0
    print(f'decode of a {n}-message Imu block: median {statistics.median(times) * 1e3:.2f} ms, '
          f'min {min(times) * 1e3:.2f} ms CPU over {repeats} runs '
          f'({statistics.median(times) / n * 1e9:.0f} ns per message)')
    return 0


def main(argv: list[str] | None = None) -> int:
    """
    Write (once) the bag, run every measurement and print the table.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments.

    Returns
    -------
    int
        Exit status.

    """
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--bag', type=Path, default=None,
                        help='bag to read, written first when missing (default: cached in '
                             'the temp dir)')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3')
    parser.add_argument('--duration-s', type=float, default=3600.0)
    parser.add_argument('--rate-hz', type=float, default=1000.0)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--subset', type=int, default=20000)
    parser.add_argument('--only', default=','.join(MEASURES),
                        help=f'comma-separated subset of {",".join(MEASURES)}')
    parser.add_argument('--decode-blocks', type=int, default=0, metavar='N',
                        help='instead: time the fixed-layout decode of one 16,384-message '
                             'Imu block (seeded) N times, in this process')
    parser.add_argument('--child', choices=MEASURES + ('write',), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.decode_blocks > 0:
        return _decode_blocks(args.decode_blocks)

    bag = args.bag or (Path(tempfile.gettempdir()) / 'gyro_tdc_bench' /
                       f'imu_{args.duration_s:g}s_{args.rate_hz:g}hz_{args.storage}')
    if args.child == 'write':
        seconds = make_bag(bag, duration_s=args.duration_s, rate_hz=args.rate_hz,
                           storage=args.storage)
        n = args.duration_s * args.rate_hz
        print(f'write_bag: {seconds:.1f} s ({n / seconds:,.0f} Imu msg/s)')
        return 0
    if args.child:
        print(json.dumps(measure(args.child, bag, args.subset)))
        return 0

    # Everything heavy runs in child processes: Linux carries a process's peak RSS over
    # fork and exec, so the parent must stay small for the children's figures to hold.
    if not (bag / 'metadata.yaml').is_file():
        bag.parent.mkdir(parents=True, exist_ok=True)
        print(f'writing {bag} ...', flush=True)
        subprocess.run([sys.executable, __file__, '--child', 'write', '--bag', str(bag),
                        '--storage', args.storage, '--duration-s', str(args.duration_s),
                        '--rate-hz', str(args.rate_hz)], check=True)
    size = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    print(f'bag: {bag} ({size:,.0f} MB on disk)')
    print(f'python {sys.version.split()[0]}, {os.cpu_count()} CPUs, median of {args.repeats} '
          'runs, each in a fresh process')

    results = {}
    for kind in args.only.split(','):
        runs = []
        for _ in range(args.repeats):
            out = subprocess.run([sys.executable, __file__, '--child', kind, '--bag', str(bag),
                                  '--subset', str(args.subset)],
                                 check=True, capture_output=True, text=True)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        results[kind] = {
            'seconds': statistics.median(r['seconds'] for r in runs),
            'cpu': statistics.median(r['cpu'] for r in runs),
            'all': [r['seconds'] for r in runs],
            'messages': runs[0]['messages'],
            'rss_mb': max(r['rss_mb'] for r in runs)}
        print(f'  {LABELS[kind]:<30} ' + ' '.join(f'{s:6.2f}' for s in results[kind]['all'])
              + ' s', flush=True)

    print()
    print(f'{"measure":<30} {"wall s":>7} {"CPU s":>7} {"msgs/s":>11} {"x raw":>6} '
          f'{"x kept":>6} {"CPU x raw":>9} {"peak RSS MB":>11}')

    def ratio(r: dict, key: str, base: str) -> str:
        return f'{r[key] / results[base][key]:.2f}' if base in results else '-'

    for kind, r in results.items():
        print(f'{LABELS[kind]:<30} {r["seconds"]:7.2f} {r["cpu"]:7.2f} '
              f'{r["messages"] / r["seconds"]:11,.0f} {ratio(r, "seconds", "raw"):>6} '
              f'{ratio(r, "seconds", "raw_kept"):>6} {ratio(r, "cpu", "raw"):>9} '
              f'{r["rss_mb"]:11,.0f}')
    print('(wall and CPU: medians; "x raw": over iterating the raw bytes, "x kept": over '
          'collecting them in a list)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
