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
Small fleets for the fleet tests: synthetic sensors written as bags, manifests, train options.

Exact synthetic runs (``synth.py``): half an hour at 5 Hz, a -10 -> 50 degC ramp, drift slopes
spread by 5 % between units and one unit with three times the x slope, plus broken inputs
(a truncated bag, a temperature on another topic, too small a span); a fleet where one unit's
z axis is stuck; a trained sensor's line with constant axes.
"""

from __future__ import annotations

from dataclasses import replace
import os
from pathlib import Path
import shutil

from bags import bag_from_run
from gyro_tdc.cli.train import build_parser as train_parser, train_options
from gyro_tdc.data import write_bag
from gyro_tdc.fleet import SensorResult
import numpy as np
from synth import synth_run

AXES = 'xyz'
BASE_A1 = np.array([0.02, -0.015, 0.01])        # deg/s/degC
GOOD = ('imu-a', 'imu-b', 'imu-c')
OUTLIER = 'imu-x'
SUMMARY_KEYS = {'engine', 'scheduler', 'workers', 'sensors'}
SENSOR_KEYS = {'sensor_id', 'status', 'model_file', 'train_bs', 'heldout_bs', 'flags'}


def sensor_run(seed: int, a1, *, t_lo: float = -10.0, t_hi: float = 50.0):
    return synth_run(seed=seed, hours=0.5, rate_hz=5.0, a1=tuple(a1), t_lo=t_lo, t_hi=t_hi)


def make_bags(root: Path):
    """Write the bags of every sensor under ``root``; return it and {name: (train, test)}."""
    rng = np.random.default_rng(7)
    out = {}
    for i, sid in enumerate(GOOD + (OUTLIER,)):
        a1 = BASE_A1 * (1.0 + 0.05 * rng.standard_normal(3))
        if sid == OUTLIER:
            a1[0] = 3.0 * BASE_A1[0]
        out[sid] = (bag_from_run(sensor_run(2 * i, a1), root / sid / 'train'),
                    bag_from_run(sensor_run(2 * i + 1, a1), root / sid / 'test'))
    # A truncated bag: the first 16 kB of a good database.
    trunc = root / 'truncated' / 'train'
    shutil.copytree(out['imu-a'][0], trunc)
    db = next(trunc.glob('*.db3'))
    db.write_bytes(db.read_bytes()[:16384])
    out['truncated'] = (trunc,)
    # Temperature on another topic than the one asked for.
    run = sensor_run(20, BASE_A1)
    notemp = root / 'notopic' / 'train'
    write_bag(notemp, imu_t=run.t + 100.0, gyro=run.omega, accel=np.zeros((len(run), 3)),
              temp_t=run.t[::5] + 100.0, temp_c=run.temp[::5],
              temperature_topic='/chamber/temperature')
    out['notopic'] = (notemp,)
    # Too small a temperature span (0.01 degC).
    out['flat'] = (bag_from_run(sensor_run(21, BASE_A1, t_lo=25.0, t_hi=25.01),
                                root / 'flat' / 'train'),)
    return root, out


def write_manifest(path: Path, rows) -> Path:
    """Write a manifest with paths relative to it; rows are (sensor_id, train, test)."""
    lines = ['sensor_id,train,test']
    for sid, train, test in rows:
        rel = [';'.join(os.path.relpath(b, path.parent) for b in bags) for bags in (train, test)]
        lines.append(f'{sid},{rel[0]},{rel[1]}')
    path.write_text('\n'.join(lines) + '\n')
    return path


def manifest_rows(bags, names):
    _, b = bags
    return [(sid, [b[sid][0]], [b[sid][1]] if len(b[sid]) > 1 else []) for sid in names]


def train_opts(*extra):
    """Return the ``train`` options parsed from ``extra`` (defaults otherwise)."""
    return train_options(train_parser().parse_args(['bag', '--out', 'm.yaml', '--no-progress',
                                                    *extra]))


def constant_sensor(sid, rng, constant=()):
    """Return a trained sensor's line: slopes spread 5 %, zero drift on its constant axes."""
    poly = np.zeros((3, 3))
    poly[:, 1] = BASE_A1 * (1 + 0.05 * rng.standard_normal(3))
    poly[:, 2] = 1e-4 * (1 + 0.05 * rng.standard_normal(3))
    for a in constant:
        poly[AXES.index(a)] = 0.0                   # identity: the model's drift is 0
    return SensorResult(sid, 'ok', drift_poly=poly.tolist(), temp_range_c=[0.0, 40.0],
                        constant_axes=list(constant))


def _with_z(run, value):
    """Return ``run`` with z reading ``value`` on every sample."""
    omega = run.omega.copy()
    omega[:, 2] = value
    return replace(run, omega=omega)


def make_constant_bags(root: Path):
    """Write three ordinary sensors and one whose z is stuck at 0.25 rad/s (train, test)."""
    rng = np.random.default_rng(11)
    out = {}
    for i, sid in enumerate(('imu-a', 'imu-b', 'imu-c', 'imu-z')):
        a1 = tuple(BASE_A1 * (1.0 + 0.05 * rng.standard_normal(3)))
        pair = [synth_run(seed=40 + 2 * i + k, hours=0.5, rate_hz=5.0, a1=a1) for k in (0, 1)]
        if sid == 'imu-z':
            pair = [_with_z(r, 0.25) for r in pair]
        out[sid] = tuple(bag_from_run(r, root / sid / name)
                         for r, name in zip(pair, ('train', 'test')))
    return root, out
