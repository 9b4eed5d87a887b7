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
``train`` and ``evaluate`` on flight-controller logs.

A simulated calibration session written as a ULog, a DataFlash log and a bag gives one
held-out accuracy; the flight controller's own correction is scored as it applies it; bad
logs are one line.
"""

from __future__ import annotations

from dataclasses import replace
import json
from pathlib import Path
import shutil
import subprocess
import sys

from bags import assert_bad_input
from flightlogs import (bag_from_imu, Imu, imu_from_sim, px4_topics, write_dataflash,
                        write_ulog)
from gyro_tdc.cli.evaluate import main as evaluate
from gyro_tdc.cli.train import main as train
from gyro_tdc.model.fc_tempcal import ardupilot_correction, px4_correction
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest
from real_logs import (ARDUPILOT_AC33, ARDUPILOT_AC45, PX4_ACCEL_THERMOMETER, PX4_HOVER,
                       PX4_SELECTION_FLIPS)


@pytest.fixture(scope='module')
def session(tmp_path_factory):
    """Write two heat-cool chamber runs as ULogs, DataFlash logs and bags."""
    root = tmp_path_factory.mktemp('session')
    imus = [imu_from_sim(s) for s in simulate_scenario('l3gd20_heat_cool', seed=3,
                                                       rate_hz=1.0)]
    paths = {'ulog': [], 'dataflash': [], 'bag': []}
    for k, imu in enumerate(imus):
        paths['ulog'].append(write_ulog(root / f'run{k}.ulg', px4_topics([imu]),
                                        {'TC_G_ENABLE': 0}))
        paths['dataflash'].append(write_dataflash(root / f'run{k}.bin', [imu],
                                                  {'INS_TCAL1_ENABLE': 0}))
        paths['bag'].append(bag_from_imu(imu, root / f'run{k}_bag'))
    return root, imus, paths


def _held_out(root, pair, label, capsys):
    """Train on the first run, evaluate on the second; return the JSON bag and the output."""
    model, scores = root / f'{label}.yaml', root / f'{label}.json'
    assert train([str(pair[0]), '--out', str(model), '--features', 'dT,dT2',
                  '--no-progress']) == 0
    assert evaluate([str(pair[1]), '--model', str(model), '--json', str(scores),
                     '--no-progress']) == 0
    return json.loads(scores.read_text())['bags'][0], capsys.readouterr().out


def test_a_calibration_session_trains_to_the_same_held_out_accuracy_in_every_format(
        session, capsys):
    root, imus, paths = session
    got = {fmt: _held_out(root, pair, fmt, capsys) for fmt, pair in paths.items()}
    bag, _ = got['bag']
    bs, raw = np.array(bag['models'][0]['bs']), np.array(bag['raw']['bs'])
    assert np.all(bs < 0.05 * raw)                     # the drift is learnt and removed
    for fmt in ('ulog', 'dataflash'):
        log, out = got[fmt]
        assert log['samples'] == bag['samples'] == len(imus[1].t)
        np.testing.assert_allclose(log['raw']['bs'], raw, rtol=1e-9)
        np.testing.assert_allclose(log['models'][0]['bs'], bs, rtol=1e-6)
    assert 'PX4 ULog, sensor_gyro instance 0 of 1 (device id 2293768): raw' in got['ulog'][1]
    assert ('ArduPilot DataFlash, IMU instance 0 of 1: calibrated on board (no thermal '
            'compensation active); INS_TCAL1_ENABLE=0') in got['dataflash'][1]


def test_logs_of_two_boards_are_said_one_model_fits_neither(session, tmp_path, capsys):
    _, imus, _ = session
    logs = [write_dataflash(tmp_path / f'{b}.bin', [imu], {'INS_TCAL1_ENABLE': 0},
                            board=f'Pixhawk6C {b} 30315109 34373938')
            for b, imu in zip(('00490034', '00450021'), imus)]
    out = ['--out', str(tmp_path / 'm.yaml'), '--features', 'dT,dT2', '--no-progress']
    assert train([*map(str, logs), *out]) == 0
    said = capsys.readouterr().out
    assert ('warning: the logs come from 2 boards (Pixhawk6C 00490034 30315109 34373938: 1 '
            'log; Pixhawk6C 00450021 30315109 34373938: 1 log): each board drifts its own way'
            in said)
    same = [write_dataflash(tmp_path / f'same{k}.bin', [imu], {'INS_TCAL1_ENABLE': 0},
                            board='Pixhawk6C 00490034 30315109 34373938')
            for k, imu in enumerate(imus)]
    assert train([*map(str, same), *out]) == 0
    assert 'warning: the logs come from' not in capsys.readouterr().out


def test_evaluate_warns_on_a_log_of_another_imu_than_the_models(session, tmp_path, capsys):
    """The model keeps the IMUs its logs name; a log of another is scored with a warning."""
    _, imus, _ = session
    board = 'Pixhawk6C 00490034 30315109 34373938'
    mine = write_dataflash(tmp_path / 'mine.bin', [imus[0]], {'INS_TCAL1_ENABLE': 0},
                           board=board)
    model = tmp_path / 'm.yaml'
    assert train([str(mine), '--out', str(model), '--features', 'dT,dT2',
                  '--no-progress']) == 0
    assert load_model(model).created['imus'] == [f'{board} IMU 0']
    other = write_dataflash(tmp_path / 'other.bin', [imus[1]], {'INS_TCAL1_ENABLE': 0},
                            board='Pixhawk6C 00450021 30315109 34373938')
    again = write_dataflash(tmp_path / 'again.bin', [imus[1]], {'INS_TCAL1_ENABLE': 0},
                            board=board)
    capsys.readouterr()
    for log, warned in ((other, True), (again, False)):
        assert evaluate([str(log), '--model', str(model), '--no-progress']) == 0
        out = capsys.readouterr().out
        assert (f'is Pixhawk6C 00450021 30315109 34373938 IMU 0; model m was trained on '
                f'{board} IMU 0: each IMU drifts its own way' in out) is warned, out
        assert ('warning: ' in out and 'trained on' in out) is warned


def _short(imu, n=600):
    """Return the first ``n`` samples of an IMU (a small log is enough to be refused)."""
    return replace(imu, t=imu.t[:n], gyro=imu.gyro[:n], temp=imu.temp[:n], accel=imu.accel[:n])


def test_bad_logs_are_one_line_and_exit_2(session, tmp_path, capsys):
    imu = _short(session[1][0])
    out = ['--out', str(tmp_path / 'm.yaml'), '--features', 'dT,dT2', '--no-progress']
    cold = write_ulog(tmp_path / 'cold.ulg', px4_topics([imu], temperature=False))
    assert_bad_input(capsys, [cold, *out], 'carries no temperature')
    cold = write_dataflash(tmp_path / 'cold.bin', [imu], temperature=False)
    assert_bad_input(capsys, [cold, *out], 'IMU instance 0 carries no temperature')
    logs = [write_ulog(tmp_path / 'short.ulg', px4_topics([imu])),
            write_dataflash(tmp_path / 'short.bin', [imu])]
    for path in logs:       # cut off at the end: read with a warning, then judged as any log
        cut = tmp_path / f'cut{path.suffix}'
        cut.write_bytes(path.read_bytes()[:-3])
        assert train([str(cut), *out]) == 2
        said = capsys.readouterr()
        assert 'ends inside a message (cut short' in said.out
        assert 'Temperature span too small' in said.err and 'Traceback' not in said.err
    for path in logs:       # damaged inside: refused without --allow-loss
        data = bytearray(path.read_bytes())
        data[len(data) // 2:len(data) // 2 + 40] = bytes(40)
        bad = tmp_path / f'damaged{path.suffix}'
        bad.write_bytes(bytes(data))
        assert_bad_input(capsys, [bad, *out], 'damaged bytes inside the log', '--allow-loss')
    assert_bad_input(capsys, [logs[0], '--log-format', 'dataflash', *out], 'short.ulg')
    assert_bad_input(capsys, [logs[0], '--imu-instance', '1', *out],
                     'sensor_gyro has no instance 1', '--imu-instance')
    assert_bad_input(capsys, [logs[0], '--imu-instance', '-1', *out],
                     '--imu-instance', 'expected an integer >= 0')


def test_data_compensated_on_board_are_refused_unless_the_override_is_given(
        session, tmp_path, capsys):
    imu = session[1][0]
    out = ['--out', str(tmp_path / 'm.yaml'), '--features', 'dT,dT2', '--no-progress']
    px4 = write_ulog(tmp_path / 'combined.ulg', px4_topics([_short(imu)], combined=True),
                     {'TC_G_ENABLE': 1})
    ardu = write_dataflash(tmp_path / 'tcal.bin', [imu], {'INS_TCAL1_ENABLE': 1})
    assert_bad_input(capsys, [px4, *out], 'TC_G_ENABLE=1', 'compensate twice',
                     '--allow-onboard-corrected')
    assert_bad_input(capsys, [ardu, *out], 'INS_TCAL1_ENABLE=1', 'compensate twice',
                     '--allow-onboard-corrected')
    assert train([str(ardu), *out, '--allow-onboard-corrected']) == 0
    said = capsys.readouterr().out
    assert 'IMU instance 0 of 1: corrected on board (thermal compensation included)' in said


def _drifting(n=3000):
    """Return an IMU heated 0 -> 70 degC whose gyro drifts as a quadratic, in float32."""
    t = 10.0 + np.arange(n) * 0.1
    temp = np.linspace(0.0, 70.0, n).astype(np.float32).astype(float)
    d = (temp - 30.0)[:, None]
    rng = np.random.default_rng(8)
    gyro = 2e-3 * d * [1.0, -0.5, 0.3] + 1e-5 * d ** 2 + rng.normal(0.0, 1e-3, (n, 3))
    return Imu(t=t, gyro=gyro.astype(np.float32).astype(float), temp=temp, device_id=555)


def _f32(params):
    """Return parameters as the log stores them (float32)."""
    return {k: float(np.float32(v)) for k, v in params.items()}


def test_the_flight_controllers_own_correction_is_scored_exactly_as_it_applies_it(
        tmp_path, capsys):
    imu = _drifting()
    px4 = {'TC_G_ENABLE': 1, 'TC_G0_ID': 555, 'TC_G0_TREF': 30.0, 'TC_G0_TMIN': 10.0,
           'TC_G0_TMAX': 60.0, 'TC_G0_X0_1': 1e-4, 'TC_G0_X1_0': 2e-3, 'TC_G0_X1_1': -1e-3,
           'TC_G0_X2_0': 1e-5, 'TC_G0_X3_2': 1e-8}
    ardu = {'INS_TCAL1_ENABLE': 0, 'INS_TCAL1_TMIN': 10.0, 'INS_TCAL1_TMAX': 60.0,
            'INS_TCAL1_GYR1_X': 2000.0, 'INS_TCAL1_GYR2_X': 10.0, 'INS_TCAL1_GYR1_Y': -900.0,
            'INS_GYR1_CALTEMP': 25.0}
    cases = [(write_ulog(tmp_path / 'tc.ulg', px4_topics([imu]), px4), 'px4-onboard',
              px4_correction(_f32(px4), imu.temp), 'TC_G0_* (device id 555)'),
             (write_dataflash(tmp_path / 'tc.bin', [imu], ardu), 'ardupilot-onboard',
              ardupilot_correction(_f32(ardu), imu.temp), 'in this log it was not applied')]
    for path, spec, correction, words in cases:
        scores = tmp_path / f'{spec}.json'
        assert evaluate([str(path), '--model', spec, '--json', str(scores),
                         '--no-progress']) == 0
        got = json.loads(scores.read_text())['bags'][0]['models'][0]['bs']
        want = bias_stability(imu.gyro - correction, np.zeros_like(imu.gyro))
        np.testing.assert_allclose(got, want, rtol=1e-9)          # the clamp included
        assert words in capsys.readouterr().out
    assert_bad_input(capsys, [cases[1][0], '--model', 'px4-onboard', '--no-progress'],
                     '--model px4-onboard needs a PX4 ULog', entry=evaluate)
    done = write_dataflash(tmp_path / 'done.bin', [imu], {**ardu, 'INS_TCAL1_ENABLE': 1})
    assert_bad_input(capsys, [done, '--model', 'ardupilot-onboard', '--no-progress',
                              '--allow-onboard-corrected'],
                     'already carries the on-board correction', entry=evaluate)


def test_a_real_flight_log_whose_still_time_spans_no_temperature_is_refused_in_one_line(
        tmp_path, capsys):
    # 10 s on the ground, then a flight; the still samples all read 23.5 degC.
    out = ['--out', str(tmp_path / 'm.yaml'), '--no-progress']
    for extra in ([], ['--still-only']):
        assert_bad_input(capsys, [PX4_ACCEL_THERMOMETER, *extra, *out],
                         'still-only training: the still time spans 0.00 degC only')
    assert not (tmp_path / 'm.yaml').exists()


def test_a_real_flight_log_trains_on_its_still_stretch_only_and_evaluate_scores_that(
        tmp_path, capsys):
    # IMU3 of an ArduCopter 3.3 log warms 28 -> 32 degC over its 40 s on the ground, flies for
    # 10 s and stands 5 s more at 33 degC. One power cycle whose span is told in the minute
    # after power-on only: no held-out power cycle could judge its curve, so the offset only.
    log = [ARDUPILOT_AC33, '--imu-instance', '2', '--no-progress']
    models, said = {}, {}
    for name, extra in (('train', []), ('still', ['--still-only'])):
        models[name] = tmp_path / f'{name}.yaml'
        assert train([*map(str, log), *extra, '--out', str(models[name])]) == 0
        said[name] = capsys.readouterr().out
        assert 'training data: 1 bag(s), 2103 samples' in said[name]   # the still stretches
    assert 'training on the still stretches only (as --still-only)' in said['train']
    assert 'one power cycle only, and no still stretch of 5 min or more spans 2 degC of its own' \
        in said['train']
    assert load_model(models['train']).model_id == load_model(models['still']).model_id
    assert load_model(models['train']).features == ()
    scores = tmp_path / 'scores.json'
    assert evaluate([*map(str, log), '--model', str(models['train']), '--json',
                     str(scores)]) == 0
    assert 'scored the still stretches only, 2103 samples in 2 stretch(es)' in \
        capsys.readouterr().out
    got = json.loads(scores.read_text())['bags'][0]
    assert got['samples'] == 2103
    # The offset alone leaves the still stretches' spread as raw's.
    assert np.allclose(got['models'][0]['bs'], got['raw']['bs'], rtol=1e-9)
    assert_bad_input(capsys, [ARDUPILOT_AC33, '--out', tmp_path / 'm0.yaml', '--no-progress'],
                     'still-only training: the still time spans 1.33 degC only')


def test_the_px4_baseline_on_a_real_flight_log_is_fitted_on_its_still_stretch_only(
        tmp_path, capsys):
    # Fitted on the whole log (25.5 .. 34.2 degC, a flight) it made the still stretch
    # 120 / 4.8 / 354 x worse than raw.
    log = [str(ARDUPILOT_AC33), '--imu-instance', '2', '--no-progress']
    scores = tmp_path / 'px4.json'
    assert evaluate([*log, '--json', str(scores), '--model', 'px4', '--train',
                     str(ARDUPILOT_AC33)]) == 0
    out = capsys.readouterr().out
    assert 'the px4 cubic is fitted on the still stretches only (42 s of 80 s' in out
    assert 'range 28.00 .. 33.32 degC' in out
    assert max(json.loads(scores.read_text())['bags'][0]['models'][0]['p_vs_raw']) < 1.0
    hover = [str(PX4_HOVER), '--temperature-source', 'baro', '--no-progress']
    assert evaluate([*hover, '--model', 'px4', '--train', str(PX4_HOVER)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith('no still stretch to fit the px4 cubic on (its motion is no drift): '
                        'record the vehicle parked with the IMU on.') and '\n' not in err


def test_the_real_log_sweep_needs_no_log_and_finds_no_defect_in_a_real_extract(tmp_path):
    bench = Path(__file__).resolve().parents[2] / 'bench' / 'bench_real_logs.py'
    out = subprocess.run([sys.executable, str(bench), str(tmp_path)], capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert out == f'nothing to read: no .ulg or .bin log under {tmp_path}\n'
    shutil.copy(ARDUPILOT_AC45, tmp_path)
    out = subprocess.run([sys.executable, str(bench), str(tmp_path), '--json',
                          str(tmp_path / 'sweep.json')], capture_output=True, text=True,
                         timeout=600, check=True).stdout
    runs = json.loads((tmp_path / 'sweep.json').read_text())[str(tmp_path / ARDUPILOT_AC45.name)]
    assert runs['read BARO.Temp 1']['line'].endswith('BARO.Temp instance 1 10 Hz 33.2..34.1 degC')
    assert all(runs[f'{cmd} imu']['outcome'] == 'refused' for cmd in ('train', 'still'))
    assert 'already thermally compensated' in runs['train imu']['line']
    assert out.splitlines()[-1].endswith('logs with a defect: 0')


def test_the_real_log_sweep_judges_sensor_combined_by_the_selection_itself():
    import importlib.util
    path = Path(__file__).resolve().parents[2] / 'bench' / 'bench_real_logs.py'
    spec = importlib.util.spec_from_file_location('bench_real_logs', path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    first, second = (bench._ulog_gyro_rates(PX4_SELECTION_FLIPS, k) for k in (0, 1))
    assert 190.0 < first['sensor_combined'] < 210.0 and 1.0 < first['sensor_gyro'] < 1.2
    assert 150.0 < second['sensor_combined'] < 200.0     # IMU 1's rows: before the flip
    for k in (0, 1):          # each IMU read at its share of sensor_combined's 200 Hz
        seen = bench.inspect(PX4_SELECTION_FLIPS, 'imu', k)
        assert seen['defects'] == [] and 'sensor_combined' in seen['line'], seen
