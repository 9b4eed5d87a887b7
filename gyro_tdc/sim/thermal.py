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
Heat conduction: chamber set point -> air -> package -> MEMS die, as first-order lags.

:func:`simulate_thermal` integrates each stage exactly on a uniform internal grid
(first-order hold), fast enough for hours of data in milliseconds.
See ``doc/internals/sim.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.model import first_order_lag
from gyro_tdc.sim.chamber import Profile
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['ThermalHistory', 'simulate_thermal']


@dataclass(frozen=True)
class ThermalHistory:
    """
    Temperatures of every thermal node on the internal grid.

    Parameters
    ----------
    t : NDArray[np.float64], shape (G,), s
        Internal grid ``k * dt``.
    setpoint_c : NDArray[np.float64], shape (G,), degC
        Chamber profile (set point).
    air_c : NDArray[np.float64], shape (G,), degC
        Chamber air at the sensor.
    package_c : NDArray[np.float64], shape (G,), degC
        Sensor package (metal shell) temperature.
    die_c : NDArray[np.float64], shape (G,), degC
        MEMS die temperature.
    die_rate_c_per_s : NDArray[np.float64], shape (G,), degC/s
        Time derivative of the die temperature.
    thermometer_c : NDArray[np.float64], shape (G,), degC
        Noise-free, unquantised thermometer reading (lagged package or die).

    """

    t: NDArray[np.float64]
    setpoint_c: NDArray[np.float64]
    air_c: NDArray[np.float64]
    package_c: NDArray[np.float64]
    die_c: NDArray[np.float64]
    die_rate_c_per_s: NDArray[np.float64]
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
