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
Constant axes: the one rule, held at their reference for a fit, passed through by the model.

An axis is constant when its finite readings take at most two values (one quantum apart by
definition): a driver filling a fixed value (a 2-axis gyro's third axis, ``(0, 0, g)``), a
dead axis, or a drift below the resolution. Nothing can be fitted on it; every trainer
(chamber, still-only, discovery, the accelerometer part) and the evaluation use this module.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Sequence

from gyro_tdc.base import AXES, DEG2_PER_RAD2, MAX_DRIFT_RAD_S
from gyro_tdc.data import Run
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import CompensationModel
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['all_constant_error', 'AXES', 'constant_axes', 'constant_axes_of', 'constant_gyro_axes',
           'constant_note', 'constant_readings', 'constant_values', 'fit_varying',
           'identity_axes', 'neutral_runs']


def _finite(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the finite values of ``v`` (``v`` itself, uncopied, when all are)."""
    ok = np.isfinite(v)
    return v if ok.all() else v[ok]


def constant_axes_of(arrays: Sequence[ArrayLike]) -> NDArray[np.bool_]:
    """
    Return per axis whether the finite readings (N_k, 3) of every run together are constant.

    True also for an axis without any finite reading.
    """
    arrays = [np.asarray(a, dtype=np.float64).reshape(-1, 3) for a in arrays]

    def constant(i: int) -> bool:
        # Three distinct finite values among the first few: not constant, no full pass.
        if np.unique(np.concatenate([_finite(a[:64, i]) for a in arrays] or [np.zeros(0)])
                     ).size > 2:
            return False
        cols = [v for v in (_finite(a[:, i]) for a in arrays) if v.size]
        lo = min((float(v.min()) for v in cols), default=0.0)     # no finite reading: True
        hi = max((float(v.max()) for v in cols), default=0.0)
        return lo == hi or all(bool(np.all((v == lo) | (v == hi))) for v in cols)

    return np.array([constant(i) for i in range(3)])


def constant_axes(values: ArrayLike) -> NDArray[np.bool_]:
    """Return per axis whether the readings (N, 3) of one run are constant (NaN ignored)."""
    return constant_axes_of([values])


def constant_values(arrays: Sequence[ArrayLike]) -> NDArray[np.float64]:
    """Return per axis the first finite reading of ``arrays`` (NaN for an axis with none)."""
    arrays = [np.asarray(a, dtype=np.float64).reshape(-1, 3) for a in arrays]
    return np.array([next((v[0] for v in (_finite(a[:, i]) for a in arrays) if v.size), np.nan)
                     for i in range(3)])


def constant_note(runs: Sequence[Run]) -> str:
    """Return why the accelerometer of ``runs`` counts as absent: every axis constant ('')."""
    acc = [np.asarray(r.accel, dtype=np.float64).reshape(-1, 3) for r in runs
           if r.accel is not None]
    if not acc or not constant_axes_of(acc).all():
        return ''
    first = next((x[0] for x in (a[np.isfinite(a).all(axis=1)] for a in acc) if len(x)), None)
    value = ', '.join(f'{v:.6g}' for v in (constant_values(acc) if first is None else first))
    return (f'the accelerometer readings are constant (({value}) m/s^2, never varying '
            'beyond one quantum: a driver filling a fixed value); treated as absent')


def constant_gyro_axes(runs: Sequence[Run]) -> NDArray[np.bool_]:
    """Return the constant gyro axes of ``runs``; DatasetError when every axis is constant."""
    const = constant_axes_of([r.omega for r in runs])
    if const.all():
        raise all_constant_error([r.omega for r in runs], 'fit', 'the training bags')
    return const


def all_constant_error(arrays: Sequence[NDArray[np.float64]], to: str,
                       where: str) -> DatasetError:
    """Return the one-line error for a gyro constant on every axis (nothing ``to`` do)."""
    shown = ', '.join(f'{a} {v:.6g}' for a, v in zip(AXES, constant_values(arrays)))
    return DatasetError(f'Expected a gyro to {to}: every axis of the angular velocity is '
                        f'constant in {where} ({shown} rad/s, never varying beyond one '
                        'quantum); check that the driver publishes the gyro.')


def neutral_runs(runs: Sequence[Run], const: NDArray[np.bool_]) -> list[Run]:
    """
    Return the runs with each constant axis reading its reference rate (no error to fit).

    Every coefficient of such an axis then comes out exactly zero (the model passes it
    through) and it adds nothing to what the axes share (the thermal state's search, the
    ridge, the feature choice): the other axes get the model they get without it.
    """
    if not const.any():
        return list(runs)
    return [replace(r, omega=np.where(const, r.omega_ref, np.asarray(r.omega, dtype=np.float64)))
            for r in runs]


def fit_varying(runs: Sequence[Run], fit: Callable[[list[Run]], CompensationModel], *,
                fitted: Sequence[Run] | None = None) -> CompensationModel:
    """
    Return ``fit`` of the runs with their constant gyro axes passed through (train's rule).

    ``fit`` gets :func:`neutral_runs` of ``fitted`` (default ``runs``), the axes constant in
    ``runs`` (:func:`constant_gyro_axes`: DatasetError when every one is) reading their
    reference; the model is then :func:`identity_axes` of ``runs``.
    """
    const = constant_gyro_axes(runs)
    return identity_axes(fit(neutral_runs(runs if fitted is None else fitted, const)), runs, const)


def identity_axes(model: CompensationModel, runs: Sequence[Run], const: NDArray[np.bool_],
                  rows: Sequence[NDArray[np.bool_]] | None = None) -> CompensationModel:
    """
    Return ``model`` with its constant axes recorded as passed through unchanged.

    Their training figures (BS, RMS, residual variance) are the raw error's mean square over
    ``runs`` as read (over ``rows`` when given); ``training.constant_axes`` names them. The
    variance is at most the square of the drift bound, what a model file holds: an axis
    stuck beyond it (saturated) is passed through too.
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
    dps2 = ms * DEG2_PER_RAD2
    met = {**model.metrics, **{key: np.where(const, v, model.metrics[key]).tolist() for key, v in (
        ('raw_bs_dps2', dps2), ('train_bs_dps2', dps2), ('train_rms_dps', np.sqrt(dps2)))},
           'constant_axes': [a for a, c in zip(AXES, const) if c]}
    var = np.minimum(ms, MAX_DRIFT_RAD_S ** 2)
    return model.replace(residual_var=np.where(const, var, model.residual_var), metrics=met)


def constant_readings(runs: Sequence[Run], const: NDArray[np.bool_]) -> dict:
    """Return axis name -> what each constant axis reads, rad/s (``TrainResult.constant``)."""
    values = constant_values([r.omega for r in runs]) if const.any() else ()
    return {a: float(v) for a, v, c in zip(AXES, values, const) if c}
