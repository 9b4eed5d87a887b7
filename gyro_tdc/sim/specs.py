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
The typed sections of a simulator scenario (frozen dataclasses, scenario units), and presets.

:func:`gyro_tdc.sim.scenario.validate` checks a scenario mapping into these; the simulator
reads them from :class:`gyro_tdc.sim.scenario.Scenario`. A sensor preset (:data:`PRESETS`)
holds the ``gyro``, ``noise`` and ``accel`` sections of a device: a scenario names one with
``sensor: l3gd20`` and its own sections override it field by field (the datasheet figures
and the chosen unit: ``doc/internals/sim.md``).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields, MISSING
from typing import Any

from gyro_tdc.base import G0
from gyro_tdc.model import EFFECT_IDS
import numpy as np
from numpy.typing import NDArray

__all__ = ['AccelSpec', 'GyroSpec', 'NoiseSpec', 'preset', 'PRESETS', 'RateTable', 'RunsSpec',
           'ThermalSpec', 'ThermometerSpec', 'Vec3', 'section_fields', 'spec_field']

Vec3 = tuple[float, float, float]


def spec_field(kind: str, default: Any, value: Any = MISSING) -> Any:
    """
    Return a section field: the schema checks it as ``kind``, ``default`` when a scenario omits it.

    ``value`` is the dataclass default, for a section built in code without a scenario.
    """
    return field(default=value, metadata={'kind': kind, 'default': default})


def section_fields(spec: type) -> dict[str, tuple[str, Any]]:
    """Return a section's fields as name -> (kind, scenario default), in order."""
    return {f.name: (f.metadata['kind'], f.metadata['default']) for f in fields(spec)}


@dataclass(frozen=True)
class ThermalSpec:
    """
    Heat-conduction chain, see :func:`gyro_tdc.sim.chamber.simulate_thermal`.

    Parameters
    ----------
    tau_air_s, tau_package_s, tau_die_s : float, s
        Set point -> air, air -> package, package -> die time constants.
    internal_step_s : float, s
        Integration grid step.

    """

    tau_air_s: float = spec_field('nonneg', 0.0)
    tau_package_s: float = spec_field('nonneg', 0.0)
    tau_die_s: float = spec_field('nonneg', 0.0)
    internal_step_s: float = spec_field('pos', 0.1)


@dataclass(frozen=True)
class ThermometerSpec:
    """Thermometer: where it sits, how often and how finely it reads."""

    #: ``'package'`` (an external probe on the package) or ``'die'`` (the on-die register).
    location: str = spec_field('location', 'package')
    #: Sample rate, Hz.
    rate_hz: float = spec_field('pos', 1.0)
    #: Quantisation step, degC (0 = none).
    resolution_c: float = spec_field('nonneg', 0.0)
    #: White noise standard deviation, degC.
    noise_c: float = spec_field('nonneg', 0.0)
    #: Sensor time constant, s.
    tau_s: float = spec_field('nonneg', 0.0)
    #: Calibration offset added to every reading, degC.
    offset_c: float = spec_field('num', 0.0)


@dataclass(frozen=True)
class GyroSpec:
    """Deterministic gyro error model, in the scenario's units (deg/s based)."""

    #: Enabled effect ids (subset of :data:`gyro_tdc.model.effects.EFFECT_IDS`).
    effects: tuple[str, ...] = spec_field('effects',
                                          {k: k in ('bias', 'dT', 'dT2') for k in EFFECT_IDS})
    #: Reference temperature of ``dT_die``, degC.
    t_ref_c: float = spec_field('num', 25.0)
    #: Constant term of the polynomial in ``dT_die`` per axis, deg/s.
    bias_dps: Vec3 = spec_field('axis', 0.0)
    #: Linear coefficient in ``dT_die`` per axis, deg/s/degC.
    dT_dps_per_c: Vec3 = spec_field('axis', 0.0)
    #: Quadratic coefficient in ``dT_die`` per axis, deg/s/degC^2.
    dT2_dps_per_c2: Vec3 = spec_field('axis', 0.0)
    #: Cubic coefficient in ``dT_die`` per axis, deg/s/degC^3.
    dT3_dps_per_c3: Vec3 = spec_field('axis', 0.0)
    #: Gain on the die's rate of temperature change per axis, (deg/s)/(degC/s).
    dTdt_dps_per_c_per_s: Vec3 = spec_field('axis', 0.0)
    #: Scale-factor change vs temperature per axis, ppm/degC.
    scale_ppm_per_c: Vec3 = spec_field('axis', 0.0)
    #: Warm-up transient amplitude per axis, deg/s.
    warmup_dps: Vec3 = spec_field('axis', 0.0)
    #: Warm-up time constant, s.
    warmup_tau_s: float = spec_field('pos', 300.0)
    #: Power-on time relative to the start of the recording, s.
    power_on_s: float = spec_field('num', 0.0)
    #: One digit of the output (quantisation step), mdps.
    sensitivity_mdps_per_digit: float = spec_field('nonneg', 0.0)
    #: Full scale (saturation), deg/s; 0 = none.
    range_dps: float = spec_field('nonneg', 0.0)
    #: Round the output to digits.
    quantise: bool = spec_field('bool', True)


@dataclass(frozen=True)
class NoiseSpec:
    """Stochastic gyro errors: white rate noise, bias instability and rate random walk."""

    #: Master switch.
    enabled: bool = spec_field('bool', True)
    #: White rate noise density per axis, (deg/s)/sqrt(Hz).
    arw_dps_per_rt_hz: Vec3 = spec_field('axis_nonneg', 0.0)
    #: Standard deviation of the Gauss-Markov sum per axis, deg/s.
    bias_instability_dps: Vec3 = spec_field('axis_nonneg', 0.0)
    #: Correlation times of the Gauss-Markov processes, s.
    bias_instability_tau_s: tuple[float, ...] = spec_field('taus', [10.0, 100.0, 1000.0])
    #: Rate random walk coefficient per axis, (deg/s)/sqrt(s).
    rrw_dps_per_rt_s: Vec3 = spec_field('axis_nonneg', 0.0)


@dataclass(frozen=True)
class AccelSpec:
    """
    Accelerometer: gravity in the sensor frame, a thermal offset of the die, noise, digits.

    Per axis, with ``dT = T_die - gyro.t_ref_c`` (the die the gyro sits on) and
    ``g0 = 9.80665 m/s^2`` per g::

        accel = gravity_mps2 * u(roll, pitch) + g0 / 1000 * (bias + a1 dT + a2 dT^2) + white

    then saturated at ``range_g`` and quantised to ``sensitivity_mg_per_digit``. ``u`` is the
    unit vector of "up" in the sensor frame, ``(-sin p, sin r cos p, cos r cos p)``: +z when
    level. The tilt is fixed per run; ``reorient_at_s`` > 0 changes it mid-run.
    """

    #: Magnitude of the specific force at rest, m/s^2.
    gravity_mps2: float = spec_field('num', G0)
    #: Noise density per axis, (m/s^2)/sqrt(Hz).
    noise_mps2_per_rt_hz: Vec3 = spec_field('axis_nonneg', 0.0)
    #: Roll and pitch of the sensor, deg ((0, 0) puts gravity on +z).
    tilt_deg: tuple[float, float] = spec_field('tilt', [0.0, 0.0], (0.0, 0.0))
    #: Standard deviation of a random roll and pitch added per run, deg.
    tilt_std_deg: float = spec_field('nonneg', 0.0, 0.0)
    #: Static offset per axis, mg (the ordinary calibration's; not thermal).
    bias_mg: Vec3 = spec_field('axis', 0.0, (0.0, 0.0, 0.0))
    #: Offset change per degC of the die, per axis, mg/degC.
    dT_mg_per_c: Vec3 = spec_field('axis', 0.0, (0.0, 0.0, 0.0))
    #: Curvature of the offset in the die temperature, per axis, mg/degC^2.
    dT2_mg_per_c2: Vec3 = spec_field('axis', 0.0, (0.0, 0.0, 0.0))
    #: One output digit (quantisation step), mg; 0 = not quantised.
    sensitivity_mg_per_digit: float = spec_field('nonneg', 0.0, 0.0)
    #: Full scale (saturation), g; 0 = none.
    range_g: float = spec_field('nonneg', 0.0, 0.0)
    #: Time of a mid-run orientation change (for the detection tests), s; 0 = none.
    reorient_at_s: float = spec_field('nonneg', 0.0, 0.0)
    #: Roll and pitch added at ``reorient_at_s``, deg.
    reorient_tilt_deg: tuple[float, float] = spec_field('tilt', [0.0, 0.0], (0.0, 0.0))


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
        Standard deviation of the run-to-run bias offset: the turn-on offset of each power
        cycle, drawn per run from the seed and the run index.

    """

    count: int = spec_field('count', 1)
    bias_offset_dps_std: Vec3 = spec_field('axis_nonneg', 0.0)


def _sensor(range_dps: float, bias: list, dT: list, dT2: list, dT3: list, dTdt: list,
            scale: list, warmup: list, warmup_tau_s: float, bias_instability: list) -> dict:
    """Return one device's sections: its datasheet figures beside what both devices share."""
    return {
        'gyro': {'t_ref_c': 25.0, 'sensitivity_mdps_per_digit': 8.75, 'range_dps': range_dps,
                 'quantise': True, 'bias_dps': bias, 'dT_dps_per_c': dT, 'dT2_dps_per_c2': dT2,
                 'dT3_dps_per_c3': dT3, 'dTdt_dps_per_c_per_s': dTdt, 'scale_ppm_per_c': scale,
                 'warmup_dps': warmup, 'warmup_tau_s': warmup_tau_s, 'power_on_s': 0.0},
        'noise': {'enabled': True, 'arw_dps_per_rt_hz': [0.03, 0.03, 0.03],
                  'bias_instability_dps': bias_instability,
                  'bias_instability_tau_s': [10.0, 100.0, 1000.0],
                  'rrw_dps_per_rt_s': [1.0e-5, 1.0e-5, 1.0e-5]},
        'accel': {'gravity_mps2': G0, 'noise_mps2_per_rt_hz': 0.0015},
    }


PRESETS: dict[str, dict] = {
    'l3gd20': _sensor(250.0, [3.6, -4.3, 1.3], [0.030, -0.024, 0.012], [8.0e-4, 6.0e-4, -2.5e-4],
                      [4.0e-6, -3.0e-6, 2.0e-6], [6.0, -4.0, 3.0], [160.0, -120.0, 90.0],
                      [0.25, -0.18, 0.12], 240.0, [0.004, 0.005, 0.004]),
    'i3g4250d': _sensor(245.0, [2.6, -6.2, 1.3], [0.026, -0.032, 0.010], [5.0e-4, 8.0e-4, -2.0e-4],
                        [3.0e-6, -4.0e-6, 1.5e-6], [5.0, -5.0, 2.5], [150.0, -110.0, 130.0],
                        [0.2, -0.22, 0.1], 300.0, [0.004, 0.004, 0.005]),
}


def preset(name: str) -> dict:
    """
    Return a deep copy of the ``gyro``, ``noise`` and ``accel`` sections of a sensor preset.

    Raises
    ------
    KeyError
        If ``name`` is not a key of ``PRESETS`` (``'l3gd20'``, ``'i3g4250d'``).

    """
    return copy.deepcopy(PRESETS[name])
