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
Beyond the trained range on the PAN CubeSat TVAC recording: clamp vs linear vs extrapolate.

Usage: ``python tools/pan_range_holdout.py [--csv PATH] [--split-c 19] [--json OUT]``.
Trains on the warmer bursts only (burst mean above ``--split-c``), holds out the colder ones
(every held-out sample lies below the trained range: the unit cools), and scores each model
on them under the three out-of-range policies of :mod:`gyro_tdc.model.out_of_range`, beside a
plain linear fit f(dT) (for which the three coincide but clamp) and a bias-only baseline.
Scores are BS in (deg/s)^2 (:func:`gyro_tdc.evaluate.score.score`, reference 0) and BS over the
white-noise floor of the held-out bursts (their samples around their own burst means, as in
``tools/pan_holdout.py``). The table and its reading are in ``doc/real_data.md``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
# A checkout without `pip install -e .`, and tools/pan_holdout.py (its run_tool) beside this.
for path in (ROOT, ROOT / 'tools'):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from gyro_tdc.data.realdata import default_pan_csv, read_pan_cubesat_csv  # noqa: E402
from gyro_tdc.data.runs import Run  # noqa: E402
from gyro_tdc.errors import GyroTdcError  # noqa: E402
from gyro_tdc.evaluate.realdata import burst_index  # noqa: E402
from gyro_tdc.evaluate.score import score  # noqa: E402
from gyro_tdc.identify import fit_model  # noqa: E402
from gyro_tdc.model.compensation import compensate  # noqa: E402
from gyro_tdc.model.out_of_range import MAX_EXTRAPOLATION_C, OUT_OF_RANGE_POLICIES  # noqa: E402
from gyro_tdc.signal.metrics import bias_stability  # noqa: E402
import numpy as np  # noqa: E402
from pan_holdout import run_tool  # noqa: E402

#: (name, description, fit_model options); ``bias`` and ``linear fit`` are the baselines.
MODELS = (
    ('rbf', 'RBF f(dT, dT^2), K = 12 (the train default kind)',
     {'kind': 'rbf', 'features': ('dT', 'dT2'), 'n_centers': 12}),
    ('modified', "poly f(dT, dT^2) (the paper's modified model)",
     {'kind': 'poly', 'features': ('dT', 'dT2')}),
    ('px4', 'PX4-style cubic f(dT, dT^2, dT^3)',
     {'kind': 'poly', 'features': ('dT', 'dT2', 'dT3')}),
    ('linear fit', 'plain linear fit f(dT)', {'kind': 'poly', 'features': ('dT',)}),
    ('bias', 'constant offset (no thermal model)', {'kind': 'poly', 'features': ()}),
)


def _rows(run: Run, keep: np.ndarray, name: str) -> Run:
    """Return the rows ``keep`` of a run as a run of their own."""
    return Run(run.t[keep], run.temp[keep], run.omega[keep], run.omega_ref[keep], name)


def range_holdout(csv: str | Path | None = None, *, split_c: float = 19.0) -> dict:
    """
    Train on the bursts warmer than ``split_c``, score the colder ones under each policy.

    Parameters
    ----------
    csv : str or Path, optional
        ``TVCtest3_7_20.csv`` (default: the copy in the repository).
    split_c : float, degC
        Bursts whose mean temperature is above it train, the others are held out.

    Returns
    -------
    dict
        Plain types: ``source``, ``split_c``, ``train`` and ``held_out`` (bursts, samples,
        temperature range), ``floor_bs_dps2`` (3), ``beyond_c`` (largest distance of a
        held-out sample from the trained range), and ``models``: ``{name: {description,
        temp_range_c, policies: {policy: {bs, floor_ratio, total_ratio}}}}``.

    """
    path = Path(csv) if csv is not None else default_pan_csv()
    data = read_pan_cubesat_csv(path)
    run = Run(data.t, data.temp_c, data.gyro, np.zeros_like(data.gyro), str(path))
    burst = burst_index(run.t)
    n_bursts = int(burst[-1]) + 1
    mean_t = np.array([run.temp[burst == b].mean() for b in range(n_bursts)])
    warm = np.isin(burst, np.flatnonzero(mean_t > split_c))
    if warm.all() or not warm.any():
        raise GyroTdcError(f'Expected bursts on both sides of --split-c {split_c:g} degC, '
                           f'got burst means {mean_t.min():.2f} .. {mean_t.max():.2f} degC.')
    train, held = _rows(run, warm, 'warm'), _rows(run, ~warm, 'cold')
    hb = burst[~warm]
    _, pos = np.unique(hb, return_inverse=True)
    err = held.omega - held.omega_ref
    means = np.array([err[pos == k].mean(axis=0) for k in range(pos.max() + 1)])
    floor = bias_stability(err, means[pos])
    t0 = float(mean_t[0])
    out = {'source': str(path), 'split_c': float(split_c), 't0_c': t0,
           'train': {'bursts': int(np.count_nonzero(mean_t > split_c)),
                     'samples': len(train),
                     'temperature_c': [float(train.temp.min()), float(train.temp.max())]},
           'held_out': {'bursts': int(np.count_nonzero(mean_t <= split_c)),
                        'samples': len(held),
                        'temperature_c': [float(held.temp.min()), float(held.temp.max())]},
           'floor_bs_dps2': floor.tolist(), 'models': {}}
    for name, description, opts in MODELS:
        model = fit_model([train], t0=t0, seed=0, **opts)
        lo, hi = model.temp_range_c
        out['beyond_c'] = float(max(lo - held.temp.min(), held.temp.max() - hi, 0.0))
        policies = {}
        for policy in OUT_OF_RANGE_POLICIES:
            comp = compensate(model, held.t, held.temp, held.omega, out_of_range=policy)
            bs = score(comp, held, allan=False).bs
            policies[policy] = {'bs': bs.tolist(), 'floor_ratio': (bs / floor).tolist(),
                                'total_ratio': float(bs.sum() / floor.sum())}
        out['models'][name] = {'description': description, 'temp_range_c': [lo, hi],
                               'policies': policies}
    return out


def format_range_holdout(r: dict) -> str:
    """Return the tables :func:`main` prints (BS / floor per axis and over the three)."""
    tr, ho = r['train'], r['held_out']
    lines = [
        f'{r["source"]}: trained on {tr["bursts"]} bursts above {r["split_c"]:g} degC '
        f'({tr["temperature_c"][0]:.2f} .. {tr["temperature_c"][1]:.2f} degC, '
        f'{tr["samples"]} samples); held out the {ho["bursts"]} colder bursts '
        f'({ho["temperature_c"][0]:.2f} .. {ho["temperature_c"][1]:.2f} degC, '
        f'{ho["samples"]} samples), up to {r["beyond_c"]:.2f} degC below the trained range',
        'noise floor of the held-out bursts (deg/s)^2: '
        + ' '.join(f'{v:.3e}' for v in r['floor_bs_dps2']),
        f'BS / floor per axis and over x+y+z (1 = the noise floor; linear: the tangent at '
        f'the range end, held beyond {MAX_EXTRAPOLATION_C:g} degC)', '',
        f'  {"model":<12}{"policy":<13}{"x":>8}{"y":>8}{"z":>8}{"x+y+z":>8}'
        f'{"BS x (deg/s)^2":>16}']
    for name, m in r['models'].items():
        for policy, p in m['policies'].items():
            lines.append(f'  {name:<12}{policy:<13}'
                         + ''.join(f'{v:8.2f}' for v in p['floor_ratio'])
                         + f'{p["total_ratio"]:8.2f}{p["bs"][0]:16.3e}')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the comparison on ``argv`` (``sys.argv[1:]`` when None); 0, or 2 on bad input."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--csv', type=Path, default=default_pan_csv(),
                        help='TVCtest3_7_20.csv (default: %(default)s)')
    parser.add_argument('--split-c', type=float, default=19.0, metavar='C',
                        help='train on bursts warmer than this, hold out the others '
                        '(default: %(default)s degC)')
    parser.add_argument('--json', type=Path, default=None, metavar='OUT',
                        help='write the figures as JSON')
    args = parser.parse_args(argv)
    return run_tool('pan_range_holdout',
                    lambda: range_holdout(args.csv, split_c=args.split_c),
                    format_range_holdout, args.json)


if __name__ == '__main__':
    sys.exit(main())
