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
Both nodes started as users start them, each parameter at the ends of its range.

Every numeric parameter of ``driver_node`` and ``compensator_node`` is set, one at a time,
to the lowest and the highest value it declares, then a seeded draw of pairs of them at
random ends, and the pairs whose order matters (``retry_initial``/``retry_max``,
``still_window``/``still_window_max``) crossed. Each start runs ``python -m
gyro_tdc.nodes.NODE --ros-args -p ...`` for a few seconds and is stopped with SIGINT. A start
passes when it runs and stops with exit 0, or refuses with exit 2 in one line; a traceback,
a ``[FATAL]`` line, or any other exit fails it. Prints each refusal and the counts; exit 1 if
any start failed. Run: ``.venv/bin/python bench/bench_node_params.py`` (about 6 minutes;
``--pairs 0`` for the single ends only).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.nodes import compensator_node, driver_node  # noqa: E402

NODES = {'driver_node': driver_node.PARAMS, 'compensator_node': compensator_node.PARAMS}
CROSSED = [('driver_node', {'retry_initial': 60.0, 'retry_max': 0.001}),
           ('driver_node', {'backend': 'iio', 'retry_initial': 2.0, 'retry_max': 1.0}),
           ('compensator_node', {'still_window': 60.0, 'still_window_max': 5.0}),
           ('compensator_node', {'learn': True, 'still_window': 3600.0})]


def cases(pairs: int, seed: int) -> list[tuple[str, dict]]:
    """Return the starts: each numeric parameter at each end, drawn pairs, crossed pairs."""
    ends = {node: [(s.name, (s.lo, s.hi)) for s in specs
                   if s.lo is not None and s.hi is not None]
            for node, specs in NODES.items()}
    out = [(node, {name: v}) for node, rows in ends.items() for name, lo_hi in rows
           for v in lo_hi]
    rng = random.Random(seed)
    for _ in range(pairs):
        node = rng.choice(sorted(ends))
        a, b = rng.sample(ends[node], 2)
        out.append((node, {a[0]: rng.choice(a[1]), b[0]: rng.choice(b[1])}))
    return out + CROSSED


def start(node: str, params: dict, seconds: float, cwd: str) -> tuple[bool, str]:
    """Start ``node`` with ``params``; return whether it passed and what it said last."""
    args = [sys.executable, '-m', f'gyro_tdc.nodes.{node}', '--ros-args']
    for name, value in params.items():
        text = str(value).lower() if isinstance(value, bool) else repr(value)
        args += ['-p', f'{name}:={text}']
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', '79'), PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(args, env=env, cwd=cwd, text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        out, err = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    text = out + err
    lines = err.strip().splitlines()
    refused = proc.returncode == 2 and len(lines) == 1 and ': error: ' in lines[0]
    ok = 'Traceback' not in text and '[FATAL]' not in text and (
        proc.returncode == 0 or refused)
    return ok, (lines[-1] if lines else '') if (refused or not ok) else ''


def main(argv: list | None = None) -> int:
    """Start every case; print refusals, failures and the counts."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--pairs', type=int, default=20, help='drawn pairs (default 20)')
    ap.add_argument('--seed', type=int, default=0, help='seed of the pairs (default 0)')
    ap.add_argument('--seconds', type=float, default=4.0,
                    help='how long a start runs before SIGINT (default 4)')
    args = ap.parse_args(argv)
    todo = cases(args.pairs, args.seed)
    failed = refused = 0
    with tempfile.TemporaryDirectory() as cwd:      # learn files and logs land here
        for node, params in todo:
            ok, said = start(node, params, args.seconds, cwd)
            failed += not ok
            refused += bool(ok and said)
            if said or not ok:
                print(f'{"FAIL" if not ok else "refused"} {node} {params}: {said[:160]}')
    print(f'{len(todo)} starts: {len(todo) - failed - refused} ran and stopped cleanly, '
          f'{refused} refused in one line, {failed} failed')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
