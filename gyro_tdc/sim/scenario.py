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
Simulator scenarios: schema, validation, presets, loading and overrides.

A scenario is a YAML mapping (``config/scenarios/NAME.yaml``) or a dict. Every physical
quantity carries its unit in its key; per-axis quantities take one number (all axes) or a
list of three (x, y, z). Unknown keys are errors, so a typo never passes silently. The
sections and their defaults::

    format_version: 1
    name: NAME                    # default: the file stem
    description: ''
    sensor: l3gd20                # optional preset (l3gd20, i3g4250d) under gyro/noise/accel
    imu_rate_hz: 100.0
    duration_s: null              # default: the profile's duration; longer holds the end
    profile:                      # chamber air temperature
      start_c: 25.0
      segments:                   # in order; each has a kind
        - {kind: hold, duration_s: 600.0}                         # soak
        - {kind: ramp, to_c: 85.0, rate_c_per_h: 18.0}            # heating or cooling
        - {kind: staircase, to_c: 85.0, step_c: 0.1, hold_s: 20.0}  # paper eq. 20/24
        - {kind: step, to_c: 30.0}                                # instantaneous jump
        - {kind: points, t_s: [0.0, 60.0], temp_c: [30.0, 35.0]}  # free piecewise leg
    thermal:                      # first-order lags, s (0 = none)
      tau_air_s: 0.0              # set point -> air at the sensor
      tau_package_s: 0.0          # air -> package (shell the probe is glued to)
      tau_die_s: 0.0              # package -> MEMS die: the `lag` effect (die lags probe)
      internal_step_s: 0.1        # integration grid
    thermometer:
      location: package           # package (external probe) | die (on-die register)
      rate_hz: 1.0
      resolution_c: 0.0           # quantisation step, 0 = none (probe 0.03, register 1/256)
      noise_c: 0.0                # white noise std
      tau_s: 0.0                  # sensor time constant
      offset_c: 0.0
    gyro:
      effects: [bias, dT, dT2]    # or a mapping id -> bool; ids of gyro_tdc.effects
      t_ref_c: 25.0               # dT_die = T_die - t_ref_c
      bias_dps: 0.0               # b0
      dT_dps_per_c: 0.0           # a1
      dT2_dps_per_c2: 0.0         # a2
      dT3_dps_per_c3: 0.0         # a3
      dTdt_dps_per_c_per_s: 0.0   # h, per (degC/s) of the die
      scale_ppm_per_c: 0.0        # s, output = w_ref (1 + s dT_die) + ...
      warmup_dps: 0.0             # w, times exp(-(t - power_on_s) / warmup_tau_s)
      warmup_tau_s: 300.0
      power_on_s: 0.0             # power-on time (<= 0: before the recording)
      sensitivity_mdps_per_digit: 0.0  # quantisation step
      range_dps: 0.0              # saturation, 0 = none
      quantise: true
    noise:
      enabled: true
      arw_dps_per_rt_hz: 0.0      # white rate noise density (angle random walk)
      bias_instability_dps: 0.0   # std of a sum of Gauss-Markov processes...
      bias_instability_tau_s: [10.0, 100.0, 1000.0]  # ...with these correlation times
      rrw_dps_per_rt_s: 0.0       # rate random walk
    accel:
      gravity_mps2: 9.80665       # on +z
      noise_mps2_per_rt_hz: 0.0
    rate_table:                   # reference rate schedule (ZOH); empty = still
      - {t_s: 0.0, rate_dps: [10.0, 5.0, 20.0]}   # or rate_rad_s
    runs:
      count: 1                    # a multi-run scenario yields several runs
      bias_offset_dps_std: 0.0    # run-to-run bias offset (drawn per run)

An effect switched off contributes nothing whatever its coefficient; the ``lag`` switch
turns ``thermal.tau_die_s`` on and off.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
from typing import Any, Mapping, Optional, Union

from gyro_tdc.errors import GyroTdcError, ScenarioError
from gyro_tdc.sim import chamber
from gyro_tdc.sim.presets import PRESETS
from gyro_tdc.yamlio import load_yaml, SCENARIO_LIMITS
import numpy as np
from numpy.typing import NDArray
import yaml

__all__ = [
    'EFFECT_IDS',
    'FORMAT_VERSION',
    'AccelSpec',
    'GyroSpec',
    'NoiseSpec',
    'RateTable',
    'RunsSpec',
    'Scenario',
    'ThermalSpec',
    'ThermometerSpec',
    'list_scenarios',
    'load_scenario',
    'scenario_dir',
]

FORMAT_VERSION = 1
EFFECT_IDS = ('bias', 'dT', 'dT2', 'dT3', 'dTdt', 'lag', 'scale', 'warmup')
DEG = math.pi / 180.0

PathLike = Union[str, 'os.PathLike[str]']

DEFAULTS: dict = {
    'format_version': FORMAT_VERSION,
    'name': None,
    'description': '',
    'sensor': None,
    'imu_rate_hz': 100.0,
    'duration_s': None,
    'profile': {'start_c': 25.0, 'segments': []},
    'thermal': {'tau_air_s': 0.0, 'tau_package_s': 0.0, 'tau_die_s': 0.0,
                'internal_step_s': 0.1},
    'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.0,
                    'noise_c': 0.0, 'tau_s': 0.0, 'offset_c': 0.0},
    'gyro': {
        'effects': {k: k in ('bias', 'dT', 'dT2') for k in EFFECT_IDS},
        't_ref_c': 25.0,
        'bias_dps': 0.0,
        'dT_dps_per_c': 0.0,
        'dT2_dps_per_c2': 0.0,
        'dT3_dps_per_c3': 0.0,
        'dTdt_dps_per_c_per_s': 0.0,
        'scale_ppm_per_c': 0.0,
        'warmup_dps': 0.0,
        'warmup_tau_s': 300.0,
        'power_on_s': 0.0,
        'sensitivity_mdps_per_digit': 0.0,
        'range_dps': 0.0,
        'quantise': True,
    },
    'noise': {'enabled': True, 'arw_dps_per_rt_hz': 0.0, 'bias_instability_dps': 0.0,
              'bias_instability_tau_s': [10.0, 100.0, 1000.0], 'rrw_dps_per_rt_s': 0.0},
    'accel': {'gravity_mps2': 9.80665, 'noise_mps2_per_rt_hz': 0.0},
    'rate_table': [],
    'runs': {'count': 1, 'bias_offset_dps_std': 0.0},
}

# Field kinds: 'num' any finite number, 'pos' > 0, 'nonneg' >= 0, 'axis' per-axis number,
# 'axis_nonneg' per-axis >= 0, 'bool', 'str', 'count' int >= 1, 'taus' list of numbers > 0.
_SECTIONS: dict[str, dict[str, str]] = {
    'thermal': {'tau_air_s': 'nonneg', 'tau_package_s': 'nonneg', 'tau_die_s': 'nonneg',
                'internal_step_s': 'pos'},
    'thermometer': {'location': 'location', 'rate_hz': 'pos', 'resolution_c': 'nonneg',
                    'noise_c': 'nonneg', 'tau_s': 'nonneg', 'offset_c': 'num'},
    'gyro': {'effects': 'effects', 't_ref_c': 'num', 'bias_dps': 'axis',
             'dT_dps_per_c': 'axis', 'dT2_dps_per_c2': 'axis', 'dT3_dps_per_c3': 'axis',
             'dTdt_dps_per_c_per_s': 'axis', 'scale_ppm_per_c': 'axis', 'warmup_dps': 'axis',
             'warmup_tau_s': 'pos', 'power_on_s': 'num', 'sensitivity_mdps_per_digit': 'nonneg',
             'range_dps': 'nonneg', 'quantise': 'bool'},
    'noise': {'enabled': 'bool', 'arw_dps_per_rt_hz': 'axis_nonneg',
              'bias_instability_dps': 'axis_nonneg', 'bias_instability_tau_s': 'taus',
              'rrw_dps_per_rt_s': 'axis_nonneg'},
    'accel': {'gravity_mps2': 'num', 'noise_mps2_per_rt_hz': 'axis_nonneg'},
    'runs': {'count': 'count', 'bias_offset_dps_std': 'axis_nonneg'},
}
_TOP = ('format_version', 'name', 'description', 'sensor', 'imu_rate_hz', 'duration_s',
        'profile', 'rate_table') + tuple(_SECTIONS)
_SEGMENTS: dict[str, tuple[str, ...]] = {
    'hold': ('duration_s',),
    'ramp': ('to_c', 'rate_c_per_h'),
    'staircase': ('to_c', 'step_c', 'hold_s'),
    'step': ('to_c',),
    'points': ('t_s', 'temp_c'),
}

Vec3 = tuple[float, float, float]


# --------------------------------------------------------------------------------------------
# Typed sections
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ThermalSpec:
    """
    Heat-conduction chain, see :func:`gyro_tdc.sim.thermal.simulate_thermal`.

    Parameters
    ----------
    tau_air_s, tau_package_s, tau_die_s : float, s
        Set point -> air, air -> package, package -> die time constants.
    internal_step_s : float, s
        Integration grid step.

    """

    tau_air_s: float
    tau_package_s: float
    tau_die_s: float
    internal_step_s: float


@dataclass(frozen=True)
class ThermometerSpec:
    """
    Thermometer: where it sits, how often and how finely it reads.

    Parameters
    ----------
    location : {'package', 'die'}
        External probe on the package, or the on-die register.
    rate_hz : float, Hz
        Sample rate.
    resolution_c : float, degC
        Quantisation step (0 = none).
    noise_c : float, degC
        White noise standard deviation.
    tau_s : float, s
        Sensor time constant.
    offset_c : float, degC
        Calibration offset added to every reading.

    """

    location: str
    rate_hz: float
    resolution_c: float
    noise_c: float
    tau_s: float
    offset_c: float


@dataclass(frozen=True)
class GyroSpec:
    """
    Deterministic gyro error model, in the scenario's units (deg/s based).

    Parameters
    ----------
    effects : tuple of str
        Enabled effect ids (subset of ``EFFECT_IDS``).
    t_ref_c : float, degC
        Reference temperature of ``dT_die``.
    bias_dps, dT_dps_per_c, dT2_dps_per_c2, dT3_dps_per_c3 : tuple of 3 float
        Polynomial coefficients in ``dT_die``.
    dTdt_dps_per_c_per_s : tuple of 3 float, (deg/s)/(degC/s)
        Gain on the die's rate of temperature change.
    scale_ppm_per_c : tuple of 3 float, ppm/degC
        Scale-factor change vs temperature.
    warmup_dps : tuple of 3 float, deg/s
        Warm-up transient amplitude.
    warmup_tau_s : float, s
        Warm-up time constant.
    power_on_s : float, s
        Power-on time relative to the start of the recording.
    sensitivity_mdps_per_digit : float, mdps
        One digit of the output (quantisation step).
    range_dps : float, deg/s
        Full scale (saturation); 0 = none.
    quantise : bool
        Round the output to digits.

    """

    effects: tuple[str, ...]
    t_ref_c: float
    bias_dps: Vec3
    dT_dps_per_c: Vec3
    dT2_dps_per_c2: Vec3
    dT3_dps_per_c3: Vec3
    dTdt_dps_per_c_per_s: Vec3
    scale_ppm_per_c: Vec3
    warmup_dps: Vec3
    warmup_tau_s: float
    power_on_s: float
    sensitivity_mdps_per_digit: float
    range_dps: float
    quantise: bool


@dataclass(frozen=True)
class NoiseSpec:
    """
    Stochastic gyro errors.

    Parameters
    ----------
    enabled : bool
        Master switch.
    arw_dps_per_rt_hz : tuple of 3 float, (deg/s)/sqrt(Hz)
        White rate noise density.
    bias_instability_dps : tuple of 3 float, deg/s
        Standard deviation of the Gauss-Markov sum.
    bias_instability_tau_s : tuple of float, s
        Correlation times of the Gauss-Markov processes.
    rrw_dps_per_rt_s : tuple of 3 float, (deg/s)/sqrt(s)
        Rate random walk coefficient.

    """

    enabled: bool
    arw_dps_per_rt_hz: Vec3
    bias_instability_dps: Vec3
    bias_instability_tau_s: tuple[float, ...]
    rrw_dps_per_rt_s: Vec3


@dataclass(frozen=True)
class AccelSpec:
    """
    Accelerometer: gravity on +z plus white noise.

    Parameters
    ----------
    gravity_mps2 : float, m/s^2
        Specific force on +z.
    noise_mps2_per_rt_hz : tuple of 3 float, (m/s^2)/sqrt(Hz)
        Noise density.

    """

    gravity_mps2: float
    noise_mps2_per_rt_hz: Vec3


@dataclass(frozen=True)
class RateTable:
    """
    Reference-rate schedule, held between change points.

    Parameters
    ----------
    t_s : tuple of float, s
        Change times, strictly increasing, the first at 0.
    rate_rad_s : tuple of 3-tuples, rad/s
        Rate from each change time on.

    """

    t_s: tuple[float, ...]
    rate_rad_s: tuple[Vec3, ...]

    @property
    def moving(self) -> bool:
        """Return True when any rate is non-zero."""
        return any(v != 0.0 for row in self.rate_rad_s for v in row)

    def arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the change points as arrays ``(t (R,), rate (R, 3))``."""
        return (np.asarray(self.t_s, dtype=np.float64),
                np.asarray(self.rate_rad_s, dtype=np.float64).reshape(-1, 3))


@dataclass(frozen=True)
class RunsSpec:
    """
    How many runs a scenario yields and how they differ.

    Parameters
    ----------
    count : int
        Number of runs.
    bias_offset_dps_std : tuple of 3 float, deg/s
        Standard deviation of the run-to-run bias offset.

    """

    count: int
    bias_offset_dps_std: Vec3


@dataclass(frozen=True, eq=False)
class Scenario:
    """
    A validated scenario: the typed sections plus the normalised dict they came from.

    Build one with :meth:`from_dict` or :func:`load_scenario`.

    Parameters
    ----------
    name : str
        Scenario name.
    description : str
        Free text.
    source : str
        File it was loaded from, or ``'<dict>'``.
    sensor : str or None
        Preset merged under ``gyro``/``noise``/``accel``.
    imu_rate_hz : float, Hz
        IMU sample rate.
    duration_s : float, s
        Length of every run.
    profile : gyro_tdc.sim.chamber.Profile
        Chamber air temperature.
    thermal : ThermalSpec
        Heat-conduction chain.
    thermometer : ThermometerSpec
        Thermometer.
    gyro : GyroSpec
        Deterministic error model.
    noise : NoiseSpec
        Stochastic errors.
    accel : AccelSpec
        Accelerometer.
    rate_table : RateTable
        Reference rates.
    runs : RunsSpec
        Number of runs and run-to-run offsets.
    data : dict
        Normalised mapping (preset and defaults merged); ``to_dict()`` returns a copy.

    """

    name: str
    description: str
    source: str
    sensor: Optional[str]
    imu_rate_hz: float
    duration_s: float
    profile: chamber.Profile
    thermal: ThermalSpec
    thermometer: ThermometerSpec
    gyro: GyroSpec
    noise: NoiseSpec
    accel: AccelSpec
    rate_table: RateTable
    runs: RunsSpec
    data: dict = field(repr=False)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, name: Optional[str] = None,
                  source: str = '<dict>') -> 'Scenario':
        """
        Validate a scenario mapping and build the scenario.

        Parameters
        ----------
        data : Mapping
            Scenario as read from YAML (see the module docstring for the schema).
        name : str, optional
            Name used when ``data`` has none (e.g. the file stem).
        source : str
            Where ``data`` came from, for error messages.

        Returns
        -------
        Scenario
            The validated scenario.

        Raises
        ------
        ScenarioError
            Naming the first bad field, what was expected and what was received.

        """
        return _build(data, name=name, source=source)

    def to_dict(self) -> dict:
        """Return the normalised scenario mapping (a deep copy, YAML-safe)."""
        return copy.deepcopy(self.data)

    def with_overrides(self, overrides: Mapping[str, Any]) -> 'Scenario':
        """
        Return a copy with fields replaced, validated again.

        Parameters
        ----------
        overrides : Mapping[str, Any]
            Dotted paths to new values, e.g. ``{'gyro.effects.dT3': True,
            'noise.enabled': False, 'gyro.dT2_dps_per_c2': [1e-3, 0, 0],
            'duration_s': 600.0, 'imu_rate_hz': 20.0}``. A mapping value replacing a
            mapping is merged into it.

        Returns
        -------
        Scenario
            The modified scenario.

        Raises
        ------
        ScenarioError
            If a path is malformed or the result does not validate.

        """
        if not isinstance(overrides, Mapping):
            raise ScenarioError(f'Expected `overrides` to be a mapping of dotted paths to '
                                f'values, got {type(overrides).__name__}.')
        data = self.to_dict()
        for key, value in overrides.items():
            if not isinstance(key, str) or not key or any(not p for p in key.split('.')):
                raise ScenarioError(f'Expected override keys to be dotted paths such as '
                                    f"'gyro.effects.dT2', got {key!r}.")
            parts = key.split('.')
            node = data
            for i, part in enumerate(parts[:-1]):
                child = node.get(part)
                if child is None:
                    child = node[part] = {}
                if not isinstance(child, dict):
                    raise ScenarioError(f'Override {key!r}: `{".".join(parts[:i + 1])}` is '
                                        f'not a mapping (it holds {child!r}).')
                node = child
            last = parts[-1]
            value = copy.deepcopy(value)
            if isinstance(value, Mapping) and isinstance(node.get(last), dict):
                node[last] = _merge(node[last], value)
            else:
                node[last] = _plain(value)
        return _build(data, name=self.name, source=self.source)

    @property
    def effects(self) -> tuple[str, ...]:
        """Return the enabled effect ids."""
        return self.gyro.effects


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------

def _plain(value: Any) -> Any:
    """Convert numpy scalars/arrays and tuples to plain YAML-safe Python objects."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _merge(base: Mapping, top: Mapping) -> dict:
    """Deep-merge ``top`` over ``base`` (mappings merge, everything else replaces)."""
    out = copy.deepcopy(dict(base))
    for key, value in top.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = _plain(copy.deepcopy(value))
    return out


class _Checker:
    """Field checks that raise one ScenarioError naming the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, expected: str, got: Any) -> ScenarioError:
        shown = repr(got)
        if len(shown) > 80:
            shown = shown[:77] + '...'
        return ScenarioError(f'{self.source}: `{path}`: expected {expected}, got {shown}.')

    @staticmethod
    def _is_num(x: Any) -> bool:
        return (isinstance(x, (int, float, np.integer, np.floating))
                and not isinstance(x, bool) and math.isfinite(float(x)))

    def num(self, path: str, x: Any, *, low: Optional[float] = None,
            strict: bool = False) -> float:
        if not self._is_num(x):
            raise self.fail(path, 'a finite number' + self._bound(low, strict), x)
        x = float(x)
        if low is not None and (x <= low if strict else x < low):
            raise self.fail(path, 'a number' + self._bound(low, strict), x)
        return x

    @staticmethod
    def _bound(low: Optional[float], strict: bool) -> str:
        if low is None:
            return ''
        return f' {">" if strict else ">="} {low:g}'

    def axis(self, path: str, x: Any, *, low: Optional[float] = None) -> Vec3:
        expected = 'a number or a list of 3 numbers' + self._bound(low, False)
        if self._is_num(x):
            v = float(x)
            values = [v, v, v]
        elif (isinstance(x, (list, tuple)) and len(x) == 3
              and all(self._is_num(e) for e in x)):
            values = [float(e) for e in x]
        else:
            raise self.fail(path, expected, x)
        if low is not None and min(values) < low:
            raise self.fail(path, expected, x)
        return (values[0], values[1], values[2])

    def boolean(self, path: str, x: Any) -> bool:
        if not isinstance(x, bool):
            raise self.fail(path, 'true or false', x)
        return x

    def mapping(self, path: str, x: Any, allowed: tuple[str, ...]) -> dict:
        if not isinstance(x, Mapping):
            raise self.fail(path, 'a mapping', x)
        for key in x:
            if key not in allowed:
                where = f'{path}.{key}' if path else str(key)
                raise self.fail(where, 'a known key (one of ' + ', '.join(allowed) + ')',
                                key)
        return dict(x)

    def field(self, section: str, key: str, kind: str, x: Any) -> Any:
        path = f'{section}.{key}'
        if kind == 'num':
            return self.num(path, x)
        if kind == 'pos':
            return self.num(path, x, low=0.0, strict=True)
        if kind == 'nonneg':
            return self.num(path, x, low=0.0)
        if kind == 'axis':
            return self.axis(path, x)
        if kind == 'axis_nonneg':
            return self.axis(path, x, low=0.0)
        if kind == 'bool':
            return self.boolean(path, x)
        if kind == 'count':
            if not isinstance(x, int) or isinstance(x, bool) or x < 1:
                raise self.fail(path, 'an integer >= 1', x)
            return x
        if kind == 'location':
            if x not in ('package', 'die'):
                raise self.fail(path, "'package' or 'die'", x)
            return x
        if kind == 'taus':
            if (not isinstance(x, (list, tuple)) or not x
                    or not all(self._is_num(e) and float(e) > 0.0 for e in x)):
                raise self.fail(path, 'a non-empty list of numbers > 0', x)
            return tuple(float(e) for e in x)
        if kind == 'effects':
            return self.effects(path, x)
        raise AssertionError(kind)  # pragma: no cover - schema table is static

    def effects(self, path: str, x: Any) -> dict[str, bool]:
        if isinstance(x, (list, tuple)):
            for e in x:
                if e not in EFFECT_IDS:
                    raise self.fail(path, 'effect ids from ' + ', '.join(EFFECT_IDS), e)
            return {k: k in x for k in EFFECT_IDS}
        if isinstance(x, Mapping):
            out = {}
            for k in EFFECT_IDS:
                if k not in x:
                    raise self.fail(f'{path}.{k}', 'true or false', None)
            for k, v in x.items():
                if k not in EFFECT_IDS:
                    raise self.fail(f'{path}.{k}', 'an effect id (' + ', '.join(EFFECT_IDS)
                                    + ')', k)
                out[k] = self.boolean(f'{path}.{k}', v)
            return out
        raise self.fail(path, 'a list of effect ids or a mapping id -> bool', x)


def _profile(chk: _Checker, raw: Any) -> tuple[chamber.Profile, dict]:
    prof = chk.mapping('profile', raw, ('start_c', 'segments'))
    start = chk.num('profile.start_c', prof.get('start_c'), low=-273.15)
    segments = prof.get('segments')
    if not isinstance(segments, (list, tuple)) or not segments:
        raise chk.fail('profile.segments', 'a non-empty list of segments', segments)
    built = []
    for i, seg in enumerate(segments):
        where = f'profile.segments[{i}]'
        if not isinstance(seg, Mapping) or seg.get('kind') not in _SEGMENTS:
            got = seg.get('kind') if isinstance(seg, Mapping) else seg
            raise chk.fail(f'{where}.kind' if isinstance(seg, Mapping) else where,
                           'a segment kind (' + ', '.join(_SEGMENTS) + ')', got)
        kind = seg['kind']
        fields = _SEGMENTS[kind]
        chk.mapping(where, seg, ('kind',) + fields)
        for key in fields:
            if key not in seg:
                raise chk.fail(f'{where}.{key}', f'a value (required by kind {kind!r})', None)
        if kind == 'hold':
            built.append(chamber.hold_segment(
                chk.num(f'{where}.duration_s', seg['duration_s'], low=0.0, strict=True)))
        elif kind == 'ramp':
            built.append(chamber.ramp_segment(
                chk.num(f'{where}.to_c', seg['to_c'], low=-273.15),
                chk.num(f'{where}.rate_c_per_h', seg['rate_c_per_h'], low=0.0, strict=True)))
        elif kind == 'staircase':
            built.append(chamber.staircase_segment(
                chk.num(f'{where}.to_c', seg['to_c'], low=-273.15),
                chk.num(f'{where}.step_c', seg['step_c'], low=0.0, strict=True),
                chk.num(f'{where}.hold_s', seg['hold_s'], low=0.0, strict=True)))
        elif kind == 'step':
            built.append(chamber.step_segment(
                chk.num(f'{where}.to_c', seg['to_c'], low=-273.15)))
        else:
            ts, temps = seg['t_s'], seg['temp_c']
            for key, arr in (('t_s', ts), ('temp_c', temps)):
                if not isinstance(arr, (list, tuple)) or not arr or not all(
                        chk._is_num(e) for e in arr):
                    raise chk.fail(f'{where}.{key}', 'a non-empty list of numbers', arr)
            if len(ts) != len(temps):
                raise chk.fail(f'{where}.temp_c', f'{len(ts)} values (as many as t_s)',
                               temps)
            t_arr = np.asarray(ts, dtype=np.float64)
            if t_arr[0] != 0.0 or np.any(np.diff(t_arr) < 0.0):
                raise chk.fail(f'{where}.t_s', 'times starting at 0 and never decreasing',
                               ts)
            if min(temps) < -273.15:
                raise chk.fail(f'{where}.temp_c', 'temperatures >= -273.15', temps)
            built.append(chamber.points_segment(t_arr, np.asarray(temps, dtype=np.float64)))
    profile = chamber.Profile.from_segments(start, built)
    if profile.duration_s <= 0.0:
        raise chk.fail('profile.segments', 'segments lasting longer than 0 s in total',
                       segments)
    return profile, prof


def _rate_table(chk: _Checker, raw: Any) -> RateTable:
    if raw is None:
        raw = []
    if not isinstance(raw, (list, tuple)):
        raise chk.fail('rate_table', 'a list of {t_s, rate_dps | rate_rad_s} entries', raw)
    times: list[float] = []
    rates: list[Vec3] = []
    for i, entry in enumerate(raw):
        where = f'rate_table[{i}]'
        entry = chk.mapping(where, entry, ('t_s', 'rate_dps', 'rate_rad_s'))
        t = chk.num(f'{where}.t_s', entry.get('t_s'), low=0.0)
        if times and t <= times[-1]:
            raise chk.fail(f'{where}.t_s', f'a time after {times[-1]:g} s (strictly '
                           'increasing)', t)
        has_dps, has_rad = 'rate_dps' in entry, 'rate_rad_s' in entry
        if has_dps == has_rad:
            raise chk.fail(where, 'exactly one of rate_dps or rate_rad_s', entry)
        if has_dps:
            rate = tuple(v * DEG for v in chk.axis(f'{where}.rate_dps', entry['rate_dps']))
        else:
            rate = chk.axis(f'{where}.rate_rad_s', entry['rate_rad_s'])
        times.append(t)
        rates.append((rate[0], rate[1], rate[2]))
    if not times or times[0] > 0.0:
        times.insert(0, 0.0)
        rates.insert(0, (0.0, 0.0, 0.0))
    return RateTable(t_s=tuple(times), rate_rad_s=tuple(rates))


def _build(data: Any, *, name: Optional[str], source: str) -> Scenario:
    chk = _Checker(source)
    top = chk.mapping('', data, _TOP) if isinstance(data, Mapping) else None
    if top is None:
        raise ScenarioError(f'{source}: expected the scenario to be a mapping of sections, '
                            f'got {type(data).__name__}.')
    version = top.get('format_version', FORMAT_VERSION)
    if version != FORMAT_VERSION:
        raise chk.fail('format_version', str(FORMAT_VERSION), version)
    sensor = top.get('sensor')
    if sensor is not None and sensor not in PRESETS:
        raise chk.fail('sensor', 'a preset name (' + ', '.join(sorted(PRESETS)) + ') or null',
                       sensor)
    top = dict(top)
    # A list of effects means exactly those: expand it before merging over the defaults.
    gyro_in = top.get('gyro')
    if isinstance(gyro_in, Mapping) and isinstance(gyro_in.get('effects'), (list, tuple)):
        top['gyro'] = dict(gyro_in, effects=chk.effects('gyro.effects', gyro_in['effects']))
    for section in _SECTIONS:
        if section in top and not isinstance(top[section], Mapping):
            raise chk.fail(section, 'a mapping', top[section])
    merged = _merge(DEFAULTS, PRESETS[sensor] if sensor else {})
    merged = _merge(merged, top)
    if 'rate_table' in top:
        merged['rate_table'] = _plain(copy.deepcopy(top['rate_table']))
    if isinstance(top.get('profile'), Mapping) and 'segments' in top['profile']:
        merged['profile']['segments'] = _plain(copy.deepcopy(top['profile']['segments']))

    the_name = merged.get('name') or name or 'scenario'
    if not isinstance(the_name, str):
        raise chk.fail('name', 'a string', the_name)
    merged['name'] = the_name
    description = merged.get('description') or ''
    if not isinstance(description, str):
        raise chk.fail('description', 'a string', description)
    rate = chk.num('imu_rate_hz', merged.get('imu_rate_hz'), low=0.0, strict=True)

    values: dict[str, dict[str, Any]] = {}
    for section, fields in _SECTIONS.items():
        body = chk.mapping(section, merged[section], tuple(fields))
        values[section] = {key: chk.field(section, key, kind, body.get(key))
                           for key, kind in fields.items()}
    merged['gyro']['effects'] = dict(values['gyro']['effects'])

    profile, _ = _profile(chk, merged['profile'])
    duration = merged.get('duration_s')
    duration = profile.duration_s if duration is None else chk.num(
        'duration_s', duration, low=0.0, strict=True)
    if duration * rate < 2.0:
        raise chk.fail('duration_s', f'at least 2 IMU samples ({2.0 / rate:g} s at '
                       f'{rate:g} Hz)', duration)
    thermometer_rate = values['thermometer']['rate_hz']
    if duration * thermometer_rate < 1.0:
        raise chk.fail('thermometer.rate_hz', f'at least one reading in {duration:g} s',
                       thermometer_rate)

    gyro_vals = dict(values['gyro'])
    effects = gyro_vals.pop('effects')
    gyro = GyroSpec(effects=tuple(k for k in EFFECT_IDS if effects[k]), **gyro_vals)
    return Scenario(
        name=the_name, description=description, source=source, sensor=sensor,
        imu_rate_hz=rate, duration_s=duration, profile=profile,
        thermal=ThermalSpec(**values['thermal']),
        thermometer=ThermometerSpec(**values['thermometer']),
        gyro=gyro, noise=NoiseSpec(**values['noise']), accel=AccelSpec(**values['accel']),
        rate_table=_rate_table(chk, merged.get('rate_table')),
        runs=RunsSpec(**values['runs']), data=merged)


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------

def scenario_dir() -> Path:
    """
    Return the directory of the shipped scenarios (``config/scenarios``).

    Returns
    -------
    pathlib.Path
        Found through :func:`gyro_tdc.resources.config_dir`.

    Raises
    ------
    ScenarioError
        If the configuration directory cannot be found.

    """
    from gyro_tdc import resources
    try:
        return resources.config_dir() / 'scenarios'
    except ScenarioError:
        raise
    except GyroTdcError as exc:
        raise ScenarioError(str(exc)) from exc


def list_scenarios() -> list[str]:
    """
    Return the names of the shipped scenarios, sorted.

    Returns
    -------
    list of str
        Stems of ``config/scenarios/*.yaml``.

    """
    from gyro_tdc import resources
    try:
        return resources.scenario_names()
    except GyroTdcError as exc:
        raise ScenarioError(str(exc)) from exc


def load_scenario(name_or_path: Union[PathLike, Scenario, Mapping[str, Any]]) -> Scenario:
    """
    Load and validate a scenario by shipped name, YAML path, mapping or Scenario.

    Parameters
    ----------
    name_or_path : str, os.PathLike, Mapping or Scenario
        A shipped name such as ``'l3gd20_paper'`` (``config/scenarios/NAME.yaml``), a path
        to a YAML file, a scenario mapping, or a Scenario (returned unchanged).

    Returns
    -------
    Scenario
        The validated scenario.

    Raises
    ------
    ScenarioError
        If the name is unknown, the file cannot be read or parsed, or a field is invalid.

    """
    if isinstance(name_or_path, Scenario):
        return name_or_path
    if isinstance(name_or_path, Mapping):
        return Scenario.from_dict(name_or_path)
    from gyro_tdc import resources
    try:
        path = resources.scenario_path(name_or_path)
    except ScenarioError:
        raise
    except GyroTdcError as exc:
        raise ScenarioError(str(exc)) from exc
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f'Cannot read scenario file {str(path)!r}: {exc}') from exc
    try:
        data = load_yaml(text, SCENARIO_LIMITS, source=path.name, error=ScenarioError)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or type(exc).__name__
        raise ScenarioError(f'{path.name}: not valid YAML{where}: {problem}') from exc
    return Scenario.from_dict(data if data is not None else {}, name=path.stem,
                              source=path.name)
