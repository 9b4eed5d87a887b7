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

"""PX4 ULog in: ``sensor_gyro`` per instance, ``sensor_combined`` fallback, the guards."""

from __future__ import annotations

from dataclasses import replace

from flightlogs import Imu, px4_topics, write_ulog
from gyro_tdc.data import BagOptions, detect_format, load_runs
from gyro_tdc.data.dataset import describe_read, load_run
from gyro_tdc.data.flightlog import rate_hz
from gyro_tdc.data.ulog import read_ulog, ulog_truncated_bytes
from gyro_tdc.errors import DatasetError
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from real_logs import PX4_ACCEL_THERMOMETER, PX4_SELECTION_FLIPS


def _imus(n: int = 300, count: int = 2) -> list:
    """Return ``count`` IMUs of ``n`` samples at 50 Hz, each with its own rates and device."""
    rng = np.random.default_rng(4)
    t = 50.0 + np.arange(n) * 0.02
    return [Imu(t=t, gyro=rng.normal(0.0, 0.01, (n, 3)).astype(np.float32).astype(float),
                temp=np.linspace(20.0 + k, 40.0 + k, n).astype(np.float32).astype(float),
                accel=rng.normal(0.0, 1.0, (n, 3)).astype(np.float32).astype(float),
                device_id=2293768 + 256 * k) for k in range(count)]


def test_each_sensor_gyro_instance_reads_as_its_own_run(tmp_path):
    imus = _imus()
    path = write_ulog(tmp_path / 'two.ulg', px4_topics(imus), {'TC_G_ENABLE': 0})
    for k, imu in enumerate(imus):
        log = read_ulog(path, instance=k, accel=True)
        assert (log.source, log.instance, log.instances) == ('sensor_gyro', k, (0, 1))
        assert log.raw and not log.compensated
        assert log.device_id == imu.device_id
        np.testing.assert_array_equal(log.gyro, imu.gyro)
        np.testing.assert_array_equal(log.temp_c, imu.temp)
        np.testing.assert_allclose(log.accel, imu.accel)
        run = load_run(path, BagOptions(imu_instance=k))
        np.testing.assert_array_equal(run.omega, imu.gyro)
        np.testing.assert_allclose(run.t, imu.t, rtol=0, atol=1e-9)
        np.testing.assert_allclose(run.temp, imu.temp)
        assert not run.omega_ref.any()
        assert run.info['reference'] == 'zero' and run.info['log_format'] == 'ulog'
        line = describe_read(path, run, '/rate_table/reference')
        assert f'sensor_gyro instance {k} of 2 (device id {imu.device_id}): raw' in line
        assert 'TC_G_ENABLE=0: on-board thermal compensation off' in line
    with pytest.raises(DatasetError, match=r'sensor_gyro has no instance 2 \(it has 0, 1'):
        load_run(path, BagOptions(imu_instance=2))


def test_raw_sensor_gyro_is_used_even_when_px4_compensates_and_its_parameters_are_kept(
        tmp_path):
    params = {'TC_G_ENABLE': 1, 'TC_G0_ID': 2293768, 'TC_G0_X0_0': 0.01, 'TC_G0_TREF': 30.0,
              'SENS_BOARD_ROT': 0}
    path = write_ulog(tmp_path / 'tc.ulg', px4_topics(_imus(count=1)), params)
    run = load_run(path)
    assert run.info['raw'] and not run.info['onboard_compensated']
    assert run.info['params'] == pytest.approx({'TC_G_ENABLE': 1.0, 'TC_G0_ID': 2293768.0,
                                                'TC_G0_X0_0': 0.01, 'TC_G0_TREF': 30.0})
    assert 'TC_G_ENABLE=1: on-board thermal compensation active' in run.info['log']


def test_sensor_combined_where_that_is_all_there_is_said_so_and_refused_when_compensated(
        tmp_path):
    imus = _imus(count=2)
    off = write_ulog(tmp_path / 'off.ulg', px4_topics(imus, combined=True), {'TC_G_ENABLE': 0})
    run = load_run(off)
    np.testing.assert_array_equal(run.omega, imus[0].gyro)
    np.testing.assert_allclose(run.temp, imus[0].temp)       # vehicle_imu_status instance 0
    assert not run.info['raw'] and not run.info['onboard_compensated']
    assert 'sensor_combined (rotated, calibrated on board) is all there is' in run.info['log']
    assert 'temperature from vehicle_imu_status.temperature_gyro' in run.info['log']
    on = write_ulog(tmp_path / 'on.ulg', px4_topics(imus, combined=True), {'TC_G_ENABLE': 1})
    with pytest.raises(DatasetError, match='already thermally compensated on board '
                                           r'\(TC_G_ENABLE=1.*--allow-onboard-corrected'):
        load_run(on)
    run = load_run(on, BagOptions(allow_onboard_corrected=True))
    assert run.info['onboard_compensated']
    assert 'corrected on board (thermal compensation included)' in run.info['log']


def test_a_log_without_temperature_is_one_error(tmp_path):
    path = write_ulog(tmp_path / 'cold.ulg', px4_topics(_imus(count=1), temperature=False))
    with pytest.raises(DatasetError, match='sensor_gyro instance 0 carries no temperature'):
        load_run(path)
    path = write_ulog(tmp_path / 'cold_combined.ulg',
                      px4_topics(_imus(count=1), combined=True, temperature=False))
    with pytest.raises(DatasetError, match='sensor_combined instance 0 carries no temperature'):
        load_run(path)


def test_a_log_cut_off_at_its_end_is_read_with_a_warning_that_counts_the_loss(tmp_path):
    imus = [replace(_imus(count=1)[0], accel=None)]          # the last message a gyro one
    whole = write_ulog(tmp_path / 'whole.ulg', px4_topics(imus))
    assert ulog_truncated_bytes(whole) == 0
    cut = tmp_path / 'cut.ulg'
    cut.write_bytes(whole.read_bytes()[:-5])
    assert ulog_truncated_bytes(cut) > 0
    for options in (BagOptions(), BagOptions(max_loss=1.0)):
        run = load_run(cut, options)
        assert len(run) == len(imus[0].t) - 1
        cut_lines = [w for w in run.info['warnings'] if 'cut short' in w]
        assert len(cut_lines) == 1
        assert f'last {ulog_truncated_bytes(cut)} bytes' in cut_lines[0]
    head = tmp_path / 'head.ulg'
    head.write_bytes(whole.read_bytes()[:40])
    with pytest.raises(DatasetError, match='head.ulg'):
        load_run(head, BagOptions(max_loss=1.0))


def test_the_format_is_told_by_the_file_and_can_be_forced(tmp_path):
    path = write_ulog(tmp_path / 'log.ulg', px4_topics(_imus(count=1)))
    renamed = tmp_path / 'log.dat'
    renamed.write_bytes(path.read_bytes())
    assert detect_format(path) == detect_format(renamed) == 'ulog'    # magic bytes
    assert detect_format(tmp_path) == 'rosbag2'
    assert detect_format(renamed, 'dataflash') == 'dataflash'
    (tmp_path / 'empty.ulg').write_bytes(b'')
    assert detect_format(tmp_path / 'empty.ulg') == 'ulog'             # the suffix
    with pytest.raises(DatasetError, match='log format to be one of auto, rosbag2'):
        detect_format(path, 'csv')
    with pytest.raises(DatasetError, match='log_format'):
        replace(BagOptions(), log_format='px4')
    with pytest.raises(DatasetError, match='imu_instance'):
        BagOptions(imu_instance=-1)
    with pytest.raises(DatasetError, match='not a readable DataFlash log|not a DataFlash log'):
        load_run(renamed, BagOptions(log_format='dataflash'))


def test_a_folder_of_logs_expands_to_its_logs(tmp_path):
    imus = _imus(count=1)
    folder = tmp_path / 'flights'
    folder.mkdir()
    for name in ('run_10.ulg', 'run_2.ulg'):
        write_ulog(folder / name, px4_topics(imus))
    runs = load_runs(folder)
    assert [r.name.rsplit('/', 1)[-1] for r in runs] == ['run_2.ulg', 'run_10.ulg']


def test_damaged_bytes_inside_are_said_on_the_read_line_not_taken_for_a_cut(tmp_path):
    imus = [replace(_imus(count=1)[0], accel=None)]
    data = bytearray(write_ulog(tmp_path / 'whole.ulg', px4_topics(imus)).read_bytes())
    middle = len(data) // 2
    data[middle:middle + 60] = bytes(60)
    path = tmp_path / 'damaged.ulg'
    path.write_bytes(bytes(data))
    assert ulog_truncated_bytes(path) == 0
    with pytest.raises(DatasetError, match='damaged bytes inside the log.*--allow-loss'):
        load_run(path)
    run = load_run(path, BagOptions(max_loss=1.0))
    assert 0 < len(run) < len(imus[0].t)
    assert 'pyulog found damaged messages (skipped)' in run.info['log']


def test_a_log_whose_subscriptions_are_damaged_is_refused_as_damaged(tmp_path):
    # A stretch of zeros over the subscriptions (ADD_LOGGED) leaves pyulog no topic to read.
    imus = [replace(_imus(count=1)[0], accel=None)]
    data = bytearray(write_ulog(tmp_path / 'whole.ulg', px4_topics(imus)).read_bytes())
    pos = 16                                  # the header; then (size, type) per message
    start = None
    while data[pos + 2] != ord('D'):
        start = pos if start is None and data[pos + 2] == ord('A') else start
        pos += 3 + int.from_bytes(data[pos:pos + 2], 'little')
    data[start:pos] = bytes(pos - start)
    path = tmp_path / 'damaged.ulg'
    path.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=r'no logged topic\): the log is damaged') as err:
        read_ulog(path)
    assert '\n' not in str(err.value)


def test_vehicle_imu_is_read_as_a_rate_where_it_is_the_fastest_gyro(tmp_path):
    from flightlogs import SENSOR_GYRO, Topic, VEHICLE_IMU
    rng = np.random.default_rng(9)
    n, dt = 1000, 0.01                        # vehicle_imu at 100 Hz
    t = 20.0 + np.arange(n) * dt
    rate = rng.normal(0.0, 0.05, (n, 3)).astype(np.float32).astype(float)
    us = np.round(t * 1e6).astype(np.uint64)
    vimu = Topic('vehicle_imu', VEHICLE_IMU, {
        'timestamp': us, 'timestamp_sample': us, 'delta_angle': rate * dt,
        'delta_velocity': np.tile([0.0, 0.0, -9.81 * dt], (n, 1)),
        'delta_angle_dt': np.full(n, 10000), 'delta_velocity_dt': np.full(n, 10000)})
    slow = us[::100]                          # sensor_gyro at 1 Hz, with the temperature
    gyro = Topic('sensor_gyro', SENSOR_GYRO, {
        'timestamp': slow, 'timestamp_sample': slow, 'device_id': 7, 'x': 0.0, 'y': 0.0,
        'z': 0.0, 'temperature': np.linspace(30.0, 31.0, len(slow))})
    path = write_ulog(tmp_path / 'vimu.ulg', [gyro, vimu])
    log = read_ulog(path, accel=True)
    assert log.source == 'vehicle_imu' and not log.raw
    np.testing.assert_allclose(log.gyro, rate, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(log.accel, np.tile([0.0, 0.0, -9.81], (n, 1)), rtol=1e-5)
    assert log.temperature == 'sensor_gyro.temperature' and len(log.temp_t) == len(slow)
    assert 'vehicle_imu (integrated, calibrated on board) at 100 Hz' in ' '.join(log.notes)


def test_a_slow_thermometer_is_held_over_its_own_period(tmp_path):
    from flightlogs import SENSOR_GYRO, Topic, VEHICLE_IMU_STATUS
    n = 3000                                  # 60 s at 50 Hz; the thermometer every 20 s
    imu = replace(_imus(n=n, count=1)[0], accel=None)
    us = np.round(imu.t * 1e6).astype(np.uint64)
    gyro = Topic('sensor_gyro', SENSOR_GYRO, {
        'timestamp': us, 'timestamp_sample': us, 'device_id': 1, 'x': imu.gyro[:, 0],
        'y': imu.gyro[:, 1], 'z': imu.gyro[:, 2], 'temperature': np.full(n, np.nan)})
    slow = us[::1000]
    status = Topic('vehicle_imu_status', VEHICLE_IMU_STATUS, {
        'timestamp': slow, 'gyro_device_id': 1,
        'temperature_gyro': np.linspace(30.0, 35.0, len(slow))})
    run = load_run(write_ulog(tmp_path / 'slow.ulg', [gyro, status]))
    assert run.info['temperature'] == 'vehicle_imu_status.temperature_gyro'
    assert len(run) == int(slow[-1] - slow[0]) // 20000 + 1     # every sample in its span
    assert run.info['rejected']['no_temperature'] == n - len(run)


def test_a_real_pixhawk_6c_whose_gyro_thermometer_reads_nan_uses_its_accelerometers():
    # px4-ulog-rs' quadrotor_local.ulg (PX4 v1.16, Pixhawk 6C): sensor_gyro.temperature and
    # vehicle_imu_status.temperature_gyro of instance 0 are NaN throughout.
    log = read_ulog(PX4_ACCEL_THERMOMETER)
    assert (log.source, log.instances, log.raw) == ('sensor_combined', (0, 1), False)
    assert log.temperature == 'vehicle_imu_status.temperature_accel' and not log.proxy
    assert 1.0 / np.median(np.diff(log.imu_t)) == pytest.approx(219.0, rel=0.05)
    assert 1.0 / np.median(np.diff(log.temp_t)) == pytest.approx(1.0, rel=0.05)
    np.testing.assert_array_equal(np.unique(log.temp_c), [23.5, 24.0])   # 0.5 degC steps
    # Instance 1 has no sensor_combined: vehicle_imu (2 Hz) with its own sensor_gyro's
    # thermometer.
    other = read_ulog(PX4_ACCEL_THERMOMETER, instance=1)
    assert other.source == 'vehicle_imu'
    assert 1.0 / np.median(np.diff(other.imu_t)) == pytest.approx(2.0, rel=0.05)
    assert other.temperature == 'sensor_gyro.temperature instance 1'
    assert 23.9 < np.nanmin(other.temp_c) < np.nanmax(other.temp_c) < 24.4
    # This PX4 logs no vehicle_air_data.baro_temp_celcius (its ambient_temperature reads a
    # constant 15): the barometer's own topic is the proxy.
    run = load_run(PX4_ACCEL_THERMOMETER, BagOptions(temperature_source='baro'))
    assert run.info['temperature'] == 'sensor_baro.temperature' and run.info['temperature_proxy']
    assert 24.4 < run.temp.min() < run.temp.max() < 24.9
    line = describe_read(PX4_ACCEL_THERMOMETER, load_run(PX4_ACCEL_THERMOMETER), '/r')
    assert 'temperature from vehicle_imu_status.temperature_accel' in line


def test_any_topic_of_the_log_serves_as_a_thermometer_and_a_sentinel_is_none(tmp_path):
    from flightlogs import Topic
    imu = replace(_imus(count=1)[0], accel=None)
    us = np.round(imu.t * 1e6).astype(np.uint64)
    fields = [('uint64_t', 'timestamp'), ('float', 'temperature')]
    topics = px4_topics([imu], temperature=False) + [
        Topic('differential_pressure', fields, {
            'timestamp': us[::10], 'temperature': np.linspace(20.0, 22.0, len(us[::10]))}),
        # PX4 fills the field with -1000 where the sensor has no thermometer.
        Topic('differential_pressure', fields, {
            'timestamp': us[::10], 'temperature': np.full(len(us[::10]), -1000.0)},
            multi_id=1)]
    path = write_ulog(tmp_path / 'airspeed.ulg', topics)
    log = read_ulog(path, temperature_source='differential_pressure.temperature')
    assert log.temperature == 'differential_pressure.temperature' and log.proxy
    np.testing.assert_allclose(log.temp_c, np.linspace(20.0, 22.0, len(us[::10])), rtol=1e-6)
    other = write_ulog(tmp_path / 'sentinel.ulg', topics[:1] + [replace(topics[2], multi_id=0)])
    with pytest.raises(DatasetError, match='no usable thermometer for --temperature-source '
                                           'differential_pressure.temperature'):
        read_ulog(other, temperature_source='differential_pressure.temperature')
    with pytest.raises(DatasetError, match='carries no temperature'):
        read_ulog(path)


def test_a_driver_that_leaves_timestamp_sample_zero_is_stamped_by_its_timestamp(tmp_path):
    imu = replace(_imus(count=1)[0], accel=None)
    topics = px4_topics([imu])
    topics[0].data['timestamp_sample'] = np.zeros(len(imu.t), dtype=np.uint64)
    log = read_ulog(write_ulog(tmp_path / 'no_sample_stamp.ulg', topics))
    np.testing.assert_allclose(log.imu_t, imu.t, atol=1e-9)     # not 300 samples at t = 0
    assert len(load_run(tmp_path / 'no_sample_stamp.ulg')) == len(imu.t)


def test_sensor_combined_is_read_for_the_imu_sensor_selection_names(tmp_path):
    from flightlogs import SENSOR_COMBINED, SENSOR_GYRO, Topic
    imus = _imus(n=1000, count=2)                # 50 Hz; sensor_gyro logged at 1 Hz
    imus[1] = replace(imus[1], temp=imus[1].temp + 20.0)
    topics = []
    for k, imu in enumerate(imus):
        us = np.round(imu.t * 1e6).astype(np.uint64)[::50]
        topics.append(Topic('sensor_gyro', SENSOR_GYRO, {
            'timestamp': us, 'timestamp_sample': us, 'device_id': imu.device_id,
            'x': imu.gyro[::50, 0], 'y': imu.gyro[::50, 1], 'z': imu.gyro[::50, 2],
            'temperature': imu.temp[::50]}, multi_id=k))
    us = np.round(imus[1].t * 1e6).astype(np.uint64)
    topics.append(Topic('sensor_combined', SENSOR_COMBINED, {   # the IMU PX4 selected: 1
        'timestamp': us, 'gyro_rad': imus[1].gyro, 'accelerometer_m_s2': imus[1].accel}))
    selection = [('uint64_t', 'timestamp'), ('uint32_t', 'accel_device_id'),
                 ('uint32_t', 'gyro_device_id')]
    path = write_ulog(tmp_path / 'selected.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': us[:1], 'accel_device_id': 7, 'gyro_device_id': imus[1].device_id})])
    log = read_ulog(path, instance=1)
    assert (log.source, log.device_id) == ('sensor_combined', imus[1].device_id)
    np.testing.assert_array_equal(log.gyro, imus[1].gyro)
    assert log.temperature == 'sensor_gyro.temperature instance 1' and log.temp_c.min() > 40.0
    log = read_ulog(path, instance=0)                # not IMU 1's gyro with IMU 0's thermometer
    assert (log.source, log.device_id, len(log.imu_t)) == ('sensor_gyro', imus[0].device_id, 20)
    assert 'sensor_combined carries instance 1 (sensor_selection)' in ' '.join(log.notes)
    # A selection that changes: each row is the IMU selected at its stamp. A selection
    # logged with stamp 0 (published before the logger started) comes first.
    half = len(us) // 2
    mixed = write_ulog(tmp_path / 'mixed.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': np.array([0, us[half], us[half] + 1], dtype=np.uint64),
        'accel_device_id': 7,
        'gyro_device_id': [imus[1].device_id, imus[0].device_id, imus[1].device_id]})])
    log = read_ulog(mixed, instance=0)      # one row is no gyro: sensor_gyro is read
    assert log.source == 'sensor_gyro' and len(log.imu_t) == 20
    log = read_ulog(mixed, instance=1)
    assert (log.source, log.device_id) == ('sensor_combined', imus[1].device_id)
    np.testing.assert_array_equal(log.gyro, np.delete(imus[1].gyro, half, axis=0))
    assert f'carries this IMU in {len(us) - 1} of {len(us)} samples' in ' '.join(log.notes)
    assert log.temperature == 'sensor_gyro.temperature instance 1'
    flips = write_ulog(tmp_path / 'flips.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': us[[0, half]], 'accel_device_id': 7,
        'gyro_device_id': [imus[0].device_id, imus[1].device_id]})])
    first, second = (read_ulog(flips, instance=k) for k in (0, 1))
    assert first.source == second.source == 'sensor_combined'
    np.testing.assert_array_equal(first.imu_t, np.round(imus[1].t * 1e6)[:half] * 1e-6)
    np.testing.assert_array_equal(second.gyro, imus[1].gyro[half:])
    # A selection of a device no instance logs: sensor_combined is no instance's.
    other = write_ulog(tmp_path / 'other.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': us[:2], 'accel_device_id': 7, 'gyro_device_id': [99, 98]})])
    log = read_ulog(other, instance=0)
    assert log.source == 'sensor_gyro'
    assert 'sensor_combined carries other IMUs (sensor_selection)' in ' '.join(log.notes)
    # Without sensor_selection it is the first IMU's, as PX4 selects by default.
    assert read_ulog(write_ulog(tmp_path / 'plain.ulg', topics)).source == 'sensor_combined'


def test_a_damaged_stamp_does_not_make_the_fastest_gyro_look_the_slowest(tmp_path):
    from flightlogs import SENSOR_COMBINED, SENSOR_GYRO, Topic
    imu = _imus(n=1200, count=1)[0]
    us = np.round(imu.t * 1e6).astype(np.uint64)
    bad = us.copy()
    bad[600] = np.uint64(71776119083914675)               # one stamp whose high byte flipped
    slow = us[::50]
    topics = [Topic('sensor_gyro', SENSOR_GYRO, {
        'timestamp': slow, 'timestamp_sample': slow, 'device_id': imu.device_id,
        'x': imu.gyro[::50, 0], 'y': imu.gyro[::50, 1], 'z': imu.gyro[::50, 2],
        'temperature': imu.temp[::50]}),
        Topic('sensor_combined', SENSOR_COMBINED, {
            'timestamp': bad, 'gyro_rad': imu.gyro, 'accelerometer_m_s2': imu.accel})]
    log = read_ulog(write_ulog(tmp_path / 'flipped.ulg', topics))
    assert log.source == 'sensor_combined' and len(log.imu_t) == 1200


def test_a_real_log_whose_selection_flips_gives_each_imu_its_own_200_hz_gyro():
    from pyulog import ULog
    log0, log1 = (read_ulog(PX4_SELECTION_FLIPS, instance=k) for k in (0, 1))
    sel = ULog(str(PX4_SELECTION_FLIPS), ['sensor_selection']).data_list[0].data
    assert [int(d) for d in sel['gyro_device_id']] == [log1.device_id, *[log0.device_id] * 2,
                                                       log1.device_id, log0.device_id]
    first, flip = (float(sel['timestamp'][k]) * 1e-6 for k in (1, -1))   # 2.55 .. 2.59 s in
    for log in (log0, log1):
        assert log.source == 'sensor_combined' and 150.0 < rate_hz(log.imu_t) < 250.0
        assert 'carries this IMU in' in log.notes[0]
    assert len(log0.imu_t) == 1300 and log0.imu_t[0] >= first and log0.imu_t[-1] > flip + 6
    assert len(log1.imu_t) == 437 and log1.imu_t[-1] < flip       # every row is one IMU's
    assert np.intersect1d(log0.imu_t, log1.imu_t).size == 0
    assert log0.temperature == 'sensor_gyro.temperature'              # each its own
    assert log1.temperature == 'vehicle_imu_status.temperature_accel instance 1'
    assert log0.device_id != log1.device_id
    # The IMU selected for less of the log names the one that holds the rest.
    assert 'instance 0 has 1300 (--imu-instance 0)' in log1.notes[0]
    assert '--imu-instance' not in log0.notes[0]
    for k, log in enumerate((log0, log1)):        # its accelerometer flips with its gyro
        with_accel = read_ulog(PX4_SELECTION_FLIPS, instance=k, accel=True)
        np.testing.assert_array_equal(with_accel.gyro, log.gyro)
        assert with_accel.accel.shape == log.gyro.shape and np.isfinite(with_accel.accel).all()


def _fifo_log(tmp_path, name: str = 'fifo.ulg', *, rate: float = 1000.0, seconds: float = 6.0,
              fifo_device: int | None = None, block: int = 8, accel_fifo: bool = False,
              blocks: slice = slice(None), edit=None, drop: str = '') -> tuple:
    """
    Write a PX4 log as its high-rate profile does; return (path, the IMU at the FIFO's rate).

    ``sensor_combined`` at a quarter of ``rate``, ``sensor_gyro`` and ``sensor_accel`` (the
    thermometer) at 1 Hz, ``sensor_gyro_fifo`` (of ``fifo_device``, by default the IMU's) at
    ``rate`` in blocks of ``block`` (``blocks`` of them), ``sensor_accel_fifo`` too where
    asked; ``edit(data)`` damages the gyro FIFO's columns before they are written, ``drop``
    leaves one of its fields out of its format.
    """
    from flightlogs import fifo_topic, SENSOR_COMBINED, Topic
    n = int(rate * seconds)
    rng = np.random.default_rng(7)
    t = 30.0 + np.arange(n) / rate
    imu = Imu(t=t, gyro=0.02 + 0.3 * np.sin(t[:, None] * [1.0, 2.0, 3.0]) + rng.normal(
        0.0, 0.01, (n, 3)), temp=np.linspace(25.0, 31.0, n),
        accel=[0.0, 0.0, -9.81] + rng.normal(0.0, 0.3, (n, 3)), device_id=2293768)
    slow = replace(imu, t=t[::int(rate)], gyro=imu.gyro[::int(rate)], temp=imu.temp[::int(rate)],
                   accel=imu.accel[::int(rate)])
    us = np.round(t[::4] * 1e6).astype(np.uint64)
    gyro = fifo_topic('sensor_gyro_fifo', t, imu.gyro, fifo_device or imu.device_id, block=block)
    gyro.data = {k: v if np.ndim(v) == 0 else v[blocks] for k, v in gyro.data.items()}
    gyro.fields = [f for f in gyro.fields if f[1] != drop]
    if edit is not None:
        edit(gyro.data)
    topics = px4_topics([slow]) + [Topic('sensor_combined', SENSOR_COMBINED, {
        'timestamp': us, 'gyro_rad': imu.gyro[::4], 'accelerometer_m_s2': imu.accel[::4]}), gyro]
    if accel_fifo:
        topics.append(fifo_topic('sensor_accel_fifo', t, imu.accel, imu.device_id + 1))
    return write_ulog(tmp_path / name, topics, {'TC_G_ENABLE': 0}), imu


def test_the_gyro_fifo_is_read_where_it_is_a_stream_the_thermometer_on_its_own_stamps(tmp_path):
    path, imu = _fifo_log(tmp_path, accel_fifo=True)
    log = read_ulog(path, accel=True)
    assert (log.source, log.raw, log.compensated) == ('sensor_gyro_fifo', True, False)
    assert log.notes == ['gyro from sensor_gyro_fifo at 1000 Hz beside sensor_combined at 250 '
                         'Hz', 'accelerometer from sensor_accel_fifo at 1000 Hz beside '
                         'sensor_combined at 250 Hz']
    np.testing.assert_allclose(log.imu_t, imu.t, atol=1.5e-6)    # the newest sample's stamp
    np.testing.assert_allclose(log.gyro, imu.gyro, atol=np.radians(1 / 131) / 1.9)
    np.testing.assert_allclose(log.accel, imu.accel, atol=9.80665 / 8192 / 1.9)
    assert log.temperature == 'sensor_gyro.temperature' and len(log.temp_t) == 6
    run = load_run(path, BagOptions(accel=True))
    assert 'gyro from sensor_gyro_fifo at 1000 Hz' in run.info['log']
    assert len(run.t) == 5000 and 24.99 < run.temp.min() < run.temp.max() < 30.01  # 30..35 s
    # Without sensor_accel_fifo the accelerometer is sensor_combined's, on the FIFO's stamps.
    path, imu = _fifo_log(tmp_path, 'no_accel.ulg', block=32)
    log = read_ulog(path, accel=True)
    assert log.source == 'sensor_gyro_fifo' and len(log.notes) == 1
    inside = (log.imu_t >= imu.t[0]) & (log.imu_t <= imu.t[::4][-1])
    assert np.isfinite(log.accel[inside]).all() and np.isnan(log.accel[~inside]).all()
    np.testing.assert_allclose(log.accel[::4][inside[::4]], imu.accel[::4], atol=1e-5)


def test_a_fifo_that_cannot_stand_in_leaves_the_log_as_it_was_said_in_one_clause(tmp_path):
    from pyulog import ULog
    plain, _ = _fifo_log(tmp_path, 'plain.ulg', blocks=slice(0, 0))
    ulog = ULog(str(plain), ['sensor_gyro_fifo'])
    assert not ulog.data_list and 'sensor_gyro_fifo' in ulog.message_formats  # defined, no data
    before = read_ulog(plain, accel=True)
    assert before.source == 'sensor_combined'
    cases = {'other.ulg': ({'fifo_device': 99}, 'sensor_gyro_fifo not used: its blocks are of '
                           'device 99, not 2293768'),
             'slow.ulg': ({'rate': 400.0, 'block': 1, 'blocks': slice(None, None, 3)},
                          'sensor_gyro_fifo not used: 800 samples at 133.3 Hz, not twice as fast '
                          'as sensor_combined'),
             'no_scale.ulg': ({'drop': 'scale'}, 'sensor_gyro_fifo not used: its format has '
                              'no scale'),
             'no_z.ulg': ({'drop': 'z'}, 'sensor_gyro_fifo not used: its format has no x[0..31], '
                          'y or z'),
             'early.ulg': ({'blocks': slice(0, 500)}, 'sensor_gyro_fifo at 1000 Hz not used: none '
                           'within 1 s of 250 of 1500 sensor_combined samples (gaps, or it ends '
                           'early)')}
    for name, (kw, said) in cases.items():
        rate = kw.get('rate', 1000.0)
        ref = before if rate == 1000.0 else read_ulog(_fifo_log(
            tmp_path, 'p' + name, rate=rate, blocks=slice(0, 0))[0], accel=True)
        log = read_ulog(_fifo_log(tmp_path, name, **kw)[0], accel=True)
        assert log.notes == ref.notes + [said]
        assert log.source == 'sensor_combined' and log.temperature == ref.temperature
        for a, b in ((log.imu_t, ref.imu_t), (log.gyro, ref.gyro), (log.accel, ref.accel),
                     (log.temp_c, ref.temp_c)):
            np.testing.assert_array_equal(a, b)


def test_damaged_fifo_blocks_are_skipped_and_counted_never_a_traceback(tmp_path):
    def damage(d):
        d['samples'] = d['samples'].copy()
        d['samples'][[3, 9]] = [40, 0]                   # beyond 32, none
        d['dt'] = np.where(np.isin(np.arange(len(d['samples'])), [20, 21]), [-5.0], d['dt'])
        d['scale'] = np.where(np.arange(len(d['samples'])) == 30, np.nan, d['scale'])
        d['timestamp_sample'] = d['timestamp_sample'].copy()
        d['timestamp_sample'][[100, 101]] = d['timestamp_sample'][[101, 100]]   # backwards
        d['device_id'] = np.where(np.isin(np.arange(len(d['samples'])), [50, 51]), 99,
                                  d['device_id'])           # another IMU's: not this one's

    path, imu = _fifo_log(tmp_path, edit=damage)
    log = read_ulog(path)
    assert log.source == 'sensor_gyro_fifo'
    assert log.notes[0].endswith(', 5 of 748 blocks skipped (samples, dt or scale out of range)')
    assert len(log.imu_t) == len(imu.t) - 7 * 8 and np.all(np.diff(log.imu_t) >= 0)
    assert np.isfinite(log.gyro).all()
    # A log cut inside a block: the blocks before it are read, the loss counted.
    cut = tmp_path / 'cut.ulg'
    cut.write_bytes(path.read_bytes()[:-100])
    run = load_run(cut)
    assert run.info['source'] == 'sensor_gyro_fifo'
    assert any('the last' in w for w in run.info['warnings'])


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(['samples', 'dt', 'scale', 'timestamp_sample', 'device_id']),
       values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=1,
                       max_size=6), share=st.floats(0.0, 1.0), cut=st.integers(0, 300))
def test_hostile_fifo_fields_read_or_refuse_in_one_line(tmp_path, field, values, share, cut):
    types = {'samples': np.uint8, 'timestamp_sample': np.uint64, 'device_id': np.uint32}

    def damage(d):
        n = len(d['samples'])
        at = np.random.default_rng(len(values)).random(n) < share
        col = np.broadcast_to(np.asarray(d[field], dtype=np.float64), (n,)).copy()
        col[at] = np.resize(values, int(at.sum()))
        if field in types:
            col = np.nan_to_num(col, nan=0.0, posinf=0.0, neginf=0.0)
            col = np.clip(col, 0, np.iinfo(types[field]).max).astype(types[field])
        d[field] = col

    path, _ = _fifo_log(tmp_path, f'h{abs(hash((field, tuple(values), share)))}.ulg',
                        seconds=3.0, edit=damage)
    if cut:
        path.write_bytes(path.read_bytes()[:-cut])
    try:
        log = read_ulog(path)
    except DatasetError as exc:
        assert '\n' not in str(exc)
        return
    assert log.source in ('sensor_gyro_fifo', 'sensor_combined')
    assert len(log.imu_t) == len(log.gyro) and np.all(np.diff(log.imu_t) >= 0) or (
        log.source == 'sensor_combined')
    if log.source == 'sensor_gyro_fifo':
        assert np.isfinite(log.imu_t).all() and np.isfinite(log.gyro).all()


def test_sensor_combined_accelerometer_rows_follow_the_accelerometer_selection(tmp_path):
    from flightlogs import SENSOR_COMBINED, Topic
    imus = _imus(n=1000, count=2)
    topics = px4_topics([replace(i, t=i.t[::50], gyro=i.gyro[::50], temp=i.temp[::50],
                                 accel=i.accel[::50]) for i in imus])
    us = np.round(imus[1].t * 1e6).astype(np.uint64)
    topics.append(Topic('sensor_combined', SENSOR_COMBINED, {
        'timestamp': us, 'gyro_rad': imus[1].gyro, 'accelerometer_m_s2': imus[1].accel}))
    selection = [('uint64_t', 'timestamp'), ('uint32_t', 'accel_device_id'),
                 ('uint32_t', 'gyro_device_id')]
    half = len(us) // 2                  # the gyro stays IMU 1's, the accelerometer flips to 0's
    path = write_ulog(tmp_path / 'accel_flip.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': us[[0, half]], 'accel_device_id': [imus[1].device_id + 1,
                                                        imus[0].device_id + 1],
        'gyro_device_id': imus[1].device_id})])
    log = read_ulog(path, instance=1, accel=True)
    assert log.source == 'sensor_combined'
    np.testing.assert_array_equal(log.gyro, imus[1].gyro)
    np.testing.assert_array_equal(log.accel[:half], imus[1].accel[:half])
    assert np.isnan(log.accel[half:]).all()
    # An accelerometer no instance logs is selected: none of its rows is this IMU's.
    path = write_ulog(tmp_path / 'unknown.ulg', topics + [Topic('sensor_selection', selection, {
        'timestamp': us[:1], 'accel_device_id': 7, 'gyro_device_id': imus[1].device_id})])
    assert np.isnan(read_ulog(path, instance=1, accel=True).accel).all()
    # A selection without accel_device_id: the gyro's rows, as before.
    path = write_ulog(tmp_path / 'gyro_only.ulg', topics + [Topic('sensor_selection', [
        ('uint64_t', 'timestamp'), ('uint32_t', 'gyro_device_id')], {
        'timestamp': us[:1], 'gyro_device_id': imus[1].device_id})])
    np.testing.assert_array_equal(read_ulog(path, instance=1, accel=True).accel, imus[1].accel)


def test_the_board_is_the_hardware_name_and_uuid_where_the_log_has_them(tmp_path):
    assert read_ulog(PX4_ACCEL_THERMOMETER).board == ('PX4_FMU_V6C 0006000000003535323734325116'
                                                      '003d0021')
    topics = px4_topics(_imus(count=1))
    info = {'sys_name': 'PX4', 'ver_hw': 'PX4_FMU_V5', 'sys_uuid': '000100020003'}
    named = write_ulog(tmp_path / 'named.ulg', topics, info=info)
    assert load_run(named).info['board'] == 'PX4_FMU_V5 000100020003'
    assert read_ulog(write_ulog(tmp_path / 'bare.ulg', topics)).board == ''
