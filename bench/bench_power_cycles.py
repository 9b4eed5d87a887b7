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
without it (``FitOptions(check_sessions=False)``)::

    .venv/bin/python bench/bench_power_cycles.py            # ~5 s
"""

import argparse
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from gyro_tdc.identify import fit_model  # noqa: E402
from gyro_tdc.model import compensate  # noqa: E402
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
    print(f'{args.sensors} sensors, {args.train} training and {args.held} held-out power '
          "cycles each; held-out drift (re-anchored) over raw's, x y z:")
    for check, name in ((True, 'check (default)'), (False, 'no check')):
        r = np.array(ratios[check])
        print(f'  {name:<16} median ' + ' '.join(f'{v:6.3f}' for v in np.median(r, axis=0))
              + '   worst ' + ' '.join(f'{v:6.3f}' for v in r.max(axis=0)))
    print(f'  x kept the offset only on {dropped} of {args.sensors} sensors')
    return 0


if __name__ == '__main__':
    sys.exit(main())
