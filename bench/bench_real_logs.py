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
Sweep real flight-controller logs through the CLI as a user runs it (issue 34's holdout).

Every ``.ulg`` / ``.bin`` under the folders given is read by the readers (every IMU
instance, with the IMU's thermometer, the barometer's and the barometer's named as
``TOPIC.FIELD`` / ``MSG.Field``), then instance 0 is run through ``train``, ``train
--still-only`` and ``evaluate`` (the model trained, and the ``px4`` cubic fitted on the
log), each with the default thermometer and with ``--temperature-source baro``. Printed per
log: the outcome of each run (ok, refused, or a defect) and the first line of what it
said; then the counts. A defect is: a traceback or an exit code other than 0 / 2, a
refusal of more than one line, a percentage above 100 % (but the paper table's P3, a ratio),
a thermometer outside -40 .. 125 degC or whose readings repeat a stamp (instances mixed), a
gyro read slower than half the fastest gyro of the instance (``sensor_combined`` counted in
its rows where ``sensor_selection`` names the instance), or a model that makes the still
stretches of its own log worse (``evaluate``'s ``p_vs_raw`` above 1.1 on an axis) or that
``evaluate`` refuses to load. A constant thermometer is noted on the read line, and so is
the ``px4`` baseline worse than raw: PX4's plain cubic with no gate of its own, where a
log's drift does not follow its temperature, is a finding of the baseline, not a defect
(``pxf_copter_23-9-2014_52.BIN`` of erlerobot/logs: 1.26 x raw on x).

``--damaged K`` also reads and trains (``--allow-loss``) K copies of each log damaged as SD
cards do (cut off, bytes flipped, a stretch zeroed; seeded by ``--seed``), with the first
thermometer (``imu``, then ``baro``) that reads the undamaged log.

No network, no logs shipped: point it at logs you have. ::

    .venv/bin/python bench/bench_real_logs.py /tmp/reallogs
    .venv/bin/python bench/bench_real_logs.py LOGS --timeout 120 --json out.json
    .venv/bin/python bench/bench_real_logs.py LOGS --damaged 6 --seed 0
"""

import argparse
import collections
import json
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import traceback  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

SUFFIXES = ('.ulg', '.bin')
SOURCES = ('imu', 'baro')
#: A thermometer outside this range (degC) is implausible on a flying board.
PLAUSIBLE_C = (-40.0, 125.0)
#: A model worse than this on the still stretches of its own log is nonsense.
HARM = 1.1
_PERCENT = re.compile(r'(-?\d+(?:\.\d+)?)\s?%')
_P3_ROW = re.compile(r'^\s+[xyz]-axis\s')


def find_logs(folders: list) -> list:
    """Return every flight log under ``folders``, sorted."""
    out = []
    for folder in folders:
        p = Path(folder)
        cands = [p] if p.is_file() else (sorted(p.rglob('*')) if p.is_dir() else [])
        out += [f for f in cands if f.is_file() and f.suffix.lower() in SUFFIXES]
    return out


def _ulog_gyro_rates(path: Path, instance: int = 0) -> dict:
    """
    Return the rate (Hz) of every gyro topic of a ULog's instance, as pyulog reads it.

    ``sensor_combined`` counts with its rows where ``sensor_selection`` names the instance's
    gyro (all of them for instance 0 when no selection is logged), judged here, not by the
    reader.
    """
    from pyulog import ULog

    names = ['sensor_gyro', 'sensor_combined', 'vehicle_imu', 'sensor_gyro_fifo',
             'sensor_selection']
    try:
        ulog = ULog(str(path), names)
    except Exception:  # noqa: B902 - the reader judges the log; this is a side figure
        return {}
    data = {(d.name, d.multi_id): d.data for d in ulog.data_list}
    out = {}
    for (name, multi_id), d in data.items():
        t = np.asarray(d['timestamp'], dtype=np.float64) * 1e-6
        if name == 'sensor_combined':
            t = t[_selected(data, instance, d['timestamp'])]
        elif multi_id != instance or name == 'sensor_selection':
            continue
        if len(t) > 1 and t[-1] > t[0]:
            per = (int(np.max(d['samples'])) if name == 'sensor_gyro_fifo'
                   and 'samples' in d else 1)        # a FIFO message holds a burst
            out[name] = (len(t) - 1) / (t[-1] - t[0]) * max(per, 1)
    return out


def _selected(data: dict, instance: int, stamps) -> np.ndarray:
    """Return which ``sensor_combined`` rows are the instance's gyro (``sensor_selection``)."""
    sel = data.get(('sensor_selection', 0))
    mine = next((int(d['device_id'][0]) for (n, k), d in data.items()
                 if n == 'sensor_gyro' and k == instance and len(d['device_id'])), None)
    if sel is None or mine is None:
        return np.full(len(stamps), instance == 0)
    order = np.argsort(sel['timestamp'], kind='stable')
    at = np.searchsorted(sel['timestamp'][order], stamps, side='right') - 1
    return (at >= 0) & (sel['gyro_device_id'][order][np.maximum(at, 0)] == mine)


def inspect(path: Path, source: str, instance: int = 0) -> dict:
    """Read one IMU of the log as the CLI does; return what was read and the defects seen."""
    from gyro_tdc.data.dataflash import read_dataflash
    from gyro_tdc.data.flightlog import detect_format, rate_hz
    from gyro_tdc.data.ulog import read_ulog
    from gyro_tdc.errors import GyroTdcError

    fmt = detect_format(path)
    reader = read_ulog if fmt == 'ulog' else read_dataflash
    try:
        log = reader(path, instance=instance, temperature_source=source)
    except GyroTdcError as exc:
        return {'outcome': 'refused', 'line': str(exc), 'defects': []}
    except Exception:  # noqa: B902 - a traceback is the defect this bench looks for
        return {'outcome': 'traceback', 'line': traceback.format_exc().splitlines()[-1],
                'defects': ['traceback (reader)']}
    temp = np.asarray(log.temp_c, dtype=np.float64)
    temp = temp[np.isfinite(temp)]
    defects = []
    if temp.size and (temp.min() < PLAUSIBLE_C[0] or temp.max() > PLAUSIBLE_C[1]):
        defects.append(f'implausible temperature {temp.min():.1f} .. {temp.max():.1f} degC')
    notes = []
    if temp.size > 10 and np.ptp(temp) == 0:     # a simulator's, or a heater's target
        notes.append(f'constant {temp[0]:.2f} degC')
    rate = rate_hz(np.asarray(log.imu_t))
    if fmt == 'ulog':
        rates = _ulog_gyro_rates(path, log.instance)
        fast = max(rates.values(), default=0.0)
        if fast > 2.0 * rate:
            defects.append(f'{log.source} read at {rate:.3g} Hz while '
                           + ', '.join(f'{k} {v:.3g} Hz' for k, v in rates.items()))
    t_src = log.imu_t if log.temp_t is None else log.temp_t
    if log.temp_t is not None and np.any(np.diff(np.sort(log.temp_t)) == 0):
        defects.append(f'{log.temperature}: readings repeat a stamp (instances mixed?)')
    line = (f'{log.firmware} {log.source} {rate:.3g} Hz x{len(log.imu_t)}, {log.temperature} '
            f'{rate_hz(np.asarray(t_src)):.3g} Hz '
            + (f'{temp.min():.1f}..{temp.max():.1f} degC' if temp.size else 'no reading')
            + ''.join(f' ({n})' for n in notes))
    return {'outcome': 'read', 'line': line, 'defects': defects,
            'instances': list(log.instances)}


def _run(args: list, timeout: float) -> dict:
    """Run one ``python -m gyro_tdc`` command; return its outcome and defects."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    try:
        p = subprocess.run([sys.executable, '-m', 'gyro_tdc', *args], capture_output=True,
                           text=True, timeout=timeout, env=env, cwd=str(ROOT))
    except subprocess.TimeoutExpired:
        return {'outcome': 'timeout', 'line': f'over {timeout:g} s', 'defects': ['timeout']}
    err = [ln for ln in p.stderr.splitlines() if ln.strip()]
    errors = [i for i, ln in enumerate(err) if ln.startswith('gyro-tdc ') and ': error:' in ln]
    defects = []
    if 'Traceback' in p.stderr or 'Traceback' in p.stdout:
        defects.append('traceback')
    if p.returncode not in (0, 2):
        defects.append(f'exit {p.returncode}')
    stray = [ln for ln in err if not ln.startswith(('warning:', 'gyro-tdc '))]
    if p.returncode == 2 and (len(errors) != 1 or stray):
        defects.append(f'refusal of {len(errors) + len(stray)} lines')
    # The paper table's P3 = BS3/BS2 is a ratio in % (above 100: the second model is worse).
    said = '\n'.join(ln for ln in (p.stdout + p.stderr).splitlines() if not _P3_ROW.match(ln))
    big = [float(v) for v in _PERCENT.findall(said) if float(v) > 100.0]
    if big:
        defects.append(f'{max(big):g} %')
    outcome = 'ok' if p.returncode == 0 else 'refused' if p.returncode == 2 else 'failed'
    line = err[errors[0]] if errors else (p.stdout.splitlines() or [''])[0]
    return {'outcome': outcome, 'line': line.split(': error: ', 1)[-1], 'defects': defects}


def sweep_log(path: Path, timeout: float) -> dict:
    """Read, train (default, ``--still-only``) and evaluate one log with each thermometer."""
    runs = {}
    named = 'sensor_baro.temperature' if path.suffix.lower() == '.ulg' else 'BARO.Temp'
    for k in inspect(path, 'imu').get('instances', [0])[1:]:
        for src in (*SOURCES, named):
            runs[f'read {src} {k}'] = inspect(path, src, k)
    runs[f'read {named}'] = inspect(path, named)
    with tempfile.TemporaryDirectory(prefix='gyro_tdc_real_') as tmp:
        for src in SOURCES:
            runs[f'read {src}'] = inspect(path, src)
            common = ['--no-progress', '--temperature-source', src]
            models = []
            for name, extra in (('train', []), ('still', ['--still-only'])):
                out = Path(tmp) / f'{src}_{name}.yaml'
                runs[f'{name} {src}'] = _run(['train', *extra, str(path), '--out', str(out),
                                              *common], timeout)
                if out.exists():
                    models.append((name, out))
            evals = [('evaluate', models[0][0], ['--model', str(models[0][1])])] if models else []
            evals.append(('px4', 'px4', ['--model', 'px4', '--train', str(path)]))  # last
            for name, by, model in evals:
                js = Path(tmp) / f'{src}_{name}.json'
                r = _run(['evaluate', str(path), '--json', str(js), *common, *model], timeout)
                if r['outcome'] == 'ok' and js.exists():
                    harm = _harm(json.loads(js.read_text()), by)
                    r.setdefault('notes' if by == 'px4' else 'defects', []).extend(harm)
                elif r['outcome'] == 'refused' and by != 'px4' and str(models[0][1]) in r['line']:
                    r['defects'].append('unloadable model written by train')
                runs[f'{name} {src}'] = r
    return runs


def damaged_runs(path: Path, count: int, rng: np.random.Generator, timeout: float,
                 swept: dict) -> dict:
    """
    Read and ``train`` ``count`` damaged copies of a log: cut, bytes flipped, bytes zeroed.

    With the first thermometer of :data:`SOURCES` that read the undamaged log (``swept``,
    :func:`sweep_log`'s runs): on a log whose only one is the barometer, damage must be met
    by a read, not by the refusal of a missing thermometer.
    """
    data = path.read_bytes()
    runs = {}
    src = next((s for s in SOURCES if swept[f'read {s}']['outcome'] == 'read'), SOURCES[0])
    with tempfile.TemporaryDirectory(prefix='gyro_tdc_damaged_') as tmp:
        for k in range(count):
            how = ('cut', 'flipped', 'zeroed')[k % 3]
            at = int(rng.integers(min(64, len(data) - 1), len(data))) if len(data) > 1 else 0
            if how == 'cut':
                bad = data[:at]
            elif how == 'flipped':
                bad = bytearray(data)
                for j in rng.integers(0, len(data), 5):
                    bad[j] ^= 0xFF
            else:
                bad = data[:at] + bytes(len(data[at:at + 300])) + data[at + 300:]
            copy = Path(tmp) / f'{how}{path.suffix}'
            copy.write_bytes(bytes(bad))
            runs[f'read {how} {at} {src}'] = inspect(copy, src)
            runs[f'train {how} {at} {src}'] = _run(
                ['train', str(copy), '--out', str(copy) + '.yaml', '--no-progress',
                 '--allow-loss', '--temperature-source', src], timeout)
    return runs


def _harm(doc: dict, trained_by: str) -> list:
    """Return a defect when a model makes the still stretches of its own log worse."""
    out = []
    for bag in doc.get('bags', []):
        share = bag.get('still', {}).get('share', 0.0)
        if share > 1.0:
            out.append(f'still share {share:g} > 1')
        for m in bag.get('models', []):
            p = [v for v in m.get('p_vs_raw', []) if v is not None and np.isfinite(v)]
            if p and max(p) > HARM:
                out.append(f'{trained_by} model {max(p):.2f} x raw on its own still stretches')
    return out


def main(argv=None) -> int:
    """Sweep the folders given; print per log, then the counts."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('folders', nargs='*', default=[], help='folders (or files) of logs')
    ap.add_argument('--timeout', type=float, default=300.0, help='per command, s')
    ap.add_argument('--json', help='write every outcome here')
    ap.add_argument('--damaged', type=int, default=0, metavar='K',
                    help='also read and train K damaged copies of each log (seeded)')
    ap.add_argument('--seed', type=int, default=0, help='seed of the damage')
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    logs = find_logs(args.folders)
    if not logs:
        print('nothing to read: no .ulg or .bin log under '
              + (', '.join(args.folders) or '(no folder given)'))
        return 0
    counts = collections.Counter()
    result = {}
    for path in logs:
        runs = sweep_log(path, args.timeout)
        runs.update(damaged_runs(path, args.damaged, rng, args.timeout, runs))
        result[str(path)] = runs
        print(f'== {path} ({path.stat().st_size / 1e6:.2f} MB)')
        for name, r in runs.items():
            counts[r['outcome']] += 1
            counts.update('defect: ' + d.split(' ')[0] for d in r['defects'])
            counts.update('note: px4 baseline worse than raw' for _ in r.get('notes', ()))
            mark = ' DEFECT ' + '; '.join(r['defects']) if r['defects'] else ''
            mark += ' NOTE ' + '; '.join(r['notes']) if r.get('notes') else ''
            print(f'  {name:26s} {r["outcome"]:9s} {r["line"][:150]}{mark}')
    bad = sum(1 for runs in result.values() if any(r['defects'] for r in runs.values()))
    print(f'{len(logs)} logs, {sum(len(r) for r in result.values())} runs; '
          + ', '.join(f'{k} {v}' for k, v in sorted(counts.items()))
          + f'; logs with a defect: {bad}')
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
