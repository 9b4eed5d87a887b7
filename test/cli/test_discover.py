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
``gyro-tdc discover``: its JSON, model file and report; bad input in one line.

A gyro whose every axis reads a fixed value, and (``--sensor accel``) an accelerometer read
as exactly ``(0, 0, g)``, leave discovery nothing to find: the command refuses in one line
before the search, in train's words, writes no output file, with every warning an error. A
gyro with one stuck axis is discovered with that axis passed through. A flight log is
searched on its still stretches only, or refused in one line about stillness.
"""

from __future__ import annotations

import json
import sys

from discover_cases import calibrate, HEAT, scenario, write_runs
from flightlogs import flight_day, write_dataflash
from gyro_tdc.cli.discover import main
from gyro_tdc.data import write_bag
from gyro_tdc.identify.accel import G0
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest
from real_logs import ARDUPILOT_CUBEBLACK, PX4_HOVER
from strict_cli import strict_cli as _cli


def test_cli_json_shape_model_file_and_report(tmp_path, capsys):
    sc = scenario(['bias', 'dT', 'dT2'], rate_hz=2.0, segments=HEAT[:1] + [
        {'kind': 'ramp', 'to_c': 30.0, 'rate_c_per_h': 40.0}])
    sc = calibrate(sc, 'dT2', 1.0, 41)
    (bag,) = write_runs(tmp_path, sc, 41)
    out = tmp_path / 'out'
    rc = main([str(bag), '--json', str(out / 'r.json'), '--out', str(out / 'm.yaml'),
               '--report', str(out / 'report'), '--no-progress'])
    assert rc == 0
    stdout = capsys.readouterr().out
    assert 'step 1: add dT2' in stdout and 'noise floor' in stdout
    doc = json.loads((out / 'r.json').read_text())
    assert list(doc) == ['base_effects', 'noise_floor_dps', 'steps', 'final_effects',
                         'unidentifiable', 'model_file']
    assert doc['base_effects'] == ['bias', 'dT']
    assert doc['final_effects'] == ['bias', 'dT', 'dT2']
    assert doc['model_file'] == str(out / 'm.yaml')
    assert isinstance(doc['noise_floor_dps'], float) and doc['noise_floor_dps'] > 0
    (step,) = doc['steps']
    required = ['effect', 'aliases', 'description', 'gap_before_dps', 'gap_after_dps',
                'heldout_gap_before_dps', 'heldout_gap_after_dps']
    assert list(step)[:len(required)] == required
    assert step['effect'] == 'dT2' and isinstance(step['aliases'], list)
    assert step['description'].startswith('Comb gap')
    assert all(isinstance(step[k], float) for k in required[3:])
    assert step['gap_after_dps'] < step['gap_before_dps']
    for u in doc['unidentifiable']:
        assert list(u) == ['effect', 'reason', 'experiment']
    model = load_model(out / 'm.yaml')
    assert model.features == ('bias', 'dT', 'dT2') and model.kind == 'poly'
    report = (out / 'report' / 'report.md').read_text()
    assert 'step1_maps.png' in report and (out / 'report' / 'step1_maps.png').stat().st_size
    assert (out / 'report' / 'allan.png').is_file()


@pytest.mark.parametrize('flag,shown', [([], True), (['--no-progress'], False)])
def test_the_candidate_bar_follows_no_progress_on_a_terminal(tmp_path, capsys, monkeypatch,
                                                             flag, shown):
    (bag,) = write_runs(tmp_path, scenario(['bias', 'dT'], rate_hz=2.0, segments=HEAT), 52)
    monkeypatch.setattr(sys.stderr, 'isatty', lambda: True)
    assert main([str(bag), *flag]) == 0
    assert ('discover: ' in capsys.readouterr().err) is shown


def test_cli_null_json_has_empty_steps(tmp_path):
    (bag,) = write_runs(tmp_path, scenario(['bias', 'dT'], rate_hz=2.0, segments=HEAT), 51)
    assert main([str(bag), '--json', str(tmp_path / 'r.json'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'r.json').read_text())
    assert doc['steps'] == [] and doc['model_file'] is None
    assert doc['final_effects'] == doc['base_effects'] == ['bias', 'dT']


@pytest.mark.parametrize('args,needle', [
    (['{missing}'], 'does not exist'),
    (['{bag}', '--base', 'bias,dT,humidity'], 'humidity'),
    (['{bag}', '--block-s', '0'], '--block-s'),
    (['{bag}', '--temperature-topic', '/nope'], '/nope'),
    (['{bag}', '--json', '{dir}'], '--json'),
])
def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys, args, needle):
    bag = tmp_path / 'bag'
    n = 400
    write_bag(bag, imu_t=np.arange(n) * 0.5, gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)),
              temp_t=np.arange(n // 2) * 1.0, temp_c=np.linspace(20.0, 30.0, n // 2))
    argv = [a.format(bag=bag, missing=tmp_path / 'nobag', dir=tmp_path) for a in args]
    assert main(argv + ['--no-progress']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write a dead gyro (every axis fixed) and a gyro with a constant accelerometer."""
    root = tmp_path_factory.mktemp('const_discover')
    sim = simulate_scenario('demo_fast', seed=3, rate_hz=2.0)[0]
    accel = np.zeros_like(sim.accel)
    accel[:, 2] = G0
    dead = np.zeros_like(sim.gyro)
    dead[:, 0] = 0.25                                # a stuck axis, off the reference
    dead[:, 1] = 0.01
    write_bag(root / 'dead', imu_t=sim.imu_t, gyro=dead, accel=sim.accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    write_bag(root / 'flat_accel', imu_t=sim.imu_t, gyro=sim.gyro, accel=accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    return root


@pytest.mark.parametrize('bag, extra', [('dead', ('--out', 'm.yaml', '--json', 'd.json')),
                                        ('flat_accel', ('--sensor', 'accel', '--json', 'd.json'))])
def test_discover_refuses_a_sensor_constant_on_every_axis(bags, tmp_path, bag, extra):
    """Exit 2 with one line naming the constant readings; no traceback, no file written."""
    argv = [a if not a.endswith(('.yaml', '.json')) else tmp_path / a for a in extra]
    res = _cli('discover', bags / bag, *argv)
    assert res.returncode == 2, (res.returncode, res.stderr)
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('gyro-tdc discover: error: '), res.stderr
    assert 'constant' in err[0] and ('every axis' in err[0] or bag == 'flat_accel'), err[0]
    assert 'Traceback' not in res.stderr and 'Warning' not in res.stderr
    assert not (tmp_path / 'm.yaml').exists() and not (tmp_path / 'd.json').exists()


def test_discover_out_passes_a_stuck_axis_through(tmp_path):
    """``discover --out`` on a gyro with z stuck at 0.25 rad/s: z not fitted, x and y as train."""
    import yaml
    sim = simulate_scenario('demo_fast', seed=4, rate_hz=2.0)[0]
    gyro = sim.gyro.copy()
    gyro[:, 2] = 0.25
    write_bag(tmp_path / 'z1', imu_t=sim.imu_t, gyro=gyro, accel=sim.accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    res = _cli('discover', tmp_path / 'z1', '--out', tmp_path / 'm.yaml')
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr and 'Warning' not in res.stderr
    doc = yaml.safe_load((tmp_path / 'm.yaml').read_text())
    assert doc['training']['constant_axes'] == ['z'], doc['training']
    from gyro_tdc.model import compensate, load_model
    model = load_model(tmp_path / 'm.yaml')
    out = compensate(model, sim.imu_t, np.interp(sim.imu_t, sim.temp_t, sim.temp_c), gyro)
    assert np.array_equal(out[:, 2], gyro[:, 2])          # passed through, bit for bit
    assert np.std(out[:, 0] - gyro[:, 0]) > 0             # x is corrected


def test_on_flight_logs_it_says_what_it_kept_and_models_the_still_time(tmp_path, capsys):
    paths = [write_dataflash(tmp_path / f'day{seed}.bin', [flight_day(seed, legs=8).imu])
             for seed in range(3)]
    out, doc = tmp_path / 'm.yaml', tmp_path / 'd.json'
    argv = [str(p) for p in paths] + ['--out', str(out), '--json', str(doc), '--max-steps', '1']
    assert main(argv + ['--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'discovering on the still stretches only' in text
    assert json.loads(doc.read_text())['noise_floor_dps'] < 0.01
    assert out.exists()


@pytest.mark.parametrize('argv, words', [
    ([str(ARDUPILOT_CUBEBLACK)], 'on the still stretches only'),
    ([str(PX4_HOVER), '--temperature-source', 'baro'], 'no still stretch to discover on'),
])
def test_real_flight_logs_are_refused_in_one_line_about_stillness(argv, words, capsys):
    assert main(argv + ['--no-progress']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and 'Traceback' not in err
