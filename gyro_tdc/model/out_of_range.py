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
Beyond the trained range: what a model does where its temperature leaves ``temp_range_c``.

The policies (:data:`OUT_OF_RANGE_POLICIES`): ``linear`` continues along the tangent at the
range end for up to :data:`MAX_EXTRAPOLATION_C`, ``clamp`` holds the end value,
``extrapolate`` evaluates without bound. :func:`split` is the one home of the rule,
:class:`Tangent` of the slope. See ``doc/internals/model.md``.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from gyro_tdc.model.effects import EFFECTS, STATE_TERMS
import numpy as np
from numpy.typing import NDArray

__all__ = ['DEFAULT_OUT_OF_RANGE', 'MAX_EXTRAPOLATION_C', 'OPERATING_RANGE_C',
           'OUT_OF_RANGE_POLICIES', 'Tangent', 'VARIANCE_SCALE_C', 'added_variance',
           'check_policy', 'range_shortfall', 'split', 'variance_growth']

#: What a model does outside its trained range (see the module docstring).
OUT_OF_RANGE_POLICIES = ('linear', 'clamp', 'extrapolate')
#: The default of the compensator node and of ``evaluate``.
DEFAULT_OUT_OF_RANGE = 'linear'
#: How far beyond the trained range ``linear`` follows the tangent before it holds, degC.
MAX_EXTRAPOLATION_C = 15.0
#: A typical operating range (degC): ``train`` warns when the data cover less.
OPERATING_RANGE_C = (-10.0, 50.0)
#: Distance from the range (degC) at which the ``linear`` policy's added variance doubles.
VARIANCE_SCALE_C = 5.0
#: Step of the central difference of a temperature term's slope, degC.
SLOPE_STEP_C = 1e-3


def check_policy(policy: str) -> str:
    """
    Return ``policy`` when it is one of :data:`OUT_OF_RANGE_POLICIES`.

    Raises
    ------
    ValueError
        Naming the argument, the choices and the value received.

    """
    if policy not in OUT_OF_RANGE_POLICIES:
        raise ValueError(f"Expected `out_of_range` 'linear', 'clamp' or 'extrapolate', "
                         f'got {policy!r}.')
    return policy


def split(s: Any, lo: float, hi: float, policy: str,
          max_c: float = MAX_EXTRAPOLATION_C) -> tuple[Any, Any]:
    """
    Split a model temperature into where the model is evaluated and the tangent's reach.

    For model temperature ``s`` (degC) and the trained range ``lo`` .. ``hi``: ``s_eval`` is
    ``s`` (``extrapolate``, or inside the range), else the nearest range end; ``reach`` is
    ``s - s_eval`` limited to ``+-max_c`` for ``linear``, else 0.
    """
    arr = isinstance(s, np.ndarray)
    inside = s if policy == 'extrapolate' else np.clip(s, lo, hi) if arr else min(max(s, lo), hi)
    if policy != 'linear':
        return inside, np.zeros_like(s) if arr else 0.0
    reach = s - inside
    return inside, np.clip(reach, -max_c, max_c) if arr else max(min(reach, max_c), -max_c)


def added_variance(base: float, distance_c: float, policy: str) -> float:
    """
    Return the variance the compensator adds outside the range, (rad/s)^2.

    Parameters
    ----------
    base : float, (rad/s)^2
        ``out_of_range_variance``.
    distance_c : float, degC
        Distance of the model temperature from the range (sign ignored; 0 inside).
    policy : str
        ``linear`` grows it as ``base * (1 + (d / VARIANCE_SCALE_C)^2)``; ``clamp`` and
        ``extrapolate`` add ``base``.

    """
    return base + variance_growth(base, distance_c, policy)


def variance_growth(base: float, distance_c: float, policy: str) -> float:
    """Return what :func:`added_variance` adds to ``base``: ``base (d / 5 degC)^2`` (linear)."""
    if policy != 'linear':
        return 0.0
    r = distance_c / VARIANCE_SCALE_C
    return base * r * r


class Tangent:
    """
    The slope of a model's drift with respect to its model temperature, db/dS.

    Parameters
    ----------
    model : CompensationModel
        The model (its inputs, normalisation, linear tail and RBF terms are read once).

    """

    def __init__(self, model: Any) -> None:
        inputs: Sequence[str] = model.inputs
        t0 = float(model.t0_c)
        # The temperature terms: column and the effect's elementwise step function of d.
        self._terms = [(j, EFFECTS[eid].stream({}, t0)) for j, eid in enumerate(inputs)
                       if eid in STATE_TERMS]
        self._f = len(inputs)
        self._std, self._linear, self._centers, self._weights = (
            np.asarray(v, dtype=np.float64)
            for v in (model.input_std, model.linear, model.centers, model.weights))
        self._inv_w2 = 1.0 / np.asarray(model.widths, dtype=np.float64) ** 2

    def _gradient(self, d: Any) -> NDArray[np.float64]:
        """Return d x~ / dS per input (last axis) at ``d`` (degC, one value or an array)."""
        h = SLOPE_STEP_C
        g = np.zeros(np.shape(d) + (self._f,))
        for j, step in self._terms:
            g[..., j] = (step(0.0, 0.0, 0.0, d + h, False)
                         - step(0.0, 0.0, 0.0, d - h, False)) / (2.0 * h)
        return g / self._std

    def slope_one(self, row: NDArray[np.float64], d: float) -> NDArray[np.float64]:
        """
        Return db/dS (rad/s per degC) at one design row (the streaming form of :meth:`slope`).

        ``row`` is one row of :func:`gyro_tdc.model.compensation.rbf_design`, ``d`` its model
        temperature minus T0 (degC).
        """
        g = self._gradient(d)
        out = g @ self._linear
        if self._centers.shape[0]:
            f = self._f
            proj = row[1:1 + f] @ g - self._centers @ g
            out += (-row[1 + f:] * proj * self._inv_w2) @ self._weights
        return out

    def slope(self, design: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
        """
        Return db/dS per axis (rad/s per degC) at design rows whose temperature terms are at ``d``.

        ``design`` holds rows ``[1, x~, phi]`` of
        :func:`gyro_tdc.model.compensation.rbf_design` at the range end, ``d`` (degC) the
        model temperature minus T0 they were computed at.
        """
        g = self._gradient(np.asarray(d, dtype=np.float64))
        out = g @ self._linear
        if self._centers.shape[0]:
            f = self._f
            xn = design[:, 1:1 + f]
            phi = design[:, 1 + f:]
            # d phi_j / dS = -phi_j * sum_f (x~_f - c_jf) g_f / sigma_j^2
            proj = (xn * g).sum(axis=1)[:, None] - g @ self._centers.T
            out += (-phi * proj * self._inv_w2) @ self._weights
        return out


def range_shortfall(temp_range_c: Sequence[float],
                    operating_c: Sequence[float] = OPERATING_RANGE_C, *,
                    margin_c: float = 1.0) -> str:
    """
    Return what a trained range misses of a typical operating range ('' when it covers it).

    E.g. ``'12.0 degC below (-10 .. 2.0) and 8.5 degC above (41.5 .. 50)'``; a shortfall up
    to ``margin_c`` is not counted (a ramp that stops at 49.99 degC).
    """
    lo, hi = (float(v) for v in temp_range_c)
    want_lo, want_hi = (float(v) for v in operating_c)
    parts = []
    if math.isfinite(lo) and lo > want_lo + margin_c:
        parts.append(f'{lo - want_lo:.1f} degC below ({want_lo:g} .. {lo:.1f})')
    if math.isfinite(hi) and hi < want_hi - margin_c:
        parts.append(f'{want_hi - hi:.1f} degC above ({hi:.1f} .. {want_hi:g})')
    return ' and '.join(parts)
