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
Training: bags in, a fitted and saved compensation model out, with the coverage of the data.

:func:`train` takes the bags, a :class:`~gyro_tdc.identify.options.TrainOptions` and a
:class:`~gyro_tdc.data.BagOptions`; the command line is :mod:`gyro_tdc.cli.train`. How the
features, the accelerometer part and the coverage come about: ``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import replace
import os
from typing import Callable, Sequence

from gyro_tdc.data import BagOptions, coverage, load_runs, Run, split_sessions
from gyro_tdc.errors import DatasetError
from gyro_tdc.identify.accel import constant_axes_of, constant_values, fit_accel
from gyro_tdc.identify.crossval import validate_curve
from gyro_tdc.identify.features import features_for_fit
from gyro_tdc.identify.fit import estimate_t0, fit_model
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.result import TrainResult
from gyro_tdc.model import CompensationModel, save_model
import numpy as np
from numpy.typing import NDArray

__all__ = ['all_constant_error', 'constant_gyro_axes', 'constant_readings', 'data_frame',
           'identity_axes', 'neutral_runs', 'train']

#: The axis names, in order.
AXES = ('x', 'y', 'z')
_DEG2 = (180.0 / np.pi) ** 2


def constant_gyro_axes(runs: Sequence[Run]) -> NDArray[np.bool_]:
    """
    Return, per axis, whether the gyro readings of ``runs`` together are constant.

    A constant axis never varies beyond one quantum over every run
    (:func:`gyro_tdc.identify.accel.constant_axes_of`, the accelerometer's rule): a 2-axis
    gyro whose driver fills the third axis with a fixed value (e.g. exactly 0), or a dead
    axis. There is nothing to fit on it.

    Raises
    ------
    DatasetError
        When every axis is constant: there is no gyro to fit.

    """
    const = constant_axes_of([r.omega for r in runs])
    if const.all():
        raise all_constant_error([r.omega for r in runs], 'fit', 'the training bags')
    return const


def all_constant_error(arrays: Sequence[NDArray[np.float64]], to: str,
                       where: str) -> DatasetError:
    """
    Return the one-line error for a gyro constant on every axis (nothing ``to`` do).

    ``arrays`` are the angular velocities read, ``where`` names them (``'the training
    bags'``); the line shows what each axis reads.
    """
    shown = ', '.join(f'{a} {v:.6g}' for a, v in zip(AXES, constant_values(arrays)))
    return DatasetError(f'Expected a gyro to {to}: every axis of the angular velocity is '
                        f'constant in {where} ({shown} rad/s, never varying beyond one '
                        'quantum); check that the driver publishes the gyro.')


def neutral_runs(runs: Sequence[Run], const: NDArray[np.bool_]) -> list[Run]:
    """
    Return the runs with each constant axis reading its reference rate (no error to fit).

    The fit then sees an error of exactly zero there: every coefficient of the axis comes
    out exactly zero (the model passes the axis through unchanged) and the axis adds exactly
    nothing to what the axes share (the thermal state's search, the ridge chosen by
    cross-validation, the feature choice), so the other axes get the model they would get
    whatever the constant axis read.
    """
    if not const.any():
        return list(runs)
    out = []
    for r in runs:
        omega = np.array(r.omega, dtype=np.float64, copy=True)
        omega[:, const] = r.omega_ref[:, const]
        out.append(replace(r, omega=omega))
    return out


def identity_axes(model: CompensationModel, runs: Sequence[Run], const: NDArray[np.bool_],
                  rows: Sequence[NDArray[np.bool_]] | None = None) -> CompensationModel:
    """
    Return ``model`` with its constant axes recorded as passed through unchanged.

    The model's coefficients of those axes are already zero (:func:`neutral_runs`); here its
    training figures get the truth of an identity axis: the compensated error is the raw
    error (``raw_bs_dps2``, ``train_bs_dps2``, ``train_rms_dps`` and the residual variance
    are its mean square over ``runs``, the data as read; over the ``rows`` that count when
    given, as :func:`gyro_tdc.identify.fit.fit_model` takes them), and
    ``training.constant_axes`` names them.
    """
    if not const.any():
        return model
    ss, n = np.zeros(int(const.sum())), 0
    for i, r in enumerate(runs):
        e = r.omega[:, const] - r.omega_ref[:, const]
        if rows is not None:
            e = e[np.asarray(rows[i], dtype=bool)]
        ss += np.einsum('ij,ij->j', e, e)
        n += len(e)
    ms = np.zeros(3)
    ms[const] = ss / max(n, 1)
    met = dict(model.metrics)
    resid = np.where(const, ms, model.residual_var)
    for key in ('raw_bs_dps2', 'train_bs_dps2'):
        met[key] = [float(v) for v in np.where(const, ms * _DEG2, met[key])]
    rms = np.where(const, np.sqrt(ms * _DEG2), met['train_rms_dps'])
    met['train_rms_dps'] = [float(v) for v in rms]
    met['constant_axes'] = [a for a, c in zip(AXES, const) if c]
    return model.replace(residual_var=resid, metrics=met)


def constant_readings(runs: Sequence[Run], const: NDArray[np.bool_]) -> dict:
    """Return axis name -> what each constant axis reads, rad/s (``TrainResult.constant``)."""
    if not const.any():
        return {}
    values = constant_values([r.omega for r in runs])
    return {a: float(v) for a, v, c in zip(AXES, values, const) if c}


def data_frame(runs: Sequence[Run]) -> str:
    """
    Return the frame the training data were recorded in, for the model's ``sensor.frame_id``.

    The frame is the ``header.frame_id`` of the IMU messages each run was read from
    (``run.info['frame_id']``); the compensator warns when its input is in another one.

    Parameters
    ----------
    runs : sequence of Run
        The training runs.

    Returns
    -------
    str
        Their one frame; '' when none of them names one (a flight log, a frame-less bag):
        the model then claims none and the compensator checks nothing.

    Raises
    ------
    DatasetError
        When the runs were recorded in different frames: a model corrects per axis, in one
        frame.

    """
    frames: dict[str, str] = {}
    for run in runs:
        frame = str(run.info.get('frame_id') or '')
        if frame:
            frames.setdefault(frame, run.name)
    if len(frames) > 1:
        named = ', '.join(f'{name}: {frame!r}' for frame, name in frames.items())
        raise DatasetError(f'Expected the IMU data of every bag in one frame (a model corrects '
                           f'per axis), got {len(frames)} frames ({named}); train one model '
                           'per frame.')
    return next(iter(frames), '')


def train(bags: Sequence[str | os.PathLike], out: str | os.PathLike,
          options: TrainOptions | None = None, bag: BagOptions | None = None, *,
          command: str = '', log: Callable[[str], None] | None = None) -> TrainResult:
    """
    Load bags, fit a compensation model and save it.

    Parameters
    ----------
    bags : sequence of str or PathLike
        rosbag2 directories (or folders of them), one run each, cut into sessions as
        ``bag.sessions`` says (:func:`gyro_tdc.data.split_sessions`): one turn-on offset per
        session beside one shared thermal curve.
    out : str or PathLike
        Model file to write.
    options : TrainOptions, optional
        Features, network, reference temperature, coverage bins, accelerometer part, sensor
        id (default :class:`~gyro_tdc.identify.options.TrainOptions`).
    bag : BagOptions, optional
        How to read the bags (default :class:`~gyro_tdc.data.BagOptions`); the accelerometer
        is read when ``options.accel`` says so.
    command : str
        Command line recorded in the model's ``created``.
    log : callable, optional
        Receives one line per bag read.

    Returns
    -------
    TrainResult
        The model, where it was written, the coverage of the data and, with ``'auto'``, the
        choice of features (also in ``model.metrics['features']``). A gyro axis whose
        readings never vary beyond one quantum (:func:`constant_gyro_axes`) is not fitted:
        its coefficients are zero, so the model passes it through unchanged
        (:func:`identity_axes`); ``result.constant`` and ``model.metrics['constant_axes']``
        name it. Each axis keeps its thermal curve only where it predicts held-out sessions
        better than its offset alone (:func:`gyro_tdc.identify.crossval.validate_curve`,
        ``result.held_out``).

    Raises
    ------
    GyroTdcError
        DatasetError for a bag that cannot be read or a gyro constant on every axis,
        FitError for data that cannot be fitted, ModelFileError or OutputError when the
        model cannot be written.

    """
    o = TrainOptions() if options is None else options
    bag = replace(BagOptions() if bag is None else bag, accel=bool(o.accel))
    runs: list[Run] = load_runs(bags, bag, log=log)
    names = [r.name for r in runs]
    split = split_sessions(runs, bag.sessions, bag.session_gap_s)
    runs = split.runs
    const = constant_gyro_axes(runs)
    fitted = neutral_runs(runs, const)
    t0 = estimate_t0(runs[0]) if o.t0 is None else o.t0
    ids, params, choice = features_for_fit(fitted, o.features, t0=t0)
    model = fit_model(fitted, features=ids, params=params or None, kind=o.kind, t0=t0,
                      n_centers=o.n_centers, refine=o.refine, ridge=o.ridge, seed=o.seed,
                      thermal=o.thermal, sessions=split.labels,
                      frame_id=data_frame(runs),
                      sensor_id=str(o.sensor_id), created={'command': command, 'bags': names})
    model = identity_axes(model, runs, const)
    model, held = validate_curve(model, fitted, split.labels, options=o, constant=const)
    accel_fit = None
    if o.accel:
        accel_fit = fit_accel(runs, model, n_centers=o.n_centers, seed=o.seed, bin_c=o.bin_c)
        if accel_fit.part is not None:
            model = model.replace(accel=accel_fit.part)
    if choice is not None:
        model = model.replace(metrics={**model.metrics, 'features': choice.to_dict()})
    cov = coverage(runs, bin_c=o.bin_c)
    path = save_model(model, out)
    return TrainResult(model=model, path=path, coverage=cov, bags=names,
                       samples=sum(len(r) for r in runs), choice=choice, accel=accel_fit,
                       sessions=split, constant=constant_readings(runs, const), held_out=held)
