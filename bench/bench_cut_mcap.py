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
mcap files cut off at random points (the power went while ``ros2 bag record`` wrote them).

Per bag shape (one chunk; four chunks; a 100 Hz IMU with Float temperatures over 14
chunks; four zstd-compressed chunks), ``--cuts`` copies are cut at seeded random offsets and
read by ``read_bag`` as ``train`` reads them. A copy must read the messages of its whole
chunks, the same as the uncut bag's first ones, with a warning naming the file, or be
refused in one line; anything else is a defect. Printed per shape: read, refused, defects,
and the worst read (the largest share of the uncut bag's IMU messages lost).

``--no-metadata``: as the power loss leaves them, without metadata.yaml (rosbag2 writes it
on close) and the file named as rosbag2 names it; a sqlite3 shape is added, whose cut copy
must read messages of the uncut bag (any of them, in order) or be refused. Every read must
then also warn of the missing metadata.yaml. ``--cut-metadata``: the same, but metadata.yaml
is cut at a random byte too (the power went while rosbag2 wrote it on close); a read must
warn of it as damaged unless what is left holds every key rosbag2 requires. ``--driver``:
each copy is also read through the driver-type path (``--input-frame frd``: read by field,
message by message); it must give the plain read's messages (y and z negated) with one
warning of the cut, or be refused in one line; printed per shape: the same, refused (of
which the plain read reads), defects. ::

    .venv/bin/python bench/bench_cut_mcap.py --cuts 40 --seed 0
    .venv/bin/python bench/bench_cut_mcap.py --cuts 40 --seed 1 --no-metadata
    .venv/bin/python bench/bench_cut_mcap.py --cuts 40 --seed 2 --cut-metadata
    .venv/bin/python bench/bench_cut_mcap.py --cuts 20 --seed 3 --no-metadata --driver
"""

import argparse
from pathlib import Path
import shutil
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
for extra in (ROOT, ROOT / 'test' / 'support'):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from columnar_tape import _chamber, _write  # noqa: E402
from gyro_tdc.data import DriverInputs, normalize_bag, read_bag  # noqa: E402
from gyro_tdc.data.bag.metadata import missing  # noqa: E402
from gyro_tdc.errors import DatasetError  # noqa: E402
import numpy as np  # noqa: E402
from rosbags.rosbag2 import CompressionMode  # noqa: E402

#: name -> (storage, IMU messages, Float temperatures, chunk compression)
SHAPES = {'one chunk': ('mcap', 700, False, None), 'four chunks': ('mcap', 9000, False, None),
          'float, 14 chunks': ('mcap', 30000, True, None),
          'zstd chunks': ('mcap', 9000, False, CompressionMode.STORAGE),
          'sqlite3': ('sqlite3', 9000, False, None)}


def _among(got, ref) -> bool:
    """Return whether every IMU and temperature sample read is one of ``ref``'s, in order."""
    for t, v, rt, rv in ((got.imu_t, got.gyro, ref.imu_t, ref.gyro),
                         (got.temp_t, got.temp_c, ref.temp_t, ref.temp_c)):
        k = np.searchsorted(rt, t)
        if np.any(k >= len(rt)) or not (np.array_equal(rt[k], t) and np.array_equal(rv[k], v)):
            return False
    return True


def judge(bag: Path, ref, cut_at: int, size: int, bare: bool) -> tuple[str, float, object]:
    """Return the outcome of reading one cut copy, the share of IMU messages lost, the read."""
    try:
        got = read_bag(bag)
    except DatasetError as exc:
        return ('refused' if '\n' not in str(exc) else 'defect: a refusal of lines'), 1.0, None
    except Exception as exc:  # noqa: B902 (any other exception is the defect counted)
        return f'defect: {type(exc).__name__}', 1.0, None
    return (*_outcome(bag, got, ref, cut_at, size, bare), got)


def _outcome(bag: Path, got, ref, cut_at: int, size: int, bare: bool) -> tuple[str, float]:
    """Return the outcome of a read of one cut copy and the share of IMU messages lost."""
    why = missing(bag) if bare else None          # what the read must warn of first
    n, m = len(got.imu_t), len(got.temp_t)
    if got.storage == 'sqlite3':
        same, warned = _among(got, ref), True
    else:
        same = (np.array_equal(got.imu_t, ref.imu_t[:n])
                and np.array_equal(got.gyro, ref.gyro[:n])
                and np.array_equal(got.temp_c, ref.temp_c[:m]))
        warned = cut_at == size or any('ends without the mcap footer' in w for w in got.warnings)
    if not same:
        return 'defect: not messages of the uncut bag', 1.0
    if why and not (got.warnings and got.warnings[0].startswith(why)):
        return f'defect: no warning of {why}', 1.0
    return ('read' if warned else 'defect: no warning'), 1.0 - n / len(ref.imu_t)


def judge_driver(bag: Path, out: Path, plain) -> str:
    """Return the driver-type path's outcome on a cut copy against the plain read (or None)."""
    warned = []
    try:
        got = read_bag(normalize_bag(bag, DriverInputs(input_frame='frd'), out=out,
                                     imu_topic='/imu/data_raw',
                                     temperature_topic='/imu/temperature', warn=warned.append))
    except DatasetError as exc:
        if '\n' in str(exc):
            return 'defect: a refusal of lines'
        return 'refused' if plain is None else 'refused (the plain read reads)'
    except Exception as exc:  # noqa: B902 (any other exception is the defect counted)
        return f'defect: {type(exc).__name__}'
    if plain is None:
        return 'read (the plain read refuses)'
    same = (np.array_equal(got.imu_t, plain.imu_t) and np.array_equal(got.temp_c, plain.temp_c)
            and np.array_equal(got.gyro * [1, -1, -1], plain.gyro))
    cut = [w for w in warned if 'ends without the mcap footer' in w]
    return 'same' if same and len(cut) == len(warned) <= 1 else 'defect: not the plain read'


def main(argv=None) -> int:
    """Cut, read and count; print per shape."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cuts', type=int, default=40, help='cut copies per shape')
    ap.add_argument('--seed', type=int, default=0, help='seed of the cut offsets')
    ap.add_argument('--no-metadata', action='store_true',
                    help='cut copies without metadata.yaml, and a sqlite3 shape')
    ap.add_argument('--cut-metadata', action='store_true',
                    help='as --no-metadata, with metadata.yaml cut at a random byte')
    ap.add_argument('--driver', action='store_true',
                    help='read each copy through the driver-type path too')
    args = ap.parse_args(argv)
    bare = args.no_metadata or args.cut_metadata
    shapes = {k: v for k, v in SHAPES.items() if bare or v[0] == 'mcap'}
    rng = np.random.default_rng(args.seed)
    print(f'{args.cuts} cut copies per shape, seed {args.seed}'
          f'{", without metadata.yaml" if args.no_metadata else ""}'
          f'{", metadata.yaml cut" if args.cut_metadata else ""}: read, refused in one '
          'line, defects, worst read (share of IMU messages lost)')
    total = {'read': 0, 'refused': 0, 'defect': 0}
    with tempfile.TemporaryDirectory(prefix='gyro_tdc_cut_') as tmp:
        for k, (name, (storage, n, floating, comp)) in enumerate(shapes.items()):
            whole = _write(Path(tmp) / f'whole{k}', storage,
                           _chamber(np.random.default_rng(k), n=n, floating=floating),
                           compression=comp)
            ref = read_bag(whole)
            (path,) = [p for p in whole.iterdir() if p.suffix in ('.db3', '.mcap')]
            raw = path.read_bytes()
            counts, worst, defects = {'read': 0, 'refused': 0, 'defect': 0}, 0.0, []
            driver: dict[str, int] = {}
            for j in range(args.cuts):
                at = int(rng.integers(0, len(raw)))
                bag = Path(tmp) / f'cut{k}_{j}'
                shutil.copytree(whole, bag)
                (bag / path.name).write_bytes(raw[:at])
                if bare:
                    if args.no_metadata:
                        (bag / 'metadata.yaml').unlink()
                    else:
                        meta = (bag / 'metadata.yaml').read_bytes()
                        (bag / 'metadata.yaml').write_bytes(meta[:rng.integers(0, len(meta))])
                    (bag / path.name).rename(bag / f'{bag.name}_0{path.suffix}')
                outcome, lost, plain = judge(bag, ref, at, len(raw), bare)
                if args.driver:
                    seen = judge_driver(bag, Path(tmp) / f'driver{k}_{j}', plain)
                    driver[seen.split(':')[0]] = driver.get(seen.split(':')[0], 0) + 1
                    if seen.startswith('defect'):
                        defects.append(f'driver path: {seen} (cut at {at} of {len(raw)} bytes)')
                    shutil.rmtree(Path(tmp) / f'driver{k}_{j}', ignore_errors=True)
                counts[outcome.split(':')[0]] += 1
                if outcome == 'read':
                    worst = max(worst, lost)
                elif outcome != 'refused':
                    defects.append(f'{outcome} (cut at {at} of {len(raw)} bytes)')
                shutil.rmtree(bag)
            for key in total:
                total[key] += counts[key]
            print(f'  {name:18s} {counts["read"]:4d} {counts["refused"]:4d} '
                  f'{counts["defect"]:4d}   worst read {100 * worst:.1f} % lost '
                  f'({len(raw)} bytes, {n} IMU messages)')
            if args.driver:
                print('    driver-type path: ' + ', '.join(
                    f'{v} {k}' for k, v in sorted(driver.items())))
                total['defect'] += driver.get('defect', 0)
            for line in defects[:5]:
                print(f'    {line}')
    print(f'{sum(total.values())} cut copies: {total["read"]} read, {total["refused"]} '
          f'refused, {total["defect"]} defects')
    return 0


if __name__ == '__main__':
    sys.exit(main())
