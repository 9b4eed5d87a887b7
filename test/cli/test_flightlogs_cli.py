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
held-out accuracy; bad logs are one line.
"""

from __future__ import annotations

from dataclasses import replace
import json

from bags import assert_bad_input
from flightlogs import bag_from_imu, imu_from_sim, px4_topics, write_dataflash, write_ulog
from gyro_tdc.cli.evaluate import main as evaluate
from gyro_tdc.cli.train import main as train
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest


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
    for path in logs:
        cut = tmp_path / f'cut{path.suffix}'
        cut.write_bytes(path.read_bytes()[:-3])
        assert_bad_input(capsys, [cut, *out], 'ends inside a message', '--allow-loss')
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
