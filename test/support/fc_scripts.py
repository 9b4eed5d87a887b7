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
Re-implementations of PX4's and ArduPilot's offline thermal-calibration scripts (for tests).

Both fit a cubic of the raw gyro against the measured temperature, from a log whose procedure
records a warm-up (cold soak, then power on and heat): PX4 ``Tools/process_sensor_caldata.py``
and ArduPilot ``Tools/scripts/tempcal_IMU.py``. The steps below follow the scripts line by
line where they shape the fit (filters, resampling, reference, clamp range, rounding of the
file); plotting and log parsing are left out. The result is the parameter set the script
would write, read by :func:`gyro_tdc.identify.export.from_params` as the firmware reads it.
"""

from __future__ import annotations

from gyro_tdc.data.runs import Run
from gyro_tdc.identify.export import from_params
import numpy as np
from scipy.signal import medfilt

__all__ = ['ardupilot_script', 'compare', 'heating_leg', 'px4_script']


def heating_leg(run: Run) -> Run:
    """
    Return the warm-up of a run: from the start to its highest temperature.

    What a calibration log following either procedure holds: the board cold-soaked, then
    powered and heated (the scripts fit whatever the log holds; a heating-and-cooling run
    cut at its top gives them the data their procedure records).
    """
    top = int(np.argmax(run.temp)) + 1
    return run.slice(0, top, name=f'{run.name} (heating)')


def _resample_with_delta_x(x: np.ndarray, y: np.ndarray, n_bins: int = 2000):
    """PX4's ``resampleWithDeltaX``: 2000 equal-width bins in x, mean x and y of each used one."""
    x_min, x_max = np.amin(x), np.amax(x)
    interval = (x_max - x_min) / n_bins
    idx = np.where(x < x_max, ((x - x_min) / interval).astype(int), n_bins - 1)
    idx = np.clip(idx, 0, n_bins - 1)
    count = np.bincount(idx, minlength=n_bins)
    sx = np.bincount(idx, weights=x, minlength=n_bins)
    sy = np.bincount(idx, weights=y, minlength=n_bins)
    keep = count != 0
    return sx[keep] / count[keep], sy[keep] / count[keep]


def px4_script(run: Run, *, slot: int = 0, device_id: int = 0):
    """
    Fit ``TC_G<slot>_*`` as ``process_sensor_caldata.py`` does on one ``sensor_gyro`` instance.

    TMIN/TMAX are the min/max temperature, TREF their mid-point; each axis is median-filtered
    (``medfilt``, 31 samples), resampled into 2000 equal-width temperature bins
    (``resampleWithDeltaX``) and fitted with ``np.polyfit(temp_rel, rate, 3)``: X3..X0. The
    file holds ``str()`` of the float64 values; the firmware reads them as float32.
    """
    temp = run.temp
    tmin, tmax = float(np.amin(temp)), float(np.amax(temp))
    tref = 0.5 * (tmin + tmax)
    rel = temp - tref
    params = {'TC_G_ENABLE': 1, f'TC_G{slot}_ID': int(device_id), f'TC_G{slot}_TMIN': tmin,
              f'TC_G{slot}_TMAX': tmax, f'TC_G{slot}_TREF': tref}
    for axis in range(3):
        rate = medfilt(run.omega[:, axis], 31)
        x, y = _resample_with_delta_x(rel, rate)
        c3, c2, c1, c0 = np.polyfit(x, y, 3)
        for k, c in enumerate((c0, c1, c2, c3)):
            params[f'TC_G{slot}_X{k}_{axis}'] = float(np.float32(c))
    for name in (f'TC_G{slot}_TMIN', f'TC_G{slot}_TMAX', f'TC_G{slot}_TREF'):
        params[name] = float(np.float32(params[name]))
    return from_params(params, 'px4', instance=slot)


def _moving_average(data: np.ndarray, w: int) -> np.ndarray:
    """``IMUData.moving_average``: the mean over a window of ``w`` samples (valid part only)."""
    ret = np.cumsum(data, dtype=float)
    ret[w:] = ret[w:] - ret[:-w]
    return ret[w - 1:] / w


def ardupilot_script(run: Run, *, imu: int = 0):
    """
    Fit ``INS_TCAL<imu + 1>_*`` as ``tempcal_IMU.py`` does on one IMU's ``IMU`` messages.

    The samples are smoothed by a 2 s moving average (``Filter(2)``: a window of
    ``int(n / seconds) * 2`` samples on X, Y, Z and T), TMIN/TMAX are the min/max filtered
    temperature, and each axis is ``np.polyfit(T - 35, gyro, 3)``; the file keeps
    ``%.1f`` of TMIN/TMAX and ``%.9f`` of the coefficients times 1e6, and drops the constant.
    The firmware then subtracts ``p(T) - p(CALTEMP)`` and the static offsets, which a gyro
    calibration takes at CALTEMP: here the script's own cubic at 35 degC (its constant), so
    the form is the script's whole cubic, as it plots it.
    """
    seconds = run.t[-1] - run.t[0]
    window = int(len(run) / seconds) * 2
    temp = run.temp
    omega = run.omega
    if window > 1:
        temp = _moving_average(temp, window)
        omega = np.column_stack([_moving_average(omega[:, i], window) for i in range(3)])
    n = imu + 1
    tmin, tmax = float(f'{np.amin(temp):.1f}'), float(f'{np.amax(temp):.1f}')
    params = {f'INS_TCAL{n}_ENABLE': 1, f'INS_TCAL{n}_TMIN': tmin, f'INS_TCAL{n}_TMAX': tmax}
    const = np.zeros(3)
    for i, axis in enumerate('XYZ'):
        coef = np.polyfit(temp - 35.0, omega[:, i], 3)          # c3, c2, c1, c0
        for p in range(3):
            params[f'INS_TCAL{n}_GYR{p + 1}_{axis}'] = float(f'{coef[3 - (p + 1)] * 1e6:.9f}')
        const[i] = coef[3]
    caltemp = min(max(35.0, tmin), tmax)
    params[f'INS_GYR{n}_CALTEMP'] = caltemp
    form = from_params(params, 'ardupilot', instance=imu)
    offset = const + form.gyro.poly([caltemp])[0]
    stem = 'INS_GYR' if imu == 0 else f'INS_GYR{n}'
    for i, axis in enumerate('XYZ'):
        params[f'{stem}OFFS_{axis}'] = float(np.float32(offset[i]))
    return from_params(params, 'ardupilot', instance=imu)


def compare(reanchor_s: float = 0.0) -> dict:
    """
    Score the exported forms and the scripts' on a held-out heating-and-cooling session.

    The session's die lags its thermometer by 300 s (``synth_run``, 2 h at 2 Hz, seed 1 to
    train, seed 2 held out with another turn-on offset); the model is ``poly dT,dT2,dT3,lag``
    fitted on the whole training session, the scripts see its heating leg. Returns the mean
    BS over the axes per label, in (deg/s)^2, and the exported forms' share of the full
    model's improvement.
    """
    from gyro_tdc.identify import fit_model
    from gyro_tdc.identify.export import fit_export, FIRMWARES, score_export
    from synth import synth_run
    train = synth_run(hours=2.0, rate_hz=2.0, cooling=True, seed=1, tau_die=300.0)
    held = synth_run(hours=2.0, rate_hz=2.0, cooling=True, seed=2, tau_die=300.0,
                     offset_dps=(0.02, -0.01, 0.01))
    model = fit_model([train], kind='poly', features=('dT', 'dT2', 'dT3', 'lag'))
    forms = {fw: fit_export(model, fw) for fw in FIRMWARES}
    heat = heating_leg(train)
    forms.update({'px4 script': px4_script(heat), 'ardupilot script': ardupilot_script(heat)})
    s = score_export(model, forms, [held], reanchor_s=reanchor_s)[0]
    return {'bs': {k: float(np.mean(v)) for k, v in s.bs.items()},
            'kept': {k: s.kept(k) for k in forms}}


if __name__ == '__main__':      # python test/support/fc_scripts.py: the figures of the docs
    for reanchor in (0.0, 60.0):
        r = compare(reanchor)
        bs = r['bs']
        print(f'held out, first {reanchor:g} s re-anchored: mean BS (deg/s)^2 and share of the '
              "full model's improvement over raw kept")
        for label, value in bs.items():
            kept = r['kept'].get(label)
            print(f'  {label:<17} {value:.5f}' + ('' if kept is None else
                                                  f'  kept {100 * kept:5.1f} %  '
                                                  f'BS/model {value / bs["model"]:.2f}'))
