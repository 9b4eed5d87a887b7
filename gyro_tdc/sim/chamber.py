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
Thermal chamber: temperature profiles and the paper's precise test method (section 3.1).

A :class:`Profile` is the air temperature as a piecewise-linear function of time (two
breakpoints at one time make a jump); :func:`staircase_plan` applies the paper's step and
heat-conduction equations (eq. 20, 24). :func:`simulate_thermal` conducts the profile as
first-order lags, set point -> air -> package -> MEMS die, each integrated exactly on a uniform
internal grid (first-order hold). See ``doc/internals/sim.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Sequence, Tuple

from gyro_tdc.model import first_order_lag
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['MAX_STAIRCASE_STEPS', 'Profile', 'SegmentError', 'StaircasePlan', 'ThermalHistory',
           'heat_conduction_time_s', 'hold_segment', 'max_temperature_step_c', 'nice_ceil',
           'nice_floor', 'points_segment', 'ramp_segment', 'simulate_thermal', 'staircase_plan',
           'staircase_segment', 'step_segment']

#: Steps a staircase segment may take (the paper's: 1,250 of 0.1 degC).
MAX_STAIRCASE_STEPS = 1_000_000


class SegmentError(ValueError):
    """A segment that cannot follow where the profile is: what it must be and what it is."""

    def __init__(self, expected: str, got: Any) -> None:
        super().__init__(f'expected {expected}, got {got!r:.40}')
        self.expected, self.got = expected, got


# --------------------------------------------------------------------------------------------
# The paper's test-method equations
# --------------------------------------------------------------------------------------------

def max_temperature_step_c(*, sensitivity_dps: float, alpha_dps_per_c: float,
                           beta_dps_per_c: float) -> float:
    """
    Return the largest chamber temperature step of the precise test (paper eq. 20), degC.

    A step must not move the output by more than one digit: ``dT <= dE_S / (|alpha| +
    |beta|)``, with the resolution ``sensitivity_dps`` (deg/s per digit) and the zero-rate
    and sensitivity changes in (deg/s)/degC. The L3GD20 (8.75e-3, 0.03, 0.04) gives 0.125.
    """
    _positive('sensitivity_dps', sensitivity_dps)
    for name, value in (('alpha_dps_per_c', alpha_dps_per_c), ('beta_dps_per_c', beta_dps_per_c)):
        if not math.isfinite(value):
            raise ValueError(f'Expected `{name}` to be finite, got {value!r}.')
    total = abs(alpha_dps_per_c) + abs(beta_dps_per_c)
    if total <= 0.0:
        raise ValueError('Expected |`alpha_dps_per_c`| + |`beta_dps_per_c`| > 0, got 0.')
    return float(sensitivity_dps / total)


def heat_conduction_time_s(*, specific_heat_kj_per_kg_k: float, density_kg_per_m3: float,
                           length_m: float, conductivity_w_per_m_k: float) -> float:
    """
    Return the paper's heat-conduction time ``t_s = C rho L^2 / k`` (eq. 24), s.

    As the paper computes it: ``C`` in kJ/(kg K), ``k`` in W/(m K), read as seconds
    (SET-Z-021 air, L = 0.6 m: 17.52 s). In consistent SI units the expression is 1000 times
    larger, so the 17.5 s and the 20 s hold derived from it are the paper's experimental
    choice, not a conduction time constant; the simulator's lags are ``thermal.tau_*_s``.
    """
    for name, value in list(locals().items()):     # every argument, in order
        _positive(name, value)
    return float(specific_heat_kj_per_kg_k * density_kg_per_m3 * length_m ** 2
                 / conductivity_w_per_m_k)


def _series(x: float) -> list[float]:
    """Return the 1-2-5 series from a decade below positive ``x`` to a decade above."""
    exponent = math.floor(math.log10(_positive('x', x)))
    return [m * 10.0 ** e for e in (exponent - 1, exponent, exponent + 1) for m in (1.0, 2.0, 5.0)]


def nice_floor(x: float) -> float:
    """
    Return the largest number of the 1-2-5 series not above ``x``.

    Parameters
    ----------
    x : float
        A positive number (e.g. the eq. 20 bound, 0.125 degC).

    Returns
    -------
    float
        ``m * 10**e`` with ``m`` in (1, 2, 5), ``<= x`` (0.125 -> 0.1).

    """
    # A relative tolerance so that 0.1 or 20 map onto themselves despite rounding.
    return max(c for c in _series(x) if c <= x * (1.0 + 1e-12))


def nice_ceil(x: float) -> float:
    """
    Return the smallest number of the 1-2-5 series not below ``x``.

    Parameters
    ----------
    x : float
        A positive number (e.g. the eq. 24 time, 17.52 s).

    Returns
    -------
    float
        ``m * 10**e`` with ``m`` in (1, 2, 5), ``>= x`` (17.52 -> 20).

    """
    return min(c for c in _series(x) if c >= x * (1.0 - 1e-12))


@dataclass(frozen=True)
class StaircasePlan:
    """The precise test's staircase derived from the sensor and chamber data."""

    #: Bound of eq. 20 on the step, degC.
    max_step_c: float
    #: Step used, degC (``max_step_c`` rounded down on the 1-2-5 series).
    step_c: float
    #: Heat-conduction time of eq. 24, s.
    min_hold_s: float
    #: Hold used, s (``min_hold_s`` rounded up on the 1-2-5 series; eq. 25).
    hold_s: float
    #: Mean heating rate ``3600 step_c / hold_s``, degC/h.
    rate_c_per_h: float


def staircase_plan(*, sensitivity_dps: float = 8.75e-3, alpha_dps_per_c: float = 0.03,
                   beta_dps_per_c: float = 0.04, specific_heat_kj_per_kg_k: float = 1.005,
                   density_kg_per_m3: float = 1.293, length_m: float = 0.6,
                   conductivity_w_per_m_k: float = 0.0267) -> StaircasePlan:
    """
    Derive step, hold and mean rate of the precise test (paper eqs. 20, 24, 25).

    The arguments are those of :func:`max_temperature_step_c` and
    :func:`heat_conduction_time_s`; the defaults, the paper's L3GD20 in the SET-Z-021
    chamber, give 0.125 -> 0.1 degC, 17.52 -> 20 s and 18 degC/h. Returns the bounds and
    the rounded values used.
    """
    max_step = max_temperature_step_c(sensitivity_dps=sensitivity_dps,
                                      alpha_dps_per_c=alpha_dps_per_c,
                                      beta_dps_per_c=beta_dps_per_c)
    min_hold = heat_conduction_time_s(specific_heat_kj_per_kg_k=specific_heat_kj_per_kg_k,
                                      density_kg_per_m3=density_kg_per_m3, length_m=length_m,
                                      conductivity_w_per_m_k=conductivity_w_per_m_k)
    step, hold = nice_floor(max_step), nice_ceil(min_hold)
    return StaircasePlan(max_step_c=max_step, step_c=step, min_hold_s=min_hold, hold_s=hold,
                         rate_c_per_h=3600.0 * step / hold)


# --------------------------------------------------------------------------------------------
# Profiles
# --------------------------------------------------------------------------------------------

# A segment maps the end of the profile so far, (t0, temp0), to the breakpoints it appends.
Segment = Callable[[float, float], Tuple[NDArray[np.float64], NDArray[np.float64]]]


@dataclass(frozen=True)
class Profile:
    """
    Chamber air temperature as a piecewise-linear function of time.

    Parameters
    ----------
    t : NDArray[np.float64], shape (P,), s
        Breakpoint times from 0, non-decreasing; equal neighbours mark a jump.
    temp_c : NDArray[np.float64], shape (P,), degC
        Temperature at each breakpoint.

    """

    t: NDArray[np.float64]
    temp_c: NDArray[np.float64]

    def __post_init__(self) -> None:
        """Check shapes, finiteness and order."""
        t = np.asarray(self.t, dtype=np.float64)
        temp = np.asarray(self.temp_c, dtype=np.float64)
        if t.ndim != 1 or t.shape[0] < 1:
            raise ValueError(f'Expected `t` to have shape (P,) with P >= 1, got {t.shape}.')
        if temp.shape != t.shape:
            raise ValueError(f'Expected `temp_c` to have shape {t.shape}, got {temp.shape}.')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(temp))):
            raise ValueError('Expected `t` and `temp_c` to be finite.')
        if t[0] != 0.0 or np.any(np.diff(t) < 0.0):
            raise ValueError('Expected `t` to start at 0 and never decrease.')
        object.__setattr__(self, 't', t)
        object.__setattr__(self, 'temp_c', temp)

    @classmethod
    def from_segments(cls, start_c: float, segments: Sequence[Segment]) -> 'Profile':
        """
        Chain segments (``hold_segment``, ``ramp_segment``, ...) from ``start_c`` (degC) at 0.

        Each segment maps ``(t0, temp0)`` to the breakpoint arrays ``(t, temp)`` that follow.
        """
        end = (0.0, float(start_c))      # the last breakpoint: an empty segment keeps it
        ts, temps = [np.zeros(1)], [np.array(end[1:])]
        for segment in segments:
            t_seg, temp_seg = (np.asarray(a, dtype=np.float64) for a in segment(*end))
            ts.append(t_seg)
            temps.append(temp_seg)
            end = (float(t_seg[-1]), float(temp_seg[-1])) if t_seg.size else end
        return cls(np.concatenate(ts), np.concatenate(temps))

    @property
    def duration_s(self) -> float:
        """Return the time of the last breakpoint."""
        return float(self.t[-1])

    def value(self, t: ArrayLike) -> NDArray[np.float64]:
        """
        Evaluate the temperature, right-continuous at jumps, held constant outside.

        Parameters
        ----------
        t : ArrayLike, shape (N,), s
            Query times.

        Returns
        -------
        NDArray[np.float64], shape (N,), degC
            Temperatures.

        """
        t, i, j, dt = self._bracket(t)
        frac = np.divide(t - self.t[i], dt, out=np.zeros_like(t), where=dt > 0.0)
        return self.temp_c[i] + np.clip(frac, 0.0, 1.0) * (self.temp_c[j] - self.temp_c[i])

    def slope(self, t: ArrayLike) -> NDArray[np.float64]:
        """
        Return the slope of the segment holding each time (jumps are ignored).

        Parameters
        ----------
        t : ArrayLike, shape (N,), s
            Query times.

        Returns
        -------
        NDArray[np.float64], shape (N,), degC/s
            Slope, 0 outside the profile.

        """
        t, i, j, dt = self._bracket(t)
        inside = (dt > 0.0) & (t >= self.t[0]) & (t < self.t[-1])
        return np.divide(self.temp_c[j] - self.temp_c[i], dt, out=np.zeros_like(t), where=inside)

    def _bracket(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.intp],
                                              NDArray[np.intp], NDArray[np.float64]]:
        """Return ``t`` as an array, the breakpoints before and after it and their spacing."""
        t = np.asarray(t, dtype=np.float64)
        i = np.clip(np.searchsorted(self.t, t, side='right') - 1, 0, self.t.size - 1)
        j = np.minimum(i + 1, self.t.size - 1)
        return t, i, j, self.t[j] - self.t[i]


def _positive(name: str, value: float) -> float:
    """Return ``value`` as a float; a ValueError naming it unless it is finite and > 0."""
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f'Expected `{name}` to be a finite number > 0, got {value!r}.')
    return float(value)


def hold_segment(duration_s: float) -> Segment:
    """
    Return a segment that holds (soaks at) the current temperature.

    Parameters
    ----------
    duration_s : float, s
        Hold time, > 0.

    Returns
    -------
    callable
        Segment for :meth:`Profile.from_segments`.

    """
    duration_s = _positive('duration_s', float(duration_s))
    return lambda t0, temp0: (np.array([t0 + duration_s]), np.array([temp0]))


def ramp_segment(to_c: float, rate_c_per_h: float) -> Segment:
    """Return a segment ramping linearly to ``to_c`` (degC) at ``rate_c_per_h`` (> 0, degC/h)."""
    rate = _positive('rate_c_per_h', float(rate_c_per_h)) / 3600.0
    to_c = float(to_c)

    def segment(t0: float, temp0: float):
        duration = abs(to_c - temp0) / rate
        if duration == 0.0:
            return np.zeros(0), np.zeros(0)
        return np.array([t0 + duration]), np.array([to_c])
    return segment


def staircase_segment(to_c: float, step_c: float, hold_s: float) -> Segment:
    """
    Return the paper's staircase: jump by ``step_c``, hold ``hold_s``, repeat to ``to_c``.

    Each step jumps at the start of its hold, so ``n`` steps last ``n * hold_s`` and the mean
    rate is ``3600 * step_c / hold_s`` degC/h. A last partial step lands exactly on ``to_c``.
    Works upwards and downwards; ``step_c`` (degC) and ``hold_s`` (s) are > 0 (the paper:
    0.1 and 20).
    """
    step = _positive('step_c', float(step_c))
    hold = _positive('hold_s', float(hold_s))
    to_c = float(to_c)

    def segment(t0: float, temp0: float):
        span = to_c - temp0
        n = int(math.ceil(abs(span) / step - 1e-9))
        if n > MAX_STAIRCASE_STEPS:
            raise SegmentError(f'a staircase of at most {MAX_STAIRCASE_STEPS:,} steps (of '
                               f'{step:g} degC from {temp0:g} to {to_c:g} degC)', n)
        if n <= 0:
            return np.zeros(0), np.zeros(0)
        k = np.arange(n, dtype=np.float64)
        levels = temp0 + np.sign(span) * step * (k + 1.0)
        levels[-1] = to_c
        starts = t0 + hold * k
        # Each level: the jump at the start of its hold, then the end of the hold. The point
        # before the jump is the previous breakpoint, so every step is two breakpoints.
        return np.column_stack([starts, starts + hold]).ravel(), np.repeat(levels, 2)
    return segment


def step_segment(to_c: float) -> Segment:
    """
    Return an instantaneous jump of the chamber to ``to_c`` (for step responses).

    Parameters
    ----------
    to_c : float, degC
        Temperature after the jump.

    Returns
    -------
    callable
        Segment for :meth:`Profile.from_segments`.

    """
    to_c = float(to_c)
    return lambda t0, temp0: (np.array([t0]), np.array([to_c]))


def points_segment(t_s: ArrayLike, temp_c: ArrayLike) -> Segment:
    """
    Return a free piecewise-linear leg through (time, temperature) points.

    ``t_s`` (s) counts from the segment start, from 0, non-decreasing; a point at 0 with
    another temperature than the current one is a jump. ``temp_c`` in degC.
    """
    t_rel = np.asarray(t_s, dtype=np.float64)
    temps = np.asarray(temp_c, dtype=np.float64)
    if t_rel.ndim != 1 or t_rel.size < 1 or temps.shape != t_rel.shape:
        raise ValueError(f'Expected `t_s` and `temp_c` of equal shape (P,), got {t_rel.shape} '
                         f'and {temps.shape}.')
    if t_rel[0] != 0.0 or np.any(np.diff(t_rel) < 0.0):
        raise ValueError('Expected `t_s` to start at 0 and never decrease.')
    return lambda t0, temp0: (t0 + t_rel, temps.copy())


# --------------------------------------------------------------------------------------------
# Heat conduction
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ThermalHistory:
    """Temperatures of every thermal node on the internal grid, from set point to thermometer."""

    #: Internal grid ``k * dt`` (G,), s.
    t: NDArray[np.float64]
    #: Chamber profile (set point) (G,), degC.
    setpoint_c: NDArray[np.float64]
    #: Chamber air at the sensor (G,), degC.
    air_c: NDArray[np.float64]
    #: Sensor package (metal shell) temperature (G,), degC.
    package_c: NDArray[np.float64]
    #: MEMS die temperature (G,), degC.
    die_c: NDArray[np.float64]
    #: Time derivative of the die temperature (G,), degC/s.
    die_rate_c_per_s: NDArray[np.float64]
    #: Noise-free, unquantised thermometer reading (lagged package or die) (G,), degC.
    thermometer_c: NDArray[np.float64]

    def at(self, name: str, t: ArrayLike) -> NDArray[np.float64]:
        """Interpolate node ``name`` (``'die_c'``...) linearly onto ``t``, held beyond the grid."""
        return np.interp(np.asarray(t, dtype=np.float64), self.t, getattr(self, name))


def simulate_thermal(profile: Profile, *, duration_s: float, dt: float = 0.1,
                     tau_air_s: float = 0.0, tau_package_s: float = 0.0,
                     tau_die_s: float = 0.0, thermometer_location: str = 'package',
                     thermometer_tau_s: float = 0.0) -> ThermalHistory:
    """
    Propagate the chamber profile through the thermal chain on a grid of ``dt`` s.

    Chain: set point --tau_air--> air --tau_package--> package --tau_die--> die (each >= 0,
    0 = no lag). The thermometer is a further lag ``thermometer_tau_s`` of the package (a
    probe on the shell) or of the die (the on-die register), per ``thermometer_location``.
    Every node starts settled at the profile's first temperature; the grid covers
    ``[0, duration_s]``.
    """
    if not (math.isfinite(duration_s) and duration_s >= 0.0):
        raise ValueError(f'Expected `duration_s` >= 0, got {duration_s!r}.')
    if thermometer_location not in ('package', 'die'):
        raise ValueError("Expected `thermometer_location` to be 'package' or 'die', got "
                         f'{thermometer_location!r}.')
    n = int(math.floor(duration_s / dt + 1e-9)) + 1
    t = np.arange(n, dtype=np.float64) * dt
    if t[-1] < duration_s:
        t = np.append(t, t[-1] + dt)
    setpoint = profile.value(t)
    # Each node lags the one before: setpoint -> air -> package -> die, with its rate: exact
    # (u - y) / tau, or the input's rate when tau = 0.
    nodes, rate = [setpoint], profile.slope(t)
    for tau in (tau_air_s, tau_package_s, tau_die_s):
        nodes.append(first_order_lag(dt, nodes[-1], tau, hold='linear'))
        rate = (nodes[-2] - nodes[-1]) / tau if tau > 0.0 else rate
    _, air, package, die = nodes
    source = package if thermometer_location == 'package' else die
    thermometer = first_order_lag(dt, source, thermometer_tau_s, hold='linear')
    return ThermalHistory(t=t, setpoint_c=setpoint, air_c=air, package_c=package, die_c=die,
                          die_rate_c_per_s=rate, thermometer_c=thermometer)
