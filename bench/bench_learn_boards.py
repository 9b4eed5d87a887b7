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

r"""
``learn:=true`` on real logs of one board: every log streamed in turn, as power cycles.

A group is the logs of one board (``--group``, as ``bench_real_boards.py`` takes it, read
as ``evaluate`` reads them, still stretches by ``gyro_tdc.identify.find_still``). Per
seeded draw the logs are put in a random order and streamed, one power cycle each, through
one ``CompensatorCore(Policy())`` with a ``Learner()`` attached from nothing (no model: the
node started with ``learn:=true`` on a new board), the learner stepped every 10 messages
(``tools/field_day.feed``). The stamps of each log either start again at 1 s, as a
flight controller's boot clock does at every power-up (``--clock boot``: the IMU's clock
stepping back), or run on, one clock with a power-off of 1 h to 2 days drawn log-uniformly
between logs (``--clock wall``; these logs pause for up to 8 min when their logger stops,
so a shorter power-off can be their rhythm to the session rule, ``BURST_MAX_S``).

Scored, on every log from the second on with two still stretches or more, as
``bench_real_boards.py --node`` scores the node: the RMS of the output's still-stretch means
after the log's first still stretch (the rate is zero while still), pooled over the logs,
over raw's (the board's boot calibration, doing nothing) and over raw re-anchored on the
whole of its first still stretch (a hindsight anchor). Printed per draw and as medians,
with what the learner counted (power cycles, stretches learned, swaps) and the held-out
record of its last model.

No logs shipped: point it at logs you have, e.g. the SpeedyBee F4 logs of
``fdeedat/Repo_TA_2024`` (``bench_real_boards.py`` says how to fetch them)::

    .venv/bin/python bench/bench_learn_boards.py --group SPEEDYBEE_FOLDER --draws 6 \
        --clock boot
"""

import argparse
import math
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'bench', ROOT / 'test' / 'support', ROOT / 'tools'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_real_boards import group_logs, read_log  # noqa: E402
import numpy as np  # noqa: E402

_DEG = 180.0 / math.pi
#: Power-off between logs with ``--clock wall``: log-uniform between these, s.
OFF_S = (3600.0, 172800.0)


def _stamps(logs: list, clock: str, rng: np.random.Generator) -> list:
    """Return each log's IMU stamps in the stream: from 1 s at every power-up, or running on."""
    if clock == 'boot':
        return [lg['run'].t - lg['run'].t[0] + 1.0 for lg in logs]
    out, start = [], 0.0
    for lg in logs:
        t = lg['run'].t
        out.append(t - t[0] + start)
        start = out[-1][-1] + float(np.exp(rng.uniform(*np.log(OFF_S))))
    return out


def run_draw(logs: list, clock: str, rng: np.random.Generator) -> dict:
    """Stream the logs in a random order through a core learning from nothing; score them."""
    from field_day import feed
    from gyro_tdc.learn import Learner
    from gyro_tdc.runtime import CompensatorCore, Policy
    order = [logs[i] for i in rng.permutation(len(logs))]
    core = CompensatorCore(Policy())
    core.learner = learner = Learner()
    ss = np.zeros((3, 3))                 # node, raw, raw re-anchored: sums of squares
    scored = 0
    for k, (lg, t) in enumerate(zip(order, _stamps(order, clock, rng))):
        r = lg['run']
        out = feed(core, t, r.omega, r.accel, t, r.temp)[0]
        if k == 0 or lg['stretches'] < 2:
            continue
        node = np.array([out[a:b].mean(axis=0) for a, b in lg['spans']])
        raw = np.array([r.omega[a:b].mean(axis=0) for a, b in lg['spans']])
        for i, e in enumerate((node[1:], raw[1:], raw[1:] - raw[0])):
            ss[i] += (e ** 2).sum(axis=0)
        scored += 1
    model = core.model
    return {'order': [lg['path'].name for lg in order], 'scored': scored,
            'over_raw': np.sqrt(ss[0] / ss[1]), 'over_anchored': np.sqrt(ss[0] / ss[2]),
            'sessions': learner.session + 1, 'stretches': learner.stretches,
            'swaps': learner.swaps,
            'held_out': None if model is None else model.created.get('held_out')}


def _fmt(v) -> str:
    return ' / '.join(f'{x:.3f}' for x in v)


def main(argv=None) -> int:
    """Run the draws of every group; print each, then the medians."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--group', action='append', required=True, metavar='DIR_OR_GLOB',
                    help='the logs of one board: folders or globs, comma-separated')
    ap.add_argument('--temperature-source', default='imu')
    ap.add_argument('--clock', choices=('boot', 'wall'), default='boot',
                    help="the stream's stamps: each log's boot clock, or one running clock")
    ap.add_argument('--draws', type=int, default=4, help='seeded orders per group')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--start-c', metavar='LO:HI', default=None,
                    help='keep the logs whose first temperature is in [LO, HI) degC (e.g. :43)')
    args = ap.parse_args(argv)
    lo, hi = ((float(v) if v else math.inf * (-1) ** (i + 1))
              for i, v in enumerate((args.start_c or ':').split(':')))
    for spec in args.group:
        paths, _ = group_logs(spec)
        logs = [lg for lg in (read_log(p, args.temperature_source) for p in paths)
                if 'run' in lg and lg['stretches'] >= 1 and lo <= lg['run'].temp[0] < hi]
        print(f'== group {spec}: {len(logs)} logs with a still stretch, '
              f"{sum(lg['stretches'] >= 2 for lg in logs)} with two or more; clock "
              f'{args.clock}', flush=True)
        rows = []
        if sum(lg['stretches'] >= 2 for lg in logs) < 2:
            print('  nothing to score: fewer than two logs with two still stretches')
            continue
        for d in range(args.draws):
            r = run_draw(logs, args.clock, np.random.default_rng([args.seed, d]))
            rows.append(r)
            rec = r['held_out'] or {}
            print(f"  draw {d}: {r['scored']} logs scored; node over raw {_fmt(r['over_raw'])}, "
                  f"over raw re-anchored on its first stop {_fmt(r['over_anchored'])}; learner: "
                  f"{r['sessions']} power cycles, {r['stretches']} stretches, {r['swaps']} swaps, "
                  f"last model's curve held out on {rec.get('folds', 0)} fold(s), offset only "
                  f"{','.join(rec.get('offset_only', [])) or '-'}", flush=True)
        if rows:
            for key, what in (('over_raw', 'raw (boot calibration)'),
                              ('over_anchored', 'raw re-anchored on its first stop')):
                a = np.array([r[key] for r in rows])
                print(f'  node with learn:=true, still means after the first stop, over {what}: '
                      f'median {_fmt(np.median(a, axis=0))}, worst {_fmt(a.max(axis=0))}, '
                      f'draws <= 1.05 on every axis: {int(np.all(a <= 1.05, axis=1).sum())} of '
                      f'{len(rows)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
