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
``--seed 5``; ``--case 1,9`` for those cases whatever they score.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'bench'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import bench_sessions as bs  # noqa: E402
from gyro_tdc.identify import estimate_t0, fit_model  # noqa: E402
from gyro_tdc.identify.features import features_for_fit  # noqa: E402
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


def main(argv: list | None = None) -> int:
    """Draw the cases and print what limits each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seed', type=int, default=27, help='seed of the draws (default 27)')
    ap.add_argument('--cases', type=int, default=12, help='cases drawn (default 12)')
    ap.add_argument('--case', default='', help='comma-separated cases to show whatever they '
                    'score (default: the lagging dies that fail)')
    args = ap.parse_args(argv)
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
