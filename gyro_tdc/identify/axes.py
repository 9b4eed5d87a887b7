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
Constant gyro axes: found, held at their reference for a fit, passed through by the model.

A 2-axis gyro whose driver fills the third axis with a fixed value, or a dead axis, has
nothing to fit; every trainer (chamber, still-only, discovery) and the evaluation use these.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import DatasetError
from gyro_tdc.identify.accel import constant_axes_of, constant_values
from gyro_tdc.model import CompensationModel
import numpy as np
from numpy.typing import NDArray

__all__ = ['all_constant_error', 'AXES', 'constant_gyro_axes', 'constant_readings',
           'identity_axes', 'neutral_runs']

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
