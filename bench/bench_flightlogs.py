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
A seeded randomized sweep over synthetic flight-controller logs (issue 34's readers and trainers).

Each case draws one board and eight power cycles of it (``test/support/flightlogs.flight_day``):
an IMU rate from 1 Hz to 2 kHz (log-uniform), a turn-on offset per power cycle, a
thermometer resolution from 0.004 to 1 degC, flights between still stretches of 10-60 s,
spike glitches, and for half the logs an end cut off inside a message; each log is written
as a PX4 ULog (``sensor_gyro`` at full rate, or ``sensor_combined`` at full rate beside a
1 Hz ``sensor_gyro`` carrying the temperature, or the sensor's FIFO ``sensor_gyro_fifo`` at
full rate in blocks beside those two at a quarter of it) or an ArduPilot DataFlash log
(``IMU.T``, or ``IMU.Temp``; or ``IMU.T`` at 25 Hz beside the sensor-rate ``GYR``) and read
back. Printed per test: the pass rate and the worst cases.

- **read**: every log is read, or refused in one line (a ``GyroTdcError``); any other
  exception is a failure.
- **fastest gyro**: every log read gives the gyro at half the drawn rate or more (the
  fastest the log holds, whatever carries the temperature).
- **never fit motion**: default ``train`` on four logs either refuses in one line or gives a
  model that does no harm on the four held-out logs: the within-log drift of their still
  stretches (each stretch's mean less the log's mean of them) at most 1.1 x raw per axis.
- **still found**: the still test with the trainers' defaults (``find_still``) finds at least
  half of the true still time in the stretches its rule can keep (60 s, or MIN_STILL_SAMPLES
  samples), and nothing of a flight (precision >= 0.99).

::

    .venv/bin/python bench/bench_flightlogs.py                # 8 cases, ~5 min
    .venv/bin/python bench/bench_flightlogs.py --cases 40 --seed 1
"""

import argparse
import math
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402
import tempfile  # noqa: E402
import traceback  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import numpy as np  # noqa: E402

#: Samples per log at most (legs are fewer at high rates, so a case stays short).
MAX_SAMPLES = 400_000


def _case(rng: np.random.Generator) -> dict:
    """Draw one board: rate, resolution, drift, legs, glitches, cuts and formats."""
    rate = float(math.exp(rng.uniform(math.log(1.0), math.log(2000.0))))
    legs = int(rng.integers(3, 8))
    per_leg = 35.0 + 70.0                       # mean still + flight, s
    legs = max(2, min(legs, int(MAX_SAMPLES / (rate * per_leg))))
    drift = np.array([rng.normal(0.0, 0.006, 3), rng.normal(0.0, 5e-5, 3)])
    return {'rate_hz': rate, 'legs': legs,
            'resolution_c': float(math.exp(rng.uniform(math.log(0.004), math.log(1.0)))),
            'noise_dps': float(rng.uniform(0.02, 0.2)), 'drift': drift,
            'glitches': int(rng.integers(0, 6)), 'cut': rng.random(8) < 0.5,
            'format': rng.choice(FORMATS, size=8)}


#: How a power cycle is written: PX4 sensor_gyro at full rate; PX4 sensor_combined at full
#: rate beside sensor_gyro (with the temperature) at 1 Hz; ArduPilot IMU with ``T``; with
#: ``Temp`` (ArduCopter 3.4); IMU with ``T`` at 25 Hz beside GYR at full rate; PX4
#: sensor_gyro_fifo at full rate (blocks of up to 32) beside the multi-rate topics at a quarter.
FORMATS = ('ulog', 'ulog_multi_rate', 'dataflash', 'dataflash_temp', 'dataflash_gyr',
           'ulog_fifo')


def _multi_rate(imu) -> list:
    """Return ULog topics: sensor_combined at the IMU's rate, sensor_gyro at 1 Hz."""
    from flightlogs import SENSOR_COMBINED, SENSOR_GYRO, Topic
    us = np.round(np.asarray(imu.t) * 1e6).astype(np.uint64)
    step = max(1, int(round(1.0 / float(np.median(np.diff(imu.t))))))
    slow = np.arange(0, len(us), step)
    return [Topic('sensor_combined', SENSOR_COMBINED, {
                'timestamp': us, 'gyro_rad': imu.gyro, 'accelerometer_m_s2': imu.accel}),
            Topic('sensor_gyro', SENSOR_GYRO, {
                'timestamp': us[slow], 'timestamp_sample': us[slow], 'device_id': 1,
                'x': imu.gyro[slow, 0], 'y': imu.gyro[slow, 1], 'z': imu.gyro[slow, 2],
                'temperature': imu.temp[slow]})]


def _fifo(imu) -> list:
    """Return ULog topics: sensor_gyro_fifo at the IMU's rate, the rest as ``_multi_rate``'s."""
    from dataclasses import replace
    from flightlogs import fifo_topic
    rate = 1.0 / float(np.median(np.diff(imu.t)))
    quarter = replace(imu, t=imu.t[::4], gyro=imu.gyro[::4], temp=imu.temp[::4],
                      accel=imu.accel[::4])
    return _multi_rate(quarter) + [fifo_topic('sensor_gyro_fifo', imu.t, imu.gyro, 1,
                                              block=int(np.clip(rate // 250, 1, 32)))]


def _gyr(imu) -> tuple:
    """Return (IMU records at 25 Hz or the IMU's rate if slower, GYR records at full rate)."""
    from dataclasses import replace
    step = max(1, int(round(1.0 / (25.0 * float(np.median(np.diff(imu.t)))))))
    slow = replace(imu, t=imu.t[::step], gyro=imu.gyro[::step], temp=imu.temp[::step],
                   accel=None if imu.accel is None else imu.accel[::step])
    return [slow], {0: replace(imu, accel=None)}


def _write(day, path: Path, fmt: str, cut: bool, rng: np.random.Generator) -> Path:
    """Write one power cycle as a log, its end cut off inside a message when ``cut``."""
    from flightlogs import px4_topics, write_dataflash, write_ulog
    from dataclasses import replace
    if fmt == 'ulog':
        topics = px4_topics([replace(day.imu, accel=None)])
        path = write_ulog(path.with_suffix('.ulg'), topics)
    elif fmt in ('ulog_multi_rate', 'ulog_fifo'):
        topics = (_multi_rate if fmt == 'ulog_multi_rate' else _fifo)(day.imu)
        path = write_ulog(path.with_suffix('.ulg'), topics)
    elif fmt == 'dataflash_gyr':
        slow, fast = _gyr(day.imu)
        path = write_dataflash(path.with_suffix('.bin'), slow, fast=fast)
    else:
        path = write_dataflash(path.with_suffix('.bin'), [day.imu],
                               temp_field='Temp' if fmt == 'dataflash_temp' else 'T')
    if cut:
        data = path.read_bytes()
        path.write_bytes(data[:len(data) - int(rng.integers(1, 20))])
    return path


def _still_found(days, paths) -> tuple[float, float]:
    """Return recall and precision of the default still test against the true still time."""
    from gyro_tdc.data.dataset import load_run
    from gyro_tdc.identify.still_only import find_still
    from gyro_tdc.signal import MIN_STILL_S, MIN_STILL_SAMPLES
    runs = [load_run(p) for p in paths]
    found = find_still(runs)
    hit = total = got = right = 0
    for day, run, st in zip(days, runs, found):
        truth = np.interp(run.t, day.imu.t, day.still.astype(float)) > 0.5
        got += int(np.count_nonzero(st.mask))
        right += int(np.count_nonzero(truth & st.mask))
        # Recall over the true stretches the default rule can keep (60 s, or MIN_STILL_SAMPLES).
        edges = np.flatnonzero(np.diff(np.concatenate([[0], truth.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= MIN_STILL_SAMPLES or run.t[b - 1] - run.t[a] >= MIN_STILL_S:
                hit += int(np.count_nonzero(st.mask[a:b]))
                total += int(b - a)
    return (hit / total if total else math.nan), (right / got if got else 1.0)


def run_case(k: int, seed: int, folder: Path) -> dict:
    """Run the three tests on one drawn board; return its figures."""
    from flightlogs import flight_day, still_drift
    from gyro_tdc.data.dataset import load_run
    from gyro_tdc.data.flightlog import rate_hz
    from gyro_tdc.errors import GyroTdcError
    from gyro_tdc.identify import train, TrainOptions
    from gyro_tdc.model import compensate, DEFAULT_OUT_OF_RANGE

    rng = np.random.default_rng([seed, k])
    c = _case(rng)
    days = [flight_day(int(rng.integers(1 << 30)), rate_hz=c['rate_hz'], legs=c['legs'],
                       resolution_c=c['resolution_c'], noise_dps=c['noise_dps'],
                       drift=c['drift'], glitches=c['glitches']) for _ in range(8)]
    paths = [_write(d, folder / f'c{k}_{j}', str(c['format'][j]), bool(c['cut'][j]), rng)
             for j, d in enumerate(days)]
    out = {'case': k, **{key: c[key] for key in ('rate_hz', 'legs', 'resolution_c',
                                                 'noise_dps', 'glitches')},
           'formats': ' '.join(f'{str(f)}{"(cut)" if cut else ""}'
                               for f, cut in zip(c['format'], c['cut']))}
    out['read'], out['read_note'], out['fast'] = True, '', True
    for p in paths:
        try:
            out['fast'] &= bool(rate_hz(load_run(p).t) >= 0.5 * c['rate_hz'])
        except GyroTdcError as exc:
            out['read_note'] = f'refused: {str(exc)[:80]}'
        except Exception:  # noqa: B902  (the bench counts what the readers must not raise)
            out['read'], out['read_note'] = False, traceback.format_exc(limit=1)[-200:]
    try:
        result = train(paths[:4], folder / f'c{k}.yaml', TrainOptions(accel=False))
    except GyroTdcError as exc:
        out['ratio'], out['train_note'] = None, f'refused: {str(exc)[:90]}'
    except Exception:  # noqa: B902
        out['ratio'], out['train_note'] = math.inf, traceback.format_exc(limit=1)[-200:]
    else:
        comp, trimmed = [], []
        for p, d in zip(paths[4:], days[4:]):
            r = load_run(p)
            comp.append(compensate(result.model, r.t, r.temp, r.omega,
                                   out_of_range=DEFAULT_OUT_OF_RANGE))
            # The held-out log's truth on the samples read (a cut end, the thermometer's span).
            at = np.clip(np.searchsorted(d.imu.t, r.t - 5e-7), 0, len(d.imu.t) - 1)
            trimmed.append(type(d)(type(d.imu)(d.imu.t[at], d.imu.gyro[at], d.imu.temp[at]),
                                   d.still[at], d.offset, d.drift))
        raw = still_drift(trimmed)
        out['ratio'] = float(np.max(still_drift(trimmed, comp) / raw))
        out['train_note'] = 'still-only' if result.still is not None else 'all samples'
    try:
        out['recall'], out['precision'] = _still_found(days[:4], paths[:4])
    except Exception:  # noqa: B902
        out['recall'], out['precision'] = 0.0, 0.0
    return out


def main(argv=None) -> int:
    """Run the sweep and print the pass rates and the worst cases."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cases', type=int, default=8)
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.cases):
            r = run_case(k, args.seed, Path(tmp))
            rows.append(r)
            ratio = '-' if r['ratio'] is None else f"{r['ratio']:.3f}"
            print(f"case {k:2d}: {r['rate_hz']:7.1f} Hz, {r['legs']} legs, res "
                  f"{r['resolution_c']:.3g} degC, noise {r['noise_dps']:.3f} deg/s, "
                  f"{r['glitches']} glitches | read {'ok' if r['read'] else 'FAIL'}"
                  f"{'' if r['fast'] else ' SLOW'} | "
                  f"train {r['train_note'][:40]}, held-out worst axis {ratio} x raw | still "
                  f"found {r['recall']:.2f}, precision {r['precision']:.3f}\n"
                  f"         logs: {r['formats']}", flush=True)
    n = len(rows)
    read_ok = sum(r['read'] for r in rows)
    harm_ok = sum(r['ratio'] is None or r['ratio'] <= 1.1 for r in rows)
    refused = sum(r['ratio'] is None for r in rows)
    still_ok = sum((math.isnan(r['recall']) or r['recall'] >= 0.5) and r['precision'] >= 0.99
                   for r in rows)
    knowable = sum(not math.isnan(r['recall']) for r in rows)
    print(f'read without traceback: {read_ok}/{n}')
    fast = sum(r['fast'] for r in rows)
    print(f'gyro read at half the drawn rate or more (the fastest the log holds): {fast}/{n}')
    print(f'never fit motion (refused in one line, or <= 1.1 x raw held out): {harm_ok}/{n} '
          f'({refused} refused)')
    from gyro_tdc.signal import MIN_STILL_SAMPLES
    print(f'still-only defaults find the still time (>= 0.5 of the stretches of 60 s or '
          f'{MIN_STILL_SAMPLES} '
          f'samples, precision >= 0.99): {still_ok}/{n} ({n - knowable} without such a '
          'stretch: precision only)')
    fitted = [r for r in rows if r['ratio'] is not None]
    if fitted:
        w = max(fitted, key=lambda r: r['ratio'])
        print(f"worst held-out ratio: {w['ratio']:.3f} x raw (case {w['case']}, "
              f"{w['rate_hz']:.1f} Hz, res {w['resolution_c']:.3g} degC)")
    known = [r for r in rows if not math.isnan(r['recall'])]
    if known:
        w = min(known, key=lambda r: r['recall'])
        print(f"worst still recall: {w['recall']:.2f} (case {w['case']}, "
              f"{w['rate_hz']:.1f} Hz)")
    w = min(rows, key=lambda r: r['precision'])
    print(f"worst still precision: {w['precision']:.3f} (case {w['case']}, "
          f"{w['rate_hz']:.1f} Hz)")
    for r in rows:
        if not r['read']:
            print(f"read failure, case {r['case']}: {r['read_note']}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
