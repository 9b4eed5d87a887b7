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
The models an evaluation scores, and the labels of models and bags.

:func:`load_models` turns command-line model specs into :class:`NamedModel` (a model file or
shipped name, the ``px4`` cubic fitted on training bags, or a log's own on-board correction,
:func:`onboard_model`); the labels name them, and the held-out bags, in tables, CSV columns and
file names.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import os
from pathlib import Path
import re
from typing import Callable, Iterable, Sequence

from gyro_tdc.base import model_path
from gyro_tdc.data import BagOptions, imu_of, iter_runs, load_runs, Run
from gyro_tdc.errors import DatasetError, FitError
from gyro_tdc.identify import (fit_accel, fit_px4_cubic, fit_varying, PX4_FEATURES,
                               still_only_runs)
from gyro_tdc.model import (ARDUPILOT_SCALE, ARDUPILOT_TREF_C, ArduPilotTempCal,
                            CompensationModel, load_model, onboard_status, px4_slot, Px4TempCal)
import numpy as np

__all__ = ['ARDUPILOT_ONBOARD', 'axes_words', 'NamedModel', 'ONBOARD', 'PX4', 'PX4_ONBOARD',
           'bag_labels', 'imu_mismatch', 'load_models', 'model_labels', 'onboard_model',
           'safe_label', 'with_accel']

#: Model spec of the PX4-style cubic in T fitted on training bags.
PX4 = 'px4'


@dataclass(frozen=True)
class NamedModel:
    """
    A model with the name it was given on the command line (a file path as given, or ``px4``).

    ``label`` is short and unique (tables, CSV columns, legends); ``out_of_range``, when set,
    is the model's own out-of-range policy (a flight controller's clamp), overriding the
    evaluation's.
    """

    name: str
    label: str
    model: CompensationModel
    out_of_range: str | None = None


# --------------------------------------------------------------------------------------------
# Labels
# --------------------------------------------------------------------------------------------

def safe_label(text: str) -> str:
    """Return ``text`` reduced to a file-name and CSV-header safe label."""
    stem = Path(str(text).rstrip('/\\')).name.removesuffix('.yaml').removesuffix('.yml')
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', stem).strip('_.') or 'unnamed'


def _uniques(bases: Iterable[str]) -> list:
    """Return ``bases`` in order, one already taken made ``base_2``, ``base_3``..."""
    out: list = []
    for base in bases:
        label, k = base, 2
        while label in out:
            label, k = f'{base}_{k}', k + 1
        out.append(label)
    return out


def model_labels(names: Sequence[str]) -> list:
    """Return short labels for model specs, made unique with a numeric suffix."""
    return _uniques('raw_model' if b == 'raw' else b for b in map(safe_label, names))


def bag_labels(paths: Sequence[str | os.PathLike]) -> list:
    """Return unique file-name labels for bag paths (parent folder added on clashes)."""
    base = [safe_label(str(p)) for p in paths]
    return _uniques(safe_label(f'{Path(p).parent.name}_{b}') if base.count(b) > 1 else b
                    for p, b in zip(paths, base))


# --------------------------------------------------------------------------------------------
# Models
# --------------------------------------------------------------------------------------------

def axes_words(axes: Sequence[str]) -> str:
    """Return ``axis x`` or ``axes x, y``: axes named in a sentence."""
    return f'ax{"es" if len(axes) > 1 else "is"} {", ".join(axes)}'


def with_accel(bag: BagOptions | None) -> BagOptions:
    """Return ``bag`` (default :class:`~gyro_tdc.data.BagOptions`) reading the accelerometer."""
    return replace(BagOptions() if bag is None else bag, accel=True)


def load_models(specs: Sequence[str], *, train_bags: Sequence[str] | None = None,
                bag: BagOptions | None = None,
                log: Callable[[str], None] | None = None,
                held_out: Sequence[str | os.PathLike] | None = None,
                loader: Callable[[str], CompensationModel] | None = None) -> list:
    """
    Load model files and fit the ``px4`` baseline when asked; return NamedModels in order.

    ``specs`` are model files or shipped names (read by ``loader``, default
    :func:`~gyro_tdc.model.load_model`), ``px4`` (a cubic fitted on ``train_bags``, read
    as ``bag`` says, accelerometer included; on the still stretches of bags without a
    reference that move, as ``train`` fits) or ``px4-onboard`` / ``ardupilot-onboard``
    (:func:`onboard_model`, from the parameters of the first ``held_out`` log).
    Labels come from :func:`model_labels`; ``log`` receives progress lines.

    Raises
    ------
    FitError
        ``px4`` without training bags.
    ModelFileError
        A model file is missing or malformed.

    """
    if PX4 in specs and not train_bags:
        raise FitError('The px4 baseline needs training bags to fit its cubic on.')
    loader = loader or (lambda spec: load_model(model_path(spec)))
    log = log or (lambda _line: None)
    files = {s: loader(s) for s in specs if s != PX4 and s not in ONBOARD}
    if any(s in ONBOARD for s in specs):
        if not held_out:
            raise FitError('The on-board models need the held-out logs they are read from.')
        first = next(iter_runs(held_out, with_accel(bag)))   # the first readable one
        for s in specs:
            if s in ONBOARD and s not in files:
                files[s], line = onboard_model(s, first)
                log(line)
    px4 = None
    if PX4 in specs:
        runs = load_runs(train_bags, with_accel(bag), log=log)
        # A flight log: its still stretches only.
        runs, kept = still_only_runs(runs, ('fit the px4 cubic', 'the px4 cubic is fitted'))
        if kept:
            log(kept)
        # As train: a constant axis passed through, every axis constant refused.
        px4 = fit_varying(runs, lambda rs: fit_px4_cubic(
            rs, created={'bags': [r.name for r in runs]}))
        acc = fit_accel(runs, px4, kind='poly', features=PX4_FEATURES, judge=False)
        if acc.part is not None:          # PX4's TC_A*: a cubic for the accelerometer too
            px4 = px4.replace(accel=acc.part)
        lo, hi = px4.temp_range_c
        axes = px4.metrics.get('constant_axes', [])
        log(f'fitted px4 cubic in T - T0 on {len(runs)} bag(s): T0 = {px4.t0_c:.3f} degC, '
            f'range {lo:.2f} .. {hi:.2f} degC; accelerometer '
            + ('cubic too' if acc.part is not None else f'not fitted: {acc.note}')
            + (f'; gyro {axes_words(axes)} constant: not fitted, passed through unchanged'
               if axes else ''))
    return [NamedModel(s, label, px4 if s == PX4 else files[s],
                       'clamp' if s in ONBOARD else None)
            for s, label in zip(specs, model_labels(specs))]


# --------------------------------------------------------------------------------------------
# The flight controller's own correction (evaluate --model px4-onboard|ardupilot-onboard):
# the log's TC_G* / INS_TCALn_* parameters as an exact cubic, evaluated with the firmware's
# clamp whatever --out-of-range says.
# --------------------------------------------------------------------------------------------

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
    params, inst = run.info.get('params', {}), int(run.info.get('instance', 0))
    active, words = onboard_status(params, firmware, instance=inst)
    created = {'bags': [run.name], 'onboard': firmware}
    if firmware == 'px4':
        device = int(run.info.get('device_id', 0))
        if (slot := px4_slot(params, device)) is None:
            raise DatasetError(f'--model {spec}: no TC_Gn_ID of {run.name!r} is the device id '
                               f'{device} of the gyro read.')
        cal = Px4TempCal.from_params(params, 'gyro', slot)
        model = _cubic(cal.tref, cal.x[0], cal.x[1:], cal.tmin, cal.tmax, created)
        what = (f'TC_G{slot}_* (device id {device}): cubic about TREF = {cal.tref:g} degC, '
                f'clamped to {cal.tmin:g} .. {cal.tmax:g} degC')
    else:
        cal = ArduPilotTempCal.from_params(params, 'gyro', inst)
        model = _cubic(ARDUPILOT_TREF_C, -cal.poly([cal.caltemp])[0],
                       cal.coeff / ARDUPILOT_SCALE, cal.tmin, cal.tmax, created)
        what = (f'INS_TCAL{inst + 1}_GYR*: cubic about {ARDUPILOT_TREF_C:g} degC, zero at '
                f'CALTEMP = {cal.caltemp:g} degC, clamped to {cal.tmin:g} .. {cal.tmax:g} degC')
        if not any(k.startswith(f'INS_TCAL{inst + 1}_') for k in params):
            what = (f'INS_TCAL{inst + 1}_*, which the log does not hold (a firmware without '
                    'temperature calibration): none, the raw rate')
    return model, (f"{spec}: the flight controller's correction from {what}; {words}"
                   + ('' if active else ' (in this log it was not applied)'))


def imu_mismatch(nm: NamedModel, run: Run | None, label: str) -> str | None:
    """
    Return a warning when ``run`` is of another IMU than ``nm``'s model was trained on.

    Both as flight logs name them (:func:`gyro_tdc.data.imu_of`: the board and the IMU
    instance); None when either is not known, or they agree.
    """
    trained = nm.model.created.get('imus') or []
    here = None if run is None else imu_of(run.info)
    if not (isinstance(trained, list) and trained) or here is None or here in trained:
        return None
    return (f'warning: {label} is {here}; model {nm.label} was trained on '
            f"{', '.join(map(str, trained))}: each IMU drifts its own way, a model of one "
            'does not carry to another')
