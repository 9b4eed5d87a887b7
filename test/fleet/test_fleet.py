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
``python -m gyro_tdc fleet``: many sensors on Dask, outlier flags, failure isolation, resume.

Small sensors are exact synthetic runs (``synth.py``) written as bags in a temporary folder:
half an hour at 5 Hz, a -10 -> 50 degC ramp, drift slopes spread by 5 % between units and one
unit with three times the x slope. The core runs on one embedded ``LocalCluster`` with two
worker processes (shared by the tests of this module); the CLI runs against the address of a
one-worker cluster started in its test. A sensor's own write error (an unwritable model path,
a full disk) fails that sensor and is the error reported; a fleet whose cluster loses every
worker, or that gets SIGTERM, runs as a child process and ends with one line and a summary.
"""

from __future__ import annotations

import csv
import errno
import json
import os
from pathlib import Path
import selectors
import shutil
import signal
import subprocess
import sys

from bags import bag_from_run
from dask_cluster import local_cluster, reaped
from gyro_tdc.cli.fleet import main
from gyro_tdc.cli.train import build_parser as train_parser, train_options
from gyro_tdc.data import BagOptions, write_bag
from gyro_tdc.errors import FleetError, OutputError
from gyro_tdc.fleet import (check_sensor_id, drift_polynomial, fleet_statistics, FleetResult,
                            format_table, open_engine, read_manifest, robust_z, run_fleet,
                            SensorResult)
from gyro_tdc.identify import fit_model
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from synth import synth_run
import yaml

# Time-bounded: a cluster that never closes fails its test within this bound (each test
# takes under a minute on a loaded 2-core machine) instead of holding the run.
pytestmark = pytest.mark.timeout(300)

BASE_A1 = np.array([0.02, -0.015, 0.01])        # deg/s/degC
GOOD = ('imu-a', 'imu-b', 'imu-c')
OUTLIER = 'imu-x'
SUMMARY_KEYS = {'engine', 'scheduler', 'workers', 'sensors'}
SENSOR_KEYS = {'sensor_id', 'status', 'model_file', 'train_bs', 'heldout_bs', 'flags'}


def _run(seed: int, a1, *, t_lo: float = -10.0, t_hi: float = 50.0):
    return synth_run(seed=seed, hours=0.5, rate_hz=5.0, a1=tuple(a1), t_lo=t_lo, t_hi=t_hi)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write the bags of every sensor; return {name: (train bag, test bag)} and extras."""
    root = tmp_path_factory.mktemp('fleet_bags')
    rng = np.random.default_rng(7)
    out = {}
    for i, sid in enumerate(GOOD + (OUTLIER,)):
        a1 = BASE_A1 * (1.0 + 0.05 * rng.standard_normal(3))
        if sid == OUTLIER:
            a1[0] = 3.0 * BASE_A1[0]
        out[sid] = (bag_from_run(_run(2 * i, a1), root / sid / 'train'),
                    bag_from_run(_run(2 * i + 1, a1), root / sid / 'test'))
    # A truncated bag: the first 16 kB of a good database.
    trunc = root / 'truncated' / 'train'
    shutil.copytree(out['imu-a'][0], trunc)
    db = next(trunc.glob('*.db3'))
    db.write_bytes(db.read_bytes()[:16384])
    out['truncated'] = (trunc,)
    # Temperature on another topic than the one asked for.
    run = _run(20, BASE_A1)
    notemp = root / 'notopic' / 'train'
    write_bag(notemp, imu_t=run.t + 100.0, gyro=run.omega, accel=np.zeros((len(run), 3)),
              temp_t=run.t[::5] + 100.0, temp_c=run.temp[::5],
              temperature_topic='/chamber/temperature')
    out['notopic'] = (notemp,)
    # Too small a temperature span (0.01 degC).
    out['flat'] = (bag_from_run(_run(21, BASE_A1, t_lo=25.0, t_hi=25.01),
                                root / 'flat' / 'train'),)
    return root, out


def _manifest(path: Path, rows) -> Path:
    """Write a manifest with paths relative to it; rows are (sensor_id, train, test)."""
    lines = ['sensor_id,train,test']
    for sid, train, test in rows:
        rel = [';'.join(os.path.relpath(b, path.parent) for b in bags) for bags in (train, test)]
        lines.append(f'{sid},{rel[0]},{rel[1]}')
    path.write_text('\n'.join(lines) + '\n')
    return path


def _rows(bags, names):
    _, b = bags
    return [(sid, [b[sid][0]], [b[sid][1]] if len(b[sid]) > 1 else []) for sid in names]


def _options(*extra):
    """Return the ``train`` options parsed from ``extra`` (defaults otherwise)."""
    return train_options(train_parser().parse_args(['bag', '--out', 'm.yaml', '--no-progress',
                                                    *extra]))


@pytest.fixture(scope='module')
def engine():
    """One embedded LocalCluster with two worker processes for the module (reaped after)."""
    with reaped(), open_engine(workers=2) as e:
        yield e


# ---- pure parts ---------------------------------------------------------------------------

def test_manifest_paths_relative_to_the_manifest(tmp_path):
    (tmp_path / 'm').mkdir()
    path = tmp_path / 'm' / 'fleet.csv'
    path.write_text('sensor_id,train,test\n'
                    'imu-1, bags/a ; bags/b ,bags/c\n'
                    '\n'
                    'IMU_2.rev3,/abs/x,\n')
    specs = read_manifest(path)
    assert [s.sensor_id for s in specs] == ['imu-1', 'IMU_2.rev3']
    assert specs[0].train == (str(tmp_path / 'm' / 'bags/a'), str(tmp_path / 'm' / 'bags/b'))
    assert specs[0].test == (str(tmp_path / 'm' / 'bags/c'),)
    assert specs[1].train == ('/abs/x',) and specs[1].test == ()
    assert specs[1].line == 4


@pytest.mark.parametrize('text', ['a/b', '../up', '', '.hidden', 'x' * 129, 'a b', 'ü'])
def test_sensor_id_that_cannot_be_a_file_name_is_refused(text):
    with pytest.raises(FleetError, match='cannot be a file name'):
        check_sensor_id(text)


def test_robust_z():
    z = robust_z([1.0, 2.0, 3.0, 4.0, 100.0])
    assert z[2] == 0.0
    assert z[4] == pytest.approx(97.0 / 1.4826)
    assert np.all(np.isnan(robust_z([5.0, 5.0, 5.0, 6.0])))


def test_drift_polynomial_recovers_the_known_drift():
    run = synth_run(seed=3, hours=1.0, rate_hz=2.0, noise_dps=0.0)
    model = fit_model([run], kind='poly', features=('dT', 'dT2'), t0=25.0)
    c = drift_polynomial(model)                       # b = c0 + c1 T + c2 T^2, deg/s
    a1, a2 = np.array([0.02, -0.015, 0.01]), np.array([2e-4, 1.5e-4, -1e-4])
    np.testing.assert_allclose(c[:, 2], a2, rtol=1e-6)
    np.testing.assert_allclose(c[:, 1] + 2 * c[:, 2] * 25.0, a1, rtol=1e-6)


def test_fleet_statistics_flag_only_the_planted_outlier():
    rng = np.random.default_rng(1)
    sensors = []
    for i in range(12):
        poly = np.zeros((3, 3))
        poly[:, 1] = BASE_A1 * (1 + 0.05 * rng.standard_normal(3))
        poly[:, 2] = 1e-4 * (1 + 0.05 * rng.standard_normal(3))
        if i == 5:
            poly[1, 1] *= 2.0
        sensors.append(SensorResult(f's{i}', 'ok', drift_poly=poly.tolist(),
                                    temp_range_c=[0.0, 0.0]))
    sensors.append(SensorResult('broken', 'failed', error='x'))
    assert fleet_statistics(sensors, outlier_z=3.5) == 0.0
    flagged = {s.sensor_id: s.flags for s in sensors if s.flags}
    assert list(flagged) == ['s5']
    assert len(flagged['s5']) == 1 and flagged['s5'][0].startswith('drift slope on y ')
    assert 'σ from the fleet' in flagged['s5'][0]
    assert sensors[-1].z_slope is None


def test_fleet_statistics_need_three_sensors():
    poly = np.zeros((3, 3)).tolist()
    two = [SensorResult(f's{i}', 'ok', drift_poly=poly, temp_range_c=[0, 10]) for i in range(2)]
    assert fleet_statistics(two) == 5.0
    assert all(s.z_slope is None and not s.flags for s in two)


def test_table_of_a_large_fleet_lists_only_failed_and_flagged_sensors():
    sensors = [SensorResult(f's{i:02d}', 'ok', train_bs=[0.1] * 3) for i in range(45)]
    sensors[7] = SensorResult('s07', 'failed', error='Bag is corrupt')
    sensors[9].flags.append('drift slope on x 9.0σ from the fleet')
    lines = format_table(FleetResult('local', 2, sensors, seconds=1.0)).splitlines()
    assert [line.split()[0] for line in lines[1:-1]] == ['s07', 's09']
    assert 'Bag is corrupt' in lines[1] and '9.0σ' in lines[2]
    assert lines[-1].startswith('45 sensors: 44 ok (0 unchanged, skipped), 1 failed, 1 flagged')


# ---- on a LocalCluster with two worker processes ------------------------------------------

def test_fleet_on_two_workers_flags_outlier_and_isolates_failures(tmp_path, bags, engine):
    root, b = bags
    rows = _rows(bags, GOOD + (OUTLIER,)) + [
        ('truncated', [b['truncated'][0]], []), ('notopic', [b['notopic'][0]], []),
        ('flat', [b['flat'][0]], []), ('missing', [root / 'no_such_bag'], [])]
    specs = read_manifest(_manifest(tmp_path / 'fleet.csv', rows))
    out = tmp_path / 'out'
    result = run_fleet(specs, out, _options(), engine)

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
    specs = read_manifest(_manifest(tmp_path / 'fleet.csv', _rows(bags, GOOD[:2])))
    out = tmp_path / 'out'
    first = run_fleet(specs, out, _options(), engine)
    assert [s.skipped for s in first.sensors] == [False, False]
    model_a = out / 'imu-a.yaml'
    before = model_a.read_bytes()

    again = run_fleet(specs, out, _options(), engine)
    assert [(s.status, s.skipped) for s in again.sensors] == [('ok', True), ('ok', True)]
    assert again.sensors[0].train_bs == first.sensors[0].train_bs
    assert again.sensors[0].heldout_bs == first.sensors[0].heldout_bs
    assert model_a.read_bytes() == before

    forced = run_fleet(specs, out, _options(), engine, force=True)
    assert [s.skipped for s in forced.sensors] == [False, False]

    changed = run_fleet(specs, out, _options('--centers', '8'), engine)
    assert [s.skipped for s in changed.sensors] == [False, False]
    assert load_model(model_a).n_centers == 8
    # The progress bar is not an input of the model: the same options with it on skip.
    shown = run_fleet(specs, out, _options('--centers', '8'), engine,
                      bag=BagOptions(progress=True))
    assert [s.skipped for s in shown.sensors] == [True, True]

    # A touched bag (new mtime) retrains that sensor only; an edited model file is replaced.
    db = next(Path(b['imu-b'][1]).glob('*.db3'))
    st = db.stat()
    os.utime(db, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    touched = run_fleet(specs, out, _options('--centers', '8'), engine)
    assert [s.skipped for s in touched.sensors] == [True, False]
    model_a.write_text(model_a.read_text() + '# edited\n')
    edited = run_fleet(specs, out, _options('--centers', '8'), engine)
    assert [s.skipped for s in edited.sensors] == [False, True]


# ---- the command line ---------------------------------------------------------------------

def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith('gyro-tdc fleet: error: ')
    return err[0]


def test_cli_against_a_scheduler_address(tmp_path, bags, capsys):
    _, b = bags
    rows = _rows(bags, GOOD) + [('truncated', [b['truncated'][0]], [])]
    manifest = _manifest(tmp_path / 'fleet.csv', rows)
    out = tmp_path / 'out'
    with local_cluster(n_workers=1) as cluster:
        addr = cluster.scheduler_address
        code = main([str(manifest), '--out', str(out), '--scheduler', addr, '--no-progress',
                     '--centers', '6'])
        text = capsys.readouterr().out
        assert code == 1
        summary = json.loads((out / 'summary.json').read_text())
        assert (summary['scheduler'], summary['workers']) == (addr, 1)
        assert [s['status'] for s in summary['sensors']] == ['ok', 'ok', 'ok', 'failed']
        assert 'truncated  failed' in text and 'corrupt' in text
        assert load_model(out / 'imu-a.yaml').n_centers == 6
        created = yaml.safe_load((out / 'imu-a.yaml').read_text())
        assert created['sensor']['sensor_id'] == 'imu-a'

        _manifest(manifest, rows[:3])
        code = main([str(manifest), '--out', str(out), '--scheduler', addr, '--no-progress',
                     '--centers', '6'])
        text = capsys.readouterr().out
        assert code == 0
        assert '3 ok (3 unchanged, skipped)' in text


def test_cli_refuses_workers_with_another_gyro_tdc(tmp_path, capsys, monkeypatch):
    stub = tmp_path / 'stub' / 'gyro_tdc'          # another version, on the worker only
    stub.mkdir(parents=True)
    (stub / '__init__.py').write_text("__version__ = '0.0.0'\n")
    manifest = _manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
    # Spawned workers start from this process's sys.path; this process has gyro_tdc already.
    monkeypatch.syspath_prepend(str(stub.parent))
    with local_cluster(n_workers=1) as cluster:
        code = main([str(manifest), '--out', str(tmp_path / 'out'),
                     '--scheduler', cluster.scheduler_address])
    assert code == 2
    line = _one_error_line(capsys)
    assert 'has gyro_tdc 0.0.0' in line and 'same version' in line
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('content, needle', [
    (None, 'cannot read'),
    ('', 'is empty'),
    ('id,train,test\na,b,c\n', 'expected the header'),
    ('sensor_id,train,test\na,b\n', 'expected 3 fields'),
    ('sensor_id,train,test\na/b,x,y\n', 'cannot be a file name'),
    ('sensor_id,train,test\nimu,x,\nIMU,y,\n', 'repeats line 2'),
    ('sensor_id,train,test\nimu,,x\n', 'no training bag'),
    ('sensor_id,train,test\n', 'lists no sensor'),
])
def test_bad_manifest_exits_2_with_one_line(tmp_path, capsys, content, needle):
    path = tmp_path / 'fleet.csv'
    if content is not None:
        path.write_text(content)
    assert main([str(path), '--out', str(tmp_path / 'out')]) == 2
    assert needle in _one_error_line(capsys)
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('argv, needle', [
    (['--workers', '0'], '--workers'),
    (['--features', 'dT,nope'], 'nope'),
    (['--workers', '2', '--scheduler', 'tcp://127.0.0.1:1'], 'not allowed with'),
    (['--outlier-z', '-1'], '--outlier-z'),
    (['--scheduler', 'tcp://127.0.0.1:1', '--connect-timeout', '0.5'], 'cannot connect'),
    (['--scheduler', 'no-port'], 'cannot connect'),
])
def test_bad_options_exit_2_with_one_line(tmp_path, capsys, argv, needle):
    path = _manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
    assert main([str(path), '--out', str(tmp_path / 'out'), *argv]) == 2
    assert needle in _one_error_line(capsys)


# ---- failures stay with their sensor; lost clusters and SIGTERM end with a summary ---------

def test_an_unwritable_model_path_fails_that_sensor_only(tmp_path, bags, engine):
    specs = read_manifest(_manifest(tmp_path / 'fleet.csv', _rows(bags, GOOD)))
    out = tmp_path / 'out'
    (out / 'imu-b.yaml').mkdir(parents=True)        # a directory where imu-b's model goes
    result = run_fleet(specs, out, _options(), engine)
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
    specs = read_manifest(_manifest(tmp_path / 'fleet.csv', _rows(bags, GOOD[:2])))
    out = tmp_path / 'out'
    with pytest.raises(OutputError) as info:
        run_fleet(specs, out, _options(), engine)
    line = str(info.value)
    assert '\n' not in line
    first = line.split(';')[0]
    assert first.startswith('imu-') and 'cannot write model file' in first, line
    assert 'No space left on device' in first and '(and 1 more sensor(s))' in first, line
    assert 'summary' in line and not (out / 'summary.json').exists()


def _fleet_child(argv: list) -> subprocess.Popen:
    """Start ``python -m gyro_tdc fleet ARGV`` with its output on pipes."""
    return subprocess.Popen([sys.executable, '-m', 'gyro_tdc', 'fleet', *map(str, argv),
                             '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_for_line(child: subprocess.Popen, prefix: str, bound_s: float = 300.0) -> list:
    """Return the child's stdout lines up to the first starting with ``prefix``."""
    lines = []
    with selectors.DefaultSelector() as sel:
        sel.register(child.stdout, selectors.EVENT_READ)
        while not lines or not lines[-1].startswith(prefix):
            assert sel.select(bound_s), f'no line {prefix!r} from fleet: {lines}'
            line = child.stdout.readline()
            assert line, f'fleet ended before {prefix!r}: {lines} {child.stderr.read()}'
            lines.append(line.rstrip('\n'))
    return lines


def _end(child: subprocess.Popen, bound_s: float = 300.0) -> tuple[int, str, list]:
    """Wait for the child's end (killed when it has not ended within ``bound_s``)."""
    try:
        out, err = child.communicate(timeout=bound_s)
    except subprocess.TimeoutExpired:
        child.kill()
        out, err = child.communicate()
        pytest.fail(f'fleet still running {bound_s:g} s after it should have stopped: {out}')
    return child.returncode, out, err.strip().splitlines()


def test_a_cluster_that_loses_every_worker_ends_fleet_with_one_line(tmp_path, bags):
    manifest = _manifest(tmp_path / 'fleet.csv', _rows(bags, GOOD + (OUTLIER,)))
    out = tmp_path / 'out'
    with local_cluster(n_workers=1) as cluster:
        child = _fleet_child([manifest, '--out', out, '--scheduler', cluster.scheduler_address,
                              '--connect-timeout', '2'])
        _wait_for_line(child, 'imu-a: ')
        cluster.scale(0)                            # every worker gone, the scheduler stays
        code, _, err = _end(child)
    assert code == 2, err
    assert len(err) == 1 and 'has had no worker for 2 s' in err[0], err
    summary = json.loads((out / 'summary.json').read_text())
    status = {r['sensor_id']: r for r in summary['sensors']}
    assert status['imu-a']['status'] == 'ok'
    assert any(r.get('error', '').startswith('not run: ') for r in status.values()), status


def test_sigterm_ends_fleet_like_ctrl_c_with_a_summary(tmp_path, bags):
    manifest = _manifest(tmp_path / 'fleet.csv', _rows(bags, GOOD + (OUTLIER,)))
    out = tmp_path / 'out'
    with reaped():                  # the child's own cluster too, should it outlive the child
        child = _fleet_child([manifest, '--out', out, '--workers', '1'])
        _wait_for_line(child, 'imu-a: ')
        child.send_signal(signal.SIGTERM)
        code, _, err = _end(child)
    assert code == 130, err
    assert err[-1:] == ['gyro-tdc fleet: error: interrupted'], err
    summary = json.loads((out / 'summary.json').read_text())
    assert [r['sensor_id'] for r in summary['sensors']] == list(GOOD + (OUTLIER,))
    assert summary['sensors'][0]['status'] == 'ok'
    assert summary['sensors'][-1]['error'] == 'not run (fleet interrupted)'


@pytest.mark.timeout(120)   # a few seconds; once hung 8 minutes in the cluster's close
def test_a_scheduler_without_workers_exits_2_after_the_timeout(tmp_path, capsys):
    path = _manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
    with local_cluster(n_workers=0) as cluster:
        assert main([str(path), '--out', str(tmp_path / 'out'), '--scheduler',
                     cluster.scheduler_address, '--connect-timeout', '1']) == 2
    assert 'no Dask worker connected within 1 s' in _one_error_line(capsys)
