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
Do no harm across power cycles, swept: curves that carry to the next power cycle, and not.

Each case is a board logged over power cycles (one log each): ``--train`` logs trained on as
``train`` trains by default (features auto, one offset per log, then validated across the
logs: :func:`gyro_tdc.identify.crossval.validate_curve`), ``--held`` further logs of the same
board held out. Drawn per case: the rate (1 Hz .. 2 kHz; a log holds at most 60 000
samples, so 2 kHz logs last 30 s), the thermometer's resolution (0.004 .. 1 degC), the range
(spans of 5 .. 30 degC, cooling only in half the cases, else heating or cooling per log), a
turn-on offset per log (std 0, 0.05 or 0.5 deg/s), white noise and a bias random walk, and
per axis whether the thermal curve carries from one power cycle to the next (the same
quadratic in every log) or not (its slope and curvature drawn anew per log: a third of the
cases on every axis, a third on none, a third axis by axis).

Judged on the held-out logs: the within-log drift (the RMS of block means of a twentieth of
the log, about the log's own mean: what no start-up offset removes) compensated over raw,
per axis. A case passes when every axis whose curve does not carry is at most
``1.05 x raw`` and every axis whose curve carries keeps it. Prints the pass rates per kind,
the ratios and the worst cases with their draws. Run:
``.venv/bin/python bench/bench_do_no_harm.py`` (``--cases N --seed S --train N --held N``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.data import Run  # noqa: E402
from gyro_tdc.identify import estimate_t0, fit_model  # noqa: E402
from gyro_tdc.identify.crossval import validate_curve  # noqa: E402
from gyro_tdc.identify.features import features_for_fit  # noqa: E402
from gyro_tdc.model import compensate, DEFAULT_OUT_OF_RANGE  # noqa: E402
import numpy as np  # noqa: E402

DEG = math.pi / 180.0
RATES = (1.0, 10.0, 100.0, 1000.0, 2000.0)
RESOLUTIONS_C = (0.004, 0.0625, 0.25, 1.0)
OFFSETS_DPS = (0.0, 0.05, 0.5)
MAX_SAMPLES = 60_000
#: An axis whose curve does not carry: held-out within-log drift at most this times raw.
BOUND = 1.05
#: The curve of the board (deg/s per degC, per degC^2), scaled per case.
A1 = np.array([0.02, -0.015, 0.01])
A2 = np.array([2e-4, 1.5e-4, -1e-4])


def _log(rng: np.random.Generator, d: dict, a1: np.ndarray, a2: np.ndarray,
         offset: np.ndarray, name: str) -> Run:
    """Simulate one power cycle: an exponential approach across the case's range."""
    n = int(min(MAX_SAMPLES, 7200.0 * d['rate']))
    t = np.arange(n) / d['rate']
    lo = d['lo'] + float(rng.uniform(-3.0, 3.0))
    hi = lo + d['span']
    cooling = d['cooling'] or bool(rng.integers(0, 2))
    a, b = (hi, lo) if cooling else (lo, hi)
    x = 1.0 - np.exp(-3.0 * t / t[-1])
    temp = a + (b - a) * x / x[-1]
    dt = temp - 25.0
    noise = d['arw'] * math.sqrt(d['rate'])
    walk = np.cumsum(rng.normal(0.0, d['rrw'] / math.sqrt(d['rate']), (n, 3)), axis=0)
    omega = (offset + dt[:, None] * a1 + dt[:, None] ** 2 * a2 + walk
             + rng.normal(0.0, noise, (n, 3))) * DEG
    meas = np.round(temp / d['res']) * d['res']
    return Run(t, meas, omega, np.zeros_like(omega), name)


def _drift(runs: list, err: list) -> np.ndarray:
    """Return the pooled within-log drift (deg/s): RMS of 1/20-log means about each log's."""
    ss, n = np.zeros(3), 0
    for r, e in zip(runs, err):
        k = max(1, len(r) // 20)
        m = e[:len(e) // k * k].reshape(-1, k, 3).mean(axis=1)
        ss += np.sum((m - m.mean(axis=0)) ** 2, axis=0)
        n += m.shape[0]
    return np.sqrt(ss / max(n, 1)) / DEG


def case(rng: np.random.Generator, k: int, n_train: int, n_held: int) -> dict:
    """Draw, train and judge one case."""
    kind = ('carries', 'changes', 'mixed')[k % 3]
    carry = {'carries': np.ones(3, bool), 'changes': np.zeros(3, bool),
             'mixed': rng.integers(0, 2, 3).astype(bool)}[kind]
    d = {'kind': kind, 'carry': carry.tolist(),
         'rate': float(rng.choice(RATES)), 'res': float(rng.choice(RESOLUTIONS_C)),
         'lo': round(float(rng.uniform(-10.0, 20.0)), 1),
         'span': round(float(rng.uniform(5.0, 30.0)), 1),
         'cooling': bool(rng.integers(0, 2)), 'offset': float(rng.choice(OFFSETS_DPS)),
         'scale': round(float(rng.uniform(0.3, 1.5)), 2),
         'arw': float(rng.choice((0.005, 0.02))), 'rrw': float(rng.choice((0.0, 1e-4)))}
    logs = []
    for j in range(n_train + n_held):
        a1 = np.where(carry, A1 * d['scale'], rng.normal(0.0, 1.0, 3) * A1 * d['scale'])
        a2 = np.where(carry, A2 * d['scale'], rng.normal(0.0, 1.0, 3) * A2 * d['scale'])
        off = rng.normal(0.0, d['offset'], 3) if d['offset'] else np.zeros(3)
        logs.append(_log(rng, d, a1, a2, off, f'log{j}'))
    train, held = logs[:n_train], logs[n_train:]
    labels = list(range(n_train))
    t0 = estimate_t0(train[0])
    ids, params, _ = features_for_fit(train, 'auto', t0=t0)
    fitted = fit_model(train, features=ids, params=params or None, t0=t0, sessions=labels)
    model, rec = validate_curve(fitted, train, labels)
    raw = _drift(held, [r.omega for r in held])
    out = {}
    for key, m in (('ours', model), ('no_rule', fitted)):
        comp = [compensate(m, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE)
                for r in held]
        out[key] = _drift(held, comp) / raw
    d.update(out, kept=list(rec.curve), features=','.join(model.features))
    d['pass'] = bool(np.all(out['ours'][~carry] <= BOUND) and np.all(np.array(rec.curve)[carry]))
    d['harm_pass'] = bool(np.all(out['ours'][~carry] <= BOUND))
    d['kept_pass'] = bool(np.all(np.array(rec.curve)[carry]))
    return d


def main(argv: list | None = None) -> int:
    """Run the sweep and print it."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--cases', type=int, default=30, help='cases (default 30)')
    ap.add_argument('--seed', type=int, default=34, help='seed of the draws (default 34)')
    ap.add_argument('--train', type=int, default=4, help='logs trained on (default 4)')
    ap.add_argument('--held', type=int, default=8, help='logs held out (default 8)')
    args = ap.parse_args(argv)
    start = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    cases = [case(rng, k, args.train, args.held) for k in range(args.cases)]
    print(f'{len(cases)} boards, {args.train} logs trained on, {args.held} held out: '
          f'{sum(c["pass"] for c in cases)}/{len(cases)} pass (axes whose curve does not '
          f'carry <= {BOUND:g} x raw within-log drift held out; axes whose curve carries keep '
          'it)')
    for kind in ('carries', 'changes', 'mixed'):
        sub = [c for c in cases if c['kind'] == kind]
        if not sub:
            continue
        print(f'  curve {kind:<8}: {sum(c["pass"] for c in sub)}/{len(sub)} pass; no harm '
              f'{sum(c["harm_pass"] for c in sub)}/{len(sub)}, curve kept where it carries '
              f'{sum(c["kept_pass"] for c in sub)}/{len(sub)}')
    for carried in (False, True):
        for key in ('ours', 'no_rule'):
            v = np.array([c[key][a] for c in cases for a in range(3)
                          if c['carry'][a] == carried])
            if v.size:
                print(f'  axes whose curve {"carries" if carried else "does not carry":<15} '
                      f'{key:<8} compensated / raw drift: median {np.median(v):6.3f}, worst '
                      f'{v.max():8.3f}, <= {BOUND:g}: {100 * np.mean(v <= BOUND):3.0f} %')

    def harm(c: dict) -> float:
        return max((c['ours'][a] for a in range(3) if not c['carry'][a]), default=0.0)

    order = sorted(cases, key=lambda c: -harm(c))
    print('  worst cases (ours x y z; no_rule x y z; draws):')
    for c in order[:5]:
        skip = ('ours', 'no_rule', 'pass', 'harm_pass', 'kept_pass')
        draws = {k: v for k, v in c.items() if k not in skip}
        print('    ' + ' '.join(f'{v:6.3f}' for v in c['ours']) + ' ; '
              + ' '.join(f'{v:6.3f}' for v in c['no_rule']) + f'   {draws}')
    for c in cases:
        if not c['pass']:
            print(f'  fails: ours {np.round(c["ours"], 3).tolist()} kept {c["kept"]} carry '
                  f'{c["carry"]} rate {c["rate"]:g} res {c["res"]:g} span {c["span"]:g} '
                  f'cooling {c["cooling"]} offset {c["offset"]:g} features {c["features"]}')
    print(f'\n{time.perf_counter() - start:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
