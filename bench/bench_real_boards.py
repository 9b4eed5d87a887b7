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

r"""
Real logs of one board: train on four with the CLI, held out on the others (issue 34).

``bench_board_logs.py`` on real flight-controller logs. A group is the logs of one board
(``--group DIR_OR_GLOB``, repeated). Every log is read once as ``evaluate`` reads it
(accelerometer included, ``--temperature-source`` passed through) and its still stretches
found by the project's own still test on the raw data (``gyro_tdc.identify.find_still``, the
test ``evaluate`` scores data without a reference with, ``gyro_tdc.evaluate.still_rows``).
Per seeded draw, four logs (``--train``; fewer in a small group, one log always held out)
are trained exactly as a user runs it (``python -m gyro_tdc train --still-only LOGS --out
m.yaml``, defaults; then default ``train``), drawn among the logs with a still stretch
(the others teach ``--still-only`` nothing), and up to eight others (``--held``) held out,
drawn among those with two still stretches or more (the score needs two); with
``--held-first`` the held-out logs are drawn first, so every draw holds out eight where the
group has eight with two still stretches and four more with one. Score, as
``flightlogs.still_drift``: per axis the within-log drift of still stretches (each
stretch's mean less its log's mean of them: each log re-anchored as the node does) of the
compensated rate over raw's, pooled over the held-out logs. ``--still-only`` passes at
<= 1.05 x on every axis, default ``train`` at <= 1.1 x; a one-line refusal is counted
apart (for default ``train`` a pass when it is about stillness). Per group: logs read,
logs with >= 2 still stretches, pass rates, the worst draws and the worst held-out logs
(each scored alone), and what the trainer's check across power cycles kept.

No logs shipped (most real logs carry no licence): point it at logs you have. A group is
folders or globs, comma-separated; a file repeating an earlier one's bytes is left out. ::

    R=/tmp/reallogs3     # erlerobot/logs
    S="$R/pxf_copter_2[579]-9-2014_*.BIN,$R/pxf_copter_29-09-2014_*.BIN"
    S="$S,$R/pxf_copter_7-9-2014_1[0-6].BIN,$R/pxf_copter_7-9-2014_2[1-5].BIN"
    .venv/bin/python bench/bench_real_boards.py --temperature-source baro --draws 6 --seed 0 \
        --group "$R/pxf_rover_2-8-2014_mpu9250-ms5611_*.BIN" \
        --group "$R/pxf_copter_6-3-2014_*.BIN" --group "$R/pxf_copter_7-9-2014_*.BIN" \
        --group "$S" --group "$R/pxf_copter_23-9-2014_*.BIN" \
        --group "/tmp/reallogs/joey/2014-10-18_*.bin"
    .venv/bin/python bench/bench_real_boards.py --group /tmp/reallogs/uob

The groups measured (``doc/benchmarks.md``). ArduCopter / ArduRover DataFlash logs of
erlerobot/logs (Erle PXF prototype boards, 2014; ``IMU`` at 50-56 Hz with no thermometer:
``--temperature-source baro``, the MS5611's): ``pxf_rover_2-8-2014_mpu9250-ms5611_*``, one
rover's MPU9250 on one day (11 logs; 5 read a constant 0 on every axis, a gyro that did not
start); ``pxf_copter_6-3-2014_*``, one copter on one day (7 logs, boot-calibrated);
``pxf_copter_7-9-2014_*``, a day of 25 logs of at least two set-ups (50 Hz logs with a
-6 deg/s offset, 56 Hz ones with +0.8); the 56 Hz copter of September 2014 (25, 27 and 29 Sep
and the 56 Hz logs of 7 Sep: the same offsets, +0.4..0.9 deg/s on x and y; the 29 Sep files
repeat 7 Sep ones byte for byte); ``pxf_copter_23-9-2014_*``, a copter with a -23 deg/s offset
that moves by up to 3 deg/s with its attitude (3 logs, two of 15 and 22 min with 15 and 14 still
stretches). joeydouglas/dataflash_logs' four logs of 18 Oct 2014 (ArduCopter 3.1.3, no
IMU thermometer, no usable barometer one: none read); UoBFlightLab/mav_log_data_science's two
logs of one board (``IMU.T``, one still stretch each: nothing to score); toopazo/toopazo_ulg's
six PX4 logs of one FMU v4 Pro copter on one day (8-94 s, barometer only, one still stretch
each at most: nothing to score). fdeedat/Repo_TA_2024 (no licence: not shipped; ``fetch
github:fdeedat/Repo_TA_2024``, then ``git show c70c7322:LOGS/000000NN.BIN``, 17 logs under
4 MiB): one SpeedyBee F4 V4 (ICM-42688-P, the same serial in every log), ArduCopter
4.6.0-dev, ``IMU`` at 25 Hz with ``T`` in 0.48 degC steps, logging stops of up to 8 min,
most ends cut inside a message, 26-47 degC: a board as issue 34 describes. ::

    .venv/bin/python bench/bench_real_boards.py --group SPEEDYBEE_FOLDER --draws 6 --seed 0

``--node`` also streams every held-out log through the compensator node's core with its
defaults (``CompensatorCore(Policy(), model)``: start-up re-anchoring with the model's gate,
out-of-range rules) and scores what the within-log drift cannot see, a constant error: the
RMS of the output's still-stretch means after each log's first still stretch (the rate is
zero while still), beside raw's (the board's own boot calibration, doing nothing) and raw
re-anchored on its first still stretch (what re-anchoring alone, without a model, gives).

A model with an accelerometer part is also scored on the held-out logs' still segments
(:func:`gyro_tdc.identify.accel.static_data`): the accelerometer's BS within each orientation
segment, compensated over raw, per axis.
"""

import argparse
import glob
import hashlib
import math
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402
import tempfile  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'bench', ROOT / 'test' / 'support', ROOT / 'tools'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import numpy as np  # noqa: E402

#: Pass bounds on every axis: ``--still-only``, default ``train``.
BOUND_STILL, BOUND_TRAIN = 1.05, 1.1
SUFFIXES = ('.ulg', '.bin')
_DEG = 180.0 / math.pi


def group_logs(spec: str) -> tuple[list, list]:
    """
    Return the logs of a group and the copies left out, sorted.

    ``spec`` is folders (walked) or globs, comma-separated; a file whose bytes repeat an
    earlier one's (the same log under two names) is left out.
    """
    found = []
    for part in spec.split(','):
        p = Path(part)
        found += sorted(p.rglob('*')) if p.is_dir() else sorted(
            Path(f) for f in glob.glob(part, recursive=True))
    seen, logs, copies = {}, [], []
    for f in found:
        if not (f.is_file() and f.suffix.lower() in SUFFIXES):
            continue
        key = hashlib.sha256(f.read_bytes()).hexdigest()
        if key in seen:
            copies.append((f, seen[key]))
        else:
            seen[key] = f
            logs.append(f)
    return logs, copies


def read_log(path: Path, source: str) -> dict:
    """
    Read one log as ``evaluate`` does; return its run, still mask and stretches, or the refusal.

    ``spans``: the (start, stop) of each run of still samples; ``stretches``: how many.
    """
    from gyro_tdc.data import BagOptions
    from gyro_tdc.data.dataset import load_run
    from gyro_tdc.errors import GyroTdcError
    from gyro_tdc.evaluate.score import held_out_constant
    from gyro_tdc.identify import find_still
    try:
        run = load_run(path, BagOptions(accel=True, temperature_source=source))
        held_out_constant(run)          # every gyro axis constant: evaluate refuses it too
    except GyroTdcError as exc:
        return {'path': path, 'refused': str(exc).splitlines()[0]}
    still = find_still([run])[0].mask
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    spans = list(zip(edges[::2].tolist(), edges[1::2].tolist()))
    return {'path': path, 'run': run, 'still': still, 'spans': spans, 'stretches': len(spans)}


def noise_se(logs: list) -> np.ndarray:
    """Return the white-noise standard error of a still stretch's mean, deg/s (RMS, per axis)."""
    se = [lg['run'].omega[a:b].var(axis=0) / (b - a) for lg in logs for a, b in lg['spans']]
    return np.sqrt(np.mean(se, axis=0)) * _DEG


def drift(logs: list, model=None) -> np.ndarray:
    """Return the within-log drift of still stretches per axis, deg/s (raw, or compensated)."""
    from flightlogs import FlightDay, Imu, still_drift
    from gyro_tdc.model import compensate, DEFAULT_OUT_OF_RANGE
    days, rates = [], []
    for lg in logs:
        r = lg['run']
        days.append(FlightDay(Imu(r.t, r.omega, r.temp), lg['still'], np.zeros(3),
                              np.zeros((2, 3))))
        rates.append(r.omega if model is None else
                     compensate(model, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE))
    return still_drift(days, rates) * _DEG


def accel_bs(logs: list, model) -> np.ndarray:
    """Return the accelerometer's BS within each still segment, compensated over raw."""
    from gyro_tdc.identify.accel import compensate_accel, static_data
    ss = np.zeros((2, 3))
    for lg in logs:
        r = lg['run']
        d = static_data(r)
        if d is None:
            continue
        a = np.asarray(r.accel, dtype=np.float64)
        for x, k in ((a, 0), (compensate_accel(model, r.t, r.temp, a), 1)):
            for s in range(d.n_segments):
                v = x[d.segment == s]
                ss[k] += ((v - v.mean(axis=0)) ** 2).sum(axis=0) if len(v) > 1 else 0.0
    return ss[1] / ss[0]


def check_note(model_path: Path) -> str:
    """Return how the trainer judged the curve across power cycles, and what it kept."""
    from bench_board_logs import check_note as note
    from gyro_tdc.model.modelfile import load_model
    rec = load_model(model_path).metrics.get('sessions', {}).get('heldout') or {}
    if rec.get('widest_span_c') is not None:
        return (f"not judged, no power cycle spans 2 degC (widest {rec['widest_span_c']:.2f}): "
                f"offset only: {','.join(rec['offset_only'])}")
    return note(model_path)


def node_error(logs: list, model=None, anchored: bool = False) -> np.ndarray:
    """
    Return the RMS of still-stretch means after each log's first, deg/s per axis.

    Of the node's output with ``model`` (streamed through ``CompensatorCore`` with the
    defaults), else of raw, ``anchored``: less its first still stretch's mean.
    """
    from field_day import feed
    from gyro_tdc.runtime import CompensatorCore, Policy
    errs = []
    for lg in logs:
        r = lg['run']
        out = r.omega if model is None else feed(CompensatorCore(Policy(), model), r.t, r.omega,
                                                 r.accel, r.t, r.temp)[0]
        means = np.array([out[a:b].mean(axis=0) for a, b in lg['spans']])
        errs.append(means[1:] - (means[0] if anchored else 0.0))
    return np.sqrt(np.mean(np.concatenate(errs) ** 2, axis=0)) * _DEG


def _ratio(comp: np.ndarray, raw: np.ndarray) -> np.ndarray:
    """Return comp / raw per axis (NaN where raw is 0: a constant axis has nothing to score)."""
    return np.divide(comp, raw, out=np.full(3, math.nan), where=raw > 0)


def draw_logs(logs: list, rng: np.random.Generator, n_train: int, n_held: int,
              held_first: bool) -> tuple[list, list]:
    """
    Return a draw's trained and held-out logs.

    By default the trained logs are drawn first among those with a still stretch, then up
    to ``n_held`` held out among the others with two. ``held_first`` draws the held-out
    logs first, leaving ``n_train`` logs with a still stretch to train on: every draw then
    holds out ``n_held`` logs where the group has that many with two still stretches.
    """
    def pick(pool, n):
        return [pool[i] for i in sorted(rng.choice(len(pool), size=n, replace=False))]

    def without(pool, drawn):
        return [lg for lg in pool if not any(lg is d for d in drawn)]

    with_still = [lg for lg in logs if lg['stretches'] >= 1]
    two = [lg for lg in logs if lg['stretches'] >= 2]
    if held_first:
        held = pick(two, max(0, min(n_held, len(two), len(with_still) - n_train)))
        pool = without(with_still, held) or without(logs, held)
        return pick(pool, min(n_train, len(pool))), held
    pool = with_still if len(with_still) >= n_train + 1 else logs
    train = [pool[i] for i in rng.choice(len(pool), size=min(n_train, len(pool) - 1),
                                         replace=False)]
    others = without(two, train)
    return train, pick(others, min(n_held, len(others)))


def run_draw(logs: list, rng: np.random.Generator, n_train: int, n_held: int, source: str,
             folder: Path, held_first: bool = False, node: bool = False) -> dict | None:
    """Train on a seeded draw of a group's logs with the CLI; return the held-out scores."""
    from bench_board_logs import cli_train
    from gyro_tdc.model.modelfile import load_model
    train, held = draw_logs(logs, rng, n_train, n_held, held_first)
    if not held or not train:
        return None
    raw = drift(held)
    out = {'train_logs': [lg['path'].name for lg in train],
           'held_logs': [lg['path'].name for lg in held],
           'raw_dps': raw, 'se_dps': noise_se(held)}
    if node:
        out['node_raw'], out['node_anchored'] = node_error(held), node_error(held, anchored=True)
    for name, extra in (('still_only', ('--still-only',)), ('train', ())):
        path = folder / f'{name}.yaml'
        path.unlink(missing_ok=True)
        code, err = cli_train([lg['path'] for lg in train], path, '--no-progress',
                              '--temperature-source', source, *extra)
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        if code != 0:
            out[name] = None
            out[name + '_note'] = lines[-1].split(': error: ', 1)[-1] if lines else f'exit {code}'
            out[name + '_one_line'] = (code == 2 and 'Traceback' not in err
                                       and sum(': error: ' in ln for ln in lines) == 1)
            continue
        model = load_model(path)
        out[name] = _ratio(drift(held, model), raw)
        out[name + '_check'] = check_note(path)
        if node:
            out[name + '_node'] = node_error(held, model)
        out[name + '_accel'] = None if model.accel is None else accel_bs(held, model)
        out[name + '_per_log'] = [(lg['path'].name, _ratio(drift([lg], model), drift([lg])))
                                  for lg in held]
    return out


def _fmt(v) -> str:
    """Return three ratios as x / y / z."""
    return ' / '.join(f'{x:.3f}' for x in v)


def _worst(v) -> float:
    """Return the largest ratio of three (a NaN axis, nothing to score, counts as 0)."""
    return float(np.max(np.nan_to_num(v, nan=0.0)))


def _passes(r: dict, name: str, bound: float) -> bool | None:
    """Return whether a trainer passed a draw (None: refused, counted apart)."""
    if r[name] is None:
        return None
    return _worst(r[name]) <= bound


def summary(rows: list, name: str, bound: float) -> list[str]:
    """Return one trainer's pass rate over the draws, its worst draws and held-out logs."""
    fitted = [r for r in rows if r[name] is not None]
    refused = [r for r in rows if r[name] is None]
    ok_ref = [r for r in refused if r[name + '_one_line']
              and (name == 'still_only' or 'still' in r[name + '_note'])]
    passed = sum(bool(_passes(r, name, bound)) for r in fitted)
    rates = ' '.join(f'<= {b:g}: {sum(bool(_passes(r, name, b)) for r in fitted)}'
                     for b in (BOUND_STILL, BOUND_TRAIN))
    out = [f'{name}: {passed + len(ok_ref)}/{len(rows)} pass (<= {bound:g} x raw on every '
           f'axis: {passed} of {len(fitted)} fitted ({rates}); refused in one line'
           + (' about stillness' if name == 'train' else '') + f': {len(ok_ref)} of '
           f'{len(refused)} refusals)']
    if fitted:
        ratios = np.array([r[name] for r in fitted])
        out.append('  median per axis (x / y / z): ' + _fmt(np.nanmedian(ratios, axis=0)))
        for r in sorted(fitted, key=lambda r: -_worst(r[name]))[:3]:
            out.append(f"  worst draw {r['draw']}: {_fmt(r[name])}; check: {r[name + '_check']}")
        logs = sorted(((f, v, r['draw']) for r in fitted for f, v in r[name + '_per_log']),
                      key=lambda x: -_worst(x[1]))
        for f, v, d in logs[:3]:
            out.append(f'  worst held-out log: {f} (draw {d}) {_fmt(v)}')
    if fitted and name + '_node' in fitted[0]:
        for base, what in (('node_raw', 'raw (boot calibration)'),
                           ('node_anchored', 'raw re-anchored on its first stop')):
            q = np.array([_ratio(r[name + '_node'], r[base]) for r in fitted])
            out.append(f'  node, still means after the first stop, over {what}: median '
                       + _fmt(np.nanmedian(q, axis=0)) + ', worst ' + _fmt(np.nanmax(q, axis=0))
                       + f', draws <= 1.05 on every axis: {int(np.sum(np.all(q <= 1.05, 1)))}'
                       f' of {len(q)}')
    if fitted:
        parts = [r[name + '_accel'] for r in fitted if r[name + '_accel'] is not None]
        out.append(f'  accelerometer part in {len(parts)} of {len(fitted)} fitted models'
                   + ('' if not parts else ': held-out still segments, BS over raw within '
                      'each: median ' + _fmt(np.nanmedian(parts, axis=0)) + ', worst '
                      + _fmt(np.nanmax(parts, axis=0)) + ', draws <= 1.05 on every axis: '
                      f'{int(np.sum(np.all(np.array(parts) <= 1.05, axis=1)))} of {len(parts)}'))
    notes = sorted({r[name + '_note'][:120] for r in refused})
    out += [f'  refused: {n}' for n in notes]
    return out


def main(argv=None) -> int:
    """Run every group's draws; print each draw, then per group the summaries."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--group', action='append', required=True, metavar='DIR_OR_GLOB',
                    help='the logs of one board: folders or globs, comma-separated (repeat '
                    'for several groups)')
    ap.add_argument('--temperature-source', default='imu',
                    help='passed to the readers and to train (imu, baro, TOPIC.FIELD)')
    ap.add_argument('--draws', type=int, default=4, help='seeded draws per group')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--train', type=int, default=4, help='logs trained on per draw')
    ap.add_argument('--held', type=int, default=8, help='held-out logs per draw, at most')
    ap.add_argument('--held-first', action='store_true',
                    help='draw the held-out logs first (up to --held with two still '
                    'stretches), then the trained among the rest')
    ap.add_argument('--node', action='store_true',
                    help="also stream the held-out logs through the node's core (defaults) "
                    'and score its still means after the first stop')
    args = ap.parse_args(argv)
    src = args.temperature_source
    for spec in args.group:
        paths, copies = group_logs(spec)
        logs = [read_log(p, src) for p in paths]
        read = [lg for lg in logs if 'run' in lg]
        two = [lg for lg in read if lg['stretches'] >= 2]
        print(f'== group {spec}: {len(paths)} logs, {len(read)} read, '
              f"{sum(lg['stretches'] >= 1 for lg in read)} with a still stretch, {len(two)} with "
              f'2 or more ({src} thermometer)', flush=True)
        for f, first in copies:
            print(f'  left out {f.name}: the same bytes as {first.name}')
        for lg in logs:
            if 'run' not in lg:
                print(f"  not read: {lg['path'].name}: {lg['refused'][:140]}")
        rows = []
        with tempfile.TemporaryDirectory(prefix='bench_real_boards_') as tmp:
            for d in range(args.draws):
                if len(read) < 2:
                    break
                r = run_draw(read, np.random.default_rng([args.seed, d]), args.train, args.held,
                             src, Path(tmp), args.held_first, args.node)
                if r is None:
                    print(f'  draw {d}: no held-out log with 2 still stretches')
                    continue
                r['draw'] = d
                rows.append(r)
                fmt = ['refused' if r[n] is None else _fmt(r[n]) for n in ('still_only', 'train')]
                print(f"  draw {d}: train {' '.join(r['train_logs'])}\n    held out "
                      f"({len(r['held_logs'])}): {' '.join(r['held_logs'])}; raw drift "
                      f"{_fmt(r['raw_dps'])} deg/s (a stretch mean's white-noise SE "
                      f"{_fmt(r['se_dps'])})\n    still-only {fmt[0]} | train {fmt[1]}"
                      + ''.join(f"\n    {n}: {r[n + '_note'][:140]}"
                                for n in ('still_only', 'train') if r[n] is None)
                      + ''.join(f"\n    {n} check: {r[n + '_check']}"
                                for n in ('still_only', 'train') if r[n] is not None),
                      flush=True)
        if rows:
            for name, bound in (('still_only', BOUND_STILL), ('train', BOUND_TRAIN)):
                print('\n'.join(f'  {ln}' for ln in summary(rows, name, bound)), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
