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
A model's drift in a flight controller's form: PX4 ``TC_G*``/``TC_A*``, ArduPilot ``INS_TCALn_*``.

The steady-state drift over the trained range, on a uniform temperature grid, fitted in the
firmware's exact cubic (:mod:`gyro_tdc.model.fc_tempcal` applies it), written as the
parameter file its ground station loads, scored held out beside the full model, and where
its clamp costs. See ``doc/flight_controllers.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
import os
from pathlib import Path
from typing import Sequence

from gyro_tdc.base import atomic_write
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError, ModelFileError
from gyro_tdc.model import (ArduPilotTempCal, compensate, CompensationModel,
                            DEFAULT_OUT_OF_RANGE, Px4TempCal, steady_drift)
from gyro_tdc.signal import bias_stability, fit_columns, rms_dps
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['check_instance', 'ExportScore', 'FIRMWARES', 'FcExport', 'GRID_POINTS', 'clamp_cost',
           'fit_export', 'from_params', 'read_params', 'score_export', 'share_kept',
           'write_params']

#: The flight-controller firmwares an export targets.
FIRMWARES = ('px4', 'ardupilot')
#: Points of the uniform temperature grid the cubic is fitted on.
GRID_POINTS = 201
#: ArduPilot's fixed reference of the cubic (``TEMP_REFERENCE``), degC, and the x1e6 storage.
AP_TREF_C = 35.0
AP_SCALE = 1.0e6
#: Valid range of ArduPilot's INS_TCALn_TMIN/TMAX (its parameter metadata), degC.
AP_LIMITS_C = (-70.0, 80.0)
#: MAVLink parameter types in a QGroundControl .params file.
_INT32, _REAL32 = 6, 9


@dataclass(frozen=True)
class FcExport:
    """
    A model's drift in one firmware's form: the parameters, and what the firmware subtracts.

    ``params`` in file order (ints are MAVLink INT32, floats REAL32); ``gyro`` and ``accel``
    (None without an accelerometer part) the calibrations as the firmware reads them;
    ``gyro_offset`` ArduPilot's ``INS_GYROFFS`` at CALTEMP, rad/s (zeros for PX4, whose X0 holds
    the constant); ``range_c`` TMIN, TMAX; ``fit_rms_dps`` the form minus the model's steady
    drift over the grid; ``notes`` what the user must know.
    """

    firmware: str
    params: dict
    gyro: Px4TempCal | ArduPilotTempCal
    gyro_offset: NDArray[np.float64]
    accel: Px4TempCal | ArduPilotTempCal | None = None
    range_c: tuple = (math.nan, math.nan)
    fit_rms_dps: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    notes: list = field(default_factory=list)

    def correction(self, temp_c: ArrayLike) -> NDArray[np.float64]:
        """Return the total gyro correction the firmware subtracts at ``temp_c``, (N, 3) rad/s."""
        return self.gyro.offset(temp_c) + self.gyro_offset


def _f32(x: ArrayLike) -> NDArray[np.float64]:
    """Round to float32, as the firmware stores a REAL32 parameter."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)


def _cubic(d: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the least-squares cubic in ``d`` per column: rows c0, c1, c2, c3, shape (4, 3)."""
    return fit_columns(np.vander(d, 4, increasing=True), y)     # the one least-squares home


def check_instance(firmware: str, instance: object, name: str = '`instance`') -> None:
    """Raise FitError unless ``instance`` is a PX4 slot 0..3 or an ArduPilot IMU 0..2."""
    if not (isinstance(instance, int) and 0 <= instance < (4 if firmware == 'px4' else 3)):
        raise FitError(f'{name} {instance!r}: {firmware} has '
                       f'{"slots 0..3" if firmware == "px4" else "IMUs 0..2"}')


def fit_export(model: CompensationModel, firmware: str, *, instance: int = 0,
               device_id: int = 0, points: int = GRID_POINTS) -> FcExport:
    """
    Fit the model's steady-state drift over its trained range in a firmware's exact cubic.

    The grid is uniform in temperature (``points`` >= 8), so every degree weighs alike whatever
    the time spent there. PX4: ``X0..X3`` about ``TREF`` (the middle of the range), clamped to
    the range; ``device_id`` is ``TC_Gn_ID`` (PX4 applies a slot to that gyro only). ArduPilot:
    the cubic about 35 degC without its constant, x1e6, clamped to the range, the constant in
    ``INS_GYROFFS`` at ``INS_GYRn_CALTEMP``. Values are rounded to float32 as stored;
    ``instance`` is the PX4 slot 0..3 or the ArduPilot IMU 0..2. FitError for an unknown firmware,
    a slot out of range or a range narrower than 1 degC.
    """
    if firmware not in FIRMWARES:
        raise FitError(f'Expected `firmware` to be one of {", ".join(FIRMWARES)}, '
                       f'got {firmware!r}.')
    check_instance(firmware, instance)
    lo, hi = (float(v) for v in model.temp_range_c)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi - lo >= 1.0):
        raise FitError(f'the model range {lo:g} .. {hi:g} degC is too narrow for a cubic in '
                       'temperature (at least 1 degC)')
    grid = np.linspace(lo, hi, max(int(points), 8))
    gyro, acc = (None if m is None else steady_drift(m, grid, out_of_range='clamp')
                 for m in (model, model.accel))
    notes: list[str] = []
    exp = (_px4 if firmware == 'px4' else _ardupilot)(gyro, acc, grid, instance, int(device_id),
                                                      notes)
    return replace(exp, range_c=(lo, hi), fit_rms_dps=rms_dps(exp.correction(grid) - gyro),
                   notes=notes)


def _px4(gyro: NDArray[np.float64], acc: NDArray[np.float64] | None, grid: NDArray[np.float64],
         slot: int, device_id: int, notes: list) -> FcExport:
    """Return the PX4 form: a cubic about the middle of the range, per sensor."""
    tref = float(_f32(0.5 * (grid[0] + grid[-1])))
    cals, params = {}, {'TC_G_ENABLE': 1}
    for sensor, y in (('gyro', gyro), ('accel', acc)):
        if y is not None:
            cals[sensor] = Px4TempCal(_f32(_cubic(grid - tref, y)), tref,
                                      *_f32(grid[[0, -1]]).tolist(), device_id)
            params.update({'TC_A_ENABLE': 1} if sensor == 'accel' else {})
            params.update(cals[sensor].to_params(sensor, slot))
    if not device_id:
        notes.append(f'TC_G{slot}_ID is 0: PX4 applies a slot only to the gyro whose device_id '
                     'it holds; pass --device-id (sensor_gyro.device_id in a ULog, or '
                     'CAL_GYRn_ID)')
    notes.append(f'after loading, redo the gyro calibration (CAL_GYR{slot}_OFF) and reboot: '
                 'PX4 reads TC_* at start-up')
    return FcExport('px4', params, cals['gyro'], np.zeros(3), cals.get('accel'))


def _ardupilot(gyro: NDArray[np.float64], acc: NDArray[np.float64] | None,
               grid: NDArray[np.float64], imu: int, _device_id: int, notes: list) -> FcExport:
    """Return the ArduPilot form: the cubic about 35 degC without constant, x1e6."""
    lo, hi = float(grid[0]), float(grid[-1])
    tmin, tmax = _f32([lo, hi]).tolist()
    if lo < AP_LIMITS_C[0] or hi > AP_LIMITS_C[1]:
        notes.append(f'the range {lo:.1f} .. {hi:.1f} degC exceeds what INS_TCALn_TMIN/TMAX '
                     f'accept ({AP_LIMITS_C[0]:g} .. {AP_LIMITS_C[1]:g} degC)')
    n = imu + 1
    caltemp = float(_f32(min(max(AP_TREF_C, lo), hi)))
    coef = _cubic(grid - AP_TREF_C, gyro)
    cal = ArduPilotTempCal(_f32(coef[1:] * AP_SCALE), tmin, tmax, caltemp)
    # The firmware subtracts p(T) - p(CALTEMP) and INS_GYROFFS: the offsets are the cubic's
    # value at CALTEMP, constant included.
    offset = _f32(coef[0] + cal.poly([caltemp])[0])
    # ENABLE applies to both: no accelerometer part is zeros.
    acal = ArduPilotTempCal(np.zeros((3, 3)) if acc is None else _f32(
        _cubic(grid - AP_TREF_C, acc)[1:] * AP_SCALE), tmin, tmax, caltemp)
    if acc is None:
        notes.append('the model has no accelerometer part: INS_TCAL'
                     f'{n}_ACC* are written as 0 (no accelerometer correction)')
    params = {f'INS_TCAL{n}_ENABLE': 1, **cal.to_params('gyro', imu),
              **{k: v for k, v in acal.to_params('accel', imu).items() if 'ACC' in k}}
    params[f'INS_GYR{n}_CALTEMP'] = caltemp
    stem = 'INS_GYR' if imu == 0 else f'INS_GYR{n}'
    params.update({f'{stem}OFFS_{axis}': float(offset[i]) for i, axis in enumerate('XYZ')})
    notes.append(f'INS_GYR{n}_CALTEMP and {stem}OFFS_* carry the constant; a gyro calibration '
                 'at boot (INS_GYR_CAL=1) replaces both with what it measures then')
    return FcExport('ardupilot', params, cal, offset, None if acc is None else acal)


# --------------------------------------------------------------------------------------------
# Parameter files
# --------------------------------------------------------------------------------------------

def _value_text(value: float | int) -> str:
    """Return a parameter value as written: an int, or a float32 with every digit kept."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return str(int(value))
    return f'{float(np.float32(value)):.9g}'


def write_params(export: FcExport, path: str | os.PathLike, *, header: Sequence[str] = ()
                 ) -> Path:
    """
    Write the parameters atomically as the firmware's ground station loads them.

    PX4: a QGroundControl ``.params`` file (tab-separated ``1 1 name value type``, as
    ``Tools/process_sensor_caldata.py`` writes it); ArduPilot: ``NAME VALUE`` lines (Mission
    Planner, MAVProxy). ``header`` lines go first as ``#`` comments.
    """
    lines = [f'# {h}'.rstrip() for h in header]
    if export.firmware == 'px4':
        lines += ['#', '# Vehicle-Id Component-Id Name Value Type'] + [
            f'1\t1\t{name}\t{_value_text(value)}\t{_INT32 if isinstance(value, int) else _REAL32}'
            for name, value in export.params.items()]
    else:
        lines += [f'{name} {_value_text(value)}' for name, value in export.params.items()]
    return atomic_write(path, '\n'.join(lines) + '\n', what='parameter file')


def read_params(path: str | os.PathLike) -> dict:
    """
    Read a ``.params`` or ``.parm`` file into ``{name: value}`` (int for INT32 / integral values).

    ModelFileError names a line that is neither a comment nor a parameter.
    """
    out: dict = {}
    for k, line in enumerate(Path(path).read_text().splitlines(), 1):
        text = line.strip()
        if not text or text.startswith('#'):
            continue
        parts = text.split('\t') if '\t' in text else text.replace(',', ' ').split()
        try:
            if len(parts) == 5:
                name, value = parts[2], (int(parts[3]) if parts[4] == str(_INT32)
                                         else float(parts[3]))
            elif len(parts) == 2:
                name, number = parts[0], float(parts[1])
                value = int(number) if number.is_integer() and '.' not in parts[1] else number
            else:
                raise ValueError(f'{len(parts)} fields')
        except ValueError as exc:
            raise ModelFileError(f'{path}:{k}: not a parameter line ({exc}): {text!r:.80}'
                                 ) from None
        out[name] = value
    return out


def from_params(params: dict, firmware: str, *, instance: int = 0) -> FcExport:
    """Return the export a firmware reads from ``params``: REAL32 values rounded to float32."""
    params = {k: v if isinstance(v, int) else float(np.float32(v)) for k, v in params.items()}
    px4 = firmware == 'px4'
    cal = Px4TempCal if px4 else ArduPilotTempCal
    gyro = cal.from_params(params, 'gyro', instance)
    accel = (cal.from_params(params, 'accel', instance)
             if not px4 or f'TC_A{instance}_X0_0' in params else None)
    stem = 'INS_GYR' if instance == 0 else f'INS_GYR{instance + 1}'
    offset = np.array([0.0 if px4 else float(params.get(f'{stem}OFFS_{a}', 0.0)) for a in 'XYZ'])
    return FcExport(firmware, dict(params), gyro, offset, accel, (gyro.tmin, gyro.tmax))


# --------------------------------------------------------------------------------------------
# What the form keeps, and what its clamp costs
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ExportScore:
    """
    One held-out run scored raw, with the full model and with forms as the firmware applies them.

    ``bs`` (deg/s)^2 and ``rms_dps`` per axis by label (``raw``, ``model``, each form);
    ``outside_fraction`` the samples outside TMIN..TMAX (clamped there).
    """

    name: str
    samples: int
    outside_fraction: float
    bs: dict
    rms_dps: dict

    def kept(self, label: str) -> float:
        """Return the share of the full model's BS improvement (axes' mean) ``label`` keeps."""
        return share_kept(*(float(np.mean(self.bs[k])) for k in ('raw', 'model', label)))


def share_kept(raw: float, full: float, part: float) -> float:
    """Return the share of the improvement ``raw - full`` that ``part`` keeps (NaN: no gain)."""
    gain = raw - full
    return (raw - part) / gain if gain > 0 else math.nan


def score_export(model: CompensationModel, forms: dict, runs: Sequence[Run], *,
                 reanchor_s: float = 0.0, out_of_range: str = DEFAULT_OUT_OF_RANGE) -> list:
    """
    Score held-out runs raw, with the full model and with each firmware form (label -> form).

    A form is applied as the firmware applies it: the raw rate minus its correction at the
    measured temperature (its formula, clamp and reference; no thermal state). With
    ``reanchor_s`` > 0 the model's and every form's mean error over the first ``reanchor_s`` s of
    each run is removed (the offset a gyro calibration at boot takes); raw never.
    """
    out = []
    for run in runs:
        comp = {'model': compensate(model, run.t, run.temp, run.omega, out_of_range=out_of_range),
                **{label: run.omega - form.correction(run.temp) for label, form in forms.items()}}
        if reanchor_s > 0:          # each one's mean error over the first reanchor_s s removed
            head = run.t <= run.t[0] + reanchor_s
            comp = {k: v - (v[head] - run.omega_ref[head]).mean(axis=0) for k, v in comp.items()}
        comp = {'raw': run.omega, **comp}
        outside = max([0.0] + [float(np.mean((run.temp < lo) | (run.temp > hi)))
                               for lo, hi in (f.range_c for f in forms.values())])
        out.append(ExportScore(run.name, len(run), outside,
                               {k: bias_stability(v, run.omega_ref) for k, v in comp.items()},
                               {k: rms_dps(v - run.omega_ref) for k, v in comp.items()}))
    return out


def clamp_cost(model: CompensationModel, export: FcExport, *, beyond_c: Sequence[float] = (
        5.0, 10.0), out_of_range: str = DEFAULT_OUT_OF_RANGE) -> list:
    """
    Say where the firmware's clamp costs: the model's drift beyond TMIN/TMAX vs the held one.

    Per end and distance ``beyond_c``: ``temp_c``, ``model_dps`` (the model continued by
    ``out_of_range``, as the compensator does), ``form_dps`` and ``gap_dps`` (largest axis gap).
    """
    lo, hi = export.range_c
    temps = [lo - d for d in beyond_c] + [hi + d for d in beyond_c]
    full = np.degrees(steady_drift(model, temps, out_of_range=out_of_range))
    form = np.degrees(export.correction(temps))
    return [{'temp_c': float(t), 'model_dps': full[k].tolist(), 'form_dps': form[k].tolist(),
             'gap_dps': float(np.max(np.abs(full[k] - form[k])))}
            for k, t in enumerate(temps)]
