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
``fleet`` with a sensor whose gyro has a constant axis (a 2-axis gyro, a dead axis).

``train`` passes such an axis through (drift exactly 0): the fleet statistics leave it out of
that axis' median and MAD, give it no slope, curvature or z-score and never flag it (it was
``drift slope on x 3757σ from the fleet``); the summary names it (``constant_axes``) and the
table says so. The whole fleet through the installed ``gyro-tdc fleet`` on one worker.
"""

from __future__ import annotations

import csv
from dataclasses import replace
import json
import math
import os
from pathlib import Path
import subprocess
import sys

from bags import bag_from_run
from dask_cluster import reaped
from gyro_tdc.fleet import (fleet_statistics, FleetResult, format_table, robust_z,
                            SensorResult)
from gyro_tdc.fleet.manifest import SensorSpec
from gyro_tdc.fleet.run import _read_state, _record, run_sensor, SensorOutcome
from gyro_tdc.fleet.summary import summary_dict
from gyro_tdc.identify import TrainOptions
from gyro_tdc.model import load_model
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run

AXES = 'xyz'
BASE_A1 = np.array([0.02, -0.015, 0.01])        # deg/s/degC
GYRO_TDC = Path(sys.executable).with_name('gyro-tdc')


def _sensor(sid, rng, constant=()):
    """Return a trained sensor's line: slopes spread 5 %, zero drift on its constant axes."""
    poly = np.zeros((3, 3))
    poly[:, 1] = BASE_A1 * (1 + 0.05 * rng.standard_normal(3))
    poly[:, 2] = 1e-4 * (1 + 0.05 * rng.standard_normal(3))
    for a in constant:
        poly[AXES.index(a)] = 0.0                   # identity: the model's drift is 0
    return SensorResult(sid, 'ok', drift_poly=poly.tolist(), temp_range_c=[0.0, 40.0],
                        constant_axes=list(constant))


@given(n=st.integers(3, 12), stuck=st.lists(st.sampled_from(['x', 'y', 'z', 'xz', 'xy']),
                                            min_size=1, max_size=4),
       seed=st.integers(0, 2 ** 16))
@settings(max_examples=40)
def test_constant_axes_take_no_part_in_the_fleet_statistics(n, stuck, seed):
    """Leave them out exactly: the others' z-scores are those of the fleet without them."""
    rng = np.random.default_rng(seed)
    good = [_sensor(f's{i}', rng) for i in range(n)]
    odd = [_sensor(f'c{k}', rng, tuple(axes)) for k, axes in enumerate(stuck)]
    alone = [SensorResult(s.sensor_id, 'ok', drift_poly=s.drift_poly, temp_range_c=[0, 40])
             for s in good]
    ref = fleet_statistics(good + odd)
    fleet_statistics(alone)
    for s in odd:
        assert not [f for f in s.flags for a in s.constant_axes if f' on {a} ' in f], s.flags
        for i, a in enumerate(AXES):
            if a in s.constant_axes:
                assert s.slope[i] is None and s.curvature[i] is None
                assert s.z_slope[i] is None and s.z_curvature[i] is None
    for i, a in enumerate(AXES):
        fitted = [s for s in good + odd if a not in s.constant_axes]
        slope = [s.drift_poly[i][1] + 2.0 * s.drift_poly[i][2] * ref for s in fitted]
        want = robust_z(slope)
        assert [s.z_slope[i] for s in fitted] == [float(v) for v in want]
        if all(a in s.constant_axes for s in odd):       # the fleet on a: the good ones
            assert [s.z_slope[i] for s in good] == [r.z_slope[i] for r in alone]
            assert [s.z_curvature[i] for s in good] == [r.z_curvature[i] for r in alone]
    assert all(v is None or math.isfinite(v) for s in good + odd
               for v in (s.z_slope or []) + (s.z_curvature or []))


def test_a_zero_drift_axis_is_flagged_unless_it_is_constant():
    """The bug this guards against: a passed-through axis read as a drift slope of 0."""
    rng = np.random.default_rng(3)
    fleet = [_sensor(f's{i}', rng) for i in range(8)]
    flat = _sensor('flat', rng)
    flat.drift_poly[0] = [0.0, 0.0, 0.0]
    fleet_statistics(fleet + [flat])
    assert flat.flags and flat.flags[0].startswith('drift slope on x ')
    fleet = [_sensor(f's{i}', rng) for i in range(8)]
    stuck = _sensor('stuck', rng, ('x',))
    fleet_statistics(fleet + [stuck])
    assert not stuck.flags and stuck.z_slope[0] is None and stuck.z_slope[1] is not None
    assert not any(s.flags for s in fleet)


def test_too_few_sensors_fitted_on_an_axis_give_it_no_z_scores():
    """Two sensors fitted on z of four: no z-score on z, the other axes scored."""
    rng = np.random.default_rng(5)
    fleet = [_sensor('a', rng), _sensor('b', rng), _sensor('c', rng, 'z'),
             _sensor('d', rng, 'z')]
    fleet_statistics(fleet)
    assert all(s.z_slope[2] is None and s.z_slope[0] is not None for s in fleet)
    assert [s.slope[2] is None for s in fleet] == [False, False, True, True]


def test_summary_and_table_name_the_constant_axes():
    """JSON key only when there are any; CSV column; table note and count; shown when many."""
    rng = np.random.default_rng(9)
    sensors = [_sensor(f's{i:02d}', rng) for i in range(44)] + [_sensor('zz', rng, 'z')]
    sensors[0].train_bs = [0.1] * 3
    result = FleetResult('local', 1, sensors, seconds=1.0)
    rows = {r['sensor_id']: r for r in summary_dict(result)['sensors']}
    assert rows['zz']['constant_axes'] == ['z'] and 'constant_axes' not in rows['s00']
    lines = format_table(result).splitlines()
    assert [line.split()[0] for line in lines[1:-1]] == ['zz']          # many: only it
    assert 'gyro axis z constant (not fitted' in lines[1]
    assert '1 with a constant gyro axis' in lines[-1] and '0 flagged' in lines[-1]


def _with_z(run, value):
    """Return ``run`` with z reading ``value`` on every sample."""
    omega = run.omega.copy()
    omega[:, 2] = value
    return replace(run, omega=omega)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write three ordinary sensors and one whose z is stuck at 0.25 rad/s (train, test)."""
    root = tmp_path_factory.mktemp('fleet_const')
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


def test_the_sensor_task_and_its_resume_state_keep_the_constant_axes(bags, tmp_path):
    """run_sensor names them; the state records them; a state without them is not resumed."""
    _, b = bags
    spec = SensorSpec('imu-z', (str(b['imu-z'][0]),), (str(b['imu-z'][1]),))
    out = run_sensor(spec, TrainOptions(n_centers=6))
    assert out.status == 'ok', out.error
    assert out.constant_axes == ['z'] and out.drift_poly[2] == [0.0, 0.0, 0.0]
    assert all(math.isfinite(v) for v in out.heldout_bs + out.train_bs)
    (tmp_path / '.fleet').mkdir()
    res = _record(out, tmp_path, tmp_path / '.fleet', None)
    assert res.constant_axes == ['z']
    state = json.loads((tmp_path / '.fleet' / 'imu-z.json').read_text())
    assert state['constant_axes'] == ['z']
    model_file = tmp_path / 'imu-z.yaml'
    assert load_model(model_file).metrics['constant_axes'] == ['z']
    state_file = tmp_path / '.fleet' / 'imu-z.json'
    assert _read_state(state_file, model_file)['constant_axes'] == ['z']
    skipped = SensorOutcome('imu-z', 'skipped', key=out.key)
    assert _record(skipped, tmp_path, tmp_path / '.fleet',
                   _read_state(state_file, model_file)).constant_axes == ['z']
    del state['constant_axes']
    state_file.write_text(json.dumps(state))
    assert _read_state(state_file, model_file) is None     # retrained, not resumed


def test_fleet_cli_reports_the_constant_sensor_without_flagging_it(bags, tmp_path):
    """The installed gyro-tdc fleet on one worker: exit 0, z never flagged, z named."""
    root, b = bags
    manifest = tmp_path / 'fleet.csv'
    manifest.write_text('sensor_id,train,test\n' + ''.join(
        f'{sid},{b[sid][0]},{b[sid][1]}\n' for sid in ('imu-a', 'imu-b', 'imu-c', 'imu-z')))
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', PYTHONWARNINGS='error')
    with reaped():                  # its cluster's processes, should they outlive it
        res = subprocess.run([str(GYRO_TDC), 'fleet', str(manifest), '--out',
                              str(tmp_path / 'o'), '--workers', '1', '--no-progress'],
                             capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0, res.stderr
    row = next(x for x in res.stdout.splitlines() if x.startswith('imu-z '))
    assert 'gyro axis z constant (not fitted, passed through' in row, res.stdout
    assert ' on z ' not in row, res.stdout                # before: slope on z ~1e3 σ
    assert 'nan' not in res.stdout.lower()
    summary = json.loads((tmp_path / 'o' / 'summary.json').read_text())
    by_id = {r['sensor_id']: r for r in summary['sensors']}
    assert by_id['imu-z']['constant_axes'] == ['z']
    assert not [f for f in by_id['imu-z']['flags'] if ' on z ' in f]
    assert all('constant_axes' not in by_id[s] for s in ('imu-a', 'imu-b', 'imu-c'))
    with open(tmp_path / 'o' / 'summary.csv', newline='') as fh:
        table = {r['sensor_id']: r for r in csv.DictReader(fh)}
    assert table['imu-z']['constant_axes'] == 'z' and table['imu-z']['z_slope_z'] == ''
    assert table['imu-z']['slope_z'] == '' and table['imu-z']['z_slope_x'] != ''
