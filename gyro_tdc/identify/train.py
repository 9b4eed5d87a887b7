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
from gyro_tdc.identify.accel import fit_accel
from gyro_tdc.identify.axes import (constant_gyro_axes, constant_readings, identity_axes,
                                    neutral_runs)
from gyro_tdc.identify.features import features_for_fit
from gyro_tdc.identify.fit import estimate_t0, fit_model
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.power_cycles import reanchor_rule
from gyro_tdc.identify.result import TrainResult
from gyro_tdc.identify.still_only import (MAX_MOVING_SHARE, moving_share, proxy_lag,
                                          train_still_only)
from gyro_tdc.model import save_model

__all__ = ['data_frame', 'train']


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
        Data without a reference rate (every run's reference zero) that move longer than
        :data:`gyro_tdc.identify.still_only.MAX_MOVING_SHARE` of the time are trained on their
        still stretches only (:func:`gyro_tdc.identify.still_only.train_still_only`, said on
        ``log``). The model, where it was written, the coverage of the data and, with
        ``'auto'``, the choice of features (also in ``model.metrics['features']``). A gyro
        axis whose readings never vary beyond one quantum
        (:func:`~gyro_tdc.identify.axes.constant_gyro_axes`) is not fitted: its
        coefficients are zero, so the model passes it through unchanged
        (:func:`~gyro_tdc.identify.axes.identity_axes`); ``result.constant`` and
        ``model.metrics['constant_axes']``
        name it. How large a start-up shift the node takes per axis is decided on the
        sessions (:func:`~gyro_tdc.identify.power_cycles.reanchor_rule`,
        ``model.metrics['reanchor']``).

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
    if all(r.info.get('reference') == 'zero' for r in runs):
        # No reference rate: the rate is known (zero) only while still. Motion (a flight, a
        # drive) would be fitted as drift, so only the still stretches are used.
        share = moving_share(neutral_runs(runs, constant_gyro_axes(runs)))
        if share > MAX_MOVING_SHARE:
            if log is not None:
                log(f'no reference rate and the IMU moves {100.0 * share:.3g} % of the time: '
                    'training on the still stretches only (as --still-only)')
            return train_still_only(bags, out, o, bag, command=command, log=log, runs=runs)
    names = [r.name for r in runs]
    split = split_sessions(runs, bag.sessions, bag.session_gap_s)
    runs = split.runs
    const = constant_gyro_axes(runs)
    fitted = neutral_runs(runs, const)
    t0 = estimate_t0(runs[0]) if o.t0 is None else o.t0
    ids, params, choice = features_for_fit(fitted, o.features, t0=t0)
    ids = proxy_lag(runs, ids, o, log)
    model = fit_model(fitted, features=ids, params=params or None, kind=o.kind, t0=t0,
                      n_centers=o.n_centers, refine=o.refine, ridge=o.ridge, seed=o.seed,
                      thermal=o.thermal, sessions=split.labels,
                      frame_id=data_frame(runs),
                      sensor_id=str(o.sensor_id), created={'command': command, 'bags': names})
    model = identity_axes(model, runs, const)

    def refit(others: list, labels: list):
        return fit_model(others, features=model.features, params=model.effect_params,
                         fit_params=False, kind=o.kind, t0=t0, n_centers=o.n_centers,
                         refine=o.refine, ridge=o.ridge, seed=o.seed, thermal=model.thermal,
                         sessions=labels)

    model = reanchor_rule(model, fitted, split.labels, refit)
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
                       sessions=split, constant=constant_readings(runs, const))
