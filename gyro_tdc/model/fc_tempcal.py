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
Flight controllers' thermal calibration: PX4 ``TC_*`` and ArduPilot ``INS_TCAL*`` parameters.

The one home of their names and of the corrections the firmware applies with them (see
``doc/internals/data.md``). PX4 subtracts ``X0 + X1 d + X2 d^2 + X3 d^3`` with
``d = clip(T, TMIN, TMAX) - TREF``; ArduPilot subtracts ``p(clip(T) - 35) - p(clip(CALTEMP) -
35)`` with ``p(d) = (c1 d + c2 d^2 + c3 d^3) * 1e-6`` and ``clip`` to ``[TMIN, TMAX]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['ARDUPILOT_SCALE', 'ARDUPILOT_TREF_C', 'ArduPilotTempCal', 'Px4TempCal',
           'ardupilot_caltemp_name', 'ardupilot_coeff_name', 'ardupilot_correction',
           'ardupilot_name', 'onboard_status', 'px4_correction', 'px4_name', 'px4_names',
           'px4_slot', 'SENSORS']

#: The sensors both firmwares calibrate: ``'gyro'`` (rad/s) and ``'accel'`` (m/s^2).
SENSORS = ('gyro', 'accel')
#: ArduPilot's fixed reference temperature of the cubic (``TEMP_REFERENCE``), degC.
ARDUPILOT_TREF_C = 35.0
#: ArduPilot stores the coefficients multiplied by this (``SCALE_FACTOR``).
ARDUPILOT_SCALE = 1.0e6
#: PX4's parameter defaults of a slot (used where a log lacks one).
PX4_DEFAULTS = {'TREF': 25.0, 'TMIN': 0.0, 'TMAX': 100.0}
#: ArduPilot's parameter defaults (CALTEMP -300: never calibrated; clipped to TMIN).
ARDUPILOT_DEFAULTS = {'TMIN': 0.0, 'TMAX': 70.0, 'CALTEMP': -300.0}
#: PX4 has calibration slots 0..3 (``TC_G0`` .. ``TC_G3``).
PX4_SLOTS = 4

_PX4_LETTER = {'gyro': 'G', 'accel': 'A'}
_AP_WORD = {'gyro': 'GYR', 'accel': 'ACC'}


def _sensor(sensor: str) -> str:
    """Return ``sensor`` checked against :data:`SENSORS`."""
    if sensor not in SENSORS:
        raise ValueError(f'Expected `sensor` to be one of {SENSORS}, got {sensor!r}.')
    return sensor


def _shaped(cal: object, name: str, shape: tuple[int, int]) -> None:
    """Store ``cal.<name>`` as a float array, checked to have ``shape``."""
    a = np.asarray(getattr(cal, name), dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f'Expected `{name}` to have shape {shape}, got {a.shape}.')
    object.__setattr__(cal, name, a)


def _temps(temp_c: ArrayLike) -> NDArray[np.float64]:
    """Return ``temp_c`` as a 1-D float64 array."""
    t = np.asarray(temp_c, dtype=np.float64)
    if t.ndim != 1:
        raise ValueError(f'Expected `temp_c` to have shape (N,), got {t.shape}.')
    return t


# --------------------------------------------------------------------------------------------
# PX4
# --------------------------------------------------------------------------------------------

def px4_name(sensor: str, slot: int | None = None, field: str = 'ENABLE',
             axis: int | None = None) -> str:
    """
    Return a PX4 thermal-calibration parameter name (``TC_G_ENABLE``, ``TC_A1_X3_2``...).

    ``sensor`` is ``'gyro'`` (``TC_G``) or ``'accel'`` (``TC_A``), ``slot`` 0..3 (None for
    ``ENABLE``), ``field`` ``ENABLE``, ``ID``, ``TREF``, ``TMIN``, ``TMAX`` or ``X0`` ..
    ``X3``, ``axis`` 0..2 for the ``X`` coefficients.
    """
    letter = _PX4_LETTER[_sensor(sensor)]
    if slot is None:
        return f'TC_{letter}_{field}'
    return f'TC_{letter}{int(slot)}_{field}' + ('' if axis is None else f'_{int(axis)}')


def px4_names(sensor: str, slot: int) -> list[str]:
    """Return every parameter name of one PX4 slot: ID, X3..X0 per axis, TREF, TMIN, TMAX."""
    return ([px4_name(sensor, slot, 'ID')]
            + [px4_name(sensor, slot, f'X{k}', i) for k in (3, 2, 1, 0) for i in range(3)]
            + [px4_name(sensor, slot, f) for f in ('TREF', 'TMIN', 'TMAX')])


def px4_slot(params: Mapping[str, float], device_id: int, sensor: str = 'gyro') -> int | None:
    """
    Return the PX4 calibration slot whose ``TC_Gn_ID`` (``TC_An_ID``) is ``device_id``, or None.

    ``device_id`` is that of the ``sensor_gyro`` / ``sensor_accel`` instance; the slot is the
    one the firmware maps that device to.
    """
    return next((slot for slot in range(PX4_SLOTS)
                 if int(params.get(px4_name(sensor, slot, 'ID')) or 0) == int(device_id) != 0),
                None)


@dataclass(frozen=True)
class Px4TempCal:
    """
    One PX4 calibration slot (``TC_Gn_*`` or ``TC_An_*``).

    Parameters
    ----------
    x : NDArray[np.float64], shape (4, 3)
        Rows X0, X1, X2, X3 (per axis x, y, z), in the sensor's unit per degC^k.
    tref, tmin, tmax : float, degC
        Reference temperature and the clamp range.
    device_id : int
        ``TC_Gn_ID``.

    """

    x: NDArray[np.float64]
    tref: float = PX4_DEFAULTS['TREF']
    tmin: float = PX4_DEFAULTS['TMIN']
    tmax: float = PX4_DEFAULTS['TMAX']
    device_id: int = 0

    def __post_init__(self) -> None:
        """Check the coefficient shape."""
        _shaped(self, 'x', (4, 3))

    @classmethod
    def from_params(cls, params: Mapping[str, float], sensor: str = 'gyro',
                    slot: int = 0) -> 'Px4TempCal':
        """Read slot ``slot`` from ``params`` (missing ones take PX4's defaults)."""
        x = np.array([[float(params.get(px4_name(sensor, slot, f'X{k}', i), 0.0))
                       for i in range(3)] for k in range(4)])
        return cls(x, *(float(params.get(px4_name(sensor, slot, f), v))      # TREF, TMIN, TMAX
                        for f, v in PX4_DEFAULTS.items()),
                   int(params.get(px4_name(sensor, slot, 'ID'), 0) or 0))

    def to_params(self, sensor: str = 'gyro', slot: int = 0) -> dict[str, float]:
        """Return this slot as ``{name: value}`` (the order of :func:`px4_names`)."""
        values = ([int(self.device_id)] + [float(v) for v in self.x[::-1].ravel()]
                  + [float(self.tref), float(self.tmin), float(self.tmax)])
        return dict(zip(px4_names(sensor, slot), values))

    def offset(self, temp_c: ArrayLike) -> NDArray[np.float64]:
        """Return the offset PX4 subtracts at ``temp_c``, shape (N, 3) (the clamp applied)."""
        d = np.clip(_temps(temp_c), self.tmin, self.tmax) - self.tref
        x = self.x
        return x[0] + d[:, None] * (x[1] + d[:, None] * (x[2] + d[:, None] * x[3]))


def px4_correction(params: Mapping[str, float] | Px4TempCal, temp_c: ArrayLike, *,
                   sensor: str = 'gyro', slot: int = 0) -> NDArray[np.float64]:
    """
    Return what PX4 subtracts from a raw sample at ``temp_c`` (its thermal offset).

    ``corrected = raw - px4_correction(...)``, as ``calibration::Gyroscope::Correct`` does
    with ``TemperatureCompensation::calc_thermal_offsets_3D`` (before the static offsets and
    the rotation): ``X0 + X1 d + X2 d^2 + X3 d^3``, ``d = clip(T, TMIN, TMAX) - TREF``, in
    rad/s (gyro) or m/s^2 (accel). ``params`` are the parameters (``TC_Gn_*`` of ``slot``)
    or one slot read; ``TC_G_ENABLE`` is not looked at (see :func:`onboard_status`).
    """
    return (params if isinstance(params, Px4TempCal) else Px4TempCal.from_params(
        params, sensor, slot)).offset(temp_c)


# --------------------------------------------------------------------------------------------
# ArduPilot
# --------------------------------------------------------------------------------------------

def ardupilot_name(instance: int, field: str = 'ENABLE') -> str:
    """Return ``INS_TCAL{instance + 1}_{field}`` (``ENABLE``, ``TMIN``, ``TMAX``); IMU 0-based."""
    return f'INS_TCAL{int(instance) + 1}_{field}'


def ardupilot_coeff_name(instance: int, order: int, axis: int, sensor: str = 'gyro') -> str:
    """Return e.g. ``INS_TCAL1_GYR3_Z``: IMU ``instance`` (0-based), ``order`` 1..3, axis 0..2."""
    if order not in (1, 2, 3):
        raise ValueError(f'Expected `order` to be 1, 2 or 3, got {order!r}.')
    return f'INS_TCAL{int(instance) + 1}_{_AP_WORD[_sensor(sensor)]}{order}_{"XYZ"[axis]}'


def ardupilot_caltemp_name(instance: int, sensor: str = 'gyro') -> str:
    """Return ``INS_GYR{instance + 1}_CALTEMP`` (or ``INS_ACC..``), the offsets' temperature."""
    return f'INS_{_AP_WORD[_sensor(sensor)]}{int(instance) + 1}_CALTEMP'


@dataclass(frozen=True)
class ArduPilotTempCal:
    """
    One ArduPilot IMU's temperature calibration (``INS_TCALn_*`` and the CALTEMP).

    Parameters
    ----------
    coeff : NDArray[np.float64], shape (3, 3)
        Rows of order 1, 2, 3 (per axis x, y, z) as stored: ``ARDUPILOT_SCALE`` times the
        sensor's unit per degC^k.
    tmin, tmax : float, degC
        The clamp range.
    caltemp : float, degC
        ``INS_GYRn_CALTEMP``: the temperature the static offsets were taken at.

    """

    coeff: NDArray[np.float64]
    tmin: float = ARDUPILOT_DEFAULTS['TMIN']
    tmax: float = ARDUPILOT_DEFAULTS['TMAX']
    caltemp: float = ARDUPILOT_DEFAULTS['CALTEMP']

    def __post_init__(self) -> None:
        """Check the coefficient shape."""
        _shaped(self, 'coeff', (3, 3))

    @classmethod
    def from_params(cls, params: Mapping[str, float], sensor: str = 'gyro',
                    instance: int = 0) -> 'ArduPilotTempCal':
        """Read IMU ``instance`` from ``params`` (missing ones take ArduPilot's defaults)."""
        c = np.array([[float(params.get(ardupilot_coeff_name(instance, k, i, sensor), 0.0))
                       for i in range(3)] for k in (1, 2, 3)])
        names = (ardupilot_name(instance, 'TMIN'), ardupilot_name(instance, 'TMAX'),
                 ardupilot_caltemp_name(instance, sensor))      # ARDUPILOT_DEFAULTS' order
        return cls(c, *(float(params.get(name, v))
                        for name, v in zip(names, ARDUPILOT_DEFAULTS.values())))

    def to_params(self, sensor: str = 'gyro', instance: int = 0) -> dict[str, float]:
        """Return TMIN, TMAX and the coefficients as ``{name: value}`` (not ENABLE)."""
        return {ardupilot_name(instance, 'TMIN'): float(self.tmin),
                ardupilot_name(instance, 'TMAX'): float(self.tmax),
                **{ardupilot_coeff_name(instance, k, i, sensor): float(self.coeff[k - 1, i])
                   for k in (1, 2, 3) for i in range(3)}}

    def poly(self, temp_c: ArrayLike) -> NDArray[np.float64]:
        """Return ``p(clip(T) - 35)``, shape (N, 3), in the sensor's unit."""
        d = (np.clip(_temps(temp_c), self.tmin, self.tmax) - ARDUPILOT_TREF_C)[:, None]
        c = self.coeff / ARDUPILOT_SCALE
        return (c[0] + (c[1] + c[2] * d) * d) * d

    def offset(self, temp_c: ArrayLike) -> NDArray[np.float64]:
        """Return what ArduPilot subtracts at ``temp_c``: ``p(T) - p(CALTEMP)``, shape (N, 3)."""
        return self.poly(temp_c) - self.poly([self.caltemp])


def ardupilot_correction(params: Mapping[str, float] | ArduPilotTempCal, temp_c: ArrayLike, *,
                         sensor: str = 'gyro', instance: int = 0) -> NDArray[np.float64]:
    """
    Return what ArduPilot subtracts from a sample at ``temp_c`` (its temperature correction).

    ``corrected = raw - ardupilot_correction(...)`` as ``AP_InertialSensor::TCal::
    correct_sensor`` does, before the static offsets: ``p(clip(T) - 35) - p(clip(CALTEMP) -
    35)``, ``p(d) = (c1 d + c2 d^2 + c3 d^3) 1e-6``, in rad/s (gyro) or m/s^2 (accel).
    ``params`` are ``INS_TCALn_*`` and ``INS_GYRn_CALTEMP``, or one IMU read; ``instance``
    is 0-based (``INS_TCAL1`` is IMU 0). ``INS_TCALn_ENABLE`` is not looked at.
    """
    return (params if isinstance(params, ArduPilotTempCal) else ArduPilotTempCal.from_params(
        params, sensor, instance)).offset(temp_c)


# --------------------------------------------------------------------------------------------
# What a log says
# --------------------------------------------------------------------------------------------

def onboard_status(params: Mapping[str, float], firmware: str, *, instance: int = 0,
                   sensor: str = 'gyro') -> tuple[bool, str]:
    """
    Return whether on-board thermal compensation was active, and that in words.

    E.g. ``(True, 'TC_G_ENABLE=1: on-board thermal compensation active')``. ``firmware`` is
    ``'px4'`` or ``'ardupilot'`` (else ValueError); ``instance`` is the ArduPilot IMU index
    (PX4 has one switch for every gyro); ``sensor`` ``'gyro'`` or ``'accel'``.
    """
    if firmware not in ('px4', 'ardupilot'):
        raise ValueError(f"Expected `firmware` to be 'px4' or 'ardupilot', got {firmware!r}.")
    name = px4_name(sensor) if firmware == 'px4' else ardupilot_name(instance)
    active = int(params.get(name, 0) or 0) == 1        # absent: off; 2: learning
    if name not in params:
        return False, f'{name} not in the log: no on-board thermal compensation known'
    shown = int(params[name]) if float(params[name]).is_integer() else params[name]
    return active, (f'{name}={shown}: on-board thermal compensation '
                    + ('active' if active else 'off'))
