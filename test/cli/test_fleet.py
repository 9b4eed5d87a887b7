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
``gyro-tdc fleet``: against a scheduler address, bad input in one line, lost clusters, SIGTERM.

The CLI runs against the address of a one-worker cluster started in its test; a fleet whose
cluster loses every worker, or that gets SIGTERM, runs as a child process and ends with one
line and a summary; the installed ``gyro-tdc fleet`` reports a sensor with a constant gyro
axis without flagging it.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
import selectors
import signal
import subprocess
import sys

from dask_cluster import local_cluster, reaped
from fleet_rig import GOOD, make_bags, make_constant_bags, manifest_rows, OUTLIER, write_manifest
from gyro_tdc.cli.fleet import main
from gyro_tdc.model import load_model
import pytest
import yaml


# Time-bounded: a cluster that never closes fails its test within this bound (each test
# takes under a minute on a loaded 2-core machine) instead of holding the run.
pytestmark = pytest.mark.timeout(300)
GYRO_TDC = Path(sys.executable).with_name('gyro-tdc')


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write the fleet's bags once for this module."""
    return make_bags(tmp_path_factory.mktemp('fleet_bags'))


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith('gyro-tdc fleet: error: ')
    return err[0]


def test_cli_against_a_scheduler_address(tmp_path, bags, capsys):
    _, b = bags
    rows = manifest_rows(bags, GOOD) + [('truncated', [b['truncated'][0]], [])]
    manifest = write_manifest(tmp_path / 'fleet.csv', rows)
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

        write_manifest(manifest, rows[:3])
        code = main([str(manifest), '--out', str(out), '--scheduler', addr, '--no-progress',
                     '--centers', '6'])
        text = capsys.readouterr().out
        assert code == 0
        assert '3 ok (3 unchanged, skipped)' in text


def test_cli_refuses_workers_with_another_gyro_tdc(tmp_path, capsys, monkeypatch):
    stub = tmp_path / 'stub' / 'gyro_tdc'          # another version, on the worker only
    stub.mkdir(parents=True)
    (stub / '__init__.py').write_text("__version__ = '0.0.0'\n")
    manifest = write_manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
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
    path = write_manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
    assert main([str(path), '--out', str(tmp_path / 'out'), *argv]) == 2
    assert needle in _one_error_line(capsys)


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
    manifest = write_manifest(tmp_path / 'fleet.csv', manifest_rows(bags, GOOD + (OUTLIER,)))
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
    manifest = write_manifest(tmp_path / 'fleet.csv', manifest_rows(bags, GOOD + (OUTLIER,)))
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
    path = write_manifest(tmp_path / 'fleet.csv', [('imu', [tmp_path / 'b'], [])])
    with local_cluster(n_workers=0) as cluster:
        assert main([str(path), '--out', str(tmp_path / 'out'), '--scheduler',
                     cluster.scheduler_address, '--connect-timeout', '1']) == 2
    assert 'no Dask worker connected within 1 s' in _one_error_line(capsys)


@pytest.fixture(scope='module')
def constant_bags(tmp_path_factory):
    """Write three ordinary sensors and one whose z axis is stuck, once for this module."""
    return make_constant_bags(tmp_path_factory.mktemp('fleet_const'))


def test_fleet_cli_reports_the_constant_sensor_without_flagging_it(constant_bags, tmp_path):
    """The installed gyro-tdc fleet on one worker: exit 0, z never flagged, z named."""
    root, b = constant_bags
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
