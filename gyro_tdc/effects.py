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
The effect catalog: named, physically described terms of the temperature drift.

Each effect has a stable id (used in model files and on the command line), a physical
description, the experiment that excites it, its parameters with defaults, and a feature
computed in two forms that agree to floating-point precision:

* batch, :func:`batch_features`, over a whole run (training, evaluation, discovery);
* streaming, :class:`StreamingFeatures`, one sample at a time (the compensator node).

Two effects are not inputs of the drift network: ``bias`` is the constant term every model
has, and ``scale`` multiplies the true rate (sensitivity change, handled by the model).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Mapping, Sequence

from gyro_tdc.errors import FeatureError
import numpy as np
from numpy.typing import NDArray

__all__ = [
    'EFFECTS', 'Effect', 'StreamingFeatures', 'batch_features', 'first_order_lag',
    'input_ids', 'normalise_ids', 'resolve_params',
]


@dataclass(frozen=True)
class Effect:
    """
    One physical effect of the catalog.

    Parameters
    ----------
    id : str
        Stable identifier (``dT``, ``lag``...).
    description : str
        The physics, in one or two sentences.
    feature : str
        What the feature is, in symbols.
    excited_by : str
        The experiment that makes the effect visible.
    params : Mapping[str, float]
        Parameter defaults (e.g. ``{'tau_s': 60.0}``).
    fitted : tuple of str
        Parameters identified from data during training (others stay at their default).
    bounds : Mapping[str, tuple of float]
        Search bounds of the fitted parameters.
    is_input : bool
        True when the feature is an input of the drift network.

    """

    id: str
    description: str
    feature: str
    excited_by: str
    params: Mapping[str, float] = field(default_factory=dict)
    fitted: tuple[str, ...] = ()
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    is_input: bool = True


EFFECTS: dict[str, Effect] = {e.id: e for e in (
    Effect('bias', 'Zero-rate offset: the output at zero rate and the reference temperature.',
           '1', 'anything', is_input=False),
    Effect('dT', 'Zero-rate level change vs temperature (paper eq. 18, alpha): the drive-mode '
           'resonance shifts as the silicon stiffness changes with temperature.',
           'dT = T - T0', 'a temperature span'),
    Effect('dT2', 'Comb gap and capacitance deformation by thermal expansion (paper eq. 15): '
           'the sensing capacitance error grows with the square of the temperature change.',
           'dT^2', 'a temperature span (centred dT)'),
    Effect('dT3', 'Higher-order curvature of the zero-rate level (the PX4/ArduPilot cubic).',
           'dT^3', 'a wide temperature span'),
    Effect('dTdt', 'Thermal gradient across the die: the output depends on how fast the '
           'temperature changes, so heating and cooling differ (hysteresis).',
           'dT/dt of T smoothed by a first-order filter (tau_s), degC/s',
           'heating and cooling legs at varied rates', params={'tau_s': 60.0}),
    Effect('lag', 'Heat conduction between the thermometer and the MEMS die (paper eq. 24): '
           'the die follows the measured temperature with a first-order lag tau_s.',
           'dT of the first-order-lagged T (tau_s fitted)',
           'steps, soaks, heating and cooling', params={'tau_s': 120.0}, fitted=('tau_s',),
           bounds={'tau_s': (1.0, 20000.0)}),
    Effect('scale', 'Sensitivity change vs temperature (paper eq. 18, beta): the scale factor '
           'is (1 + s dT); removed at run time from the measured rate, '
           'omega = (omega_raw - b) / (1 + s dT).',
           'dT * omega_ref (training); measured rate at run time',
           'rate-table steps at several rates and temperatures', is_input=False),
    Effect('warmup', 'Self-heating after power-on that the thermometer does not see: a drift '
           'that decays with the warm-up time constant tau_s.',
           'exp(-(t - t_power_on) / tau_s) (tau_s fitted)',
           'power-on at a fixed ambient temperature, then a soak',
           params={'tau_s': 300.0}, fitted=('tau_s',), bounds={'tau_s': (5.0, 20000.0)}),
)}

#: Order in which network inputs are laid out in a feature matrix.
_INPUT_ORDER = ('dT', 'dT2', 'dT3', 'dTdt', 'lag', 'warmup')


def normalise_ids(ids: str | Sequence[str]) -> tuple[str, ...]:
    """
    Parse and check a list of effect ids.

    Parameters
    ----------
    ids : str or sequence of str
        Ids, or one comma-separated string such as ``'dT,dT2'``.

    Returns
    -------
    tuple of str
        The unique ids in catalog order.

    """
    if isinstance(ids, str):
        ids = [s.strip() for s in ids.split(',') if s.strip()]
    unknown = [i for i in ids if i not in EFFECTS]
    if unknown:
        raise FeatureError(
            f'Unknown effect id(s) {", ".join(map(repr, unknown))}; '
            f'expected some of {", ".join(EFFECTS)}.')
    return tuple(i for i in EFFECTS if i in set(ids))


def input_ids(ids: Sequence[str]) -> tuple[str, ...]:
    """Return the ids among ``ids`` that are inputs of the drift network, in layout order."""
    chosen = set(normalise_ids(ids))
    return tuple(i for i in _INPUT_ORDER if i in chosen)


def resolve_params(ids: Sequence[str],
                   params: Mapping[str, Mapping[str, float]] | None = None
                   ) -> dict[str, dict[str, float]]:
    """
    Merge parameter values over the catalog defaults and check them.

    Parameters
    ----------
    ids : sequence of str
        Effect ids.
    params : mapping, optional
        ``{effect_id: {param: value}}`` overrides.

    Returns
    -------
    dict
        ``{effect_id: {param: value}}`` for every id with parameters.

    """
    params = params or {}
    out: dict[str, dict[str, float]] = {}
    for eid in normalise_ids(ids):
        eff = EFFECTS[eid]
        given = dict(params.get(eid, {}))
        extra = set(given) - set(eff.params)
        if extra:
            raise FeatureError(f'Effect {eid!r} has no parameter(s) {sorted(extra)}; '
                               f'expected {sorted(eff.params)}.')
        if eff.params:
            merged = {k: float(given.get(k, v)) for k, v in eff.params.items()}
            for k, v in merged.items():
                if not math.isfinite(v) or v <= 0.0:
                    raise FeatureError(f'Parameter {eid}.{k} must be a positive finite number, '
                                       f'got {v!r}.')
            out[eid] = merged
    return out


def first_order_lag(t: NDArray[np.float64], u: NDArray[np.float64],
                    tau: float) -> NDArray[np.float64]:
    """
    Filter ``u`` through a first-order lag with time constant ``tau`` on stamps ``t``.

    The recursion is ``y[0] = u[0]``, ``y[k] = a_k y[k-1] + (1 - a_k) u[k]`` with
    ``a_k = exp(-(t[k] - t[k-1]) / tau)``, exactly what :class:`StreamingFeatures` does one
    sample at a time. It is evaluated as a parallel prefix scan in numpy, so irregular stamps
    cost no Python loop.

    Parameters
    ----------
    t : NDArray[np.float64], shape (N,), s
        Stamps, non-decreasing.
    u : NDArray[np.float64], shape (N,)
        Input signal.
    tau : float, s
        Time constant, > 0.

    Returns
    -------
    NDArray[np.float64], shape (N,)
        The lagged signal.

    """
    u = np.asarray(u, dtype=np.float64)
    n = u.shape[0]
    y = np.empty(n)
    if n == 0:
        return y
    y[0] = u[0]
    if n == 1:
        return y
    a = np.exp(-np.maximum(np.diff(np.asarray(t, dtype=np.float64)), 0.0) / tau)
    b = (1.0 - a) * u[1:]
    shift = 1
    m = a.shape[0]
    while shift < m:
        b[shift:] = a[shift:] * b[:-shift] + b[shift:]
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
        if shift < m and a[shift - 1:].max() < 1e-17:
            break
    y[1:] = a * u[0] + b
    return y


def batch_features(ids: Sequence[str], t: NDArray[np.float64], temp: NDArray[np.float64], *,
                   t0: float, params: Mapping[str, Mapping[str, float]] | None = None,
                   t_start: float | None = None) -> NDArray[np.float64]:
    """
    Compute the network-input features of one run.

    Parameters
    ----------
    ids : sequence of str
        Effect ids; only the network inputs (see :func:`input_ids`) produce columns.
    t : NDArray[np.float64], shape (N,), s
        Stamps of one continuous run (filters start at ``t[0]``).
    temp : NDArray[np.float64], shape (N,), degC
        Temperature at each stamp.
    t0 : float, degC
        Reference temperature.
    params : mapping, optional
        Effect parameters (defaults from the catalog).
    t_start : float, optional, s
        Power-on time for ``warmup`` (default ``t[0]``).

    Returns
    -------
    NDArray[np.float64], shape (N, F)
        One column per input id in :func:`input_ids` order.

    """
    t = np.asarray(t, dtype=np.float64)
    temp = np.asarray(temp, dtype=np.float64)
    if t.shape != temp.shape or t.ndim != 1:
        raise ValueError(f'Expected `t` and `temp` of equal shape (N,), got {t.shape} and '
                         f'{temp.shape}.')
    cols = input_ids(ids)
    p = resolve_params(cols, params)
    out = np.empty((t.shape[0], len(cols)))
    dt_ = temp - t0
    for j, eid in enumerate(cols):
        if eid == 'dT':
            out[:, j] = dt_
        elif eid == 'dT2':
            out[:, j] = dt_ * dt_
        elif eid == 'dT3':
            out[:, j] = dt_ * dt_ * dt_
        elif eid == 'dTdt':
            tau = p[eid]['tau_s']
            out[:, j] = (temp - first_order_lag(t, temp, tau)) / tau
        elif eid == 'lag':
            out[:, j] = first_order_lag(t, temp, p[eid]['tau_s']) - t0
        elif eid == 'warmup':
            start = t[0] if t_start is None and t.shape[0] else (t_start or 0.0)
            out[:, j] = np.exp(-(t - start) / p[eid]['tau_s'])
    return out


class StreamingFeatures:
    """
    Compute the same features as :func:`batch_features`, one sample at a time.

    Parameters
    ----------
    ids : sequence of str
        Effect ids.
    t0 : float, degC
        Reference temperature.
    params : mapping, optional
        Effect parameters (defaults from the catalog).

    """

    def __init__(self, ids: Sequence[str], *, t0: float,
                 params: Mapping[str, Mapping[str, float]] | None = None) -> None:
        self.ids = input_ids(ids)
        self.t0 = float(t0)
        self.params = resolve_params(self.ids, params)
        self.reset()

    def reset(self) -> None:
        """Forget the filter states (a new run starts with the next sample)."""
        self._t_prev: float | None = None
        self._t_start = 0.0
        self._lag: dict[str, float] = {}

    def update(self, t: float, temp: float) -> NDArray[np.float64]:
        """
        Advance to stamp ``t`` with temperature ``temp`` and return the feature vector.

        Parameters
        ----------
        t : float, s
            Stamp; a stamp not after the previous one leaves the filters unchanged.
        temp : float, degC
            Temperature at ``t``.

        Returns
        -------
        NDArray[np.float64], shape (F,)
            The features in :func:`input_ids` order.

        """
        first = self._t_prev is None
        dt_s = 0.0 if first else max(t - self._t_prev, 0.0)
        if first:
            self._t_start = t
        self._t_prev = t if first else max(t, self._t_prev)
        out = np.empty(len(self.ids))
        d = temp - self.t0
        for j, eid in enumerate(self.ids):
            if eid == 'dT':
                out[j] = d
            elif eid == 'dT2':
                out[j] = d * d
            elif eid == 'dT3':
                out[j] = d * d * d
            elif eid in ('dTdt', 'lag'):
                tau = self.params[eid]['tau_s']
                if first:
                    y = temp
                else:
                    a = math.exp(-dt_s / tau)
                    y = a * self._lag[eid] + (1.0 - a) * temp
                self._lag[eid] = y
                out[j] = (temp - y) / tau if eid == 'dTdt' else y - self.t0
            elif eid == 'warmup':
                out[j] = math.exp(-(t - self._t_start) / self.params[eid]['tau_s'])
        return out
