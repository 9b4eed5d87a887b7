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
Running a fleet on Dask: the sensor task, outlier flags, failure isolation, resume state.

The core runs on one embedded ``LocalCluster`` with two worker processes (shared by the tests
of this module). A sensor's own write error (an unwritable model path, a full disk) fails that
sensor and is the error reported. The sensor task keeps a constant axis through its resume
state, and a sensor with several training bags gets one turn-on offset per bag.
"""

from __future__ import annotations

import csv
from dataclasses import replace
import errno
import gc
import json
import math
import os
from pathlib import Path

from bags import bag_from_run
from dask_cluster import reaped
from fleet_rig import (GOOD, make_bags, make_constant_bags, manifest_rows, OUTLIER, SENSOR_KEYS,
                       SUMMARY_KEYS, train_opts, write_manifest)
from gyro_tdc.data import BagOptions
from gyro_tdc.errors import FleetError, OutputError
from gyro_tdc.fleet import open_engine, read_manifest, run_fleet
from gyro_tdc.fleet.manifest import SensorSpec
from gyro_tdc.fleet.run import _read_state, _record, run_sensor, SensorOutcome
from gyro_tdc.identify import TrainOptions
from gyro_tdc.model import load_model
import numpy as np
import pytest
from synth import synth_run


# Time-bounded: a cluster that never closes fails its test within this bound (each test
# takes under a minute on a loaded 2-core machine) instead of holding the run.
pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write the fleet's bags once for this module."""
    return make_bags(tmp_path_factory.mktemp('fleet_bags'))


@pytest.fixture(scope='module')
def engine():
    """One embedded LocalCluster with two worker processes for the module (reaped after)."""
    with reaped(), open_engine(workers=2) as e:
        yield e


def test_fleet_on_two_workers_flags_outlier_and_isolates_failures(tmp_path, bags, engine):
    root, b = bags
    rows = manifest_rows(bags, GOOD + (OUTLIER,)) + [
        ('truncated', [b['truncated'][0]], []), ('notopic', [b['notopic'][0]], []),
        ('flat', [b['flat'][0]], []), ('missing', [root / 'no_such_bag'], [])]
    specs = read_manifest(write_manifest(tmp_path / 'fleet.csv', rows))
    out = tmp_path / 'out'
    result = run_fleet(specs, out, train_opts(), engine)

    assert engine.workers == 2
    assert engine.client.run(lambda: 'rclpy' in __import__('sys').modules) == {
        w: False for w in engine.client.nthreads()}
    status = {s.sensor_id: s for s in result.sensors}
    assert [s.sensor_id for s in result.sensors] == [r[0] for r in rows]
    for sid in GOOD + (OUTLIER,):
        assert status[sid].status == 'ok', status[sid].error
        model = load_model(out / f'{sid}.yaml')
        assert model.sensor_id == sid
        assert len(status[sid].heldout_bs) == 3
        assert max(status[sid].heldout_bs) < 0.01          # noise 0.05 deg/s: BS ~ 0.0025
    assert status[OUTLIER].flags and status[OUTLIER].flags[0].startswith('drift slope on x ')
    assert all(not status[sid].flags for sid in GOOD)
    for sid, needle in (('truncated', 'corrupt'), ('notopic', '/imu/temperature'),
                        ('flat', 'span'), ('missing', 'does not exist')):
        s = status[sid]
        assert s.status == 'failed' and needle in s.error, (sid, s.error)
        assert '\n' not in s.error and s.model_file is None
        assert not (out / f'{sid}.yaml').exists()
    assert len(result.failed) == 4

    summary = json.loads((out / 'summary.json').read_text())
    assert set(summary) == SUMMARY_KEYS
    assert (summary['engine'], summary['scheduler'], summary['workers']) == ('dask', 'local', 2)
    for row in summary['sensors']:
        extra = {'error'} if row['status'] == 'failed' else set()
        assert set(row) == SENSOR_KEYS | extra
    by_id = {r['sensor_id']: r for r in summary['sensors']}
    assert by_id[OUTLIER]['flags'] == status[OUTLIER].flags
    assert by_id['flat']['heldout_bs'] is None and by_id['flat']['train_bs'] is None
    with open(out / 'summary.csv', newline='') as fh:
        table = list(csv.DictReader(fh))
    assert [r['sensor_id'] for r in table] == [r[0] for r in rows]
    assert float(table[3]['z_slope_x']) > 3.5


def test_resume_skips_unchanged_and_reruns_on_force_or_change(tmp_path, bags, engine):
    _, b = bags
    specs = read_manifest(write_manifest(tmp_path / 'fleet.csv', manifest_rows(bags, GOOD[:2])))
    out = tmp_path / 'out'
    first = run_fleet(specs, out, train_opts(), engine)
    assert [s.skipped for s in first.sensors] == [False, False]
    model_a = out / 'imu-a.yaml'
    before = model_a.read_bytes()

    again = run_fleet(specs, out, train_opts(), engine)
    assert [(s.status, s.skipped) for s in again.sensors] == [('ok', True), ('ok', True)]
    assert again.sensors[0].train_bs == first.sensors[0].train_bs
    assert again.sensors[0].heldout_bs == first.sensors[0].heldout_bs
    assert model_a.read_bytes() == before

    forced = run_fleet(specs, out, train_opts(), engine, force=True)
    assert [s.skipped for s in forced.sensors] == [False, False]

    changed = run_fleet(specs, out, train_opts('--centers', '8'), engine)
    assert [s.skipped for s in changed.sensors] == [False, False]
    assert load_model(model_a).n_centers == 8
    # The progress bar is not an input of the model: the same options with it on skip.
    shown = run_fleet(specs, out, train_opts('--centers', '8'), engine,
                      bag=BagOptions(progress=True))
    assert [s.skipped for s in shown.sensors] == [True, True]

    # A touched bag (new mtime) retrains that sensor only; an edited model file is replaced.
    db = next(Path(b['imu-b'][1]).glob('*.db3'))
    st = db.stat()
    os.utime(db, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    touched = run_fleet(specs, out, train_opts('--centers', '8'), engine)
    assert [s.skipped for s in touched.sensors] == [True, False]
    model_a.write_text(model_a.read_text() + '# edited\n')
    edited = run_fleet(specs, out, train_opts('--centers', '8'), engine)
    assert [s.skipped for s in edited.sensors] == [False, True]


def test_an_unwritable_model_path_fails_that_sensor_only(tmp_path, bags, engine):
    specs = read_manifest(write_manifest(tmp_path / 'fleet.csv', manifest_rows(bags, GOOD)))
    out = tmp_path / 'out'
    (out / 'imu-b.yaml').mkdir(parents=True)        # a directory where imu-b's model goes
    result = run_fleet(specs, out, train_opts(), engine)
    status = {s.sensor_id: s for s in result.sensors}
    assert status['imu-a'].status == 'ok' and status['imu-c'].status == 'ok'
    assert load_model(out / 'imu-c.yaml').sensor_id == 'imu-c'
    assert status['imu-b'].status == 'failed'
    assert str(out / 'imu-b.yaml') in status['imu-b'].error
    assert 'it is a directory' in status['imu-b'].error
    summary = json.loads((out / 'summary.json').read_text())
    assert [r['status'] for r in summary['sensors']] == ['ok', 'failed', 'ok']


def test_a_full_disk_reports_the_model_write_error(tmp_path, bags, engine, monkeypatch):
    from gyro_tdc.base import atomicio

    def full(directory, name):
        raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(atomicio, '_create_temp', full)     # every write of this process
    specs = read_manifest(write_manifest(tmp_path / 'fleet.csv', manifest_rows(bags, GOOD[:2])))
    out = tmp_path / 'out'
    with pytest.raises(OutputError) as info:
        run_fleet(specs, out, train_opts(), engine)
    line = str(info.value)
    assert '\n' not in line
    first = line.split(';')[0]
    assert first.startswith('imu-') and 'cannot write model file' in first, line
    assert 'No space left on device' in first and '(and 1 more sensor(s))' in first, line
    assert 'summary' in line and not (out / 'summary.json').exists()


@pytest.fixture(scope='module')
def constant_bags(tmp_path_factory):
    """Write three ordinary sensors and one whose z axis is stuck, once for this module."""
    return make_constant_bags(tmp_path_factory.mktemp('fleet_const'))


def test_the_sensor_task_and_its_resume_state_keep_the_constant_axes(constant_bags, tmp_path):
    """run_sensor names them; the state records them; a state without them is not resumed."""
    _, b = constant_bags
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


NOISE_DPS = 0.02
OFFSETS = ((0.4, -0.3, 0.1), (-0.5, 0.2, 0.45), (0.1, 0.5, -0.4))
RANGES = ((-10.0, 30.0), (15.0, 50.0), (0.0, 40.0))


def test_a_sensor_trained_on_bags_with_their_own_offsets(tmp_path):
    bags = [str(bag_from_run(synth_run(seed=i, hours=0.5, rate_hz=2.0, t_lo=lo, t_hi=hi,
                                       noise_dps=NOISE_DPS, offset_dps=off),
                             tmp_path / f'bag{i}'))
            for i, (off, (lo, hi)) in enumerate(zip(OFFSETS, RANGES))]
    spec = SensorSpec('imu-1', tuple(bags[:2]), (bags[2],))
    options = TrainOptions(features='dT,dT2', kind='poly', accel=False)
    out = run_sensor(spec, options)
    assert out.status == 'ok', out.error
    info = out.model.metrics['sessions']
    off = np.array(OFFSETS[:2])
    np.testing.assert_allclose(info['offset_dps'], off - off.mean(axis=0), atol=0.003)
    floor = NOISE_DPS ** 2
    assert max(out.heldout_bs) < 1.1 * floor          # re-anchored on its own power cycle
    one = run_sensor(spec, options, bag=replace(BagOptions(), sessions='none'))
    assert 'sessions' not in one.model.metrics
    assert min(one.heldout_bs) > 5 * floor             # one intercept: a bent curve
    assert one.key != out.key                          # the choice is part of the resume key


def test_a_failed_connection_leaves_no_client_for_the_collector():
    # distributed's Client finaliser takes a process-wide loop lock: a half-made Client left
    # for the cyclic collector deadlocked a cluster started later in the same process.
    from distributed import Client

    def clients() -> list:
        return [o for o in gc.get_objects() if isinstance(o, Client)]

    gc.collect()
    gc.disable()
    try:
        before = clients()             # another test's engine may be open
        with pytest.raises(FleetError, match='cannot connect'):
            with open_engine(scheduler='tcp://127.0.0.1:1', timeout_s=0.5):
                pass
        left = [c for c in clients() if not any(c is b for b in before)]
    finally:
        gc.enable()
    assert left == []
