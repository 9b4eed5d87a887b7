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
Old code against new, side by side: the trainer's stages of two source trees, alternated.

Each run is a fresh interpreter running ``bench/bench_train.py --child STAGE`` of one tree
with that tree first on ``PYTHONPATH``; runs of the two trees alternate, so both see the same
machine load. Prints the median seconds of each tree and the ratio new / old per stage::

    git worktree add /tmp/old 0606780
    .venv/bin/python bench/bench_old_new.py --old /tmp/old --repeat 3
"""

import argparse
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile

ROOT = Path(__file__).resolve().parents[1]


def run_stage(tree: Path, stage: str, bag: Path) -> tuple[float, float]:
    """
    Return the seconds one ``--child`` stage of ``tree``'s bench_train took, wall and CPU.

    The CPU seconds are the stage's process time as the child measures it: on a shared
    machine they vary far less than the wall time.
    """
    env = dict(os.environ, PYTHONPATH=str(tree), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    done = subprocess.run([sys.executable, str(tree / 'bench' / 'bench_train.py'), '--child',
                           stage, '--bag', str(bag)], capture_output=True, text=True, env=env,
                          check=False)
    if done.returncode != 0:
        raise SystemExit(f'{tree}: stage {stage} failed: {done.stderr.strip()[-400:]}')
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    return figures['seconds'], figures['cpu']


def main(argv=None) -> int:
    """Alternate the stages of the old and the new tree; print medians and ratios."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--old', type=Path, required=True, help='source tree of the old code')
    p.add_argument('--bag', type=Path, default=None,
                   help="bag (default: bench_train.py's cached 1 h, 1 kHz sqlite3 bag)")
    p.add_argument('--stages', default='load,train,train_paper')
    p.add_argument('--repeat', type=int, default=3)
    args = p.parse_args(argv)
    bag = args.bag or Path(tempfile.gettempdir()) / 'gyro_tdc_bench_60min_1000hz_sqlite3'
    if not (bag / 'metadata.yaml').is_file():
        # bench_train writes the bag first; with no repeats it then has nothing to report.
        subprocess.run([sys.executable, str(ROOT / 'bench' / 'bench_train.py'), '--bag',
                        str(bag), '--repeat', '0'], capture_output=True, check=False)
        if not (bag / 'metadata.yaml').is_file():
            raise SystemExit(f'could not write the bench bag {bag}')
    trees = {'old': args.old.resolve(), 'new': ROOT}
    times = {(t, s): [] for t in trees for s in args.stages.split(',')}
    for k in range(args.repeat):
        for stage in args.stages.split(','):
            for name, tree in trees.items():
                sec, cpu = run_stage(tree, stage, bag)
                times[name, stage].append((sec, cpu))
                print(f'  run {k + 1}/{args.repeat} {stage:<12} {name} {sec:7.2f} s wall '
                      f'{cpu:7.2f} s CPU', flush=True)
    print(f'\nmedian of {args.repeat} alternated runs ({bag.name}; wall and CPU '
          'seconds of the stage):')
    print(f'  {"stage":<12} {"old s":>8} {"new s":>8} {"new/old":>8}   '
          f'{"old CPU":>8} {"new CPU":>8} {"new/old":>8}')
    for stage in args.stages.split(','):
        old, new = ([statistics.median(x[i] for x in times[tree, stage]) for i in (0, 1)]
                    for tree in ('old', 'new'))
        print(f'  {stage:<12} {old[0]:8.2f} {new[0]:8.2f} {new[0] / old[0]:8.3f}   '
              f'{old[1]:8.2f} {new[1]:8.2f} {new[1] / old[1]:8.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
