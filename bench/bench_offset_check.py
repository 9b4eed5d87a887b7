#!/usr/bin/env python3
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
The offset check across power cycles (``gyro_tdc.signal.check_offsets``), swept.

Seeded draws of turn-on offsets per power cycle, of two kinds of gyro:

- **not zeroed at power-on**: a mean offset of -1..1 deg/s per axis and a spread between
  power cycles of 0.005..0.5 deg/s;
- **zeroed at power-on** (ArduPilot, PX4): offsets of 0.002..0.05 deg/s around zero, and
  with a chance of 0..40 % a failed calibration of 0.1..0.4 deg/s (the board moved).

2..8 power cycles are trained on and 40 new ones held out. A draw's figure, per axis: the RMS
and the mean absolute error of the held-out offsets against the level the check gives, over
the better of its two choices in hindsight (the training mean, or none). A draw passes when
both are at most 1.05 on every axis. Beside it, the RMS over always the training mean (the
model before the check) and over always none.

Usage: ``python bench/bench_offset_check.py [--draws N] [--seed S]``.
"""

import argparse
import sys

from gyro_tdc.signal import check_offsets
import numpy as np

BOUND = 1.05
HELD = 40


def draw(rng: np.random.Generator) -> dict:
    """Return one draw: its kind, trained and held-out offsets (deg/s, (n, 3))."""
    n = int(rng.integers(2, 9))
    if rng.random() < 0.5:
        mu, sd = rng.uniform(-1.0, 1.0, 3), np.exp(rng.uniform(np.log(0.005), np.log(0.5), 3))
        make = (lambda k: mu + sd * rng.standard_normal((k, 3)))
        kind = 'not zeroed'
    else:
        sd, p = rng.uniform(0.002, 0.05), rng.uniform(0.0, 0.4)

        def make(k):
            fail = rng.random((k, 1)) < p
            return (sd * rng.standard_normal((k, 3))
                    + fail * rng.choice([-1.0, 1.0], (k, 3)) * rng.uniform(0.1, 0.4, (k, 3)))
        kind = 'zeroed'
    return {'kind': kind, 'n': n, 'train': make(n), 'held': make(HELD)}


def score(d: dict) -> dict:
    """Return the check's level and its held-out figures over the better choice's."""
    level, _ = check_offsets(np.radians(d['train']), np.zeros((1, 3)), np.zeros(3))
    level = np.degrees(level)
    held = d['held']

    def figs(lv):
        e = held - lv
        return np.sqrt((e ** 2).mean(axis=0)), np.abs(e).mean(axis=0)
    ours, mean, none = figs(level), figs(d['train'].mean(axis=0)), figs(np.zeros(3))
    best = [np.minimum(a, b) for a, b in zip(mean, none)]
    ratio = [o / np.maximum(b, 1e-12) for o, b in zip(ours, best)]
    return {'rms': ratio[0], 'mae': ratio[1],
            'pass': bool(np.all(ratio[0] <= BOUND) and np.all(ratio[1] <= BOUND)),
            # The RMS over always the training mean (before the check) and over always none.
            'vs_mean': ours[0] / np.maximum(mean[0], 1e-12),
            'vs_none': ours[0] / np.maximum(none[0], 1e-12),
            'none': np.flatnonzero(level == 0.0).size}


def main(argv=None) -> int:
    """Run the sweep; print pass rates per kind and the worst draws."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--draws', type=int, default=400)
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = []
    for _ in range(args.draws):
        d = draw(rng)
        rows.append({**d, **score(d)})
    print(f'offset check, {args.draws} draws (seed {args.seed}), {HELD} held-out power cycles '
          f'each: RMS and mean absolute error over the better of mean and none, pass <= {BOUND}')
    for kind in ('not zeroed', 'zeroed'):
        k = [r for r in rows if r['kind'] == kind]
        rms = np.array([r['rms'] for r in k])
        mae = np.array([r['mae'] for r in k])
        print(f'  {kind:<10}  {sum(r["pass"] for r in k)}/{len(k)} pass; axes given no offset '
              f'{sum(r["none"] for r in k)}/{3 * len(k)}; RMS ratio median {np.median(rms):.3f} '
              f'worst {rms.max():.3f}; MAE ratio median {np.median(mae):.3f} '
              f'worst {mae.max():.3f}')
        for what in ('mean', 'none'):
            v = np.array([r[f'vs_{what}'] for r in k])
            print(f'    RMS over always {what:<4}: draws <= {BOUND} on every axis '
                  f'{int(np.sum(np.all(v <= BOUND, axis=1)))}/{len(k)}, median '
                  f'{np.median(v):.3f}, worst {v.max():.3f}')
    worst = sorted(rows, key=lambda r: -max(r['rms'].max(), r['mae'].max()))[:5]
    print('  worst draws (kind, power cycles trained, RMS ratio x y z, MAE ratio x y z):')
    for r in worst:
        print(f"    {r['kind']:<10} n={r['n']}  " + ' '.join(f'{v:6.3f}' for v in r['rms'])
              + '   ' + ' '.join(f'{v:6.3f}' for v in r['mae']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
