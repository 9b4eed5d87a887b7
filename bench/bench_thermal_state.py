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
The thermal-state estimator: tau, its interval and the held-out error over a sweep (a table).

``fit_model(features=('dT', 'dT2', 'lag'))`` on ``test/thermal_synth.py`` runs (3.3 h at
10 Hz: soaks, heating and cooling ramps at three rates; the die lags the thermometer by
``tau_die`` through an exact conduction lag; drift quadratic in the die temperature, white
noise 0.05 deg/s, floor 0.0025 (deg/s)^2), ``poly`` and ``rbf``, trained on one profile and
held out on another. Columns: the fitted tau and its 95 % profile-likelihood interval, the
error against ``tau_die``, whether the interval holds ``tau_die``, the held-out bias
stability over the floor (worst axis), the same for the measured-temperature model
f(dT, dT2), and the fit time. Then the cases the data cannot pin (one constant ramp, no lag)
and the two-node choice of ``thermal='auto'``::

    .venv/bin/python bench/bench_thermal_state.py             # 36 fits + 6 cases, ~1-2 min
    .venv/bin/python bench/bench_thermal_state.py --tau 420 --curvature 5
"""

import argparse
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

TAUS = (60.0, 120.0, 240.0, 420.0, 600.0, 900.0)
CURVATURES = (0.0, 1.0, 5.0)
FLOOR = 0.05 ** 2


def held_out(model, run) -> float:
    """Return the held-out BS over the floor, worst axis."""
    import numpy as np

    from gyro_tdc.signal.metrics import bias_stability
    from gyro_tdc.model.compensation import compensate

    bs = bias_stability(compensate(model, run.t, run.temp, run.omega), run.omega_ref)
    return float(np.max(bs) / FLOOR)


def sweep(taus, curvatures, seed: int) -> None:
    """Print the tau x curvature x kind table."""
    from gyro_tdc.identify import fit_model
    from thermal_synth import lag_run, OTHER

    print('tau_die s | curvature | kind | tau s (95 % interval) | error | holds tau_die | '
          'held-out BS / floor | f(dT, dT2) of T | fit s')
    print('|'.join(['---'] * 9))
    for tau in taus:
        for curv in curvatures:
            train = lag_run(seed=seed, tau_die=tau, curvature=curv)
            test = lag_run(seed=seed + 1, tau_die=tau, curvature=curv, segments=OTHER)
            static = held_out(fit_model([train], kind='poly', features='dT,dT2'), test)
            for kind in ('poly', 'rbf'):
                t0 = time.perf_counter()
                model = fit_model([train], kind=kind, features=('dT', 'dT2', 'lag'))
                el = time.perf_counter() - t0
                th = model.thermal
                lo, hi = th.tau_interval_s[0]
                flag = '' if th.identifiable else ' not identifiable'
                print(f'{tau:.0f} | {curv:g} | {kind} | {th.tau_s[0]:.1f} ({lo:.1f}..{hi:.1f})'
                      f'{flag} | {100 * (th.tau_s[0] / tau - 1):+.2f} % | '
                      f'{"yes" if lo <= tau <= hi else "NO"} | {held_out(model, test):.3f} | '
                      f'{static:.2f} | {el:.2f}', flush=True)


def cases(seed: int) -> None:
    """Print what the estimator says where the data cannot pin tau, and the two-node choice."""
    from gyro_tdc.identify import fit_model
    from thermal_synth import lag_run, OTHER

    print('\ncase | thermal | result | held-out BS / floor | fit s')
    print('|'.join(['---'] * 5))
    rows = [
        ('one constant ramp, die already lagging (300 s)', 'first_order',
         dict(tau_die=300.0, segments=(('ramp', 60.0, 20.0),), start_c=-10.0, skip_s=3000.0),
         None),
        ('no lag', 'first_order', dict(tau_die=0.0), None),
        ('one node 420 s', 'auto', dict(tau_die=420.0), dict(tau_die=420.0)),
        ('two nodes 30 + 300 s', 'auto', dict(tau_die=300.0, tau_package=30.0),
         dict(tau_die=300.0, tau_package=30.0)),
        ('two nodes 120 + 400 s', 'auto', dict(tau_die=400.0, tau_package=120.0),
         dict(tau_die=400.0, tau_package=120.0)),
        ('two nodes 400 + 400 s', 'auto', dict(tau_die=400.0, tau_package=400.0),
         dict(tau_die=400.0, tau_package=400.0)),
    ]
    for name, thermal, kw, test_kw in rows:
        run = lag_run(seed=seed, **kw)
        t0 = time.perf_counter()
        model = fit_model([run], kind='poly', features='dT,dT2,lag', thermal=thermal)
        el = time.perf_counter() - t0
        bs = '-'
        if test_kw is not None:
            bs = f'{held_out(model, lag_run(seed=seed + 1, segments=OTHER, **test_kw)):.3f}'
        cv = model.metrics['thermal'].get('cv_sse')
        note = ('' if cv is None else
                f' [cv slow error two/one node {cv["two_node"] / cv["first_order"]:.2f}]')
        print(f'{name} | {thermal} | {model.thermal.describe()}{note} | {bs} | {el:.2f}',
              flush=True)


def main(argv=None) -> int:
    """Run the sweep and the cases."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--tau', type=float, action='append', help='tau_die in s (repeatable)')
    p.add_argument('--curvature', type=float, action='append',
                   help='factor on the quadratic coefficients (repeatable)')
    p.add_argument('--seed', type=int, default=1)
    p.add_argument('--no-cases', action='store_true', help='the sweep only')
    args = p.parse_args(argv)
    sweep(args.tau or TAUS, args.curvature or CURVATURES, args.seed)
    if not args.no_cases:
        cases(args.seed)
    return 0


if __name__ == '__main__':
    sys.exit(main())
