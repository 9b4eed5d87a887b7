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
``evaluate --model px4-onboard|ardupilot-onboard``: the flight controller's own correction.

The log's ``TC_G*`` / ``INS_TCALn_*`` parameters become an exact cubic
:class:`~gyro_tdc.model.compensation.CompensationModel` (features ``dT, dT2, dT3`` about
``TREF`` or 35 degC, range ``[TMIN, TMAX]``), evaluated with the firmware's clamp whatever
``--out-of-range`` says.
"""

from __future__ import annotations

from gyro_tdc.data import Run
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import (ARDUPILOT_SCALE, ARDUPILOT_TREF_C, ArduPilotTempCal,
                            CompensationModel, onboard_status, px4_slot, Px4TempCal)
import numpy as np

__all__ = ['ARDUPILOT_ONBOARD', 'ONBOARD', 'onboard_model', 'PX4_ONBOARD']

PX4_ONBOARD = 'px4-onboard'
ARDUPILOT_ONBOARD = 'ardupilot-onboard'
#: The model specs of the flight controllers' own corrections, and the firmware of each.
ONBOARD = {PX4_ONBOARD: 'px4', ARDUPILOT_ONBOARD: 'ardupilot'}
#: Residual variance given to the cubic (only the automatic re-anchoring's tolerance reads it).
_RESIDUAL_VAR = 1e-8


def _cubic(t0: float, intercept, linear, lo: float, hi: float, created: dict) -> CompensationModel:
    """Return ``intercept + linear . (d, d^2, d^3)``, ``d = T - t0``, valid on ``[lo, hi]``."""
    coef = np.vstack([np.reshape(intercept, (1, 3)), np.reshape(linear, (3, 3))])
    return CompensationModel.polynomial(('dT', 'dT2', 'dT3'), t0, coef, temp_range_c=(lo, hi),
                                        residual_var=np.full(3, _RESIDUAL_VAR), created=created)


def onboard_model(spec: str, run: Run) -> tuple[CompensationModel, str]:
    """
    Return the flight controller's correction of a log as a model, and a line saying what it is.

    Parameters
    ----------
    spec : str
        ``px4-onboard`` or ``ardupilot-onboard``.
    run : Run
        A run read from a log of that firmware (``info['params']`` holds its parameters).

    Returns
    -------
    (CompensationModel, str)
        A ``poly`` cubic equal to the firmware's formula inside ``[TMIN, TMAX]`` (evaluate it
        with the ``clamp`` policy), and a line naming the parameters it was built from.

    Raises
    ------
    DatasetError
        The run is no log of that firmware, its data already carry the correction, or (PX4)
        no ``TC_Gn_ID`` matches the sensor's device id.

    """
    firmware = ONBOARD[spec]
    if run.info.get('firmware') != firmware:
        kind = {'px4': 'a PX4 ULog', 'ardupilot': 'an ArduPilot DataFlash log'}[firmware]
        raise DatasetError(f'--model {spec} needs {kind} (its parameters), got {run.name!r}.')
    if run.info.get('onboard_compensated'):
        raise DatasetError(f'--model {spec}: {run.name!r} already carries the on-board '
                           'correction; evaluate it on data logged without it.')
    params = run.info.get('params', {})
    active, words = onboard_status(params, firmware, instance=int(run.info.get('instance', 0)))
    created = {'bags': [run.name], 'onboard': firmware}
    if firmware == 'px4':
        device = int(run.info.get('device_id', 0))
        slot = px4_slot(params, device)
        if slot is None:
            raise DatasetError(f'--model {spec}: no TC_Gn_ID of {run.name!r} is the device id '
                               f'{device} of the gyro read.')
        cal = Px4TempCal.from_params(params, 'gyro', slot)
        model = _cubic(cal.tref, cal.x[0], cal.x[1:], cal.tmin, cal.tmax, created)
        what = (f'TC_G{slot}_* (device id {device}): cubic about TREF = {cal.tref:g} degC, '
                f'clamped to {cal.tmin:g} .. {cal.tmax:g} degC')
    else:
        inst = int(run.info.get('instance', 0))
        cal = ArduPilotTempCal.from_params(params, 'gyro', inst)
        model = _cubic(ARDUPILOT_TREF_C, -cal.poly([cal.caltemp])[0],
                       cal.coeff / ARDUPILOT_SCALE, cal.tmin, cal.tmax, created)
        what = (f'INS_TCAL{inst + 1}_GYR*: cubic about {ARDUPILOT_TREF_C:g} degC, zero at '
                f'CALTEMP = {cal.caltemp:g} degC, clamped to {cal.tmin:g} .. {cal.tmax:g} degC')
    return model, (f"{spec}: the flight controller's correction from {what}; {words}"
                   + ('' if active else ' (in this log it was not applied)'))
