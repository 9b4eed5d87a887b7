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
Calibrate without a chamber, end to end: train on vehicle day 1's still time, judge day 2.

Usage: ``python tools/field_day.py [--out DIR] [--force] [--json OUT]``.

1. ``gyro-tdc simulate`` the shipped scenarios ``vehicle_day1`` (seed 1) and ``vehicle_day2``
   (seed 2, 4 degC hotter, another schedule and session offset) into ``DIR/day1`` and
   ``DIR/day2`` (kept when present, unless ``--force``);
2. ``gyro-tdc train DIR/day1 --still-only --out DIR/model.yaml`` (default features: auto);
3. judges the model on the whole of day 2, driving included, against the simulator's true
   rate (``/truth/angular_velocity``, never trained on) with the compensator's default
   settings plus start-up re-anchoring, two ways:

   * ``evaluate`` (batch, :func:`gyro_tdc.evaluation.evaluate`, ``--reanchor auto``);
   * streamed one message at a time through :class:`gyro_tdc.compensation_logic.
     CompensatorCore` with default parameters and ``reanchor_on_start`` (the node's logic
     without ROS: thermometer and IMU messages in stamp order, re-anchoring by the node's
     own still test), scored on the samples it compensated;

4. prints BS per axis beside the noise floor (the simulator's per-sample white noise and
   quantisation, ``SimTruth.noise_std``), and the ratio the done-criterion of issue 14
   bounds (1.1x).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run from a checkout without `pip install -e .`
    sys.path.insert(0, str(ROOT))

from gyro_tdc.bagio import read_bag  # noqa: E402
from gyro_tdc.cli.simulate import simulate  # noqa: E402
from gyro_tdc.cli.train import main as train_main  # noqa: E402
from gyro_tdc.compensation_logic import CompensatorCore, Policy  # noqa: E402
from gyro_tdc.errors import GyroTdcError  # noqa: E402
from gyro_tdc.evaluation import evaluate, NamedModel  # noqa: E402
from gyro_tdc.health import PASSTHROUGH  # noqa: E402
from gyro_tdc.model import CompensationModel  # noqa: E402
from gyro_tdc.modelfile import load_model  # noqa: E402
from gyro_tdc.sim import simulate_run  # noqa: E402
from gyro_tdc.sim.vehicle import TRUTH_TOPIC  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

DAYS = (('day1', 'vehicle_day1', 1), ('day2', 'vehicle_day2', 2))
#: The done-criterion: BS within this many noise floors per axis.
BOUND = 1.1
_DEG2 = (180.0 / math.pi) ** 2


def stream(model: CompensationModel, imu_t: NDArray[np.float64], gyro: NDArray[np.float64],
           accel: NDArray[np.float64] | None, temp_t: NDArray[np.float64],
           temp_c: NDArray[np.float64], policy: Policy | None = None
           ) -> tuple[NDArray[np.float64], NDArray[np.bool_], CompensatorCore]:
    """
    Stream a recording through the compensator's core, one message at a time.

    Thermometer messages stamped at or before an IMU stamp are delivered first (the node
    holds the temperature by stamp, so the interleaving does not matter otherwise).

    Parameters
    ----------
    model : CompensationModel
        The model.
    imu_t, gyro, accel : NDArray[np.float64]
        IMU stamps (N,), rates (N, 3) and accelerations (N, 3) or None.
    temp_t, temp_c : NDArray[np.float64]
        Thermometer stamps and readings (M,).
    policy : Policy, optional
        Default: the node's defaults with ``reanchor_on_start``.

    Returns
    -------
    out : NDArray[np.float64], shape (N, 3), rad/s
        The output rate.
    compensated : NDArray[np.bool_], shape (N,)
        Samples compensated (not passed through raw).
    core : CompensatorCore
        The core at the end (its ``anchor``).

    """
    core = CompensatorCore(policy or Policy(reanchor_on_start=True), model)
    out = np.empty_like(gyro)
    ok = np.ones(gyro.shape[0], dtype=bool)
    j, m = 0, temp_t.shape[0]
    tt, tc = temp_t.tolist(), temp_c.tolist()
    acc = accel.tolist() if accel is not None else [None] * gyro.shape[0]
    for k, (t, w, a) in enumerate(zip(imu_t.tolist(), gyro.tolist(), acc)):
        while j < m and tt[j] <= t:
            core.add_temperature(tt[j], tc[j])
            j += 1
        ox, oy, oz, _, flags = core.process(t, w[0], w[1], w[2], a)
        out[k] = (ox, oy, oz)
        ok[k] = not flags & PASSTHROUGH
    return out, ok, core


def field_day(out_dir: Path, *, force: bool = False) -> dict:
    """Run the four steps (module docstring) and return the figures."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for folder, scenario, seed in DAYS:
        bag = out_dir / folder
        if force or not bag.exists():
            simulate(scenario, str(bag), seed=seed, force=force)
    model_path = out_dir / 'model.yaml'
    if train_main([str(out_dir / 'day1'), '--still-only', '--out', str(model_path)]) != 0:
        raise GyroTdcError('train --still-only failed (see above)')
    model = load_model(model_path)
    # The noise floor: what the simulator's white noise and digits leave per sample.
    truth = simulate_run('vehicle_day2', seed=2).truth
    floor = truth.noise_std ** 2 * _DEG2
    batch = evaluate([out_dir / 'day2'], [NamedModel('still-only', 'still-only', model)],
                     options={'reference_topic': TRUTH_TOPIC}, reanchor_s='auto')[0]
    bs_batch = batch.models[0].bs
    raw_bs = batch.raw.bs
    data = read_bag(out_dir / 'day2', reference_topic=TRUTH_TOPIC)
    ref = data.ref[np.clip(np.searchsorted(data.ref_t, data.imu_t, side='right') - 1, 0,
                           None)]
    out, ok, core = stream(model, data.imu_t, data.gyro, data.accel, data.temp_t, data.temp_c)
    err = out[ok] - ref[ok]
    bs_stream = (err ** 2).mean(axis=0) * _DEG2
    anchor = core.anchor
    return {
        'floor_dps2': floor.tolist(), 'raw_bs_dps2': raw_bs.tolist(),
        'evaluate_bs_dps2': bs_batch.tolist(), 'evaluate_ratio': (bs_batch / floor).tolist(),
        'stream_bs_dps2': bs_stream.tolist(), 'stream_ratio': (bs_stream / floor).tolist(),
        'stream_passthrough': int(np.count_nonzero(~ok)), 'samples': int(ok.size),
        'anchor': None if anchor is None else {
            't_s': anchor.t, 'samples': anchor.samples, 'reason': anchor.reason,
            'shift_dps': [math.degrees(v) for v in anchor.delta]},
        'outside_fraction': batch.models[0].outside_fraction,
        'model_range_c': list(model.temp_range_c), 'features': list(model.features),
        'day2_temperature_c': list(batch.temperature_c),
    }


def _print(r: dict) -> None:
    """Print the figures as a table."""
    print(f'\nday 2 (whole day, driving included) against {TRUTH_TOPIC}; model '
          f'f({", ".join(r["features"])}) trained {r["model_range_c"][0]:.1f} .. '
          f'{r["model_range_c"][1]:.1f} degC on day 1\'s still time; day 2 reads '
          f'{r["day2_temperature_c"][0]:.1f} .. {r["day2_temperature_c"][1]:.1f} degC '
          f'({100 * r["outside_fraction"]:.0f} % of it beyond the trained range)')
    print(f'  {"(deg/s)^2":<30}{"x":>11}{"y":>11}{"z":>11}')
    rows = (('noise floor', r['floor_dps2']), ('raw BS', r['raw_bs_dps2']),
            ('evaluate BS (--reanchor auto)', r['evaluate_bs_dps2']),
            ('  / floor', r['evaluate_ratio']),
            ('streamed BS (node core)', r['stream_bs_dps2']), ('  / floor', r['stream_ratio']))
    for name, v in rows:
        print(f'  {name:<30}' + ''.join(f'{x:>11.4g}' for x in v))
    a = r['anchor']
    if a is not None:
        print(f'  streamed: re-anchored at t = {a["t_s"]:.0f} s on {a["samples"]} samples '
              f'({a["reason"]}), shift ' + ', '.join(f'{v:+.4f}' for v in a['shift_dps'])
              + f' deg/s; {r["stream_passthrough"]} of {r["samples"]} samples passed through '
              'before the first temperature (not scored)')
    worst = max(max(r['evaluate_ratio']), max(r['stream_ratio']))
    print(f'  worst ratio {worst:.3f} (bound {BOUND:g}): {"PASS" if worst <= BOUND else "FAIL"}')


def main(argv: list | None = None) -> int:
    """Run the figures; 0 when within the bound, 1 when not, 2 on bad input."""
    p = argparse.ArgumentParser(prog='python tools/field_day.py', description=__doc__.split(
        '\n\n')[0].strip())
    p.add_argument('--out', default='out/field', help='folder of the bags and the model '
                   '(default: %(default)s)')
    p.add_argument('--force', action='store_true', help='simulate the bags again')
    p.add_argument('--json', default=None, metavar='OUT', help='write the figures as JSON')
    args = p.parse_args(argv)
    try:
        r = field_day(Path(args.out), force=args.force)
    except GyroTdcError as exc:
        print(f'field_day: error: {exc}', file=sys.stderr)
        return 2
    _print(r)
    if args.json:
        Path(args.json).write_text(json.dumps(r, indent=1) + '\n', encoding='utf-8')
    return 0 if max(max(r['evaluate_ratio']), max(r['stream_ratio'])) <= BOUND else 1


if __name__ == '__main__':
    sys.exit(main())
