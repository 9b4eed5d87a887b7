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

   * ``evaluate`` (batch, :func:`gyro_tdc.evaluate.score.evaluate`, ``--reanchor auto``);
   * streamed one message at a time through :class:`gyro_tdc.runtime.core.
     CompensatorCore` with default parameters and ``reanchor_on_start`` (the node's logic
     without ROS: thermometer and IMU messages in stamp order, re-anchoring by the node's
     own still test), scored on the samples it compensated;

4. prints BS per axis beside the noise floor (the simulator's per-sample white noise and
   quantisation, ``SimTruth.noise_std``), and the ratio the field criterion
   bounds (1.1x);
5. learns on the vehicle (``compensator_node`` ``learn:=true``, no model): the same core
   with a :class:`gyro_tdc.learn.learner.Learner` attached and stepped by stamp, fed day 1 then
   day 2 (a new session after a 1 h gap); prints day 2's ratio (bound 1.3x), and the second
   half of day 2 uninterrupted beside the same after a kill in the middle of day 2 and a
   restart from the ``learn_file`` saved every ``learn_save_period`` (the restarted state
   equals the last save).
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

from gyro_tdc.base import DEG2_PER_RAD2  # noqa: E402
from gyro_tdc.cli.simulate import simulate  # noqa: E402
from gyro_tdc.cli.train import main as train_main  # noqa: E402
from gyro_tdc.data import BagOptions, read_bag  # noqa: E402
from gyro_tdc.errors import GyroTdcError  # noqa: E402
from gyro_tdc.evaluate.score import evaluate, NamedModel  # noqa: E402
from gyro_tdc.learn.learner import Learner  # noqa: E402
from gyro_tdc.model.compensation import CompensationModel  # noqa: E402
from gyro_tdc.model.modelfile import load_model  # noqa: E402
from gyro_tdc.runtime import CompensatorCore, PASSTHROUGH, Policy  # noqa: E402
from gyro_tdc.sim import simulate_run  # noqa: E402
from gyro_tdc.sim.vehicle import TRUTH_TOPIC  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

DAYS = (('day1', 'vehicle_day1', 1), ('day2', 'vehicle_day2', 2))
#: The done-criterion: BS within this many noise floors per axis (train --still-only) ...
BOUND = 1.1
#: ... and learning online with no model.
LEARN_BOUND = 1.3
#: The night between the days (stamp gap): the learner starts a new session.
GAP_S = 3600.0
#: IMU messages between learner steps (1 s at 10 Hz): within ``swap_delay_s``, so the output
#: is the node's whenever its timer runs (swaps take effect at their stamps).
POLL = 10


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
    out, ok = feed(core, imu_t, gyro, accel, temp_t, temp_c)
    return out, ok, core


def feed(core: CompensatorCore, imu_t: NDArray[np.float64], gyro: NDArray[np.float64],
         accel: NDArray[np.float64] | None, temp_t: NDArray[np.float64],
         temp_c: NDArray[np.float64], *, on_poll=None
         ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """
    Feed a recording to ``core`` (:func:`stream`); step its learner every :data:`POLL`.

    With a learner attached, every :data:`POLL` messages its step runs (the node's timer),
    a swapped model is installed, and ``on_poll(k)`` is called with the message index.

    Returns
    -------
    out : NDArray[np.float64], shape (N, 3), rad/s
        The output rate.
    compensated : NDArray[np.bool_], shape (N,)
        Samples compensated.

    """
    out = np.empty_like(gyro)
    ok = np.ones(gyro.shape[0], dtype=bool)
    tt, tc = temp_t.tolist(), temp_c.tolist()
    m = len(tt)
    j = 0
    learner = core.learner
    acc = accel.tolist() if accel is not None else [None] * gyro.shape[0]
    for k, (t, w, a) in enumerate(zip(imu_t.tolist(), gyro.tolist(), acc)):
        while j < m and tt[j] <= t:
            core.add_temperature(tt[j], tc[j])
            j += 1
        ox, oy, oz, _, flags, _, _ = core.process(t, w[0], w[1], w[2], a)
        out[k] = (ox, oy, oz)
        ok[k] = not flags & PASSTHROUGH
        if learner is not None and k % POLL == POLL - 1:
            core.learn_step()
            if on_poll is not None:
                on_poll(k)
    return out, ok


def learn_days(day1, day2, ref2: NDArray[np.float64], floor: NDArray[np.float64],
               learn_file: Path) -> dict:
    """
    Learn with no model over day 1 then day 2; again, killed mid day 2 and restarted.

    Parameters
    ----------
    day1, day2 : BagData
        The two days (``imu_t``, ``gyro``, ``accel``, ``temp_t``, ``temp_c``).
    ref2 : NDArray[np.float64], shape (N2, 3), rad/s
        Day 2's true rate at its IMU stamps.
    floor : NDArray[np.float64], shape (3,), (deg/s)^2
        The noise floor.
    learn_file : Path
        Where the killed run saves its state (every ``learn_save_period`` of stamps).

    Returns
    -------
    dict
        Ratios to the floor and the learner's summary (see :func:`_print_learn`).

    """
    off = day1.imu_t[-1] + GAP_S - day2.imu_t[0]
    half = day2.imu_t.size // 2
    temps = (day2.temp_t + off, day2.temp_c)

    def part(sl: slice) -> tuple:
        acc = None if day2.accel is None else day2.accel[sl]
        return (day2.imu_t[sl] + off, day2.gyro[sl], acc) + temps

    def new() -> CompensatorCore:
        core = CompensatorCore(Policy())
        core.learner = Learner()
        return core

    def ratio(out, ok, start=0):
        ref = ref2[start:start + out.shape[0]]
        return ((out[ok] - ref[ok]) ** 2).mean(axis=0) * DEG2_PER_RAD2 / floor

    core = new()
    feed(core, day1.imu_t, day1.gyro, day1.accel, day1.temp_t, day1.temp_c)
    out, ok = feed(core, *part(slice(None)))
    full = core.learner
    # Killed in the middle of day 2: everything after the last periodic save is lost.
    killed = new()
    feed(killed, day1.imu_t, day1.gyro, day1.accel, day1.temp_t, day1.temp_c)
    saved = {}

    def save(k: int) -> None:
        if killed.learner.tick_save_clock():
            killed.learner.save(learn_file)
            saved['state'], saved['k'] = json.loads(json.dumps(killed.learner.state())), k

    feed(killed, *part(slice(0, half)), on_poll=save)
    restarted = new()
    restarted.learner.load(learn_file)
    same = json.loads(json.dumps(restarted.learner.state())) == saved['state']
    model = restarted.learner.take_model()
    if model is not None:
        restarted.set_model(model)
    out_r, ok_r = feed(restarted, *part(slice(half, None)))
    s = full.summary()
    lost = day2.imu_t[half - 1] - day2.imu_t[saved['k']]
    return {
        'learn_ratio': ratio(out, ok).tolist(), 'learn_passthrough': int(np.count_nonzero(~ok)),
        'learn_half_ratio': ratio(out[half:], ok[half:], half).tolist(),
        'restart_half_ratio': ratio(out_r, ok_r, half).tolist(),
        'restart_state_equals_save': bool(same), 'restart_lost_samples': half - 1 - saved['k'],
        'restart_lost_s': float(lost), 'points': s['points'], 'bins': s['bins'],
        'covered_c': list(s['covered_c']), 'still_h': s['still_s'] / 3600.0,
        'learn_features': s['features'], 'sessions': full.session + 1,
    }


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
    floor = truth.noise_std ** 2 * DEG2_PER_RAD2
    batch = evaluate([out_dir / 'day2'], [NamedModel('still-only', 'still-only', model)],
                     bag=BagOptions(reference_topic=TRUTH_TOPIC), reanchor_s='auto')[0]
    bs_batch = batch.models[0].bs
    raw_bs = batch.raw.bs
    data = read_bag(out_dir / 'day2', reference_topic=TRUTH_TOPIC)
    ref = data.ref[np.clip(np.searchsorted(data.ref_t, data.imu_t, side='right') - 1, 0,
                           None)]
    out, ok, core = stream(model, data.imu_t, data.gyro, data.accel, data.temp_t, data.temp_c)
    err = out[ok] - ref[ok]
    bs_stream = (err ** 2).mean(axis=0) * DEG2_PER_RAD2
    anchor = core.anchor
    learn = learn_days(read_bag(out_dir / 'day1'), data, ref, floor, out_dir / 'learn.json')
    return {
        **learn, 'floor_dps2': floor.tolist(), 'raw_bs_dps2': raw_bs.tolist(),
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
    _print_learn(r)


def _print_learn(r: dict) -> None:
    """Print the learn-on-the-vehicle figures."""
    print(f'\nlearn on the vehicle (learn:=true, no model), day 1 then day 2 after a '
          f'{GAP_S / 3600:g} h gap; day 2 against {TRUTH_TOPIC}')
    print(f'  {"(deg/s)^2 / floor":<54}{"x":>8}{"y":>8}{"z":>8}')
    rows = (('learned online, day 2', r['learn_ratio']),
            ('second half of day 2, uninterrupted', r['learn_half_ratio']),
            ('same, killed mid day 2, restarted from learn_file', r['restart_half_ratio']))
    for name, v in rows:
        print(f'  {name:<54}' + ''.join(f'{x:>8.3f}' for x in v))
    lo, hi = r['covered_c']
    print(f'  restarted state == last save: {r["restart_state_equals_save"]} (the save '
          f'{r["restart_lost_samples"]} samples, {r["restart_lost_s"]:.0f} s, before the kill); '
          f'end of day 2: {r["points"]} points in {r["bins"]} bins over {lo:.1f} .. {hi:.1f} '
          f'degC from {r["still_h"]:.1f} h still time, {", ".join(r["learn_features"])}; '
          f'{r["learn_passthrough"]} day-2 samples passed through')
    worst = max(r['learn_ratio'])
    print(f'  worst ratio {worst:.3f} (bound {LEARN_BOUND:g}): '
          f'{"PASS" if worst <= LEARN_BOUND else "FAIL"}')


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
    ok = (max(max(r['evaluate_ratio']), max(r['stream_ratio'])) <= BOUND
          and max(r['learn_ratio']) <= LEARN_BOUND and r['restart_state_equals_save'])
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
