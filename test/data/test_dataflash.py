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

"""ArduPilot DataFlash in: ``IMU`` with ``T`` per instance, ``GYR``/``ACC``, ``PARM``, guards."""

from __future__ import annotations

import hashlib

from flightlogs import Imu, write_dataflash
from gyro_tdc.data import BagOptions, detect_format
from gyro_tdc.data.dataflash import read_dataflash
from gyro_tdc.data.dataset import describe_read, load_run
from gyro_tdc.data.flightlog import describe_log
from gyro_tdc.errors import DatasetError
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from real_logs import ARDUPILOT_AC33, ARDUPILOT_AC45, ARDUPILOT_CUBEBLACK


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


def test_a_file_without_one_dataflash_record_is_no_log_not_a_log_without_imu(tmp_path):
    # A firmware image, an EEPROM dump: ``.bin`` too (found among real logs in repositories).
    for name, data in (('px4io.bin', bytes(range(256)) * 40), ('eeprom.bin', bytes(4096))):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(DatasetError, match=r'is not a DataFlash log: not one record in '
                                               rf'its {len(data)} bytes\.$'):
            read_dataflash(tmp_path / name)
    log = write_dataflash(tmp_path / 'noimu.bin', [], {'INS_TCAL1_ENABLE': 0.0})
    with pytest.raises(DatasetError, match='has no IMU records'):
        read_dataflash(log)


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
    with pytest.raises(DatasetError, match=r'IMU instance 0 carries no temperature \(no '
                                           r'thermometer reads other than a constant 0 or '
                                           r'NaN; what each instance carries: 0: 300 samples '
                                           r'at 50 Hz, '
                                           r'temperature none; the log has no other '
                                           r'thermometer\)\.$'):
        load_run(path)


def test_an_imu_logged_only_while_armed_is_said_at_its_rate_and_its_mean(tmp_path):
    # ArduCopter 3.2 logs IMU only while armed: the mean rate counts the pauses.
    imu = _imus(count=1)[0]
    t = np.r_[imu.t[:150], imu.t[150:] + 6.0]           # 3 s at 50 Hz, 6 s off, 3 s on
    path = write_dataflash(tmp_path / 'armed.bin', [Imu(t=t, gyro=imu.gyro,
                                                        temp=np.zeros_like(imu.temp))])
    with pytest.raises(DatasetError, match=r'0: 300 samples at 50 Hz \(25 Hz over the log: '
                                           r'it pauses\), temperature none'):
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
                                           r'each instance carries: 0: 3854 samples at '
                                           r'48.2 Hz, '
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


# --------------------------------------------------------------------------------------------
# The gyro at the sensor rate: GYR (and ACC) beside IMU
# --------------------------------------------------------------------------------------------

def _f32(a: np.ndarray) -> np.ndarray:
    """Return ``a`` as the float32 a log holds, in float64."""
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def _slow_and_fast(seconds: float = 20.0, rate: float = 1000.0, count: int = 2,
                   accel: bool = True) -> tuple[list, dict]:
    """Return ``count`` IMUs at 25 Hz and the same IMUs at ``rate`` (GYR, ACC when ``accel``)."""
    rng = np.random.default_rng(7)
    t = 20.0 + np.arange(int(seconds * 25)) / 25.0
    slow = [Imu(t=t, gyro=_f32(rng.normal(0.0, 0.01, (len(t), 3))),
                temp=_f32(np.linspace(30.0 + k, 40.0 + k, len(t))),
                accel=_f32(rng.normal(0.0, 1.0, (len(t), 3)))) for k in range(count)]
    ft = np.round((20.0 + np.arange(int(seconds * rate)) / rate) * 1e6) * 1e-6
    fast = {k: Imu(t=ft, gyro=_f32(rng.normal(0.0, 0.01, (len(ft), 3))), temp=None,
                   accel=_f32(rng.normal(0.0, 1.0, (len(ft), 3))) if accel else None)
            for k in range(count)}
    return slow, fast


def test_gyr_at_the_sensor_rate_gives_the_gyro_the_imu_thermometer_held_onto_its_stamps(
        tmp_path):
    slow, fast = _slow_and_fast()
    fast[1].accel = None                       # ACC of instance 0 only
    fast[2] = Imu(t=fast[0].t, gyro=fast[0].gyro + 1.0, temp=None)   # a post-filter copy
    path = write_dataflash(tmp_path / 'raw.bin', slow, fast=fast, bursts=3)
    for k in range(2):
        log = read_dataflash(path, instance=k, accel=True)
        assert (log.source, log.instance, log.instances, log.temperature) == (
            'GYR', k, (0, 1), 'IMU.T')
        np.testing.assert_allclose(log.imu_t, fast[k].t, atol=1e-9)   # SampleUS, not TimeUS
        np.testing.assert_array_equal(log.gyro, fast[k].gyro)         # never instance 2's
        np.testing.assert_allclose(log.temp_t, slow[k].t, atol=1e-9)  # on the IMU's stamps
        np.testing.assert_array_equal(log.temp_c, slow[k].temp)
        src = 'ACC' if k == 0 else 'IMU'
        assert log.notes == [f'gyro from GYR at 1000 Hz beside IMU at 25 Hz, accelerometer '
                             f'from {src}']                # and no word of ISBD: not needed
        if k == 0:                             # ACC: on the same stamps
            np.testing.assert_array_equal(log.accel, fast[0].accel)
        else:                                  # IMU's, interpolated (NaN after its last)
            inside = log.imu_t <= slow[1].t[-1]
            np.testing.assert_allclose(log.accel[inside], np.column_stack(
                [np.interp(log.imu_t[inside], slow[1].t, slow[1].accel[:, j])
                 for j in range(3)]), atol=1e-12)
            assert np.isnan(log.accel[~inside]).all() and (~inside).sum() == 39
        assert read_dataflash(path, instance=k).accel is None
    run = load_run(path, BagOptions(imu_instance=1))
    assert len(run) == 20000 - 39          # GYR after the last IMU reading: no temperature
    np.testing.assert_allclose(run.temp, np.interp(run.t, slow[1].t, slow[1].temp), atol=1e-9)
    line = describe_read(path, run, '/r')
    assert ('ArduPilot DataFlash, GYR instance 1 of 2: calibrated on board (no thermal '
            'compensation active)') in line
    assert 'gyro from GYR at 1000 Hz beside IMU at 25 Hz; temperature from IMU.T' in line
    proxy = read_dataflash(path, temperature_source='IMU.T', instance=1)
    assert proxy.source == 'GYR' and proxy.proxy and proxy.temperature == 'IMU.T instance 1'


def test_gyr_is_compensated_on_board_like_imu_and_refused_so(tmp_path):
    slow, fast = _slow_and_fast(count=1)
    path = write_dataflash(tmp_path / 'tcal.bin', slow, {'INS_TCAL1_ENABLE': 1}, fast=fast)
    with pytest.raises(DatasetError, match=r'the GYR data were already thermally compensated '
                                           r'on board \(INS_TCAL1_ENABLE=1'):
        load_run(path)


def test_arducopter_3_gyr1_records_without_an_instance_field(tmp_path):
    slow, fast = _slow_and_fast(count=2)
    old = ('GYR1', 'QQfff', 'TimeUS,SampleUS,GyrX,GyrY,GyrZ')
    path = write_dataflash(tmp_path / 'gyr1.bin', slow, fast={0: fast[0]}, gyr_format=old)
    log = read_dataflash(path)
    assert log.source == 'GYR' and len(log.imu_t) == len(fast[0].t)
    np.testing.assert_array_equal(log.gyro, fast[0].gyro)
    other = read_dataflash(path, instance=1)
    assert other.source == 'IMU' and other.notes == ['GYR not used: it has no instance 1']


def test_logs_without_a_gyr_stream_read_as_before_and_isbd_bursts_are_said(tmp_path):
    slow, fast = _slow_and_fast(count=2)
    plain = read_dataflash(write_dataflash(tmp_path / 'plain.bin', slow), accel=True)
    cases = {'slow': ({0: Imu(t=slow[0].t, gyro=slow[0].gyro, temp=None)}, 0,
                      ['GYR not used: 500 samples at 25 Hz, not twice as fast as IMU']),
             'other': ({1: fast[1]}, 0, ['GYR not used: it has no instance 0']),
             'isbd': (None, 4, ['ISBD batch samples not read (bursts, not a stream)'])}
    for name, (gyr, bursts, notes) in cases.items():
        log = read_dataflash(write_dataflash(tmp_path / f'{name}.bin', slow, fast=gyr,
                                             bursts=bursts), accel=True)
        assert (log.source, log.notes, log.temp_t) == ('IMU', notes, None), name
        for got, want in ((log.imu_t, plain.imu_t), (log.gyro, plain.gyro),
                          (log.temp_c, plain.temp_c), (log.accel, plain.accel)):
            np.testing.assert_array_equal(got, want)


def _cut(t: np.ndarray, *spans: tuple) -> np.ndarray:
    """Return which stamps ``t`` lie outside every (start, end) span (s after the first)."""
    keep = np.ones(len(t), dtype=bool)
    for a, b in spans:
        keep &= ~((t >= t[0] + a) & (t < t[0] + b))
    return keep


def test_gyr_with_gaps_of_its_own_or_ending_early_is_not_read(tmp_path):
    slow, fast = _slow_and_fast(count=1)
    f = fast[0]
    for name, keep, words in (
            ('gap', _cut(f.t, (8.0, 11.0)), '850 Hz not used: none within 1 s of 25 of 500'),
            ('early', _cut(f.t, (15.0, 99.0)), '1000 Hz not used: none within 1 s of 100 of 500')):
        gyr = {0: Imu(t=f.t[keep], gyro=f.gyro[keep], temp=None)}
        log = read_dataflash(write_dataflash(tmp_path / f'{name}.bin', slow, fast=gyr))
        assert log.source == 'IMU' and log.notes == [
            f'GYR at {words} IMU samples (gaps, or it ends early)'], name
    # A gap the log's own IMU shares (disarmed, LOG_DISARMED 0): the stream stands.
    imu = slow[0]
    both = _cut(imu.t, (8.0, 11.0))
    shared = write_dataflash(tmp_path / 'shared.bin', [Imu(t=imu.t[both], gyro=imu.gyro[both],
                                                           temp=imu.temp[both])],
                             fast={0: Imu(t=f.t[_cut(f.t, (8.0, 11.0))],
                                          gyro=f.gyro[_cut(f.t, (8.0, 11.0))], temp=None)})
    log = read_dataflash(shared)
    assert log.source == 'GYR' and len(log.imu_t) == 17000


def test_damaged_gyr_records_are_read_or_refused_in_one_line_never_a_traceback(tmp_path):
    slow, fast = _slow_and_fast(count=1, accel=False)
    g, t = fast[0].gyro.copy(), fast[0].t.copy()
    g[100:110] = np.nan
    g[200, 1] = np.inf
    t[300:305] = t[299]                        # duplicated SampleUS
    t[400], t[401] = t[401], t[400]            # one step backward
    path = write_dataflash(tmp_path / 'bad.bin', slow, fast={0: Imu(t=t, gyro=g, temp=None)})
    log = read_dataflash(path)
    assert log.source == 'GYR' and len(log.imu_t) == 20000
    run = load_run(path)
    rej = run.info['rejected']
    assert (rej['imu_nonfinite'], rej['duplicate_stamps'], rej['out_of_order']) == (11, 5, 1)
    assert np.all(np.diff(run.t) > 0) and np.isfinite(run.omega).all()
    # Every GYR sample non-finite: no stream, IMU's gyro.
    g[:] = np.nan
    nan = write_dataflash(tmp_path / 'nan.bin', slow, fast={0: Imu(t=t, gyro=g, temp=None)})
    assert read_dataflash(nan).notes == [
        'GYR not used: 0 samples at 0 Hz, not twice as fast as IMU']
    # A GYR whose FMT record's length is not its format's: IMU's gyro, and why.
    wide = ('GYR', 'QBQffff', 'TimeUS,I,SampleUS,GyrX,GyrY,GyrZ,GyrW')
    data = bytearray(write_dataflash(tmp_path / 'w.bin', slow, fast=fast,
                                     gyr_format=wide).read_bytes())
    at = data.index(b'QBQffff')
    data[at:at + 7] = b'QBQfff\0'
    at = data.index(wide[2].encode())
    data[at:at + len(wide[2])] = wide[2][:-5].encode().ljust(len(wide[2]), b'\0')
    (tmp_path / 'fmt.bin').write_bytes(bytes(data))
    log = read_dataflash(tmp_path / 'fmt.bin')
    assert log.source == 'IMU' and log.notes[-1] == (
        "GYR not used: its records cannot be decoded (GYR: format 'QBQfff' is 29 bytes, the "
        'FMT record says 33.)')
    # A log cut off inside its last GYR record (32 bytes): a warning counting the loss.
    data = write_dataflash(tmp_path / 'whole.bin', slow, fast=fast).read_bytes()
    cut = tmp_path / 'cut.bin'
    cut.write_bytes(data[:-10])
    assert read_dataflash(cut).truncated_bytes == 32 - 10
    run = load_run(cut)
    assert run.info['source'] == 'GYR'
    assert any('the last 22 bytes' in w for w in run.info['warnings'])


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(rate=st.floats(10.0, 800.0), gap=st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 6.0)),
       cut=st.integers(0, 40), seed=st.integers(0, 1000))
def test_a_gyr_stream_is_read_exactly_when_fast_and_whole_else_imu_unchanged(
        tmp_path, rate, gap, cut, seed):
    slow, fast = _slow_and_fast(seconds=12.0, rate=rate, count=1, accel=seed % 2 == 0)
    f = fast[0]
    keep = _cut(f.t, (gap[0], gap[0] + gap[1]))
    path = write_dataflash(tmp_path / f'h{seed}.bin', slow,
                           fast={0: Imu(t=f.t[keep], gyro=f.gyro[keep], temp=None,
                                        accel=None if f.accel is None else f.accel[keep])})
    if cut:
        path.write_bytes(path.read_bytes()[:-cut])
    try:
        log = read_dataflash(path, accel=True)
    except DatasetError:
        return                                  # one line: the cut took the IMU's last
    # A gap under 0.9 s anywhere, or under 1.5 s inside, leaves every IMU sample within 1 s.
    whole = rate >= 2.5 * 25.0 and (gap[1] < 0.9 or (gap[1] < 1.5 and 0.5 < gap[0]
                                                     and gap[0] + gap[1] < 11.0))
    broken = rate < 1.5 * 25.0 or (gap[1] > 2.5 and gap[0] + gap[1] < 10.0)
    assert log.source == ('GYR' if whole else 'IMU' if broken else log.source)
    if log.source == 'GYR':
        assert log.notes[0].startswith('gyro from GYR at ')
        m = len(log.imu_t)
        np.testing.assert_array_equal(log.gyro, f.gyro[keep][:m])
        assert log.accel.shape == (m, 3) and len(log.temp_t) <= len(slow[0].t)
    else:
        assert log.notes[0].startswith('GYR') and log.temp_t is None
        np.testing.assert_array_equal(log.gyro, slow[0].gyro[:len(log.imu_t)])


def _digest(path, instance: int, source: str) -> str:
    """Return a digest of what the reader gives for one IMU and thermometer ('refused')."""
    try:
        log = read_dataflash(path, instance=instance, accel=True, temperature_source=source)
    except DatasetError:
        return 'refused'
    h = hashlib.sha256(describe_log(log).encode())
    for a in (log.imu_t, log.gyro, log.temp_c, log.accel, log.temp_t):
        h.update(b'' if a is None else np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()[:12]


def test_the_real_logs_without_gyr_read_byte_for_byte_as_before_gyr_was_read():
    # Digests of the line and arrays each committed ArduPilot log gave before GYR was read.
    before = {ARDUPILOT_AC33: ['865910e482dd', '1e0b53f03326', '3990f5d7b389',
                               '3cd12a1acfff', 'e8f7bad393b7', '60b7fdee8167'],
              ARDUPILOT_AC45: ['c484510dc4e2', 'c2bbc430c437', 'df95205d016b',
                               'fe0c328cc050', 'f400350a829c', '9e361e1e3bc7'],
              ARDUPILOT_CUBEBLACK: ['788b0d98f3b0', '4517882dd572', 'refused',
                                    '5e7c00810314', '1dbdd12e4006', '5d013cf1f875']}
    for path, want in before.items():
        assert [_digest(path, k, s) for k in range(3) for s in ('imu', 'baro')] == want


def test_damaged_bytes_read_as_records_make_no_instance_and_no_warning(tmp_path):
    """
    Leave out a lone IMU record beside a stream, and read a signalling NaN without a warning.

    As a log with 6,705 damaged headers did (Krutharth23/Biomimicry): instances 45 and 48
    of one record each beside two IMUs were listed and counted ("instance 0 of 4"), and a
    thermometer reading whose bytes were a signalling NaN printed numpy's ``RuntimeWarning:
    invalid value encountered in cast`` on the console.
    """
    import dataclasses
    import struct
    import warnings
    imus = _imus(count=2)
    temp = imus[0].temp.copy()
    temp[100] = 37.123457
    lone = Imu(t=imus[1].t[:1], gyro=imus[1].gyro[:1], temp=imus[1].temp[:1],
               accel=imus[1].accel[:1])
    path = write_dataflash(tmp_path / 'd.bin', [dataclasses.replace(imus[0], temp=temp), lone])
    raw, mark = path.read_bytes(), struct.pack('<f', 37.123457)
    assert raw.count(mark) == 1
    path.write_bytes(raw.replace(mark, struct.pack('<I', 0x7F800001)))   # a signalling NaN
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        log = read_dataflash(path)
    assert log.instances == (0,) and 'IMU instance 1 left out' in '; '.join(log.notes)
    assert np.isnan(log.temp_c[100]) and np.isfinite(np.delete(log.temp_c, 100)).all()
    assert 'instance 0 of 1' in describe_log(log)


def test_the_board_is_its_boot_line_real_and_written(tmp_path):
    """The board is ArduPilot's MSG at boot naming it and its unique id; '' where none does."""
    for path, board in ((ARDUPILOT_AC33, 'PX4v2 004A002F 33345119 32383433'),
                        (ARDUPILOT_AC45, 'CubeOrangePlus 00260020 31325110 32313638'),
                        (ARDUPILOT_CUBEBLACK, 'CubeBlack 004F0021 33375118 37333835')):
        assert read_dataflash(path).board == board
    named = write_dataflash(tmp_path / 'named.bin', _imus()[:1], board='Pixhawk6C 00490034 '
                            '30315109 34373938')
    assert load_run(named).info['board'] == 'Pixhawk6C 00490034 30315109 34373938'
    said = write_dataflash(tmp_path / 'said.bin', _imus()[:1], board='Frame: QUAD/X')
    assert read_dataflash(said).board == ''                  # a MSG, but no board line
    assert read_dataflash(write_dataflash(tmp_path / 'none.bin', _imus()[:1])).board == ''
