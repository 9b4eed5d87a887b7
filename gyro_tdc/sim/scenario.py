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
Simulator scenarios: the schema, the Scenario, loading and overrides.

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
      effects: [bias, dT, dT2]    # or a mapping id -> bool; ids of gyro_tdc.model.effects
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
    accel:                        # specific force: gravity in the sensor frame + offset + noise
      gravity_mps2: 9.80665       # magnitude; on +z when level
      noise_mps2_per_rt_hz: 0.0
      tilt_deg: [0.0, 0.0]        # roll, pitch of the sensor (fixed per run) ...
      tilt_std_deg: 0.0           # ... plus a random roll and pitch drawn per run (std)
      bias_mg: 0.0                # static offset (the ordinary calibration's)
      dT_mg_per_c: 0.0            # offset change per degC of the die (dT of gyro.t_ref_c)
      dT2_mg_per_c2: 0.0          # curvature of the offset in the die temperature
      sensitivity_mg_per_digit: 0.0  # quantisation step, 0 = none
      range_g: 0.0                # saturation, 0 = none
      reorient_at_s: 0.0          # a mid-run orientation change at this time, 0 = none ...
      reorient_tilt_deg: [0.0, 0.0]  # ... adding this roll and pitch
    rate_table:                   # reference rate schedule (ZOH); empty = still
      - {t_s: 0.0, rate_dps: [10.0, 5.0, 20.0]}   # or rate_rad_s
    runs:
      count: 1                    # a multi-run scenario yields several runs
      bias_offset_dps_std: 0.0    # run-to-run bias offset (drawn per run)
    vehicle:                      # optional: a vehicle day instead of a chamber (see
      start_parked_s: 1800.0      # gyro_tdc.sim.vehicle for every field and default);
      drive_s: [600.0, 1800.0]    # the profile is then the ambient, the rate table empty

An effect switched off contributes nothing whatever its coefficient; the ``lag`` switch
turns ``thermal.tau_die_s`` on and off.
"""


from __future__ import annotations

import copy
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Any, Mapping, Optional, Union

from gyro_tdc.base import load_yaml, plain, SCENARIO_LIMITS
from gyro_tdc.errors import GyroTdcError, ScenarioError
from gyro_tdc.model import EFFECT_IDS
from gyro_tdc.sim import chamber
from gyro_tdc.sim.schema import DEG, FORMAT_VERSION, merge, validate
from gyro_tdc.sim.specs import (AccelSpec, GyroSpec, NoiseSpec, RateTable, RunsSpec, ThermalSpec,
                                ThermometerSpec)
from gyro_tdc.sim.vehicle import VehicleSpec
import yaml

__all__ = [
    'DEG',
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
        return cls(**validate(data, name=name, source=source))

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
                node[last] = merge(node[last], value)
            else:
                node[last] = plain(value, str_keys=False)
        return self.from_dict(data, name=self.name, source=self.source)

    @property
    def effects(self) -> tuple[str, ...]:
        """Return the enabled effect ids."""
        return self.gyro.effects


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------

def scenario_dir() -> Path:
    """
    Return the directory of the shipped scenarios (``config/scenarios``).

    Returns
    -------
    pathlib.Path
        Found through :func:`gyro_tdc.base.resources.config_dir`.

    Raises
    ------
    ScenarioError
        If the configuration directory cannot be found.

    """
    from gyro_tdc.base import config_dir
    try:
        return config_dir() / 'scenarios'
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
    from gyro_tdc.base import scenario_names
    try:
        return scenario_names()
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
    from gyro_tdc.base import scenario_path
    try:
        path = scenario_path(name_or_path)
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
