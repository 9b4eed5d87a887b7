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
The effect library: named, physically described terms of the temperature drift.

Each :class:`Effect` in :data:`EFFECTS` carries its id, physics, exciting experiment,
parameters and feature, batch (:func:`batch_features`) and streaming
(:class:`StreamingFeatures`) alike; column layouts and effect groups are derived from the
catalog. Adding an effect is one entry and its tests. See ``doc/internals/model.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable, Mapping, Sequence

from gyro_tdc.errors import FeatureError
from gyro_tdc.model.lag import first_order_lag, lag_step
import numpy as np
from numpy.typing import NDArray

__all__ = ['EFFECT_IDS', 'EFFECTS', 'Effect', 'INPUT_ORDER', 'NONLINEAR_EFFECTS',
           'REFERENCE_EFFECTS', 'STATE_TERMS', 'STATIC_EFFECTS', 'Series', 'StreamStep',
           'StreamingFeatures', 'TEMPERATURE_EFFECTS', 'THERMAL_EFFECTS', 'batch_features',
           'input_ids', 'normalise_ids', 'resolve_params', 'with_implied']


@dataclass(frozen=True)
class Series:
    """The signals of one continuous run that batch features are computed from."""

    #: Stamps (N,), s (filters start at ``t[0]``).
    t: NDArray[np.float64]
    #: Measured temperature at each stamp (N,), degC.
    temp: NDArray[np.float64]
    #: Reference temperature, degC.
    t0: float
    #: The model temperature minus ``t0`` (N,), degC, the thermal state's or (without one)
    #: ``temp``'s.
    d: NDArray[np.float64]
    #: Power-on time, s.
    t_start: float


#: A batch feature: ``(series, params) -> column (N,)``.
BatchFeature = Callable[[Series, Mapping[str, float]], NDArray[np.float64]]
#: One streaming step: ``(t, dt_s, temp, d, first) -> value``, with ``dt_s`` the time since
#: the previous sample (0 on the first, ``first`` True), ``temp`` the measured temperature
#: and ``d`` the model temperature minus T0 (``temp - t0`` without a thermal state).
StreamStep = Callable[[float, float, float, float, bool], float]
#: Builds a fresh streaming step (its own filter state): ``(params, t0) -> StreamStep``.
StreamFactory = Callable[[Mapping[str, float], float], StreamStep]


@dataclass(frozen=True)
class Effect:
    """
    One physical effect of the catalog: its description, parameters, flags and feature.

    Training, discovery and the compensator all read an effect from here, so its batch and
    streaming forms and what identifies it are defined once.
    """

    #: Stable identifier (``dT``, ``lag``...).
    id: str
    #: The physics, in one or two sentences.
    description: str
    #: What the feature is, in symbols.
    feature: str
    #: The experiment that makes the effect visible.
    excited_by: str
    #: Parameter defaults (e.g. ``{'tau_s': 60.0}``).
    params: Mapping[str, float] = field(default_factory=dict)
    #: Parameters identified from data during training (others stay at their default).
    fitted: tuple[str, ...] = ()
    #: Search bounds (low, high) of the fitted parameters.
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    #: True when the feature is an input of the drift network (then ``batch`` and
    #: ``stream`` are given; ``bias`` and ``scale`` have neither).
    is_input: bool = True
    #: The feature over a run, ``batch(series, params) -> NDArray (N,)``.
    batch: BatchFeature | None = field(default=None, repr=False, compare=False)
    #: A fresh stateful step, ``stream(params, t0) -> step``, with ``step(t, dt_s, temp, d,
    #: first) -> float`` equal to ``batch`` sample by sample.
    stream: StreamFactory | None = field(default=None, repr=False, compare=False)
    #: No time memory, the effect depends on the current temperature (and rate) alone.
    #: False by default, the safe side: the compensator re-evaluates a model with any
    #: non-static effect at every sample.
    static: bool = False
    #: Identifiable only from data that span a range of temperatures.
    needs_span: bool = True
    #: Identifiable only with a non-zero reference rate (rate-table data).
    needs_reference: bool = False
    #: The effect is the thermal front end (``lag``), which in a model with a thermal state
    #: adds no column and makes every temperature term follow the lagged state; its
    #: ``batch``/``stream`` forms are the additive column of discovery's search.
    thermal: bool = False

    def __post_init__(self) -> None:
        """Check that the entry is complete and consistent."""
        forms = (self.batch is not None, self.stream is not None)
        if forms != (self.is_input, self.is_input):
            raise FeatureError(f'Effect {self.id!r}: a network input needs both a batch and a '
                               'streaming feature, a non-input neither.')
        missing = [k for k in self.fitted if k not in self.params or k not in self.bounds]
        if missing:
            raise FeatureError(f'Effect {self.id!r}: fitted parameter(s) {missing} need a '
                               'default and bounds.')


# ----------------------------------------------------------------------------- features
# Static effects: the streaming step is elementwise in d = T - T0, so the same function maps
# a whole run's arrays (batch) and one sample's floats (stream), in one call per sample.


def _static(step: StreamStep) -> dict:
    """Return the forms of a stateless step elementwise in ``d``, flagged ``static``."""
    return {'batch': lambda s, p: step(s.t, 0.0, s.temp, s.d, False),
            'stream': lambda p, t0: step, 'static': True}


# Lagged effects: a function ``out(T, T_lag, tau, T0)`` of the first-order-lagged
# temperature (tau_s), the lag run by first_order_lag (batch) or its recursion (streaming).


def _of_lag(out: Callable) -> dict:
    """Return both forms of a feature ``out(T, T_lag, tau, T0)`` of the lagged temperature."""
    def batch(s: Series, p: Mapping[str, float]) -> NDArray[np.float64]:
        tau = p['tau_s']
        return out(s.temp, first_order_lag(s.t, s.temp, tau), tau, s.t0)

    def stream(p: Mapping[str, float], t0: float) -> StreamStep:
        tau = p['tau_s']
        y = 0.0

        def step(t: float, dt_s: float, temp: float, d: float, first: bool) -> float:
            nonlocal y
            y = temp if first else lag_step(y, temp, dt_s, tau)
            return out(temp, y, tau, t0)
        return step
    return {'batch': batch, 'stream': stream}


def _warmup() -> dict:
    """Return both forms of ``exp(-(t - t_power_on) / tau_s)``."""
    def stream(p: Mapping[str, float], t0: float) -> StreamStep:
        tau = p['tau_s']
        start = 0.0

        def step(t: float, dt_s: float, temp: float, d: float, first: bool) -> float:
            nonlocal start
            start = t if first else start
            return math.exp(-(t - start) / tau)
        return step
    return {'batch': lambda s, p: np.exp(-(s.t - s.t_start) / p['tau_s']), 'stream': stream}


EFFECTS: dict[str, Effect] = {e.id: e for e in (
    Effect('bias', 'Zero-rate offset: the output at zero rate and the reference temperature.',
           '1', 'anything', is_input=False, static=True, needs_span=False),
    Effect('dT', 'Zero-rate level change vs temperature (paper eq. 18, alpha): the drive-mode '
           'resonance shifts as the silicon stiffness changes with temperature.',
           'dT = T - T0', 'a temperature span',
           **_static(lambda t, dt_s, temp, d, first: d)),
    Effect('dT2', 'Comb gap and capacitance deformation by thermal expansion (paper eq. 15): '
           'the sensing capacitance error grows with the square of the temperature change.',
           'dT^2', 'a temperature span (centred dT)',
           **_static(lambda t, dt_s, temp, d, first: d * d)),
    Effect('dT3', 'Higher-order curvature of the zero-rate level (the PX4/ArduPilot cubic).',
           'dT^3', 'a wide temperature span',
           **_static(lambda t, dt_s, temp, d, first: d * d * d)),
    Effect('dTdt', 'Thermal gradient across the die: the output depends on how fast the '
           'temperature changes, so heating and cooling differ (hysteresis).',
           'dT/dt of T smoothed by a first-order filter (tau_s), degC/s',
           'heating and cooling legs at varied rates', params={'tau_s': 60.0},
           **_of_lag(lambda temp, lag, tau, t0: (temp - lag) / tau)),
    Effect('lag', 'Heat conduction between the thermometer and the MEMS die (paper eq. 24): '
           'the die follows the measured temperature with a first-order lag tau_s, and the '
           'drift follows the die: every temperature term is of the lagged state.',
           'the model temperature is the first-order-lagged state (tau_s fitted), no column '
           'of its own (in the additive layout: the column dT of the lagged T)',
           'steps, soaks, heating and cooling', params={'tau_s': 120.0}, fitted=('tau_s',),
           bounds={'tau_s': (1.0, 20000.0)}, thermal=True,
           **_of_lag(lambda temp, lag, tau, t0: lag - t0)),
    Effect('scale', 'Sensitivity change vs temperature (paper eq. 18, beta): the scale factor '
           'is (1 + s dT); removed at run time from the measured rate, '
           'omega = (omega_raw - b) / (1 + s dT).',
           'dT * omega_ref (training); measured rate at run time',
           'rate-table steps at several rates and temperatures', is_input=False,
           static=True, needs_reference=True),
    Effect('warmup', 'Self-heating after power-on that the thermometer does not see: a drift '
           'that decays with the warm-up time constant tau_s.',
           'exp(-(t - t_power_on) / tau_s) (tau_s fitted)',
           'power-on at a fixed ambient temperature, then a soak',
           params={'tau_s': 300.0}, fitted=('tau_s',), bounds={'tau_s': (5.0, 20000.0)},
           needs_span=False, **_warmup()),
)}

#: Every effect id, in catalog order.
EFFECT_IDS: tuple[str, ...] = tuple(EFFECTS)
#: Order in which network inputs are laid out in a feature matrix (catalog order).
INPUT_ORDER: tuple[str, ...] = tuple(e.id for e in EFFECTS.values() if e.is_input)
#: Effects without time memory: a function of the current temperature (and rate) only.
STATIC_EFFECTS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.static)
#: Effects with fitted parameters (the lag and warm-up time constants): the feature is
#: nonlinear in them, so a fit searches them around the linear solve.
NONLINEAR_EFFECTS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.fitted)
#: Effects identifiable only from data that span a range of temperatures.
TEMPERATURE_EFFECTS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.needs_span)
#: Effects identifiable only with a non-zero reference rate.
REFERENCE_EFFECTS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.needs_reference)
#: The thermal front end (``lag``): with a thermal state, no column; the state follows it.
THERMAL_EFFECTS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.thermal)
#: The temperature terms (static inputs: ``dT``, ``dT2``, ``dT3``): of the state when there
#: is one.
STATE_TERMS: frozenset[str] = frozenset(e.id for e in EFFECTS.values() if e.static and e.is_input)


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
        raise FeatureError(f'Unknown effect id(s) {", ".join(map(repr, unknown))}; '
                           f'expected some of {", ".join(EFFECTS)}.')
    return tuple(i for i in EFFECTS if i in set(ids))


def input_ids(ids: Sequence[str], *, state: bool = False) -> tuple[str, ...]:
    """
    Return the ids among ``ids`` that are inputs of the drift network, in layout order.

    With ``state`` (a thermal state) the ``thermal`` effect (``lag``) is no column; without, it
    is a column of its own (the additive layout of discovery's search).
    """
    return tuple(i for i in normalise_ids(ids) if EFFECTS[i].is_input
                 and not (state and EFFECTS[i].thermal))


def with_implied(ids: str | Sequence[str]) -> tuple[str, ...]:
    """
    Return ``ids`` (catalog order) with ``dT`` added when ``lag`` has no temperature term.

    With a thermal state ``lag`` only says that the drift follows the lagged state; asked for
    alone it is the linear model, ``dT`` of the state.
    """
    ids = normalise_ids(ids)
    if THERMAL_EFFECTS & set(ids) and not STATE_TERMS & set(ids):
        ids = normalise_ids(ids + ('dT',))
    return ids


def resolve_params(ids: Sequence[str], params: Mapping[str, Mapping[str, float]] | None = None
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
    out: dict[str, dict[str, float]] = {}
    for eid in normalise_ids(ids):
        eff = EFFECTS[eid]
        given = dict((params or {}).get(eid, {}))
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


def batch_features(ids: Sequence[str], t: NDArray[np.float64], temp: NDArray[np.float64], *,
                   t0: float, params: Mapping[str, Mapping[str, float]] | None = None,
                   t_start: float | None = None, state: NDArray[np.float64] | None = None
                   ) -> NDArray[np.float64]:
    """
    Compute the network-input features of one run, one column per :func:`input_ids` entry.

    ``t`` (s) are the stamps of one continuous run (filters start at ``t[0]``; ``warmup``
    at ``t_start``, default ``t[0]``), ``temp`` the measured temperature, ``t0`` the
    reference (degC), ``params`` the effect parameters (default the catalog's). With
    ``state`` (the model temperature, clamped when the model clamps) the temperature terms
    are of it and ``lag`` adds no column; None: the additive layout, features of ``temp``.
    """
    t, temp = np.asarray(t, dtype=np.float64), np.asarray(temp, dtype=np.float64)
    if t.shape != temp.shape or t.ndim != 1:
        raise ValueError(f'Expected `t` and `temp` of equal shape (N,), got {t.shape} and '
                         f'{temp.shape}.')
    if state is not None:
        state = np.asarray(state, dtype=np.float64)
        if state.shape != temp.shape:
            raise ValueError(f'Expected `state` of shape {temp.shape} like `temp`, '
                             f'got {state.shape}.')
    cols = input_ids(ids, state=state is not None)
    p = resolve_params(cols, params)
    out = np.empty((t.shape[0], len(cols)))
    start = t[0] if t_start is None and t.shape[0] else (t_start or 0.0)
    d = (temp if state is None else state) - t0
    series = Series(t=t, temp=temp, t0=t0, d=d, t_start=start)
    for j, eid in enumerate(cols):
        out[:, j] = EFFECTS[eid].batch(series, p.get(eid, {}))
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
    state : bool
        :meth:`update` receives the thermal state (see :func:`batch_features`).

    """

    def __init__(self, ids: Sequence[str], *, t0: float,
                 params: Mapping[str, Mapping[str, float]] | None = None,
                 state: bool = False) -> None:
        self.ids = input_ids(ids, state=state)
        self.state = bool(state)
        self.t0 = float(t0)
        self.params = resolve_params(self.ids, params)
        self.reset()

    def reset(self) -> None:
        """Forget the filter states (a new run starts with the next sample)."""
        self._t_prev: float | None = None
        self._steps = [EFFECTS[eid].stream(self.params.get(eid, {}), self.t0) for eid in self.ids]

    def update(self, t: float, temp: float, state: float | None = None) -> NDArray[np.float64]:
        """
        Advance to stamp ``t`` (s) with temperature ``temp`` (degC); return the features.

        A stamp not after the previous one leaves the filters unchanged. ``state`` is the
        thermal state at ``t`` (degC; required when built with ``state=True``, else ignored).
        """
        first = self._t_prev is None
        dt_s = 0.0 if first else max(t - self._t_prev, 0.0)
        self._t_prev = t if first else max(t, self._t_prev)
        if self.state and state is None:
            raise ValueError('Expected the thermal `state` (features built with state=True).')
        d = (state if self.state else temp) - self.t0
        return np.array([step(t, dt_s, temp, d, first) for step in self._steps], dtype=np.float64)
