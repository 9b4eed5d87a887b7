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
The accelerometer part across power cycles: judged on held-out ones, or kept unchecked.

Seeded draws of the ``accel_chamber`` scenario (a tilted combo IMU whose accelerometer offset
moves 2-3 mg per 10 degC with curvature, the die lagging the probe): 2-4 power cycles
trained at 1-10 Hz, some cut to part of the profile (heating only, cooling only, a 25 degC
window), two others held out whole. Half the draws are ``carries`` (the scenario's change,
the same on every power cycle); in the other half, ``own``, one to three axes get a change
of each power cycle's own on top (a slope of 0.5-5 times the scenario's 0.25 mg/degC, its
sign drawn per power cycle: a part whose change does not repeat). Per draw the part is
fitted as ``train`` fits it (:func:`gyro_tdc.identify.fit_accel`, the check across power
cycles) and with the check off (``judge=False``: the part before it), and scored on the
held-out power cycles: their accelerometer BS (:func:`gyro_tdc.identify.accel_scores`) over
raw's, per axis; no part is raw (1.0). Printed per kind: the parts fitted, the draws at <= 1.05 on
every axis (no harm), the median and worst ratios. ::

    .venv/bin/python bench/bench_accel_cycles.py --draws 24 --seed 0
"""

import argparse
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from dataclasses import replace  # noqa: E402, I100
from pathlib import Path  # noqa: E402
import sys  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.identify import accel_scores, fit_accel, fit_model, MG  # noqa: E402
from gyro_tdc.sim import load_scenario, simulate_scenario, to_run  # noqa: E402
import numpy as np  # noqa: E402

#: The scenario's change on x, mg/degC: the scale of a power cycle's own.
SCALE_MG_PER_C = 0.25


def _cut(run, how: str):
    """Return ``run`` whole, or its heating part, cooling part or a 25 degC window."""
    if how == 'whole':
        return run
    peak = int(np.argmax(run.temp))
    if how == 'heating':
        keep = np.arange(len(run)) <= peak
    elif how == 'cooling':
        keep = np.arange(len(run)) >= peak
    else:
        keep = (run.temp >= 5.0) & (run.temp <= 30.0) & (np.arange(len(run)) <= peak)
    return replace(run, t=run.t[keep], temp=run.temp[keep], omega=run.omega[keep],
                   omega_ref=run.omega_ref[keep], accel=run.accel[keep])


def _own(run, slopes: np.ndarray):
    """Return ``run`` with a change of its own power cycle, ``slopes`` (m/s^2 per degC)."""
    acc = np.array(run.accel, dtype=np.float64)
    acc += (run.temp - run.temp.mean())[:, None] * slopes
    return replace(run, accel=acc)


def draw(k: int, seed: int) -> dict:
    """Simulate, fit with and without the check, and score one seeded draw."""
    rng = np.random.default_rng([seed, k])
    rate = float(rng.choice([1.0, 2.0, 5.0, 10.0]))
    n_train, kind = int(rng.integers(2, 5)), ('carries', 'own')[k % 2]
    sc = load_scenario('accel_chamber').with_overrides({'imu_rate_hz': rate})
    runs = []
    for s in range((n_train + 2 + 1) // 2):
        runs += [to_run(sim) for sim in simulate_scenario(sc, seed=1000 * seed + 10 * k + s,
                                                          rate_hz=rate)]
    runs = runs[:n_train + 2]
    if kind == 'own':
        axes = rng.permutation(3)[:int(rng.integers(1, 4))]
        size = rng.uniform(0.5, 5.0) * SCALE_MG_PER_C * MG
        for i, r in enumerate(runs):
            slopes = np.zeros(3)
            slopes[axes] = size * rng.choice([-1.0, 1.0], size=axes.size)
            runs[i] = _own(r, slopes)
    cuts = [str(rng.choice(['whole', 'whole', 'heating', 'cooling', 'window']))
            for _ in range(n_train)]
    train = [_cut(r, c) for r, c in zip(runs[:n_train], cuts)]
    held = runs[n_train:]
    gyro = fit_model(train[:1], features='dT,dT2,lag')
    parts = {'check': fit_accel(train, gyro).part,
             'unchecked': fit_accel(train, gyro, judge=False).part}
    out = {'kind': kind, 'rate': rate, 'train': n_train, 'cuts': cuts}
    for name, part in parts.items():
        raw, ratio = np.zeros(3), np.zeros(3)
        for r in held:
            if part is None:
                continue
            rb, (bs,) = accel_scores(r, [gyro.replace(accel=part)])
            raw, ratio = raw + rb, ratio + bs
        out[name] = np.ones(3) if part is None else ratio / raw
        out[name + '_part'] = part is not None
    return out


def main(argv=None) -> int:
    """Run the draws; print each, then per kind the parts fitted and the pass rates."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--draws', type=int, default=24)
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args(argv)
    rows = []
    for k in range(args.draws):
        r = draw(k, args.seed)
        rows.append(r)
        print(f"draw {k:2d} {r['kind']:<7} {r['rate']:4g} Hz, {r['train']} cycles "
              f"({', '.join(r['cuts'])}): held-out BS / raw, checked "
              + ' / '.join(f'{v:.3f}' for v in r['check'])
              + ' | unchecked ' + ' / '.join(f'{v:.3f}' for v in r['unchecked']), flush=True)
    for kind in ('carries', 'own'):
        sub = [r for r in rows if r['kind'] == kind]
        print(f'{kind}: {len(sub)} draws')
        for name in ('check', 'unchecked'):
            q = np.array([r[name] for r in sub])
            parts = sum(r[name + '_part'] for r in sub)
            print(f'  {name:<10} part in {parts} of {len(sub)}; <= 1.05 on every axis: '
                  f'{int(np.sum(np.all(q <= 1.05, axis=1)))} of {len(sub)}; median '
                  + ' / '.join(f'{v:.3f}' for v in np.median(q, axis=0)) + ', worst '
                  + ' / '.join(f'{v:.3f}' for v in q.max(axis=0)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
