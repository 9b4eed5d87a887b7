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
A model validated by what it computes: bounded parameters and a bounded drift.

A model file can pass every shape and finiteness check and still compute Inf, NaN or
1e300 rad/s (its ``model_id`` is a public hash, so a crafted file carries a matching one);
:func:`check_model`, run on every load, refuses such a model in one line.
"""

from __future__ import annotations

from contextlib import contextmanager
import itertools
from typing import Any, Iterator, Sequence

from gyro_tdc.base import (MAX_ACCEL_DRIFT_MPS2, MAX_DRIFT_RAD_S, MAX_TEMP_RATE_C_S,
                           TEMP_PLAUSIBLE_C)
from gyro_tdc.errors import FeatureError, ModelFileError
from gyro_tdc.model.compensation import CompensationModel, rbf_design
from gyro_tdc.model.effects import EFFECTS
from gyro_tdc.model.out_of_range import MAX_EXTRAPOLATION_C, Tangent
import numpy as np
from numpy.typing import NDArray

__all__ = ['GAIN_BOUNDS', 'MAX_PARAM', 'MIN_INPUT_STD', 'MIN_WIDTH', 'TAU_BOUNDS_S',
           'check_accel', 'check_model', 'drift_grid', 'reworded']

#: Smallest input standard deviation (in the feature's own unit): 1/std scales every input.
MIN_INPUT_STD = 1e-9
#: Smallest RBF width (normalised input units): 1/width^2 scales the squared distances.
MIN_WIDTH = 1e-6
#: Largest magnitude of an input mean or std, a centre, a width, a weight, the intercept or a
#: linear-tail entry (weights in the output's unit, rad/s or m/s^2): far beyond any fitted
#: model (a ``dT3`` mean over the plausible span reaches 3e7), small enough that nothing a
#: model computes overflows.
MAX_PARAM = 1e9
#: Range of the sensitivity gain ``1 + scale dT`` (compensation divides by it).
GAIN_BOUNDS = (0.5, 2.0)
#: Range of an effect's time constant ``tau_s``, s.
TAU_BOUNDS_S = (1e-3, 1e8)
#: Model temperatures on the grid (besides the range ends and the centres' own points).
_GRID_TEMPS = 257
#: Values of each dynamic input on the grid.
_GRID_DYNAMIC = 5
#: Rows evaluated at once.
_CHUNK = 1024
#: Centres (those of the largest weights) whose own points are evaluated.
_MAX_OWN = 512
#: Grid rows times centres evaluated term by term (fewer temperatures for a large model).
_BUDGET = 20_000_000


def check_model(model: CompensationModel) -> None:
    """
    Check that a model's parameters are bounded and its drift finite and plausible.

    For a model built from a file (shapes and finiteness checked); the bounds are listed in
    ``doc/model_file.md`` ("Limits on what a model holds").

    Raises
    ------
    ModelFileError
        One line naming the field or what the model computes, and the bound.

    """
    with np.errstate(all='ignore'):          # overflow shows as a value out of bounds
        _check_part(model, MAX_DRIFT_RAD_S, 'rad/s', 'residual_var_rad2_s2')
        if model.accel is not None:
            check_accel(model.accel)


@contextmanager
def reworded(prefix: str, error: type[Exception] = FeatureError) -> Iterator[None]:
    """Re-raise an ``error`` raised inside as one ModelFileError line ``PREFIX: MESSAGE``."""
    try:
        yield
    except error as exc:
        raise ModelFileError(f'{prefix}: {exc}') from None


def check_accel(part: CompensationModel) -> None:
    """Check an accelerometer part as :func:`check_model` does (its line names `accel`)."""
    with np.errstate(all='ignore'), reworded('field `accel`', ModelFileError):
        _check_part(part, MAX_ACCEL_DRIFT_MPS2, 'm/s^2', 'residual_var_m2_s4')


def _check_part(m: CompensationModel, bound: float, unit: str, resid: str) -> None:
    """Check one part (the gyro model, or its accelerometer part) against ``bound``."""
    lo_c, hi_c = TEMP_PLAUSIBLE_C
    if not lo_c <= m.t0_c <= hi_c:
        raise ModelFileError(f'field `t0_c` must lie within the plausible temperatures '
                             f'{lo_c:g} .. {hi_c:g} degC, got {m.t0_c:g}')
    lo, hi = m.temp_range_c
    if not (lo_c <= lo and hi <= hi_c):
        raise ModelFileError(f'field `temp_range_c` must lie within the plausible '
                             f'temperatures {lo_c:g} .. {hi_c:g} degC, got [{lo:g}, {hi:g}]')
    _at_least(m.input_std, MIN_INPUT_STD, 'normalization.std', 'it divides every input')
    _at_least(m.widths, MIN_WIDTH, 'widths', 'normalised input units')
    for name, arr, what in (('normalization.mean', m.input_mean, ''),
                            ('normalization.std', m.input_std, ''),
                            ('centers', m.centers, ' (normalised input units)'),
                            ('widths', m.widths, ' (normalised input units)'),
                            ('weights', m.weights, f' {unit}'),
                            ('intercept', m.intercept, f' {unit}'),
                            ('linear', m.linear, f' {unit}')):
        _at_most(arr, MAX_PARAM, name, what)
    _at_most(m.residual_var, bound * bound, resid, f' ({unit})^2, the square of the drift bound,')
    _check_taus(m)
    ext = MAX_EXTRAPOLATION_C
    d_ends = np.array([lo - ext, hi + ext]) - m.t0_c
    gain = 1.0 + d_ends[:, None] * m.scale[None, :]
    g_lo, g_hi = GAIN_BOUNDS
    bad = ~((gain >= g_lo) & (gain <= g_hi))
    if bad.any():
        i, axis = np.argwhere(bad)[0]
        raise ModelFileError(f'field `scale` ({m.scale[axis]:g} 1/degC, axis {"xyz"[axis]}) '
                             f'makes the gain 1 + scale*dT {gain[i, axis]:.3g} at '
                             f'{d_ends[i] + m.t0_c:g} degC, outside {g_lo:g} .. {g_hi:g} '
                             f'(compensation divides by it; the range plus the '
                             f'{ext:g} degC extrapolation limit)')
    for where, b in _drifts(m, bound):
        big = ~(np.abs(b) <= bound)
        if big.any():
            row, axis = np.argwhere(big)[0]
            raise ModelFileError(f'the drift it computes is {b[row, axis]:.3g} {unit} '
                                 f'(axis {"xyz"[axis]}) {where(row)}, beyond the plausible '
                                 f'{bound:g} {unit}')


def _refuse(bad: NDArray[np.bool_], arr: NDArray[np.float64], name: str, must: str) -> None:
    """Refuse the first entry of ``arr`` where ``bad``: field ``name`` must be ``must``."""
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ModelFileError(f'field `{name}` must be {must}, got {arr[idx]:.3g} at {list(idx)}')


def _at_least(arr: NDArray[np.float64], floor: float, name: str, why: str) -> None:
    """Refuse an entry of ``arr`` below ``floor``."""
    _refuse(~(arr >= floor), arr, name, f'at least {floor:g} ({why})')


def _at_most(arr: NDArray[np.float64], limit: float, name: str, unit: str) -> None:
    """Refuse an entry of ``arr`` whose magnitude exceeds ``limit``."""
    _refuse(~(np.abs(arr) <= limit), arr, name, f'within +-{limit:g}{unit}')


def _check_taus(m: CompensationModel) -> None:
    """Refuse a time constant of an effect or of the thermal state outside TAU_BOUNDS_S."""
    lo, hi = TAU_BOUNDS_S
    taus = [(f'effect_params.{eid}.{k}', v) for eid, p in m.effect_params.items()
            for k, v in p.items()]
    taus += [(f'thermal.tau_s[{i}]', v) for i, v in enumerate(m.thermal.tau_s)]
    for name, v in taus:
        if not lo <= v <= hi:
            raise ModelFileError(f'field `{name}` must lie within {lo:g} .. {hi:g} s, got {v:g}')


def drift_grid(m: CompensationModel, *, ext: float = MAX_EXTRAPOLATION_C,
               own: Sequence[int] | None = None, n_temps: int = _GRID_TEMPS
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the feature rows :func:`check_model` evaluates, and their model temperature.

    Model temperatures from the range's low end minus ``ext`` to its high end plus ``ext``,
    with the dynamic inputs over what they plausibly take (``dTdt`` within
    +-``MAX_TEMP_RATE_C_S``, ``warmup`` 0 .. 1, an additive ``lag`` column over the range), in
    every combination; and every RBF centre's own point (its dynamic coordinates, at the
    temperatures where the temperature terms reach it), so a narrow peak between grid
    points is seen too.

    Parameters
    ----------
    m : CompensationModel
        The model (or an accelerometer part).
    ext : float, degC
        How far beyond the trained range the grid reaches.
    own : sequence of int, optional
        The centres whose own points are added (default: all; ``()``: the grid alone).
    n_temps : int
        Model temperatures on the grid, besides the range ends.

    Returns
    -------
    x : NDArray[np.float64], shape (N, F)
        Raw feature rows (the model's inputs, in column order).
    s : NDArray[np.float64], shape (N,), degC
        The model temperature of each row.

    """
    lo, hi = m.temp_range_c
    t0 = float(m.t0_c)
    inputs = m.inputs
    known = {'dTdt': (-MAX_TEMP_RATE_C_S, MAX_TEMP_RATE_C_S), 'warmup': (0.0, 1.0),
             'lag': (lo - ext - t0, hi + ext - t0)}
    dyn_cols = _dynamic(inputs)
    fixed = [j for j in range(len(inputs)) if j not in dyn_cols]     # the temperature terms
    # Another dynamic effect: the values it took in training, mean +- 4 std.
    values = [np.linspace(*known.get(inputs[j], (m.input_mean[j] - 4.0 * m.input_std[j],
                                                 m.input_mean[j] + 4.0 * m.input_std[j])),
                          _GRID_DYNAMIC) for j in dyn_cols]
    # The grid: model temperatures x every combination of the dynamic inputs' values.
    temps = np.concatenate([np.linspace(lo - ext, hi + ext, n_temps), [lo, hi]])
    combos = np.array(list(itertools.product(*values)), dtype=np.float64)
    s = np.repeat(temps, combos.shape[0])
    dyn = np.tile(combos, (temps.size, 1))
    # Every centre's own point: the dynamic inputs at its coordinates (clipped to what
    # they plausibly take), the temperature where each temperature term reaches it.
    picked = np.arange(m.n_centers) if own is None else np.asarray(own, dtype=np.intp)
    raw = m.input_mean + m.centers[picked] * m.input_std   # raw feature units
    at = np.clip(raw[:, dyn_cols], [v[0] for v in values], [v[-1] for v in values])
    for j in fixed:
        for d in _roots(inputs[j], raw[:, j]):
            s = np.concatenate([s, np.clip(d + t0, lo - ext, hi + ext)])
            dyn = np.vstack([dyn, at])
    x = np.empty((s.size, len(inputs)))
    x[:, dyn_cols] = dyn
    for j in fixed:
        x[:, j] = EFFECTS[inputs[j]].stream({}, t0)(0.0, 0.0, 0.0, s - t0, False)
    return x, s


def _dynamic(inputs: tuple[str, ...]) -> list[int]:
    """Return the columns of the inputs with time memory (not a function of dT alone)."""
    return [j for j, eid in enumerate(inputs) if not EFFECTS[eid].static]


def _roots(eid: str, v: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """Return dT values at which the temperature term ``eid`` equals (or is nearest) ``v``."""
    if eid == 'dT':
        return [v]
    if eid == 'dT2':
        r = np.sqrt(np.maximum(v, 0.0))
        return [r, -r]
    return [np.cbrt(v)]         # dT3 (STATE_TERMS are dT, dT2 and dT3)


def _drifts(m: CompensationModel, bound: float) -> Iterator[tuple[Any, NDArray[np.float64]]]:
    """
    Yield (row describer, drift) blocks: the grid, then the linear tangents' far ends.

    A Gaussian term is at most 1, so the RBF terms add at most the sum of their weights'
    magnitudes anywhere: when the intercept and linear tail on the grid plus that sum stay
    within ``bound``, the whole drift does, and the grid is not evaluated term by term (a
    fitted model's weights are small). Otherwise it is, with the own points of the
    ``_MAX_OWN`` centres of the largest weights (and, for a large model, fewer grid
    temperatures: at most ``_BUDGET`` rows times centres).
    """
    lo, hi = m.temp_range_c
    ext = MAX_EXTRAPOLATION_C
    x, s = drift_grid(m, own=())
    coef = m.coefficients
    dyn_cols = _dynamic(m.inputs)

    def describe(xs: NDArray[np.float64], ss: NDArray[np.float64], note: str = '') -> Any:
        return lambda row: f'at {ss[row]:.4g} degC{note}' + ''.join(
            f', {m.inputs[j]} {xs[row, j]:.3g}' for j in dyn_cols)

    tail = m.intercept + ((x - m.input_mean) / m.input_std) @ m.linear
    spread = np.abs(m.weights).sum(axis=0)
    if not np.all(np.abs(tail).max(axis=0, initial=0.0) + spread <= bound):
        top = np.argsort(-np.abs(m.weights).max(axis=1), kind='stable')[:_MAX_OWN]
        per_temp = max(_GRID_DYNAMIC ** len(dyn_cols) * m.n_centers, 1)
        n = int(np.clip(_BUDGET // per_temp, 65, _GRID_TEMPS))
        xa, sa = drift_grid(m, own=top, n_temps=n)
        for i in range(0, sa.size, _CHUNK):
            xs, ss = xa[i:i + _CHUNK], sa[i:i + _CHUNK]
            yield describe(xs, ss), rbf_design(m, xs) @ coef
    # The ``linear`` policy: the tangent at each range end, followed out to the limit.
    tangent = Tangent(m)
    for end, sign in ((lo, -1.0), (hi, 1.0)):
        rows = s == end
        xs, ss = x[rows], s[rows]
        design = rbf_design(m, xs)
        slope = tangent.slope(design, ss - m.t0_c)
        yield (describe(xs, ss + sign * ext, ' (along the linear policy tangent)'),
               design @ coef + sign * ext * slope)
