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

A scenario is a YAML mapping (``config/scenarios/NAME.yaml``) or a dict with a unit in every
key; unknown keys are errors. :func:`load_scenario` reads and validates one into a
:class:`Scenario`; :func:`gyro_tdc.base.resources.scenario_names` names the shipped ones.
Every section and its defaults: ``doc/internals/sim.md``.
"""


from __future__ import annotations

import copy
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Any, Mapping, Optional, Union

from gyro_tdc.base import config_dir, read_yaml, SCENARIO_LIMITS, scenario_path
from gyro_tdc.errors import GyroTdcError, ScenarioError
from gyro_tdc.sim import chamber
from gyro_tdc.sim.schema import merge, validate
from gyro_tdc.sim.specs import (AccelSpec, GyroSpec, NoiseSpec, RateTable, RunsSpec, ThermalSpec,
                                ThermometerSpec)
from gyro_tdc.sim.vehicle import VehicleSpec

__all__ = ['Scenario', 'load_scenario', 'scenario_dir']

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
                child = node.get(part)
                if child is None:
                    child = node[part] = {}
                if not isinstance(child, dict):
                    raise ScenarioError(f'Override {key!r}: `{".".join(parts[:i + 1])}` is '
                                        f'not a mapping (it holds {child!r}).')
                node = child
            node[parts[-1]] = merge(node, {parts[-1]: value})[parts[-1]]
        return self.from_dict(data, name=self.name, source=self.source)


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
    return _as_scenario_error(config_dir) / 'scenarios'


def _as_scenario_error(call: Any, *args: Any) -> Any:
    """Return ``call(*args)``; a resource error becomes a ScenarioError (one message)."""
    try:
        return call(*args)
    except ScenarioError:
        raise
    except GyroTdcError as exc:
        raise ScenarioError(str(exc)) from exc


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
    path = _as_scenario_error(scenario_path, name_or_path)
    data = read_yaml(path, SCENARIO_LIMITS, error=ScenarioError)
    return Scenario.from_dict({} if data is None else data, name=path.stem, source=path.name)
