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

"""ArduPilot DataFlash in: ``IMU`` with ``T`` per instance, ``PARM``, the guards."""

from __future__ import annotations

from flightlogs import Imu, write_dataflash
from gyro_tdc.data import BagOptions, detect_format
from gyro_tdc.data.dataflash import read_dataflash
from gyro_tdc.data.dataset import describe_read, load_run
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
from real_logs import ARDUPILOT_AC33, ARDUPILOT_AC45


def _imus(n: int = 300, count: int = 3) -> list:
    """Return ``count`` IMUs of ``n`` samples at 50 Hz, each with its own rates."""
    rng = np.random.default_rng(5)
    t = 20.0 + np.arange(n) * 0.02
    return [Imu(t=t, gyro=rng.normal(0.0, 0.01, (n, 3)).astype(np.float32).astype(float),
                temp=np.linspace(30.0 + k, 45.0 + k, n).astype(np.float32).astype(float),
                accel=rng.normal(0.0, 1.0, (n, 3)).astype(np.float32).astype(float))
            for k in range(count)]


def test_each_imu_instance_reads_as_its_own_run_with_the_log_parameters(tmp_path):
    imus = _imus()
    params = {'INS_TCAL1_ENABLE': 0, 'INS_TCAL1_GYR1_X': 120.5, 'INS_GYR1_CALTEMP': 31.0,
              'INS_TCAL2_ENABLE': 2, 'ATC_RAT_RLL_P': 0.135}
    path = write_dataflash(tmp_path / 'three.bin', imus, params)
    assert detect_format(path) == 'dataflash'
    for k, imu in enumerate(imus):
        log = read_dataflash(path, instance=k, accel=True)
        assert (log.source, log.instance, log.instances) == ('IMU', k, (0, 1, 2))
        assert not log.raw and not log.compensated      # ENABLE 2 is learning: not applied
        np.testing.assert_array_equal(log.gyro, imu.gyro)
        np.testing.assert_array_equal(log.temp_c, imu.temp)
        np.testing.assert_array_equal(log.accel, imu.accel)
        np.testing.assert_allclose(log.imu_t, imu.t, atol=1e-9)
        assert log.params['ATC_RAT_RLL_P'] == pytest.approx(0.135)
        run = load_run(path, BagOptions(imu_instance=k))
        np.testing.assert_array_equal(run.omega, imu.gyro)
        assert run.info['params'] == pytest.approx({
            'INS_TCAL1_ENABLE': 0.0, 'INS_TCAL1_GYR1_X': 120.5, 'INS_GYR1_CALTEMP': 31.0,
            'INS_TCAL2_ENABLE': 2.0})
    line = describe_read(path, load_run(path, BagOptions(imu_instance=1)), '/r')
    assert 'ArduPilot DataFlash, IMU instance 1 of 3: calibrated on board' in line
    assert 'INS_TCAL2_ENABLE=2: on-board thermal compensation off' in line
    with pytest.raises(DatasetError, match=r'IMU has no instance 3 \(it has 0, 1, 2'):
        load_run(path, BagOptions(imu_instance=3))


def test_an_imu_compensated_on_board_is_refused_unless_allowed_and_only_that_imu(tmp_path):
    path = write_dataflash(tmp_path / 'tcal.bin', _imus(count=2), {'INS_TCAL1_ENABLE': 1})
    with pytest.raises(DatasetError, match=r'the IMU data were already thermally compensated '
                                           r'on board \(INS_TCAL1_ENABLE=1'):
        load_run(path)
    run = load_run(path, BagOptions(allow_onboard_corrected=True))
    assert run.info['onboard_compensated']
    assert not load_run(path, BagOptions(imu_instance=1)).info['onboard_compensated']


def test_a_log_without_temperature_is_one_error(tmp_path):
    path = write_dataflash(tmp_path / 'cold.bin', _imus(count=1), temperature=False)
    with pytest.raises(DatasetError, match='IMU instance 0 carries no temperature'):
        load_run(path)


def test_a_log_cut_off_at_its_end_is_read_with_a_warning_that_counts_the_loss(tmp_path):
    imus = _imus(count=1)
    whole = write_dataflash(tmp_path / 'whole.bin', imus)
    cut = tmp_path / 'cut.bin'
    cut.write_bytes(whole.read_bytes()[:-9])
    run = load_run(cut)                      # every SD-card log whose power goes ends so
    assert len(run) == len(imus[0].t) - 1
    cut_lines = [w for w in run.info['warnings'] if 'ends inside a message' in w]
    assert len(cut_lines) == 1 and f'last {54 - 9} bytes' in cut_lines[0]   # IMU: 54 bytes
    run = load_run(cut, BagOptions(max_loss=1.0))
    assert len(run) == len(imus[0].t) - 1
    head = tmp_path / 'head.bin'
    head.write_bytes(whole.read_bytes()[:50])
    with pytest.raises(DatasetError, match='head.bin'):
        load_run(head, BagOptions(max_loss=1.0))


def test_damaged_bytes_inside_are_skipped_quietly_and_said_on_the_read_line(tmp_path, capfd):
    imus = _imus(count=1)
    data = bytearray(write_dataflash(tmp_path / 'whole.bin', imus).read_bytes())
    middle = len(data) // 2
    data[middle:middle + 60] = bytes(60)
    path = tmp_path / 'damaged.bin'
    path.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=r'damaged.bin.*damaged bytes inside the log '
                                           r'\(pymavlink skipped \d+ damaged headers\); '
                                           '--allow-loss'):
        load_run(path)
    run = load_run(path, BagOptions(max_loss=1.0))
    assert len(imus[0].t) - 3 <= len(run) < len(imus[0].t)
    assert 'pymavlink skipped damaged bytes' in run.info['log']
    assert any('damaged bytes inside' in w for w in run.info['warnings'])
    assert capfd.readouterr().err == ''          # the indexer's reports do not leak


def test_arducopter_up_to_3_3_stamps_in_milliseconds(tmp_path):
    imus = _imus(count=2)
    path = write_dataflash(tmp_path / 'ms.bin', imus, stamp='TimeMS', temp_field='Temp')
    for k, imu in enumerate(imus):
        log = read_dataflash(path, instance=k)
        np.testing.assert_allclose(log.imu_t, np.floor(imu.t * 1e3 + 1e-6) * 1e-3, atol=1e-9)
        np.testing.assert_array_equal(log.temp_c, imu.temp)
        assert log.temperature == 'IMU.Temp'
    assert len(load_run(path, BagOptions(imu_instance=1))) == len(imus[1].t)


def test_one_imu_whose_thermometer_reads_zero_is_refused_saying_what_the_log_has(tmp_path):
    imu = _imus(count=1)[0]
    path = write_dataflash(tmp_path / 'zero.bin', [Imu(t=imu.t, gyro=imu.gyro,
                                                       temp=np.zeros_like(imu.temp))])
    with pytest.raises(DatasetError, match=r'IMU instance 0 carries no temperature \(what '
                                           r'each instance carries: 0: 300 samples at 50 Hz, '
                                           r'temperature none; the log has no other '
                                           r'thermometer\)\.$'):
        load_run(path)


def test_a_real_arducopter_3_3_log_three_imus_with_temp_stamped_in_milliseconds():
    # dronekit-la-testdata's log171.bin (a Pixhawk): handled, 40 s still, then a flight.
    for k in range(3):
        log = read_dataflash(ARDUPILOT_AC33, instance=k)
        assert (log.instances, log.temperature) == ((0, 1, 2), 'IMU.Temp')
        assert 1.0 / np.median(np.diff(log.imu_t)) == pytest.approx(50.0, rel=1e-6)
        assert len(log.imu_t) == 3854 and log.truncated_bytes == 0 and not log.damage
        assert 'INS_TCAL' in log.onboard and not log.compensated
    steps = np.diff(np.unique(read_dataflash(ARDUPILOT_AC33, instance=1).temp_c))
    np.testing.assert_allclose(steps, 0.125)                  # IMU2's thermometer: 1/8 degC
    warming = read_dataflash(ARDUPILOT_AC33, instance=2).temp_c
    assert warming[0] < 27.0 and warming.max() > 34.0          # IMU3 warms by 7 degC
    run = load_run(ARDUPILOT_AC33, BagOptions(imu_instance=1, temperature_source='baro'))
    assert run.info['temperature'] == 'BARO.Temp instance 1'  # BAR2 beside IMU2
    assert 27.0 < run.temp.min() < run.temp.max() < 36.5
    with pytest.raises(DatasetError, match=r'IMU has no instance 3 \(it has 0, 1, 2; what '
                                           r'each carries: 0: 3854 samples at 48.2 Hz, '
                                           r'temperature IMU.Temp; .*BARO instance 0, 1'):
        load_run(ARDUPILOT_AC33, BagOptions(imu_instance=3))


def test_a_real_arducopter_4_5_log_tells_instances_of_one_message_apart_by_their_i_field():
    # mavparser's 00000081.BIN (CubeOrangePlus, heated): IMU and BARO each carry their
    # instances in one message; HEAT's I is its heater's integrator, not an instance.
    ranges = []
    for k in range(3):
        log = read_dataflash(ARDUPILOT_AC45, instance=k)
        assert (log.instances, log.temperature, len(log.imu_t)) == ((0, 1, 2), 'IMU.T', 1255)
        assert log.compensated and f'INS_TCAL{k + 1}_ENABLE=1' in log.onboard
        assert not log.truncated_bytes and not log.damage
        ranges.append((log.temp_c.min(), log.temp_c.max()))
    assert ranges[0][0] > 43.0 and ranges[2][1] < 36.0       # IMU 3 sits away from the heater
    with pytest.raises(DatasetError, match=r'already thermally compensated on board '
                                           r'\(INS_TCAL1_ENABLE=1'):
        load_run(ARDUPILOT_AC45)
    # MSG.Field of a message with instances: the IMU's own, else the first; never mixed.
    for src, k, name, lo, hi in (('BARO.Temp', 1, 'BARO.Temp instance 1', 33.0, 34.5),
                                 ('BARO.Temp', 2, 'BARO.Temp', 44.5, 45.0),
                                 ('IMU.T', 2, 'IMU.T instance 2', 33.8, 35.2),
                                 ('HEAT.Temp', 1, 'HEAT.Temp', 43.4, 44.1),
                                 ('MCU.MTemp', 0, 'MCU.MTemp', 37.3, 38.2)):
        log = read_dataflash(ARDUPILOT_AC45, instance=k, temperature_source=src)
        assert log.temperature == name and log.proxy
        assert lo < log.temp_c.min() <= log.temp_c.max() < hi
        assert np.all(np.diff(log.temp_t) > 0)                # one reading per stamp
    assert len(read_dataflash(ARDUPILOT_AC45, temperature_source='HEAT.Temp').temp_t) == 50
    run = load_run(ARDUPILOT_AC45, BagOptions(imu_instance=1, temperature_source='BARO.Temp',
                                              allow_onboard_corrected=True))
    assert run.info['temperature'] == 'BARO.Temp instance 1' and 33.0 < run.temp.min()
