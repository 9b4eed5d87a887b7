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
Fleet statistics: each model's static drift quadratic, robust z-scores, outlier flags.

The static drift curve of a model (at thermal equilibrium) is fitted with a quadratic in
temperature; its slope at the fleet's reference temperature (the median middle of the
trained ranges, where slopes are best determined) and its curvature, per axis, are compared
with the fleet by a robust z-score ``(v - median) / (1.4826 MAD)``; beyond ``outlier_z`` a
flag such as ``drift slope on x 6.0σ from the fleet`` is raised. A sensor's constant axis
(``SensorResult.constant_axes``: not fitted, its model passes it through, so its drift is
exactly 0) is no drift to compare: it takes no part in that axis' statistics.
"""

from __future__ import annotations

import math
from typing import Sequence

from gyro_tdc.base import AXES
from gyro_tdc.fleet.results import SensorResult
from gyro_tdc.model import CompensationModel, steady_drift
from gyro_tdc.signal import fit_columns, mad_sigma
import numpy as np
from numpy.typing import NDArray

__all__ = ['DEFAULT_OUTLIER_Z', 'MIN_FLEET', 'drift_polynomial', 'fleet_statistics', 'robust_z']

DEFAULT_OUTLIER_Z = 3.5      # Iglewicz and Hoaglin's cut-off for the modified z-score
MIN_FLEET = 3                # fewer trained sensors: no z-scores, no flags


def drift_polynomial(model: CompensationModel, *, points: int = 41) -> NDArray[np.float64]:
    """
    Fit a quadratic in temperature to the model's static drift over its trained range.

    The static drift is the drift at thermal equilibrium (lag, dT/dt and warm-up terms
    settled), sampled at ``points`` temperatures. Returns ``c[axis, k]`` (3, 3) of
    ``b(T) = c0 + c1 T + c2 T^2``, deg/s per degC^k, T in degC.
    """
    grid = np.linspace(*model.temp_range_c, points)
    design = np.vander(grid, 3, increasing=True)          # 1, T, T^2
    return fit_columns(design, np.degrees(steady_drift(model, grid))).T.copy()


def robust_z(values: Sequence[float]) -> NDArray[np.float64]:
    """
    Return the robust z-score ``(v - median) / (1.4826 MAD)`` of each value.

    Parameters
    ----------
    values : sequence of float
        One value per sensor.

    Returns
    -------
    NDArray[np.float64], shape (N,)
        z-scores; NaN for every value when the MAD is zero or not finite.

    """
    v = np.asarray(values, dtype=np.float64)
    scale = float(mad_sigma(v))
    ok = math.isfinite(scale) and scale > 0
    return (v - float(np.median(v))) / scale if ok else np.full(v.shape, math.nan)


def fleet_statistics(sensors: Sequence[SensorResult], *,
                     outlier_z: float = DEFAULT_OUTLIER_Z) -> float | None:
    """
    Fill in drift slope, curvature, their robust z-scores and the flags of the sensors.

    Parameters
    ----------
    sensors : sequence of SensorResult
        Every sensor; those with a drift polynomial take part.
    outlier_z : float
        A coefficient with ``|z| > outlier_z`` is flagged.

    Returns
    -------
    float or None, degC
        The reference temperature of the slopes (the fleet's median of the middle of each
        trained range, where a slope is best determined), None without any trained sensor.
        z-scores and flags of an axis need at least :data:`MIN_FLEET` sensors fitted on it:
        a sensor's constant axes (``constant_axes``) get no slope, curvature or z-score
        (None) and are left out of the axis' median and MAD.

    """
    if not (fleet := [s for s in sensors if s.status == 'ok' and s.drift_poly is not None]):
        return None
    ref = float(np.median([sum(s.temp_range_c) / 2.0 for s in fleet]))
    # fitted[i, a]: sensor i's model is fitted on axis a (not an identity axis).
    fitted = np.array([[a not in (s.constant_axes or ()) for a in AXES] for s in fleet])
    for s, ok in zip(fleet, fitted):
        c = np.asarray(s.drift_poly, dtype=np.float64)          # (axis, power)
        slope, curv = c[:, 1] + 2.0 * c[:, 2] * ref, c[:, 2]
        s.slope = [float(v) if k else None for v, k in zip(slope, ok)]
        s.curvature = [float(v) if k else None for v, k in zip(curv, ok)]
    if len(fleet) < MIN_FLEET:
        return ref
    for name, unit in (('slope', 'deg/s/degC'), ('curvature', 'deg/s/degC^2')):
        # (sensor, axis); a constant axis (None) is NaN
        values = np.array([getattr(s, name) for s in fleet], dtype=np.float64)
        z, med = np.full(values.shape, math.nan), np.full(3, math.nan)
        for a in range(3):
            rows = fitted[:, a]
            if np.count_nonzero(rows) >= MIN_FLEET:
                z[rows, a] = robust_z(values[rows, a])
                med[a] = float(np.median(values[rows, a]))
        for i, s in enumerate(fleet):
            setattr(s, f'z_{name}', [None if math.isnan(v) else float(v) for v in z[i]])
            s.flags += [f'drift {name} on {axis} {abs(z[i, a]):.1f}σ from the fleet '
                        f'({values[i, a]:+.3g} vs median {med[a]:+.3g} {unit})'
                        for a, axis in enumerate(AXES) if abs(z[i, a]) > outlier_z]
    return ref
