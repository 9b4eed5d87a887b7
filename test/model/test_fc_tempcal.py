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

"""The flight controllers' thermal corrections: PX4 ``TC_*`` and ArduPilot ``INS_TCAL*``."""

from __future__ import annotations

from gyro_tdc.model.fc_tempcal import (ardupilot_caltemp_name, ardupilot_coeff_name,
                                       ardupilot_correction, ArduPilotTempCal,
                                       onboard_status, px4_correction, px4_name, px4_names,
                                       px4_slot, Px4TempCal)
import numpy as np
import pytest


def test_px4_names():
    assert px4_name('gyro') == 'TC_G_ENABLE'
    assert px4_name('accel', 2, 'X3', 1) == 'TC_A2_X3_1'
    names = px4_names('gyro', 1)
    assert names[0] == 'TC_G1_ID' and names[-3:] == ['TC_G1_TREF', 'TC_G1_TMIN', 'TC_G1_TMAX']
    assert len(names) == 1 + 12 + 3 and len(set(names)) == len(names)


def test_px4_offset_is_the_cubic_about_tref_clamped_to_its_range():
    x = np.array([[0.01, -0.02, 0.0], [1e-3, 2e-4, -1e-4], [1e-5, 0.0, 3e-6],
                  [-2e-7, 1e-7, 0.0]])
    cal = Px4TempCal(x, tref=25.0, tmin=5.0, tmax=55.0, device_id=77)
    params = cal.to_params('gyro', 1)
    temps = np.array([-10.0, 5.0, 25.0, 40.0, 55.0, 80.0])
    got = px4_correction(params, temps, slot=1)
    d = np.clip(temps, 5.0, 55.0) - 25.0
    want = np.stack([x[0, i] + x[1, i] * d + x[2, i] * d**2 + x[3, i] * d**3
                     for i in range(3)], axis=1)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    np.testing.assert_array_equal(got[0], got[1])        # held below TMIN
    np.testing.assert_array_equal(got[-1], got[-2])      # and above TMAX
    np.testing.assert_array_equal(got[2], x[0])          # X0 at TREF
    assert px4_slot(params, 77) == 1 and px4_slot(params, 78) is None
    back = Px4TempCal.from_params(params, 'gyro', 1)
    np.testing.assert_array_equal(back.x, x)
    assert (back.tref, back.tmin, back.tmax, back.device_id) == (25.0, 5.0, 55.0, 77)


def test_px4_defaults_where_the_log_lacks_a_parameter():
    cal = Px4TempCal.from_params({'TC_G0_X1_0': 1e-3})
    assert (cal.tref, cal.tmin, cal.tmax) == (25.0, 0.0, 100.0)
    np.testing.assert_allclose(px4_correction({'TC_G0_X1_0': 1e-3}, [35.0])[0], [0.01, 0, 0])


def test_ardupilot_names():
    assert ardupilot_coeff_name(0, 3, 2) == 'INS_TCAL1_GYR3_Z'
    assert ardupilot_coeff_name(2, 1, 0, 'accel') == 'INS_TCAL3_ACC1_X'
    assert ardupilot_caltemp_name(1) == 'INS_GYR2_CALTEMP'
    with pytest.raises(ValueError, match='order'):
        ardupilot_coeff_name(0, 0, 0)


def test_ardupilot_correction_is_zero_at_caltemp_scaled_and_clamped():
    c = np.array([[150.0, -80.0, 20.0], [3.0, 1.5, -2.0], [-0.05, 0.02, 0.01]])
    cal = ArduPilotTempCal(c, tmin=10.0, tmax=60.0, caltemp=28.0)
    params = {**cal.to_params('gyro', 0), ardupilot_caltemp_name(0): 28.0}
    temps = np.array([0.0, 10.0, 28.0, 35.0, 50.0, 60.0, 75.0])
    got = ardupilot_correction(params, temps)

    def p(t):
        d = np.clip(t, 10.0, 60.0) - 35.0
        return np.stack([(c[0, i] * d + c[1, i] * d**2 + c[2, i] * d**3) * 1e-6
                         for i in range(3)], axis=1)

    np.testing.assert_allclose(got, p(temps) - p(np.array([28.0])), rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(got[2], 0.0, atol=1e-18)              # at CALTEMP
    np.testing.assert_array_equal(got[0], got[1])
    np.testing.assert_array_equal(got[-1], got[-2])
    uncal = ardupilot_correction({**params, 'INS_GYR1_CALTEMP': -300.0}, temps)
    np.testing.assert_allclose(uncal, p(temps) - p(np.array([10.0])), atol=1e-18)


def test_onboard_status_reads_the_switches():
    assert onboard_status({'TC_G_ENABLE': 1}, 'px4') == (
        True, 'TC_G_ENABLE=1: on-board thermal compensation active')
    assert onboard_status({}, 'px4')[0] is False
    assert onboard_status({'INS_TCAL2_ENABLE': 1}, 'ardupilot', instance=1)[0]
    assert onboard_status({'INS_TCAL1_ENABLE': 2}, 'ardupilot')[0] is False    # learning
    with pytest.raises(ValueError, match='firmware'):
        onboard_status({}, 'betaflight')
