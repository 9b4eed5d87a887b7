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
What limits family 1 of bench_sessions on a lagging die: the choice, the thermometer, tau.

Draws the power cycles of ``bench/bench_sessions.py`` family 1 exactly as it does (its own
draw and simulation, the same seed), and for every case with a lagging die that misses the
target (or every case named by ``--case``) prints the held-out BS / floor per axis of:

* ``auto``: ``train``'s default (features auto, one offset per session), with the features
  and the thermal state's tau;
* the same draw with a 0.004 degC thermometer (quantisation out of the way);
* ``dT,dT2,lag`` and ``dT,dT2,dT3,lag`` named, tau fitted, and with tau fixed at the die's
  (the tau fit out of the way);
* beside them the PX4 cubic, whose figure plus 0.005 is the second bound.

Run: ``.venv/bin/python bench/bench_lag_selection.py`` (seed 27, 12 cases, about 40 s);
``--seed 5``; ``--case 1,9`` for those cases whatever they score. ``--old COMMIT`` instead
draws the same cases, trains them by default with this tree and with COMMIT's ``gyro_tdc``
(``git archive``, in a subprocess), and prints the pass counts and every case whose features
differ, old and new (about 1 minute per seed)::

    .venv/bin/python bench/bench_lag_selection.py --old 2fd470b --seed 5
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'bench'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))
#: Set (by ``--old``) to a tree whose ``gyro_tdc`` is imported instead of this one's.
OLD_TREE = os.environ.get('BENCH_LAG_SELECTION_TREE')
if OLD_TREE:
    sys.path.insert(0, OLD_TREE)

import bench_sessions as bs  # noqa: E402
from gyro_tdc.identify import estimate_t0, fit_model  # noqa: E402
from gyro_tdc.identify.train import features_for_fit  # noqa: E402
from gyro_tdc.model import ThermalState  # noqa: E402
import numpy as np  # noqa: E402

DEG = math.pi / 180.0


def _draw(seed: int, cases: int) -> list:
    """Return family 1's cases as bench_sessions draws them, with each cycle's arguments."""
    calls: list = []
    cycle = bs._cycle

    def recorded(name, lo, hi, heating, d, s):
        out = cycle(name, lo, hi, heating, d, s)
        calls.append(((name, lo, hi, heating, dict(d), s), out))
        return out

    bs._cycle = recorded
    try:
        rng = np.random.default_rng(seed)
        out = []
        for k in range(cases):
            calls.clear()
            d = bs.power_cycles(rng, k)
            d['cycles'] = list(calls)
            out.append(d)
        return out
    finally:
        bs._cycle = cycle


def _score(train: list, held, noise, features='auto', tau: float | None = None) -> tuple:
    """Fit as ``train`` does (``features`` auto or named, tau fixed if given); BS / floor."""
    t0 = estimate_t0(train[0])
    kw = {}
    if features == 'auto':
        ids, params, _ = features_for_fit(train, 'auto', t0=t0)
        kw['params'] = params or None
    else:
        ids = features
    if tau is not None:
        kw['thermal'] = ThermalState('first_order', (float(tau),))
    model = fit_model(train, features=ids, t0=t0, sessions=[0, 1], **kw)
    err = bs._reanchored(model, held)
    ratio = np.mean(err ** 2, axis=0) / DEG ** 2 / (noise / DEG) ** 2
    taus = model.thermal.tau_s if model.thermal.kind != 'none' else ()
    return ','.join(model.features), taus, ratio


def _line(label: str, result: tuple, cubic: np.ndarray) -> str:
    """Return one printed line: label, BS / floor per axis, pass mark, features and tau."""
    feats, taus, ratio = result
    ok = bool(np.all(ratio <= bs.FLOOR_BOUND) and np.all(ratio <= cubic + bs.CUBIC_TIE))
    tau = f'tau {taus[0]:.0f} s' if taus else 'no state'
    return (f'    {label:<26} ' + ' '.join(f'{v:6.3f}' for v in ratio)
            + f'  {"pass" if ok else "FAIL"}  {feats} ({tau})')


def _rows(seed: int, cases: int) -> list:
    """Return every case's draws, default features and held-out BS / floor (plain types)."""
    out = []
    for k, d in enumerate(_draw(seed, cases)):
        out.append({'case': k, 'rate': d['rate'], 'res': d['res'], 'lag': d['lag'],
                    'heating': d['heating'], 'features': d['features'],
                    'ours': [float(v) for v in d['ours']], 'pass': bool(d['pass'])})
    return out


def _old_rows(commit: str, seed: int, cases: int) -> list:
    """Return :func:`_rows` computed with ``commit``'s ``gyro_tdc`` (a subprocess)."""
    with tempfile.TemporaryDirectory() as tmp:
        tar = subprocess.run(['git', '-C', str(ROOT), 'archive', commit, 'gyro_tdc'],
                             check=True, capture_output=True).stdout
        subprocess.run(['tar', '-x', '-C', tmp], input=tar, check=True)
        env = dict(os.environ, BENCH_LAG_SELECTION_TREE=tmp)
        done = subprocess.run([sys.executable, __file__, '--rows', '--seed', str(seed),
                               '--cases', str(cases)], env=env, check=True,
                              capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def compare(commit: str, seed: int, cases: int) -> int:
    """Print the pass counts of ``commit`` and this tree, and the cases whose features differ."""
    old, new = _old_rows(commit, seed, cases), _rows(seed, cases)
    print(f'family 1, seed {seed}: {commit} {sum(r["pass"] for r in old)}/{cases} pass, '
          f'this tree {sum(r["pass"] for r in new)}/{cases} pass; cases whose features '
          'differ (held-out BS / floor x y z):')
    for a, b in zip(old, new):
        if a['features'] == b['features']:
            continue
        worst_a, worst_b = max(a['ours']), max(b['ours'])
        how = ('better' if worst_b < worst_a - 1e-3 else
               'worse' if worst_b > worst_a + 1e-3 else 'same')
        print(f'  case {a["case"]}: {a["rate"]:g} Hz, {a["res"]:g} degC, lag {a["lag"]:g} s, '
              f'heating {a["heating"]}')
        for tag, r in ((commit, a), ('this tree', b)):
            print(f'    {tag:<10} ' + ' '.join(f'{v:6.3f}' for v in r['ours'])
                  + f'  {"pass" if r["pass"] else "FAIL"}  {r["features"]}')
        print(f'    worst axis: {how}')
    return 0


def main(argv: list | None = None) -> int:
    """Draw the cases and print what limits each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seed', type=int, default=27, help='seed of the draws (default 27)')
    ap.add_argument('--cases', type=int, default=12, help='cases drawn (default 12)')
    ap.add_argument('--case', default='', help='comma-separated cases to show whatever they '
                    'score (default: the lagging dies that fail)')
    ap.add_argument('--old', metavar='COMMIT', help="compare with COMMIT's gyro_tdc instead")
    ap.add_argument('--rows', action='store_true', help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.rows:                     # the subprocess of --old: one JSON line
        print(json.dumps(_rows(args.seed, args.cases)))
        return 0
    if args.old:
        return compare(args.old, args.seed, args.cases)
    start = time.perf_counter()
    cases = _draw(args.seed, args.cases)
    chosen = ({int(c) for c in args.case.split(',') if c.strip()} if args.case else
              {k for k, d in enumerate(cases) if not d['pass'] and d['lag'] > 0})
    print(f'family 1, seed {args.seed}: {sum(d["pass"] for d in cases)}/{len(cases)} pass; '
          f'held-out BS / floor x y z (bound {bs.FLOOR_BOUND:g} and the cubic + '
          f'{bs.CUBIC_TIE:g})')
    for k in sorted(chosen):
        d = cases[k]
        runs = [out[0] for _args, out in d['cycles']]
        noise = d['cycles'][0][1][1]
        train, held = runs[:2], runs[2]
        cubic = d['cubic']
        print(f'  case {k}: {d["rate"]:g} Hz, thermometer {d["res"]:g} degC, lag {d["lag"]:g} s, '
              f'ranges {d["ranges"]}, heating {d["heating"]}')
        print(f'    {"PX4 cubic":<26} ' + ' '.join(f'{v:6.3f}' for v in cubic))
        print(_line('auto', _score(train, held, noise), cubic))
        fine = []
        for (name, lo, hi, heating, dd, s), _out in d['cycles']:
            fine.append(bs._cycle(name, lo, hi, heating, dict(dd, res=0.004), s))
        print(_line('auto, 0.004 degC', _score([r for r, _n in fine[:2]], fine[2][0],
                                               fine[2][1]), cubic))
        for feats in ('dT,dT2,lag', 'dT,dT2,dT3,lag'):
            print(_line(feats, _score(train, held, noise, feats), cubic))
            print(_line(f'{feats}, tau {d["lag"]:g} s', _score(train, held, noise, feats,
                                                               d['lag']), cubic))
    print(f'{time.perf_counter() - start:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
