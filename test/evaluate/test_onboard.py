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

"""The flight controller's own correction as a model: its formula, or one line why not."""

from __future__ import annotations

from gyro_tdc.data.runs import Run
from gyro_tdc.errors import DatasetError
from gyro_tdc.evaluate.onboard import onboard_model
from gyro_tdc.model import compensate
from gyro_tdc.model.fc_tempcal import ardupilot_correction, px4_correction
import numpy as np
import pytest

PX4 = {'TC_G_ENABLE': 0, 'TC_G0_ID': 555, 'TC_G0_TREF': 30.0, 'TC_G0_TMIN': 10.0,
       'TC_G0_TMAX': 60.0, 'TC_G0_X0_1': 1e-4, 'TC_G0_X1_0': 2e-3, 'TC_G0_X2_0': 1e-5}
ARDU = {'INS_TCAL1_ENABLE': 0, 'INS_TCAL1_TMIN': 10.0, 'INS_TCAL1_TMAX': 60.0,
        'INS_TCAL1_GYR1_X': 2000.0, 'INS_TCAL1_GYR2_X': 10.0, 'INS_GYR1_CALTEMP': 25.0}


def _log(firmware: str, params: dict, **info) -> Run:
    """Return a flat run from a log of ``firmware`` with ``params``, 0 to 70 degC."""
    t = np.arange(200.0)
    return Run(t, np.linspace(0.0, 70.0, 200), np.zeros((200, 3)), np.zeros((200, 3)),
               f'log.{firmware}', {'firmware': firmware, 'params': params, **info})


@pytest.mark.parametrize('spec, run, correction', [
    ('px4-onboard', _log('px4', PX4, device_id=555), px4_correction),
    ('ardupilot-onboard', _log('ardupilot', ARDU), ardupilot_correction),
])
def test_the_model_is_the_firmware_formula_clamped_to_its_range(spec, run, correction):
    model, line = onboard_model(spec, run)
    assert line.startswith(f"{spec}: the flight controller's correction from ")
    assert 'clamped to 10 .. 60 degC' in line and 'not applied' in line
    got = run.omega - compensate(model, run.t, run.temp, run.omega, out_of_range='clamp')
    np.testing.assert_allclose(got, correction(run.info['params'], run.temp), atol=1e-12)
    assert model.temp_range_c == (10.0, 60.0)


def test_a_log_that_cannot_give_the_model_is_refused_in_one_line():
    with pytest.raises(DatasetError, match='needs a PX4 ULog'):
        onboard_model('px4-onboard', _log('ardupilot', ARDU))
    with pytest.raises(DatasetError, match='no TC_Gn_ID .* is the device id 7'):
        onboard_model('px4-onboard', _log('px4', PX4, device_id=7))
    with pytest.raises(DatasetError, match='already carries the on-board correction'):
        onboard_model('ardupilot-onboard', _log('ardupilot', ARDU, onboard_compensated=True))
