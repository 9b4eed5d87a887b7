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

"""Real flight-controller logs no one on the project wrote (test/support/files/flightlogs)."""

from __future__ import annotations

from flightlogs import Imu, write_dataflash
from gyro_tdc.data import BagOptions
from gyro_tdc.data.dataflash import read_dataflash
from gyro_tdc.data.dataset import describe_read, load_run
from gyro_tdc.data.flightlog import rate_words
from gyro_tdc.data.ulog import read_ulog
from gyro_tdc.errors import DatasetError
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from real_logs import (ARDUPILOT_CUBEBLACK, PX4_BARO_ONLY, PX4_MULTI_RATE,
                       PX4_ZERO_THERMOMETERS)


def _rate_hz(t):
    """Return the median sample rate of stamps, Hz."""
    return 1.0 / float(np.median(np.diff(t)))


def test_px4_sensor_gyro_at_1_hz_beside_sensor_combined_gives_the_200_hz_gyro():
    log = read_ulog(PX4_MULTI_RATE)
    assert log.source == 'sensor_combined' and not log.raw
    assert _rate_hz(log.imu_t) == pytest.approx(200.0, rel=0.05)
    assert _rate_hz(log.temp_t) == pytest.approx(1.0, rel=0.05)
    assert log.temperature == 'sensor_gyro.temperature' and not log.proxy
    assert 40.0 < np.nanmin(log.temp_c) and np.nanmax(log.temp_c) < 40.5
    assert log.instances == (0, 1, 2)
    run = load_run(PX4_MULTI_RATE)
    assert len(run) > 1000         # not the six 1 Hz samples of sensor_gyro
    assert _rate_hz(run.t) == pytest.approx(200.0, rel=0.05)
    line = describe_read(PX4_MULTI_RATE, run, '/r')
    assert 'sensor_gyro at 1 Hz beside sensor_combined' in line
    assert 'temperature from sensor_gyro.temperature' in line
    # Instances 1 and 2 have no sensor_combined: vehicle_imu at 2 Hz, the fastest they have,
    # both alike (sensor_gyro at the logger's 1 Hz is no full-rate gyro beside it).
    other = read_ulog(PX4_MULTI_RATE, instance=1)
    assert other.source == 'vehicle_imu' and _rate_hz(other.imu_t) == pytest.approx(2.0, 0.05)
    assert 28.0 < np.nanmin(other.temp_c) < 29.0        # that IMU's own thermometer
    assert read_ulog(PX4_MULTI_RATE, instance=2).source == 'vehicle_imu'


def test_px4_barometer_as_a_proxy_where_it_is_the_only_thermometer():
    with pytest.raises(DatasetError, match=r'sensor_combined instance 0 carries no '
                                           r'temperature.*baro_temp_celcius.*'
                                           '--temperature-source baro'):
        load_run(PX4_BARO_ONLY)
    run = load_run(PX4_BARO_ONLY, BagOptions(temperature_source='baro'))
    assert run.info['temperature'] == 'sensor_combined.baro_temp_celcius'
    assert run.info['temperature_proxy']
    assert 40.0 < run.temp.min() < run.temp.max() < 42.0
    assert "(a proxy of the IMU's)" in run.info['log']
    named = load_run(PX4_MULTI_RATE, BagOptions(temperature_source='sensor_baro.temperature'))
    assert named.info['temperature'] == 'sensor_baro.temperature'
    with pytest.raises(DatasetError, match='no usable thermometer for --temperature-source '
                                           'sensor_baro.nothing'):
        load_run(PX4_MULTI_RATE, BagOptions(temperature_source='sensor_baro.nothing'))


def test_px4_thermometers_that_read_a_constant_zero_are_no_thermometers():
    with pytest.raises(DatasetError) as err:
        load_run(PX4_ZERO_THERMOMETERS)
    text = str(err.value)
    assert 'carries no temperature' in text and 'constant 0' in text
    # One line names every instance and what it carries; no barometer to propose.
    assert '0: sensor_gyro 1 Hz, sensor_combined 188 Hz' in text
    assert '2: sensor_gyro 1 Hz, vehicle_imu 2 Hz, temperature: none' in text
    assert '--temperature-source baro' not in text and '\n' not in text
    # No other IMU has a thermometer either: --imu-instance would not help.
    assert '--imu-instance' not in text and 'the log has no other thermometer' in text
    with pytest.raises(DatasetError, match='no usable thermometer'):
        load_run(PX4_ZERO_THERMOMETERS, BagOptions(temperature_source='baro'))


def test_ardupilot_cubeblack_three_imus_at_25_hz_and_the_barometer():
    for k in (0, 2):
        log = read_dataflash(ARDUPILOT_CUBEBLACK, instance=k)
        assert log.instances == (0, 1, 2) and log.temperature == 'IMU.T'
        assert _rate_hz(log.imu_t) == pytest.approx(25.0, rel=0.05)
        assert 35.0 < log.temp_c.min() < log.temp_c.max() < 60.0
    # IMU2 of this board logs T as a constant 0: no thermometer; the line says what each has.
    with pytest.raises(DatasetError, match=r'IMU instance 1 carries no temperature \(no '
                                           r'thermometer reads other than a constant 0 or '
                                           r'NaN; what each instance carries: 0: 2055 samples at '
                                           r'24.5 Hz, temperature IMU.T; 1: 2055 samples at '
                                           r'24.5 Hz, temperature none; 2: .*BARO instance '
                                           r'0, 1; --imu-instance N, or --temperature-source '
                                           r'baro\)'):
        load_run(ARDUPILOT_CUBEBLACK, BagOptions(imu_instance=1))
    run = load_run(ARDUPILOT_CUBEBLACK, BagOptions(imu_instance=1, temperature_source='baro'))
    assert run.info['temperature'] == 'BARO.Temp instance 1' and run.info['temperature_proxy']
    with pytest.raises(DatasetError, match=r'IMU has no instance 3 \(it has 0, 1, 2; what '
                                           r'each instance carries: 0: 2055 samples at '
                                           r'24.5 Hz, '
                                           r'temperature IMU.T'):
        load_run(ARDUPILOT_CUBEBLACK, BagOptions(imu_instance=3))


def test_a_real_log_cut_off_inside_a_record_is_read_with_a_warning(tmp_path):
    whole = ARDUPILOT_CUBEBLACK.read_bytes()
    cut = tmp_path / 'cut.bin'
    cut.write_bytes(whole[:len(whole) * 2 // 3 + 7])
    run = load_run(cut)
    assert 0 < len(run) < len(load_run(ARDUPILOT_CUBEBLACK))
    assert any('ends inside a message' in w for w in run.info['warnings'])


def test_arducopter_3_4_names_the_imu_temperature_temp(tmp_path):
    n = 200
    imu = Imu(t=10.0 + 0.04 * np.arange(n), gyro=np.zeros((n, 3)),
              temp=np.linspace(30.0, 33.0, n))
    path = write_dataflash(tmp_path / 'ac34.bin', [imu, imu], temp_field='Temp')
    log = read_dataflash(path)
    assert log.temperature == 'IMU.Temp'
    np.testing.assert_allclose(log.temp_c, imu.temp, rtol=1e-6)
    cold = write_dataflash(tmp_path / 'cold.bin', [imu, imu], temperature=False)
    with pytest.raises(DatasetError, match=r'IMU instance 1 carries no temperature \(no '
                                           r'thermometer reads other than a constant 0 or '
                                           r'NaN; what each instance carries: 0: 200 samples '
                                           r'at 25 Hz, '
                                           r'temperature none; 1:'):
        load_run(cold, BagOptions(imu_instance=1))


def test_a_thermometer_is_none_when_missing_nan_zero_or_implausible_and_keeps_real_gaps():
    from gyro_tdc.data.flightlog import PLAUSIBLE_C, thermometer
    assert thermometer(None) is None
    assert thermometer([np.nan, np.nan]) is None
    assert thermometer([0.0, 0.0, np.nan]) is None
    assert thermometer([-1000.0] * 5) is None              # PX4's "no thermometer" filler
    np.testing.assert_array_equal(thermometer([25.0, np.nan, 1e4, 26.0, -1000.0]),
                                  [25.0, np.nan, np.nan, 26.0, np.nan])
    np.testing.assert_array_equal(thermometer(list(PLAUSIBLE_C)), PLAUSIBLE_C)


def test_one_stamp_a_damaged_byte_threw_away_does_not_change_a_topics_rate():
    from gyro_tdc.data.flightlog import rate_hz
    t = 20.0 + np.arange(1200) * 0.005                   # 200 Hz
    assert rate_hz(t) == pytest.approx(200.0)
    bad = t.copy()
    bad[600] = 7.2e10                                      # a flipped high byte of its stamp
    assert rate_hz(bad) == pytest.approx(200.0, rel=0.01)  # not 1200 / 7.2e10 s
    gaps = np.concatenate([t[:600], t[600:] + 3.0])        # a logger dropout is no outlier
    assert rate_hz(gaps) == pytest.approx(1199 / (gaps[-1] - gaps[0]))
    assert rate_hz(t[:2]) == pytest.approx(200.0) and rate_hz(t[:1]) == 0.0


def test_stamps_that_go_back_count_the_time_their_runs_cover_once():
    # As px4-ulog-rs' corrupt_format_not_utf8.ulg: a 200 Hz topic whose stamps jump back
    # 244 s and 117 s, leaving gaps between its three runs (the span read as 72 Hz before).
    from gyro_tdc.data.flightlog import rate_hz
    a = 5488.0 + np.arange(7000) * 0.005
    b = a[-1] - 243.8 + np.arange(7000) * 0.005
    c = b[-1] - 117.2 + np.arange(7000) * 0.005
    assert rate_hz(np.concatenate([a, b, c])) == pytest.approx(200.0, rel=1e-3)
    # Messages out of order by a step (pyulog's sample_unordered.ulg) cover their span once.
    t = 20.0 + np.arange(1200) * 0.005
    swapped = t.copy()
    swapped[[300, 301]] = swapped[[301, 300]]
    assert rate_hz(swapped) == pytest.approx(rate_hz(t))
    assert rate_hz(np.r_[t, np.nan]) == pytest.approx(200.0)    # a NaN stamp is no stamp


def test_values_are_put_on_other_stamps_with_nan_outside_their_span():
    from gyro_tdc.data.flightlog import on_stamps
    t_src = np.array([2.0, 0.0, 1.0])                       # out of order: sorted first
    v = np.array([[20.0, 2.0], [0.0, 0.0], [10.0, 1.0]])
    out = on_stamps(np.array([-1.0, 0.5, 1.5, 3.0]), t_src, v)
    np.testing.assert_array_equal(out[1:3], [[5.0, 0.5], [15.0, 1.5]])
    assert np.isnan(out[[0, 3]]).all()
    assert on_stamps(np.arange(3.0), np.array([]), np.empty((0, 3))) is None
    assert on_stamps(np.arange(3.0), t_src, None) is None


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(st.floats(-1e9, 1e9), st.just(float('nan'))), max_size=40))
def test_an_inventory_says_a_rate_of_any_stamps_damage_leaves(stamps):
    """Stamps out of order, repeated, NaN, none or one: a rate in words, never an error."""
    with np.errstate(all='ignore'):
        said = rate_words(np.array(stamps, dtype=np.float64))
    assert said.endswith(('Hz', 'it pauses)')) and 'Hz' in said
