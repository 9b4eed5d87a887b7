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
The thermal state found by default: a sweep of die lag and curvature (prints a table).

For every die time constant ``tau_die`` (1 to 15 min) and curvature (none, the L3GD20
preset's ``dT2``, five times it: dominant over the linear term) the ``die_lag`` scenario
(two 5.7 h runs at 10 Hz, heating and cooling ramps at three rates with soaks; the die lags
the package thermometer; run-to-run offsets off, so the held-out figures need no
re-anchoring) is simulated, and:

* ``discover`` runs on both runs (leave-one-run-out): the effects it names, tau with its
  95 % interval and its error against ``tau_die``, the final gap in its own noise floors, in
  sample and held out, and beside it what the true drift removed leaves (the sensor's bias
  instability and rate random walk: the best any model can do);
* ``train`` with default options (``--features auto``) fits run 1, and run 2 is held out: the
  features chosen, tau and its error, and the compensated bias stability over the white-noise
  floor (``noise_std^2`` of the simulator), worst axis; beside it the paper's f(dT, dT2)
  RBF (``--features dT,dT2``, the default before the thermal state).

::

    .venv/bin/python bench/bench_thermal_discovery.py            # 18 cases, ~10 min
    .venv/bin/python bench/bench_thermal_discovery.py --tau 420 --curvature moderate
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import argparse  # noqa: E402, I100
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

TAUS = (60.0, 120.0, 240.0, 420.0, 600.0, 900.0)
#: Curvature: factor on the preset's dT2 coefficients (0: the effect switched off).
CURVATURES = {'none': 0.0, 'moderate': 1.0, 'dominant': 5.0}


def overrides(tau_die: float, curvature: str) -> dict:
    """Return the scenario overrides of one case."""
    from gyro_tdc.sim.specs import preset

    factor = CURVATURES[curvature]
    dt2 = [factor * v for v in preset('l3gd20')['gyro']['dT2_dps_per_c2']]
    out = {'thermal.tau_die_s': tau_die, 'runs.bias_offset_dps_std': 0.0,
           'gyro.effects.dT2': factor > 0}
    if factor > 0:
        out['gyro.dT2_dps_per_c2'] = dt2
    return out


def run_case(tau_die: float, curvature: str, seed: int, folder: Path) -> dict:
    """Simulate, discover on both runs, train on run 1 and evaluate on run 2."""
    import contextlib
    import io
    import math

    import numpy as np

    from gyro_tdc.data import write_bag
    from gyro_tdc.identify.discover import discover
    from gyro_tdc.identify.discover.data import BlockData
    from gyro_tdc.signal.metrics import bias_stability
    from gyro_tdc.model.compensation import compensate
    from gyro_tdc.data.runs import Run
    from gyro_tdc.sim import simulate_scenario
    from gyro_tdc.sim.simulator import to_run
    from gyro_tdc.identify import train, TrainOptions

    sims = simulate_scenario('die_lag', seed=seed, overrides=overrides(tau_die, curvature))
    runs = [to_run(s) for s in sims]
    t = time.perf_counter()
    res = discover(runs, allan=False)
    t_disc = time.perf_counter() - t
    # What the sensor's slow noise alone leaves: the true drift removed, one offset per run.
    clean = [Run(r.t, r.temp, r.omega - s.truth.drift, r.omega_ref, r.name)
             for r, s in zip(runs, sims)]
    data = BlockData(clean, block_s=res.block_s, t0=res.t0_c)
    y = data.y.copy()
    for k in range(data.n_runs):
        m = data.run == k
        y[m] -= (data.w[m, None] * y[m]).sum(axis=0) / data.w[m].sum()
    oracle = math.degrees(math.sqrt((data.w[:, None] * y * y).sum() / (3 * data.w.sum())))
    s1, s2 = sims
    bag = folder / f'{int(tau_die)}_{curvature}'
    write_bag(bag, imu_t=s1.imu_t, gyro=s1.gyro, accel=s1.accel, temp_t=s1.temp_t,
              temp_c=s1.temp_c)
    floor = (np.degrees(s2.truth.noise_std)) ** 2       # (deg/s)^2, as bias_stability
    held = runs[1]
    out = {}
    for name, features in (('auto', 'auto'), ('paper', 'dT,dT2')):
        t = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            tr = train([bag], folder / f'{bag.name}_{name}.yaml',
                       TrainOptions(features=features))
        out[f't_{name}'] = time.perf_counter() - t
        bs = bias_stability(compensate(tr.model, held.t, held.temp, held.omega),
                            held.omega_ref)
        out[name] = tr
        out[f'bs_{name}'] = float(np.max(np.asarray(bs) / floor))
    return {'res': res, 't_disc': t_disc, 'oracle': oracle, **out}


def main(argv=None) -> int:
    """Run the sweep and print the table."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--tau', type=float, action='append', help='tau_die in s (repeatable)')
    p.add_argument('--curvature', choices=sorted(CURVATURES), action='append')
    p.add_argument('--seed', type=int, default=7)
    args = p.parse_args(argv)
    taus = args.tau or TAUS
    curvs = args.curvature or list(CURVATURES)
    print('tau_die | curvature | discover names | tau (95 % interval) | tau err | gap / floor '
          '(held out; true drift removed) | train auto: features | tau | tau err | '
          'held-out BS / floor (paper dT,dT2) | s')
    print('|'.join(['---'] * 11))
    with tempfile.TemporaryDirectory() as tmp:
        for tau in taus:
            for curv in curvs:
                c = run_case(tau, curv, args.seed, Path(tmp))
                res = c['res']
                th = res.thermal
                if th is None:
                    disc_tau, disc_err = '-', '-'
                else:
                    lo, hi = th.tau_interval_s[0]
                    disc_tau = (f'{th.tau_s[0]:.0f} ({lo:.0f}..{hi:.0f})'
                                + ('' if th.identifiable else ' not identifiable'))
                    disc_err = f'{100 * (th.tau_s[0] / tau - 1):+.1f} %'
                fl = res.noise_floor_dps
                model = c['auto'].model
                mth = model.thermal
                if mth is not None and mth.kind != 'none':
                    tr_tau = f'{mth.tau_total_s:.0f}'
                    tr_err = f'{100 * (mth.tau_total_s / tau - 1):+.1f} %'
                else:
                    tr_tau = tr_err = '-'
                print(f'{tau:.0f} s | {curv} | {", ".join(res.named) or "nothing"} | '
                      f'{disc_tau} | {disc_err} | {res.gap_dps / fl:.2f} '
                      f'({res.heldout_gap_dps / fl:.2f}; {c["oracle"] / fl:.2f}) | '
                      f'{",".join(c["auto"].choice.features)} | {tr_tau} | {tr_err} | '
                      f'{c["bs_auto"]:.3f} ({c["bs_paper"]:.2f}) | '
                      f'{c["t_disc"]:.0f}+{c["t_auto"]:.0f}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
