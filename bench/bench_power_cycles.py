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
Do no harm across power cycles: a curve that does not carry from one power cycle to the next.

Seeded sensors whose x drift changes its slope at every power cycle (a random slope per
session, as the real ICM-42688 board of issue 34 does on x) while y and z share one curve,
plus white noise; ``--train`` sessions (0..40 degC, each its turn-on offset) train a
``dT, dT2`` poly as ``train`` does (one offset per session), ``--held`` more are held out.
Each held-out session is re-anchored (its mean removed, as the compensator does at start-up)
and its drift is the RMS of what is left; printed per axis, the median and worst over the
sensors of that drift over raw's (raw re-anchored alike), with the check (the default) and
without it (``FitOptions(check_sessions=False)``).

Then the start-up shift rule (:func:`gyro_tdc.identify.power_cycles.reanchor_rule`), swept:
seeded sensors at 2 to 50 Hz, continuous or in 5 s bursts every 300 s (PAN's layout), each
burst with its own jitter of 0 or 0.003 deg/s (a wander the anchors see), turn-on offsets of
std 0, 0.002 or 0.3 deg/s per power cycle; the rule decided on the training sessions, each
held-out session re-anchored at its start by the node's rule (``reanchor_shift``) with any
shift, with the model's gate, or never. Printed per offset std: the RMS over held-out
sessions of their mean error for each, and the largest regret of the rule (gated minus the
better of the other two)::

    .venv/bin/python bench/bench_power_cycles.py            # ~1 minute
"""

import argparse
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from gyro_tdc.data import Run  # noqa: E402
from gyro_tdc.identify import fit_model, reanchor_rule  # noqa: E402
from gyro_tdc.model import compensate  # noqa: E402
from gyro_tdc.runtime import default_tolerance, gated_shift, reanchor_shift  # noqa: E402
import numpy as np  # noqa: E402
from synth import synth_run  # noqa: E402


def _sessions(seed: int, n: int) -> list:
    """Return ``n`` power cycles of one sensor: x's slope random per cycle, y and z shared."""
    rng = np.random.default_rng(seed)
    return [synth_run(seed=1000 * seed + i, hours=1.0, rate_hz=2.0, t_lo=0.0, t_hi=40.0,
                      cooling=bool(i % 2), noise_dps=0.02,
                      a1=(float(rng.normal(0.0, 0.02)), -0.015, 0.01),
                      a2=(0.0, 1.5e-4, -1e-4),
                      offset_dps=tuple(rng.normal(0.0, 0.3, 3)), name=f's{i}')
            for i in range(n)]


def _drift(rate: np.ndarray) -> np.ndarray:
    """Return the RMS per axis of a session's rate around its mean (re-anchored)."""
    return np.sqrt(np.mean((rate - rate.mean(axis=0)) ** 2, axis=0))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--sensors', type=int, default=6, help='seeded sensors (default 6)')
    p.add_argument('--train', type=int, default=3, help='training sessions (default 3)')
    p.add_argument('--held', type=int, default=3, help='held-out sessions (default 3)')
    p.add_argument('--cases', type=int, default=24, help='draws of the rule sweep (default 24)')
    args = p.parse_args(argv)
    ratios = {True: [], False: []}
    dropped = 0
    for seed in range(args.sensors):
        runs = _sessions(seed, args.train + args.held)
        train, held = runs[:args.train], runs[args.train:]
        for check in (True, False):
            m = fit_model(train, kind='poly', features='dT,dT2', t0=20.0,
                          sessions=list(range(args.train)), check_sessions=check)
            if check:
                dropped += 'x' in m.metrics['sessions'].get('heldout', {}).get(
                    'offset_only', [])
            for r in held:
                comp = compensate(m, r.t, r.temp, r.omega)
                ratios[check].append(_drift(comp) / _drift(r.omega))
    if args.sensors:
        print(f'{args.sensors} sensors, {args.train} training and {args.held} held-out power '
              "cycles each; held-out drift (re-anchored) over raw's, x y z:")
        for check, name in ((True, 'check (default)'), (False, 'no check')):
            r = np.array(ratios[check])
            print(f'  {name:<16} median ' + ' '.join(f'{v:6.3f}' for v in np.median(r, axis=0))
                  + '   worst ' + ' '.join(f'{v:6.3f}' for v in r.max(axis=0)))
        print(f'  x kept the offset only on {dropped} of {args.sensors} sensors')
    rule(args.cases)
    return 0


def _rule_case(k: int, d: dict) -> np.ndarray:
    """Return one draw's RMS of held-out session mean errors: any shift, gated, never (3, 3)."""
    rng = np.random.default_rng(k)
    runs = []
    for i in range(6):
        r = synth_run(seed=100 * k + i, hours=1.0, rate_hz=d['rate'], t_lo=0.0, t_hi=40.0,
                      cooling=bool(i % 2), noise_dps=0.02, a1=(0.01, -0.015, 0.01),
                      a2=(1e-4, 1.5e-4, -1e-4), offset_dps=tuple(rng.normal(0, d['offset'], 3)))
        keep = np.ones(len(r), dtype=bool) if not d['bursts'] else (r.t % 300.0) < 5.0
        burst = (r.t // 300.0).astype(int)
        omega = r.omega + np.radians(rng.normal(0, d['jitter'], (burst.max() + 1, 3)))[burst]
        runs.append(Run(r.t[keep], r.temp[keep], omega[keep], r.omega_ref[keep], f's{i}'))
    train, held = runs[:3], runs[3:]
    m = fit_model(train, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1, 2])
    m = reanchor_rule(m, train, [0, 1, 2], lambda o, g: fit_model(
        o, kind='poly', features='dT,dT2', t0=20.0, sessions=g))
    ss = np.zeros((3, 3))
    for r in held:
        e = compensate(m, r.t, r.temp, r.omega) - r.omega_ref
        s = np.asarray(reanchor_shift(r.t, e, tolerance=default_tolerance(m.residual_var)).delta)
        for i, shift in enumerate((s, gated_shift(m, s), np.zeros(3))):
            ss[i] += (e.mean(axis=0) - shift) ** 2
    return np.degrees(np.sqrt(ss / len(held)))


def rule(cases: int) -> None:
    """Sweep the start-up shift rule over rates, layouts, jitter and offsets; print it."""
    print(f"\nthe start-up shift rule, {cases} draws: RMS of the held-out sessions' mean "
          'error, mdeg/s x y z, median (worst)')
    rng = np.random.default_rng(7)
    rows = []
    for k in range(cases):
        d = {'rate': float(rng.choice((2.0, 10.0, 50.0))), 'bursts': bool(rng.integers(2)),
             'jitter': float(rng.choice((0.0, 0.003))),
             'offset': float(rng.choice((0.0, 0.002, 0.3)))}
        rms = _rule_case(k, d)
        rows.append((d, rms[1] - np.minimum(rms[0], rms[2]), rms))
    for off in (0.0, 0.002, 0.3):
        sub = [r for r in rows if r[0]['offset'] == off]
        if not sub:
            continue
        a = 1000.0 * np.array([r[2] for r in sub])
        print(f'  turn-on offset std {off:g} deg/s, {len(sub)} draws:')
        for i, name in enumerate(('any shift', 'gated (the rule)', 'never')):
            print(f'    {name:<17}' + ' '.join(f'{m:7.2f} ({w:6.2f})' for m, w in zip(
                np.median(a[:, i], axis=0), a[:, i].max(axis=0))))
    d, regret, rms = max(rows, key=lambda r: float(r[1].max()))
    print(f'  largest regret (gated minus the better of the other two) '
          f'{1000.0 * regret.max():.2f} mdeg/s: {d}')


if __name__ == '__main__':
    sys.exit(main())
