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
The compensation model: features of the temperature history -> per-axis drift.

:class:`CompensationModel` is the fitted model (RBF network or polynomial over the effect
features, optional scale term, thermal front end, accelerometer part); :func:`drift` and
:func:`compensate` evaluate it over a run, :class:`StreamingCompensator` one sample at a
time. The equations and the model temperature: ``doc/internals/model.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
import hashlib
import json
import math
from typing import Any, ClassVar

from gyro_tdc.base import plain
from gyro_tdc.errors import FeatureError
from gyro_tdc.model.effects import batch_features, input_ids, StreamingFeatures, THERMAL_EFFECTS
from gyro_tdc.model.out_of_range import check_policy, MAX_EXTRAPOLATION_C, split, Tangent
from gyro_tdc.model.thermal_state import ThermalState
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['CompensationModel', 'FORMAT_VERSION', 'StreamingCompensator', 'compensate', 'drift',
           'model_temperature', 'predict_drift', 'rbf_design', 'static_slope', 'steady_drift']

KINDS = ('rbf', 'poly')
#: The model-file format every model is (:mod:`gyro_tdc.model.modelfile` writes and reads it).
FORMAT_VERSION = 2


@dataclass(frozen=True, eq=False)
class CompensationModel:
    """
    A fitted temperature-drift compensation model (immutable data).

    Parameters
    ----------
    kind : str
        ``'rbf'`` (Gaussian RBF network with a linear tail) or ``'poly'`` (linear in the
        features; the PX4-style cubic when the features are ``dT, dT2, dT3``).
    features : tuple of str
        Effect ids of the model, in catalog order (``bias`` is always implied).
    effect_params : dict
        ``{effect_id: {param: value}}`` (e.g. the warm-up ``tau_s``). With a thermal state,
        ``lag.tau_s`` mirrors the state's total time constant
        (``thermal.tau_total_s``).
    t0_c : float, degC
        Reference temperature T0.
    input_mean, input_std : NDArray[np.float64], shape (F,)
        Normalisation of the network inputs.
    centers : NDArray[np.float64], shape (K, F)
        RBF centres in normalised input space.
    widths : NDArray[np.float64], shape (K,)
        RBF widths sigma_j in normalised input space.
    weights : NDArray[np.float64], shape (K, 3), rad/s
        RBF output weights per axis.
    intercept : NDArray[np.float64], shape (3,), rad/s
        Constant term w_0 (the ``bias`` effect).
    linear : NDArray[np.float64], shape (F, 3), rad/s
        Linear tail per normalised input and axis.
    scale : NDArray[np.float64], shape (3,), 1/degC
        Sensitivity change s per axis (zeros when ``scale`` is not modelled).
    temp_range_c : tuple of float, degC
        Range of the model temperature (the thermal state) over the training data.
    residual_var : NDArray[np.float64], shape (3,), (rad/s)^2
        Variance of the training residual per axis.
    frame_id : str
        Frame of the gyro the model was fitted for.
    sensor_id : str
        Free-form sensor identifier.
    metrics : dict
        Training metrics (plain types).
    created : dict
        Creation info (UTC time, gyro_tdc version, command, data).
    thermal : ThermalState
        The thermal front end: kind ``none`` (the default) when the model has no ``lag``,
        else ``first_order`` or ``two_node``.
    accel : CompensationModel, optional
        The accelerometer part: the same thermal front end and T0, output
        in m/s^2, ``residual_var`` in (m/s^2)^2, ``scale`` zero, zero at T0
        (:mod:`gyro_tdc.identify`). None: the model compensates the gyro only.

    """

    kind: str
    features: tuple[str, ...]
    effect_params: dict
    t0_c: float
    input_mean: NDArray[np.float64]
    input_std: NDArray[np.float64]
    centers: NDArray[np.float64]
    widths: NDArray[np.float64]
    weights: NDArray[np.float64]
    intercept: NDArray[np.float64]
    linear: NDArray[np.float64]
    scale: NDArray[np.float64]
    temp_range_c: tuple[float, float]
    residual_var: NDArray[np.float64]
    frame_id: str = 'imu_link'
    sensor_id: str = ''
    metrics: dict = field(default_factory=dict, compare=False)
    created: dict = field(default_factory=dict, compare=False)
    thermal: ThermalState = ThermalState()
    accel: 'CompensationModel | None' = None

    def __post_init__(self) -> None:
        """Check that the thermal front end agrees with the features."""
        th = self.thermal
        if not isinstance(th, ThermalState):
            raise FeatureError(f'`thermal` must be a ThermalState, got {type(th).__name__}')
        if self.accel is not None:
            self._check_accel()
        if bool(THERMAL_EFFECTS & set(self.features)) != (th.kind != 'none'):     # lagged
            raise FeatureError(f'thermal kind {th.kind!r} does not match the features '
                               f'{list(self.features)}: `lag` goes with a lagged state '
                               '(first_order, two_node), no `lag` with kind none')
        for eid in THERMAL_EFFECTS & set(self.features):
            tau = self.effect_params.get(eid, {}).get('tau_s')
            if tau != th.tau_total_s:
                raise FeatureError(f'effect_params {eid}.tau_s ({tau!r}) must equal the '
                                   f"thermal state's total time constant ({th.tau_total_s!r})")

    def _check_accel(self) -> None:
        """Check that the accelerometer part shares the thermal front end and T0."""
        a = self.accel
        if not isinstance(a, CompensationModel):
            raise FeatureError(f'`accel` must be a CompensationModel or None, got '
                               f'{type(a).__name__}')
        if a.accel is not None:
            raise FeatureError('an accelerometer part cannot hold an accelerometer part')
        if a.thermal != self.thermal or a.t0_c != self.t0_c:
            raise FeatureError('the accelerometer part must share the thermal front end and '
                               'T0 of the model')
        if np.any(a.scale != 0):
            raise FeatureError('the accelerometer part has no scale term (scale must be 0)')

    #: The model-file format (:data:`FORMAT_VERSION`, the one there is).
    format_version: ClassVar[int] = FORMAT_VERSION

    def __eq__(self, other: object) -> bool:
        """Compare every fitted field exactly (arrays element-wise)."""
        if not isinstance(other, CompensationModel):
            return NotImplemented
        pairs = [(getattr(self, f.name), getattr(other, f.name))
                 for f in fields(self) if f.compare]
        return all(np.array_equal(a, b) if isinstance(a, np.ndarray) or isinstance(b, np.ndarray)
                   else a == b for a, b in pairs)

    __hash__ = object.__hash__

    @property
    def inputs(self) -> tuple[str, ...]:
        """Return the ids of the network inputs, in feature-matrix column order."""
        return input_ids(self.features, state=True)

    @property
    def n_centers(self) -> int:
        """Return the number of RBF centres K."""
        return int(self.centers.shape[0])

    @property
    def model_id(self) -> str:
        """
        Return a short content hash of every field but ``created``.

        Every field a compensator or a reader relies on (the accelerometer part by its own
        id) is covered; numbers are hashed as float64 bytes, so the id survives a YAML round
        trip.
        """
        h = hashlib.sha256()
        head = [self.kind, list(self.features), self.effect_params, self.frame_id,
                self.sensor_id, self.metrics,
                {'format_version': FORMAT_VERSION, 'thermal': self.thermal.to_dict()}]
        if self.accel is not None:          # a gyro-only model keeps the id it had
            head.append({'accel': self.accel.model_id})
        # One canonical JSON text of plain data (sorted keys, exact floats).
        h.update(json.dumps(plain(head), sort_keys=True, separators=(',', ':'),
                            default=repr).encode())
        for arr in (self.t0_c, self.temp_range_c, self.input_mean, self.input_std, self.centers,
                    self.widths, self.weights, self.intercept, self.linear, self.scale,
                    self.residual_var):
            a = np.ascontiguousarray(arr, dtype=np.float64)
            h.update(repr(a.shape).encode() + a.tobytes())
        return h.hexdigest()[:12]

    def replace(self, **changes: Any) -> 'CompensationModel':
        """Return a copy with some fields changed."""
        return replace(self, **changes)

    @property
    def offset_only(self) -> bool:
        """Return whether the drift is the intercept alone: no linear, RBF or scale term."""
        return not (np.any(self.linear) or np.any(self.weights) or np.any(self.scale))

    @property
    def coefficients(self) -> NDArray[np.float64]:
        """Return intercept, linear tail and RBF weights stacked, (1 + F + K, 3)."""
        return np.vstack([self.intercept[None, :], self.linear, self.weights])

    @classmethod
    def network(cls, kind: str, features: tuple[str, ...], effect_params: dict, t0_c: float,
                norm: tuple, coef: NDArray[np.float64], *, temp_range_c: tuple[float, float],
                residual_var: NDArray[np.float64], scale: NDArray[np.float64] | None = None,
                **extra: Any) -> 'CompensationModel':
        """
        Return the model of fitted network weights: the estimator's output, or a model file's.

        ``norm`` is ``(input_mean, input_std, centers, widths)`` and ``coef`` the weights of
        the design ``[1, x~, phi]`` (:func:`rbf_design`), shape (1 + F + K, 3); ``extra``
        holds the remaining fields (sensor ids, metrics, created, thermal, accel).
        """
        mean, std, centers, widths = norm
        f = len(mean)
        coef = np.array(coef, dtype=np.float64)
        return cls(kind=kind, features=tuple(features), effect_params=effect_params,
                   t0_c=float(t0_c), input_mean=mean, input_std=std, centers=centers,
                   widths=widths, weights=coef[1 + f:], intercept=coef[0],
                   linear=coef[1:1 + f], scale=np.zeros(3) if scale is None else scale,
                   temp_range_c=(float(temp_range_c[0]), float(temp_range_c[1])),
                   residual_var=np.asarray(residual_var, dtype=np.float64).reshape(3), **extra)

    @classmethod
    def polynomial(cls, features: tuple[str, ...], t0_c: float, coef: NDArray[np.float64], *,
                   temp_range_c: tuple[float, float], residual_var: NDArray[np.float64],
                   effect_params: dict | None = None, **extra: Any) -> 'CompensationModel':
        """
        Return a ``poly`` model of raw features: ``coef`` is the intercept, then one row each.

        No input normalisation (mean 0, deviation 1): the flight controllers' cubics and the
        learner's fits are written in the powers of ``T - T0`` themselves.
        """
        f = np.shape(coef)[0] - 1
        norm = (np.zeros(f), np.ones(f), np.zeros((0, f)), np.zeros(0))
        return cls.network('poly', features, effect_params or {}, t0_c, norm, coef,
                           temp_range_c=temp_range_c, residual_var=residual_var, **extra)


def rbf_design(model_or_norm: CompensationModel | tuple, x: NDArray[np.float64]
               ) -> NDArray[np.float64]:
    """
    Build the design matrix ``[1, x~, phi_1(x~) ... phi_K(x~)]`` (N, 1 + F + K) of rows ``x``.

    ``model_or_norm`` is a model or ``(input_mean, input_std, centers, widths)``; ``x`` the
    raw feature rows (N, F).
    """
    m = model_or_norm
    mean, std, centers, widths = ((m.input_mean, m.input_std, m.centers, m.widths)
                                  if isinstance(m, CompensationModel) else m)
    xn = (np.asarray(x, dtype=np.float64) - mean) / std
    n, f = xn.shape
    out = np.empty((n, 1 + f + centers.shape[0]))
    out[:, 0] = 1.0
    out[:, 1:1 + f] = xn
    # Squared distances accumulated one input at a time: no (N, K, F) temporary.
    phi = out[:, 1 + f:]
    phi.fill(0.0)
    for j in range(f):
        diff = xn[:, j:j + 1] - centers[None, :, j]
        diff *= diff
        phi += diff
    phi *= -1.0 / (2.0 * widths ** 2)
    np.exp(phi, out=phi)
    return out


def model_temperature(model: CompensationModel, t: NDArray[np.float64],
                      temp: NDArray[np.float64], *, clamp: bool = False) -> NDArray[np.float64]:
    """
    Return the model temperature over one run: the thermal state of the measured ``temp``.

    ``t`` (N,) are the stamps of one continuous run, s, ``temp`` (N,) the measured
    temperature, degC; ``clamp`` clips the result to ``temp_range_c``. Every temperature
    term of the model is evaluated at it (N,), degC.
    """
    temp = model.thermal.temperature(t, np.asarray(temp, dtype=np.float64))
    return np.clip(temp, *model.temp_range_c) if clamp else temp


def _drift(model: CompensationModel, t: NDArray[np.float64], temp: NDArray[np.float64],
           clamp: bool, out_of_range: str | None, max_c: float, chunk: int = 200_000
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the drift b (N, 3) over one run and the ``dT`` (N,) of its scale term.

    The features are evaluated at the model temperature
    :func:`gyro_tdc.model.out_of_range.split` gives for the policy (``out_of_range``, else
    ``clamp`` or ``extrapolate``), in chunks of rows; the ``linear`` tangent continues from
    there by the reach, which ``dT`` includes.
    """
    policy = check_policy(out_of_range) if out_of_range is not None else (
        'clamp' if clamp else 'extrapolate')
    temp = np.asarray(temp, dtype=np.float64)
    lo, hi = model.temp_range_c
    s, reach = split(model_temperature(model, t, temp), lo, hi, policy, max_c)
    x = batch_features(model.features, t, temp, t0=model.t0_c, params=model.effect_params, state=s)
    d = s - model.t0_c
    out = np.empty((x.shape[0], 3))
    tangent = Tangent(model) if np.any(reach) else None
    for i in range(0, x.shape[0], chunk):
        design = rbf_design(model, x[i:i + chunk])
        out[i:i + chunk] = design @ model.coefficients
        if tangent is not None:
            r = reach[i:i + chunk]
            k = np.flatnonzero(r)
            out[i + k] += r[k, None] * tangent.slope(design[k], d[i:i + chunk][k])
    return out, d + reach


def drift(model: CompensationModel, t: NDArray[np.float64], temp: NDArray[np.float64], *,
          clamp: bool = True, out_of_range: str | None = None,
          max_extrapolation_c: float = MAX_EXTRAPOLATION_C, chunk: int = 200_000
          ) -> NDArray[np.float64]:
    """
    Evaluate the zero-rate drift b(x) over one run, rad/s (N, 3).

    ``t`` (s) are the stamps of one continuous run, ``temp`` (degC) the measured
    temperature. ``out_of_range`` (``'linear'``, ``'clamp'``, ``'extrapolate'``:
    :mod:`gyro_tdc.model.out_of_range`, with ``max_extrapolation_c``) decides beyond the
    range; without it, ``clamp`` clamps the model temperature to the range (False
    extrapolates). ``chunk`` rows are evaluated at once to bound memory.
    """
    return _drift(model, t, temp, clamp, out_of_range, max_extrapolation_c, chunk)[0]


def steady_drift(model: CompensationModel, temps: ArrayLike, **policy: Any
                 ) -> NDArray[np.float64]:
    """
    Return the drift b(T) (N, 3) of ``model`` held long at each temperature ``temps`` (degC).

    The static drift: the thermal state equals T, dT/dt is 0 and the warm-up has decayed
    (each temperature held 1e7 s twice after one settling sample, so the batch features
    are their settled values). ``policy``: :func:`drift`'s ``clamp`` or ``out_of_range``.
    """
    temps = np.asarray(temps, dtype=np.float64).reshape(-1)
    u = np.concatenate([temps[:1], np.repeat(temps, 2)])
    return drift(model, np.arange(u.size) * 1e7, u, **policy)[2::2]


def static_slope(model: CompensationModel) -> NDArray[np.float64]:
    """
    Return the mean slope of the static drift over the trained range, per degC per axis.

    The change of :func:`steady_drift` across ``temp_range_c`` over the span, in the model's
    unit (rad/s, m/s^2 for an accelerometer part) per degC; NaN without a span. For the
    conventional f(dT) it is the zero-rate level change per degC (eq. 18, alpha).
    """
    lo, hi = (float(v) for v in model.temp_range_c)
    if not hi > lo:
        return np.full(3, math.nan)
    b = steady_drift(model, [lo, hi])
    return (b[1] - b[0]) / (hi - lo)


def compensate(model: CompensationModel, t: NDArray[np.float64], temp: NDArray[np.float64],
               omega: NDArray[np.float64], *, clamp: bool = True, out_of_range: str | None = None,
               max_extrapolation_c: float = MAX_EXTRAPOLATION_C) -> NDArray[np.float64]:
    """
    Remove the modelled drift from a run: ``(omega - b) / (1 + s dT)``, rad/s (N, 3).

    ``omega`` is the raw gyro output (N, 3), rad/s; the other arguments are :func:`drift`'s.
    """
    b, d = _drift(model, t, temp, clamp, out_of_range, max_extrapolation_c)
    return (np.asarray(omega, dtype=np.float64) - b) / (1.0 + d[:, None] * model.scale[None, :])


def predict_drift(model: CompensationModel, t: NDArray[np.float64], temp: NDArray[np.float64],
                  omega_ref: NDArray[np.float64], *, clamp: bool = False,
                  out_of_range: str | None = None,
                  max_extrapolation_c: float = MAX_EXTRAPOLATION_C) -> NDArray[np.float64]:
    """
    Simulate the raw output for a true rate: ``(1 + s dT) omega_ref + b``, rad/s (N, 3).

    ``omega_ref`` is the true (reference) rate (N, 3), rad/s; the other arguments are
    :func:`drift`'s, but the model temperature is not clamped by default.
    """
    b, d = _drift(model, t, temp, clamp, out_of_range, max_extrapolation_c)
    return (1.0 + d[:, None] * model.scale[None, :]) * np.asarray(omega_ref) + b


class StreamingCompensator:
    """
    Compensate one sample at a time, exactly as :func:`compensate` does on a whole run.

    With a thermal state the state starts at the first measured temperature (steady-state
    assumption); :attr:`thermal_progress` counts the time constants passed since that first
    sample, judged by the stamps (settled at :data:`gyro_tdc.model.thermal_state.SETTLE_TAUS`).

    Parameters
    ----------
    model : CompensationModel
        The model.
    out_of_range : str
        ``'clamp'`` (default) evaluates at the nearest valid model temperature;
        ``'linear'`` continues along the tangent at the range end up to
        ``max_extrapolation_c``, then holds; ``'extrapolate'`` evaluates the model outside
        its range (:mod:`gyro_tdc.model.out_of_range`).
    max_extrapolation_c : float, degC
        Reach of the ``linear`` tangent.

    """

    def __init__(self, model: CompensationModel, *, out_of_range: str = 'clamp',
                 max_extrapolation_c: float = MAX_EXTRAPOLATION_C) -> None:
        self.model = model
        self.policy = check_policy(out_of_range)
        self.max_extrapolation_c = float(max_extrapolation_c)
        self._tangent = Tangent(model) if self.policy == 'linear' else None
        self.thermal = model.thermal.stream()
        self.features = StreamingFeatures(model.features, t0=model.t0_c,
                                          params=model.effect_params, state=True)
        self._coef = model.coefficients
        self._inv2w2 = 1.0 / (2.0 * model.widths ** 2)
        self._lo, self._hi = model.temp_range_c
        self.offset = np.zeros(3)
        self.in_range = True
        self.model_temp: float | None = None
        self.range_distance_c = self.dt_c = 0.0
        #: The accelerometer part streamed alongside (None without one): ``accel.drift(t,
        #: temp)`` is the correction in m/s^2, ``accel.step(t, temp, a)`` the corrected
        #: specific force; its own copy of the thermal state, fed the same samples, equals
        #: this one's exactly.
        self.accel = (None if getattr(model, 'accel', None) is None else StreamingCompensator(
            model.accel, out_of_range=out_of_range, max_extrapolation_c=max_extrapolation_c))

    def reset(self) -> None:
        """Restart the thermal state and the feature filters (a new run)."""
        self.features.reset()
        self.thermal.reset()
        self.model_temp = None
        if self.accel is not None:
            self.accel.reset()

    @property
    def thermal_progress(self) -> float | None:
        """
        Return the stamp time since the first sample, in the state's time constants.

        None when the model has no lagged state (kind ``none``).
        """
        return None if self.thermal.thermal.kind == 'none' else self.thermal.progress

    def shift_offset(self, delta: NDArray[np.float64]) -> None:
        """Add ``delta`` (3,), rad/s, to the modelled drift (start-up re-anchoring)."""
        self.offset = self.offset + np.asarray(delta, dtype=np.float64).reshape(3)

    def drift(self, t: float, temp: float) -> NDArray[np.float64]:
        """
        Advance the state and filters to stamp ``t`` (s) at ``temp`` (degC); return b (3,).

        The drift in rad/s plus the re-anchoring offset. After the call ``in_range`` tells
        whether the model temperature was inside ``temp_range_c``, ``range_distance_c`` how far
        outside (degC, negative below), ``model_temp`` the temperature the correction
        stands for and ``dt_c`` that minus T0 (the ``dT`` of the scale term).
        """
        s = self.thermal.update(t, temp)
        self.in_range = bool(self._lo <= s <= self._hi)
        reach = self.range_distance_c = 0.0
        if not self.in_range:
            self.range_distance_c = s - min(max(s, self._lo), self._hi)
            s, reach = split(s, self._lo, self._hi, self.policy, self.max_extrapolation_c)
        xn = (self.features.update(t, temp, s) - self.model.input_mean) / self.model.input_std
        phi = np.exp(-((xn - self.model.centers) ** 2).sum(axis=1) * self._inv2w2)
        row = np.concatenate(([1.0], xn, phi))
        d = s - self.model.t0_c
        b = row @ self._coef + self.offset
        if reach:
            b = b + reach * self._tangent.slope_one(row, d)
        self.model_temp, self.dt_c = s + reach, d + reach
        return b

    def step(self, t: float, temp: float, omega: NDArray[np.float64]) -> NDArray[np.float64]:
        """
        Compensate one raw rate ``omega`` (rad/s) at stamp ``t`` (s); return the rate.

        ``temp`` (degC) is the latest thermometer sample at ``t``.
        """
        b = self.drift(t, temp)
        return (np.asarray(omega, dtype=np.float64) - b) / (1.0 + self.dt_c * self.model.scale)
