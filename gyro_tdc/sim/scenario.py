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
Simulator scenarios: the schema, its validation, the Scenario, loading and overrides.

A scenario is a YAML mapping (``config/scenarios/NAME.yaml``) or a dict with a unit in every
key; unknown keys are errors. :func:`validate` checks one field by field (one
:class:`ScenarioError` naming the first bad field, what was expected and what was received),
merges it over the sensor preset and the defaults and builds the typed sections of
:mod:`gyro_tdc.sim.specs`; :func:`load_scenario` reads and validates one into a
:class:`Scenario`; :func:`gyro_tdc.base.resources.scenario_names` names the shipped ones.
Every section and its defaults: ``doc/internals/sim.md``.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
import os
from typing import Any, Callable, Mapping, Optional, Union

from gyro_tdc.base import (FieldChecker, is_number, MAX_SIM_RUNS, MAX_SIM_SAMPLES, plain,
                           RAD_PER_DEG, read_yaml, SCENARIO_LIMITS, scenario_path,
                           TEMP_PLAUSIBLE_C)
from gyro_tdc.errors import GyroTdcError, ScenarioError
from gyro_tdc.model import EFFECT_IDS
from gyro_tdc.sim import chamber
from gyro_tdc.sim.specs import (AccelSpec, GyroSpec, NoiseSpec, PRESETS, RateTable, RunsSpec,
                                section_fields, ThermalSpec, ThermometerSpec, Vec3)
from gyro_tdc.sim.vehicle import VEHICLE_FIELDS, VehicleSpec
import numpy as np

__all__ = ['DEFAULTS', 'FORMAT_VERSION', 'Scenario', 'load_scenario', 'merge', 'validate']

FORMAT_VERSION = 1

# Each section's type, its fields' (kind, default) on the type; each kind is a check of _KINDS.
_SPECS = {'thermal': ThermalSpec, 'thermometer': ThermometerSpec, 'gyro': GyroSpec,
          'noise': NoiseSpec, 'accel': AccelSpec, 'runs': RunsSpec}
_SECTIONS = {section: section_fields(spec) for section, spec in _SPECS.items()}
_DEFAULT = {s: {k: d for k, (_, d) in f.items()} for s, f in _SECTIONS.items()}
DEFAULTS: dict = {
    'format_version': FORMAT_VERSION, 'name': None, 'description': '', 'sensor': None,
    'imu_rate_hz': 100.0, 'duration_s': None, 'profile': {'start_c': 25.0, 'segments': []},
    **{s: d for s, d in _DEFAULT.items() if s != 'runs'}, 'rate_table': [],
    'runs': _DEFAULT['runs'],
}
_TOP = ('format_version', 'name', 'description', 'sensor', 'imu_rate_hz', 'duration_s',
        'profile', 'rate_table') + tuple(_SECTIONS) + ('vehicle',)
# Each segment kind: its builder and its fields' kinds ('points' has its own checks).
_SEGMENTS: dict[str, tuple[Any, dict[str, str]]] = {
    'hold': (chamber.hold_segment, {'duration_s': 'pos'}),
    'ramp': (chamber.ramp_segment, {'to_c': 'temp', 'rate_c_per_h': 'pos'}),
    'staircase': (chamber.staircase_segment, {'to_c': 'temp', 'step_c': 'pos', 'hold_s': 'pos'}),
    'step': (chamber.step_segment, {'to_c': 'temp'}),
    'points': (chamber.points_segment, {'t_s': 'list', 'temp_c': 'list'}),
}


def merge(base: Mapping, top: Mapping) -> dict:
    """Deep-merge ``top`` over ``base`` (mappings merge, everything else replaces)."""
    out = copy.deepcopy(dict(base))
    for key, value in top.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value)
        else:
            out[key] = plain(copy.deepcopy(value), str_keys=False)
    return out


#: Any number of a scenario, in its unit: far beyond every physical one, and squared (a
#: variance) still a float.
MAX_MAGNITUDE = 1e9


class _Checker(FieldChecker):
    """The scenario's field kinds on base's FieldChecker: one ScenarioError naming the field."""

    def __init__(self, source: str) -> None:
        super().__init__(self._error)
        self.source = source

    def _error(self, path: str, expected: str, got: Any) -> ScenarioError:
        shown = f'{got!r:.77}...' if len(repr(got)) > 80 else repr(got)
        return ScenarioError(f'{self.source}: `{path}`: expected {expected}, got {shown}.')

    def num(self, path: str, x: Any, *, low: float | None = None, strict: bool = False) -> float:
        v = (self.number(x, path, what='a finite number') if low is None else
             self.above(x, path, low, strict, what='a finite number'))
        if not abs(v) <= MAX_MAGNITUDE:
            raise self.fail(path, f'a number within +-{MAX_MAGNITUDE:g}', x)
        return v

    def seq(self, path: str, x: Any, expected: str, n: Optional[int] = None,
            ok: Callable[[float], bool] = lambda v: True) -> tuple[float, ...]:
        """Return a non-empty list of (``n``) numbers, each ``ok``, as a tuple of floats."""
        if (not isinstance(x, (list, tuple)) or not x or (n is not None and len(x) != n)
                or not all(is_number(e) and ok(float(e)) for e in x)):
            raise self.fail(path, expected, x)
        if not all(abs(float(e)) <= MAX_MAGNITUDE for e in x):
            raise self.fail(path, f'numbers within +-{MAX_MAGNITUDE:g}', x)
        return tuple(float(e) for e in x)

    def axis(self, path: str, x: Any, *, low: Optional[float] = None) -> Vec3:
        expected = 'a number or a list of 3 numbers' + ('' if low is None else f' >= {low:g}')
        ok = (lambda v: True) if low is None else (lambda v: v >= low)
        if not (is_number(x) and ok(float(x))):
            return self.seq(path, x, expected, 3, ok)      # a number not ok fails here too
        if not abs(float(x)) <= MAX_MAGNITUDE:
            raise self.fail(path, f'a number within +-{MAX_MAGNITUDE:g}', x)
        return (float(x),) * 3

    def range(self, path: str, x: Any, positive: bool) -> tuple[float, float]:
        expected = f'[low, high] with {"0 < low" if positive else "0 <= low"} <= high'
        lo, hi = self.seq(path, x, expected, 2)
        if lo < 0.0 or hi < lo or (positive and lo <= 0.0):
            raise self.fail(path, expected, x)
        return lo, hi

    def choice(self, path: str, x: Any, ok: bool | type, expected: str) -> Any:
        """Return ``x`` when ``ok`` (or an instance of the type ``ok``), else fail."""
        if not (isinstance(x, ok) if isinstance(ok, type) else ok):
            raise self.fail(path, expected, x)
        return x

    def mapping(self, path: str, x: Any, allowed: tuple[str, ...]) -> dict:
        """Return ``x`` as a dict (base's check) whose keys are all ``allowed``."""
        out = super().mapping(x, path)
        for key in out:
            if key not in allowed:
                where = f'{path}.{key}' if path else str(key)
                raise self.fail(where, 'a known key (one of ' + ', '.join(allowed) + ')', key)
        return out

    def section(self, path: str, x: Any, fields: Mapping[str, tuple[str, Any]]) -> dict:
        """Return a section's fields checked by kind (missing ones at their defaults)."""
        body = self.mapping(path, x, tuple(fields))
        return {key: _KINDS[kind](self, f'{path}.{key}', body.get(key, default))
                for key, (kind, default) in fields.items()}

    def effects(self, path: str, x: Any) -> dict[str, bool]:
        if isinstance(x, (list, tuple)):
            if unknown := [e for e in x if e not in EFFECT_IDS]:
                raise self.fail(path, 'effect ids from ' + ', '.join(EFFECT_IDS), unknown[0])
            return {k: k in x for k in EFFECT_IDS}
        if isinstance(x, Mapping):
            if unknown := [k for k in x if k not in EFFECT_IDS]:
                raise self.fail(f'{path}.{unknown[0]}', 'an effect id ('
                                + ', '.join(EFFECT_IDS) + ')', unknown[0])
            return {k: self.boolean(x.get(k), f'{path}.{k}') for k in EFFECT_IDS}
        raise self.fail(path, 'a list of effect ids or a mapping id -> bool', x)


# Each field kind of the sections, the segments and the vehicle: its check (checker, path, x).
_KINDS: dict[str, Callable[[_Checker, str, Any], Any]] = {
    'num': lambda c, p, x: c.num(p, x),
    'pos': lambda c, p, x: c.num(p, x, low=0.0, strict=True),
    'nonneg': lambda c, p, x: c.num(p, x, low=0.0),
    'temp': lambda c, p, x: c.number(x, p, *TEMP_PLAUSIBLE_C, 'a temperature in degC'),
    'axis': lambda c, p, x: c.axis(p, x),
    'axis_nonneg': lambda c, p, x: c.axis(p, x, low=0.0),
    'bool': lambda c, p, x: c.boolean(x, p),
    'count': lambda c, p, x: c.choice(p, x, isinstance(x, int) and not isinstance(x, bool)
                                      and 1 <= x <= MAX_SIM_RUNS,
                                      f'an integer within 1 .. {MAX_SIM_RUNS:,}'),
    'location': lambda c, p, x: c.choice(p, x, x in ('package', 'die'), "'package' or 'die'"),
    'taus': lambda c, p, x: c.seq(p, x, 'a non-empty list of numbers > 0', ok=lambda v: v > 0.0),
    'tilt': lambda c, p, x: c.seq(p, x, 'roll and pitch in degrees, a list of 2 numbers within '
                                  '+-180', 2, lambda v: abs(v) <= 180.0),
    'effects': lambda c, p, x: c.effects(p, x),
    'range': lambda c, p, x: c.range(p, x, positive=False),
    'prange': lambda c, p, x: c.range(p, x, positive=True),
}


def _points(chk: _Checker, where: str, seg: Mapping) -> chamber.Segment:
    """Return the segment of a ``points`` entry, its two lists checked."""
    ts, temps = (chk.seq(f'{where}.{key}', seg[key], 'a non-empty list of numbers')
                 for key in ('t_s', 'temp_c'))
    if len(ts) != len(temps):
        raise chk.fail(f'{where}.temp_c', f'{len(ts)} values (as many as t_s)', seg['temp_c'])
    if ts[0] != 0.0 or any(b < a for a, b in zip(ts, ts[1:])):
        raise chk.fail(f'{where}.t_s', 'times starting at 0 and never decreasing', seg['t_s'])
    lo, hi = TEMP_PLAUSIBLE_C
    if not lo <= min(temps) <= max(temps) <= hi:
        raise chk.fail(f'{where}.temp_c', f'temperatures within {lo:g} .. {hi:g} degC',
                       seg['temp_c'])
    return chamber.points_segment(np.asarray(ts), np.asarray(temps))


def _profile(chk: _Checker, raw: Any) -> chamber.Profile:
    prof = chk.mapping('profile', raw, ('start_c', 'segments'))
    start = _KINDS['temp'](chk, 'profile.start_c', prof.get('start_c'))
    segments = prof.get('segments')
    if not isinstance(segments, (list, tuple)) or not segments:
        raise chk.fail('profile.segments', 'a non-empty list of segments', segments)
    built = []
    for i, seg in enumerate(segments):
        where = f'profile.segments[{i}]'
        if not isinstance(seg, Mapping) or seg.get('kind') not in tuple(_SEGMENTS):
            got = seg.get('kind') if isinstance(seg, Mapping) else seg
            raise chk.fail(f'{where}.kind' if isinstance(seg, Mapping) else where,
                           'a segment kind (' + ', '.join(_SEGMENTS) + ')', got)
        kind = seg['kind']
        make, fields = _SEGMENTS[kind]
        chk.mapping(where, seg, ('kind',) + tuple(fields))
        if missing := [key for key in fields if key not in seg]:
            raise chk.fail(f'{where}.{missing[0]}', f'a value (required by kind {kind!r})', None)
        built.append(_points(chk, where, seg) if kind == 'points' else make(
            *(_KINDS[bound](chk, f'{where}.{key}', seg[key]) for key, bound in fields.items())))
    try:
        profile = chamber.Profile.from_segments(start, built)
    except chamber.SegmentError as exc:     # a staircase of too many steps
        raise chk.fail('profile.segments', exc.expected, exc.got) from None
    if profile.duration_s <= 0.0:
        raise chk.fail('profile.segments', 'segments lasting longer than 0 s in total', segments)
    return profile


def _rate_table(chk: _Checker, raw: Any) -> RateTable:
    raw = [] if raw is None else raw
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
        if ('rate_dps' in entry) == ('rate_rad_s' in entry):
            raise chk.fail(where, 'exactly one of rate_dps or rate_rad_s', entry)
        key, factor = ('rate_dps', RAD_PER_DEG) if 'rate_dps' in entry else ('rate_rad_s', 1.0)
        times.append(t)
        rates.append(tuple(v * factor for v in chk.axis(f'{where}.{key}', entry[key])))
    if not times or times[0] > 0.0:          # at rest from 0 s until the first entry
        times, rates = [0.0] + times, [(0.0, 0.0, 0.0)] + rates
    return RateTable(t_s=tuple(times), rate_rad_s=tuple(rates))


def validate(data: Any, *, name: Optional[str], source: str) -> dict[str, Any]:
    """
    Validate a scenario mapping and return the fields of its Scenario.

    Parameters
    ----------
    data : Any
        The scenario as read from YAML (the schema: ``doc/internals/sim.md``).
    name : str, optional
        Name used when ``data`` has none.
    source : str
        Where ``data`` came from, for error messages.

    Returns
    -------
    dict
        Keyword arguments of ``Scenario``: the typed sections and ``data``, the normalised
        mapping (preset and defaults merged).

    Raises
    ------
    ScenarioError
        Naming the first bad field, what was expected and what was received.

    """
    chk = _Checker(source)
    if not isinstance(data, Mapping):
        raise ScenarioError(f'{source}: expected the scenario to be a mapping of sections, '
                            f'got {type(data).__name__}.')
    top = chk.mapping('', data, _TOP)
    version = top.get('format_version', FORMAT_VERSION)
    if version != FORMAT_VERSION:
        raise chk.fail('format_version', str(FORMAT_VERSION), version)
    sensor = top.get('sensor')
    if sensor is not None and not (isinstance(sensor, str) and sensor in PRESETS):
        raise chk.fail('sensor', 'a preset name (' + ', '.join(sorted(PRESETS)) + ') or null',
                       sensor)
    # A list of effects means exactly those: expand it before merging over the defaults.
    gyro_in = top.get('gyro')
    if isinstance(gyro_in, Mapping) and isinstance(gyro_in.get('effects'), (list, tuple)):
        top['gyro'] = dict(gyro_in, effects=chk.effects('gyro.effects', gyro_in['effects']))
    # Lists (rate_table, segments) replace, never merge.
    merged = merge(merge(DEFAULTS, PRESETS[sensor] if sensor else {}), top)

    the_name = merged['name'] = chk.choice('name', merged.get('name') or name or 'scenario',
                                           str, 'a string')
    description = chk.choice('description', merged.get('description') or '', str, 'a string')
    rate = chk.num('imu_rate_hz', merged.get('imu_rate_hz'), low=0.0, strict=True)

    values = {section: chk.section(section, merged[section], fields)
              for section, fields in _SECTIONS.items()}
    effects = merged['gyro']['effects'] = dict(values['gyro']['effects'])
    values['gyro']['effects'] = tuple(k for k in EFFECT_IDS if effects[k])

    profile = _profile(chk, merged['profile'])
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

    # Optional vehicle day (gyro_tdc.sim.vehicle): normalised over its defaults when present.
    vehicle = merged.pop('vehicle', None)
    if vehicle is not None:
        vehicle = VehicleSpec(**chk.section('vehicle', vehicle, VEHICLE_FIELDS))
        merged['vehicle'] = vehicle.to_dict()
    # The other streams a run samples, as bounded as the IMU's (checked where it is chosen).
    for where, r in (('thermometer.rate_hz', thermometer_rate),
                     ('vehicle.cmd_vel_rate_hz', vehicle.cmd_vel_rate_hz if vehicle else 0.0)):
        if not duration * r <= MAX_SIM_SAMPLES:
            raise chk.fail(where, f'at most {MAX_SIM_SAMPLES:.3g} samples in {duration:g} s', r)
    return dict(name=the_name, description=description, source=source, sensor=sensor,
                imu_rate_hz=rate, duration_s=duration, profile=profile,
                **{section: spec(**values[section]) for section, spec in _SPECS.items()},
                rate_table=_rate_table(chk, merged.get('rate_table')), data=merged,
                vehicle=vehicle)


# --------------------------------------------------------------------------------------------
# The Scenario
# --------------------------------------------------------------------------------------------
PathLike = Union[str, 'os.PathLike[str]']


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
    vehicle : gyro_tdc.sim.vehicle.VehicleSpec or None
        A vehicle day (drives, stops on slopes, self-heating) instead of a chamber.

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
    vehicle: Optional[VehicleSpec] = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, name: Optional[str] = None,
                  source: str = '<dict>') -> 'Scenario':
        """
        Validate a scenario mapping (as read from YAML) and build the scenario.

        ``name`` is used when ``data`` has none, ``source`` names it in a ScenarioError (the first
        bad field, what was expected and what was received).
        """
        return cls(**validate(data, name=name, source=source))

    def to_dict(self) -> dict:
        """Return the normalised scenario mapping (a deep copy, YAML-safe)."""
        return copy.deepcopy(self.data)

    def with_overrides(self, overrides: Mapping[str, Any]) -> 'Scenario':
        """
        Return a copy with fields replaced by dotted path, validated again.

        ``overrides``: e.g. ``{'gyro.effects.dT3': True, 'noise.enabled': False,
        'duration_s': 600.0}``; a mapping value replacing a mapping is merged into it.
        ScenarioError: a path is malformed or the result does not validate.
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
                child = node[part] = {} if node.get(part) is None else node[part]
                if not isinstance(child, dict):
                    raise ScenarioError(f'Override {key!r}: `{".".join(parts[:i + 1])}` is '
                                        f'not a mapping (it holds {child!r}).')
                node = child
            node[parts[-1]] = merge(node, {parts[-1]: value})[parts[-1]]
        return self.from_dict(data, name=self.name, source=self.source)


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------

def load_scenario(name_or_path: Union[PathLike, Scenario, Mapping[str, Any]]) -> Scenario:
    """
    Load and validate a scenario by shipped name, YAML path, mapping or Scenario.

    A shipped name such as ``'l3gd20_paper'`` is ``config/scenarios/NAME.yaml``; a Scenario
    is returned unchanged.

    Raises
    ------
    ScenarioError
        If the name is unknown, the file cannot be read or parsed, or a field is invalid.

    """
    if isinstance(name_or_path, Scenario):
        return name_or_path
    if isinstance(name_or_path, Mapping):
        return Scenario.from_dict(name_or_path)
    try:
        path = scenario_path(name_or_path)
    except ScenarioError:
        raise
    except GyroTdcError as exc:         # no config directory: one ScenarioError too
        raise ScenarioError(str(exc)) from exc
    data = read_yaml(path, SCENARIO_LIMITS, error=ScenarioError)
    return Scenario.from_dict({} if data is None else data, name=path.stem, source=path.name)
