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
Sweep damaged rosbag2 bags (sqlite3 and mcap) through ``train`` and ``evaluate``.

One still 20 Hz bag per storage (15 min, a thermometer at 1 Hz) is written, then copies of
it damaged as storage media do: a few bits flipped, many bytes overwritten, cut at a random
offset, a stretch of 16 to 4,096 bytes zeroed, in the storage file (3 in 4) or in
``metadata.yaml`` (seeded). Each copy goes through ``train`` and ``evaluate``
(``--allow-loss``), and with ``--driver`` also through the driver-type path
(``--input-frame frd``: the bag read by field with rosbags' reader). A run passes when it
exits 0, or exits 2 with one line naming what is wrong; a defect is anything else (an
exception out of the command, an exit code other than 0 or 2, a refusal of more than one
line). Printed per storage and damage: runs, ok,
refused, defects; then every defect. ``--no-metadata``: each damaged copy also loses its
metadata.yaml (the storage file named as rosbag2 names it), as a power loss leaves a bag;
the same damage draws. ::

    .venv/bin/python bench/bench_damaged_bags.py                  # 40 copies per storage
    .venv/bin/python bench/bench_damaged_bags.py --bags 100 --seed 3 --driver
    .venv/bin/python bench/bench_damaged_bags.py --bags 50 --seed 5 --driver --no-metadata
"""

import argparse
import collections
import contextlib
import io
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import numpy as np  # noqa: E402

DAMAGE = ('flip', 'overwrite', 'cut', 'zero')


def damage(path: Path, how: str, rng: np.random.Generator) -> None:
    """Damage the file ``path`` in place, as ``how`` says."""
    data = bytearray(path.read_bytes())
    n = len(data)
    if how == 'flip':
        for _ in range(int(rng.integers(1, 6))):
            i = int(rng.integers(n))
            data[i] ^= 1 << int(rng.integers(8))
    elif how == 'overwrite':
        for i in rng.integers(0, n, int(rng.integers(20, 301))):
            data[int(i)] = int(rng.integers(256))
    elif how == 'cut':
        del data[int(rng.integers(n)):]
    else:
        i = int(rng.integers(n))
        size = len(data[i:i + int(rng.integers(16, 4097))])
        data[i:i + size] = bytes(size)
    path.write_bytes(bytes(data))


def run(command: str, argv: list) -> tuple:
    """Run a command's ``main`` in process; return (outcome, its first line, what failed)."""
    from gyro_tdc.cli import load_main
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = load_main(command)(argv)
    except SystemExit as exc:
        code = exc.code
    except BaseException as exc:  # noqa: B902 (whatever escapes the command is the defect)
        return 'defect', f'{type(exc).__name__}: {exc}'[:200], 'exception'
    lines = [x for x in err.getvalue().splitlines() if ': error: ' in x]
    if code == 0:
        return 'ok', '', ''
    if code == 2 and len(lines) == 1:
        return 'refused', lines[0], ''
    return 'defect', (lines or err.getvalue().splitlines() or [''])[-1][:200], f'exit {code}'


def sweep(storage: str, bags: int, rng: np.random.Generator, driver: bool, root: Path,
          bare: bool = False) -> list:
    """Write one bag of ``storage``, damage ``bags`` copies; return one record per run."""
    from bags import bag_from_run
    from synth import synth_run
    base = bag_from_run(synth_run(seed=3, hours=0.25, rate_hz=20.0, noise_dps=0.02),
                        root / f'{storage}-base', storage=storage)
    extra = ['--input-frame', 'frd'] if driver else []
    out = []
    for k in range(bags):
        bag = root / f'{storage}-{k}'
        shutil.copytree(base, bag)
        storage_file, meta = sorted(bag.iterdir(), key=lambda p: p.name == 'metadata.yaml')
        target = storage_file if rng.random() < 0.75 else meta
        how = DAMAGE[k % len(DAMAGE)]
        damage(target, how, rng)
        if bare:
            meta.unlink()
            storage_file.rename(bag / f'{bag.name}_0{storage_file.suffix}')
        for opts in ([], extra) if extra else ([],):
            for command, argv in (
                    ('train', [str(bag), '--out', str(root / f'm{k}.yaml'), '--features',
                               'dT,dT2', '--no-progress', '--allow-loss']),
                    ('evaluate', [str(bag), '--model', 'l3gd20_modified', '--no-progress',
                                  '--allow-loss'])):
                outcome, line, why = run(command, argv + opts)
                out.append({'storage': storage, 'damage': how, 'file': target.name, 'copy': k,
                            'command': ' '.join([command] + opts), 'outcome': outcome,
                            'line': line, 'why': why})
        shutil.rmtree(bag)
    return out


def main(argv=None) -> int:
    """Sweep both storages; print the counts per storage and damage, then the defects."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--bags', type=int, default=40, help='damaged copies per storage')
    ap.add_argument('--seed', type=int, default=0, help='seed of the damage')
    ap.add_argument('--driver', action='store_true',
                    help='also run each copy through the driver-type path (--input-frame frd)')
    ap.add_argument('--no-metadata', action='store_true',
                    help='each damaged copy without metadata.yaml (as a power loss leaves it)')
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory(prefix='gyro_tdc_damaged_bags_') as tmp:
        runs = [r for s in ('sqlite3', 'mcap')
                for r in sweep(s, args.bags, rng, args.driver, Path(tmp), args.no_metadata)]
    counts = collections.Counter((r['storage'], r['damage'], r['outcome']) for r in runs)
    print(f'{args.bags} damaged copies per storage, seed {args.seed}'
          f'{", without metadata.yaml" if args.no_metadata else ""}: runs, ok, refused in one '
          'line, defects')
    for storage in ('sqlite3', 'mcap'):
        for how in DAMAGE:
            n = [counts[(storage, how, o)] for o in ('ok', 'refused', 'defect')]
            print(f'  {storage:8s} {how:10s} {sum(n):4d} {n[0]:4d} {n[1]:4d} {n[2]:4d}')
    defects = [r for r in runs if r['outcome'] == 'defect']
    print(f'{len(runs)} runs: {sum(r["outcome"] == "ok" for r in runs)} ok, '
          f'{sum(r["outcome"] == "refused" for r in runs)} refused, {len(defects)} defects')
    for r in defects:
        print(f'  DEFECT {r["storage"]} {r["damage"]} {r["file"]} copy {r["copy"]} '
              f'{r["command"]}: {r["why"]}: {r["line"]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
