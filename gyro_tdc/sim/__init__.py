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
Thermal-chamber gyro simulator (pure numpy; no rclpy).

A chamber profile drives a chain of first-order lags (air, package, die); a thermometer reads
the package or the die; the gyro adds per-axis thermal effects and noise to the rate-table
reference. :func:`load_scenario` reads a scenario, :func:`simulate_scenario` runs it and
:func:`to_run` turns a run into a :class:`gyro_tdc.data.runs.Run`. See ``doc/internals/sim.md``.
"""

from gyro_tdc.model import EFFECT_IDS
from gyro_tdc.sim.chamber import (heat_conduction_time_s, max_temperature_step_c, nice_ceil,
                                  nice_floor, Profile, simulate_thermal, staircase_plan,
                                  StaircasePlan, ThermalHistory)
from gyro_tdc.sim.scenario import load_scenario, Scenario
from gyro_tdc.sim.simulator import (SimRun, SimStream, SimTruth, simulate_run, simulate_scenario,
                                    to_run)
from gyro_tdc.sim.specs import PRESETS
from gyro_tdc.sim.vehicle import CMD_VEL_TOPIC, TRUTH_TOPIC

__all__ = ['CMD_VEL_TOPIC', 'EFFECT_IDS', 'PRESETS', 'Profile', 'Scenario', 'SimRun', 'SimStream',
           'SimTruth', 'StaircasePlan', 'ThermalHistory', 'TRUTH_TOPIC', 'heat_conduction_time_s',
           'load_scenario', 'max_temperature_step_c', 'nice_ceil', 'nice_floor', 'simulate_run',
           'simulate_scenario', 'simulate_thermal', 'staircase_plan', 'to_run']
