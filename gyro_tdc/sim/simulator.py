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
Simulate a gyro in a thermal chamber on a rate table: whole runs as numpy arrays.

:func:`simulate_run` and :func:`simulate_scenario` compute each effect's term of the gyro
and accelerometer outputs, noise, saturation and digits, vectorised, with one seeded random
stream per component (switching an effect off leaves the others' noise unchanged);
:class:`SimStream` hands a run out chunk by chunk up to a requested simulated time, for a live
driver. The output equation: ``doc/internals/sim.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
from typing import Any, Mapping, NamedTuple, Optional, Sequence, Union

from gyro_tdc.base import G0, is_number, MG, RAD_PER_DEG
from gyro_tdc.data import Run
from gyro_tdc.errors import ScenarioError
from gyro_tdc.model import EFFECT_IDS
from gyro_tdc.sim.chamber import simulate_thermal, ThermalHistory
from gyro_tdc.sim.noise import gauss_markov, quantise, random_walk, white_noise
from gyro_tdc.sim.scenario import load_scenario, Scenario
from gyro_tdc.sim.specs import GyroSpec, NoiseSpec, ThermometerSpec
from gyro_tdc.sim.vehicle import (gravity_in_sensor, heated_profile, plan_legs, vehicle_motion,
                                  VehicleMotion)
import numpy as np
from numpy.typing import NDArray

__all__ = ['G0', 'ImuChunk', 'RefChunk', 'SimRun', 'SimStream', 'SimTruth', 'TempChunk',
           'simulate_run', 'simulate_scenario', 'to_run']

ScenarioLike = Union[Scenario, str, 'os.PathLike[str]', Mapping[str, Any]]

# Child random streams of one run, in SeedSequence.spawn order.
# Appending a stream leaves the earlier ones (and so every earlier run) unchanged.
_STREAMS = ('offset', 'white', 'bias_instability', 'rrw', 'accel', 'thermometer', 'tilt',
            'vehicle')


@dataclass(frozen=True, eq=False)
class SimTruth:
    """
    What the simulator knows and a real experiment does not.

    The true temperatures, drift and noise behind a simulated run: tests check what a model
    recovered against them.
    """

    #: MEMS die temperature at the IMU stamps (N,), degC.
    die_c: NDArray[np.float64]
    #: Its time derivative (N,), degC/s.
    die_rate_c_per_s: NDArray[np.float64]
    #: Package temperature at the IMU stamps (N,), degC.
    package_c: NDArray[np.float64]
    #: Chamber air temperature at the IMU stamps (N,), degC.
    air_c: NDArray[np.float64]
    #: Deterministic error ``output - w_ref`` before noise, saturation and quantisation
    #: (N, 3), rad/s.
    drift: NDArray[np.float64]
    #: Enabled effect ids.
    effects: tuple[str, ...]
    #: Applied coefficients (3,) by effect id, zero when the effect is off, ``bias`` rad/s
    #: (run offset included), ``dT`` rad/s/degC, ``dT2`` rad/s/degC^2, ``dT3``
    #: rad/s/degC^3, ``dTdt`` (rad/s)/(degC/s), ``scale`` 1/degC, ``warmup`` rad/s.
    coefficients: dict[str, NDArray[np.float64]]
    #: ``t_ref_c``, ``tau_die_s`` (applied die lag), ``tau_package_s``, ``tau_air_s``,
    #: ``thermometer_tau_s``, ``warmup_tau_s``, ``power_on_s``.
    params: dict[str, float]
    #: This run's run-to-run bias offset (3,), rad/s (part of ``coefficients['bias']``).
    bias_offset: NDArray[np.float64]
    #: Per-sample standard deviation of the white rate noise (3,), rad/s
    #: (``density sqrt(rate)``).
    white_std: NDArray[np.float64]
    #: One output digit, rad/s (0 when not quantised).
    quant_step: float
    #: Noise floor per sample (3,), rad/s, ``sqrt(white_std^2 + quant_step^2 / 12)``.
    noise_std: NDArray[np.float64]
    #: Every thermal node on the internal grid.
    thermal: ThermalHistory = field(repr=False)
    #: Accelerometer offset before noise (N, 3), m/s^2, static bias plus the thermal terms.
    accel_offset: NDArray[np.float64] = field(default=None, repr=False)
    #: Its change with temperature alone (N, 3), m/s^2, relative to ``t_ref_c`` (what a model
    #: removes).
    accel_thermal: NDArray[np.float64] = field(default=None, repr=False)
    #: Gravity in the sensor frame before and after ``reorient_at_s`` (2, 3), m/s^2 (equal
    #: without one).
    accel_gravity: NDArray[np.float64] = field(default=None)
    #: Roll and pitch of this run (2,), deg (before any reorientation).
    accel_tilt_deg: NDArray[np.float64] = field(default=None)
    #: Time of the orientation change, s (0 for none).
    accel_reorient_s: float = 0.0
    #: Coefficients (3,) by term, ``bias`` m/s^2, ``dT`` m/s^2/degC, ``dT2`` m/s^2/degC^2.
    accel_coefficients: dict = field(default_factory=dict)
    #: Per-sample standard deviation of the accelerometer's white noise (3,), m/s^2.
    accel_white_std: NDArray[np.float64] = field(default=None)
    #: One accelerometer digit, m/s^2 (0 when not quantised).
    accel_quant_step: float = 0.0
    #: Accelerometer noise floor per sample (3,), m/s^2, ``sqrt(white^2 + step^2 / 12)``.
    accel_noise_std: NDArray[np.float64] = field(default=None)


@dataclass(frozen=True, eq=False)
class SimRun:
    """
    One simulated run, as a driver and thermometer would record it.

    Parameters
    ----------
    name : str
        ``SCENARIO`` or ``SCENARIO/runK`` (K from 1) for multi-run scenarios.
    imu_t : NDArray[np.float64], shape (N,), s
        IMU stamps ``k / rate_hz`` from 0.
    gyro : NDArray[np.float64], shape (N, 3), rad/s
        Gyro output.
    accel : NDArray[np.float64], shape (N, 3), m/s^2
        Accelerometer output (gravity in the sensor frame plus offset and noise).
    temp_t : NDArray[np.float64], shape (M,), s
        Thermometer stamps (its own rate).
    temp_c : NDArray[np.float64], shape (M,), degC
        Thermometer readings, quantised to its resolution.
    temp_var : float, degC^2
        Thermometer variance (noise plus quantisation), for ``Temperature.variance``.
    ref_t : NDArray[np.float64], shape (R,), s
        Rate-table change points (the first at 0).
    ref : NDArray[np.float64], shape (R, 3), rad/s
        Reference rate from each change point on.
    truth : SimTruth
        Die temperature, coefficients and noise floor.
    scenario : str
        Scenario name.
    seed : int
        Seed of the scenario run set.
    run_index : int
        Index of this run (0-based).
    rate_hz : float, Hz
        IMU rate.
    vehicle : gyro_tdc.sim.vehicle.VehicleMotion, optional
        A vehicle day's schedule, motion and commanded motion (``ref`` is then the true
        body rate at every IMU stamp, never a rate table).

    """

    name: str
    imu_t: NDArray[np.float64]
    gyro: NDArray[np.float64]
    accel: NDArray[np.float64]
    temp_t: NDArray[np.float64]
    temp_c: NDArray[np.float64]
    temp_var: float
    ref_t: NDArray[np.float64]
    ref: NDArray[np.float64]
    truth: SimTruth = field(repr=False)
    scenario: str = ''
    seed: int = 0
    run_index: int = 0
    rate_hz: float = 0.0
    vehicle: Optional[VehicleMotion] = field(default=None, repr=False)

    def __len__(self) -> int:
        """Return the number of IMU samples."""
        return int(self.imu_t.shape[0])

    @property
    def moving(self) -> bool:
        """Return True when the rate table is ever non-zero (a vehicle day has none)."""
        return self.vehicle is None and bool(np.any(self.ref != 0.0))

    def ref_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """
        Return the reference rate held (zero-order) at times ``t``.

        Parameters
        ----------
        t : NDArray[np.float64], shape (N,), s
            Query times.

        Returns
        -------
        NDArray[np.float64], shape (N, 3), rad/s
            Reference rate.

        """
        return _held(self.ref_t, self.ref, t)


def _whole(x: Any, end: float, message: str) -> int:
    """Return ``x`` as an int in ``0 .. end - 1``; else raise ``ScenarioError(message)``."""
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or not 0 <= x < end:
        raise ScenarioError(message)
    return int(x)


def _held(t_points: NDArray[np.float64], values: NDArray, t: NDArray[np.float64]) -> NDArray:
    """Return ``values`` held (zero-order) at times ``t``; the first before ``t_points[0]``."""
    return values[np.clip(np.searchsorted(t_points, t, side='right') - 1, 0, t_points.size - 1)]


def _stamps(duration: float, rate: float) -> NDArray[np.float64]:
    """Return ``k / rate`` for every ``k`` with ``k / rate < duration``."""
    n = int(math.ceil(duration * rate - 1e-9))
    return np.arange(max(n, 1), dtype=np.float64) / rate


def _vec(values: Sequence[float], factor: float = 1.0) -> NDArray[np.float64]:
    return np.asarray(values, dtype=np.float64) * factor


#: Each gyro effect's coefficient field and its factor to rad/s units.
_GYRO_FIELDS = (('bias', 'bias_dps', RAD_PER_DEG), ('dT', 'dT_dps_per_c', RAD_PER_DEG),
                ('dT2', 'dT2_dps_per_c2', RAD_PER_DEG), ('dT3', 'dT3_dps_per_c3', RAD_PER_DEG),
                ('dTdt', 'dTdt_dps_per_c_per_s', RAD_PER_DEG),
                ('scale', 'scale_ppm_per_c', 1e-6), ('warmup', 'warmup_dps', RAD_PER_DEG))


def _coefficients(g: GyroSpec, on: Mapping[str, bool], offset: NDArray[np.float64]
                  ) -> dict[str, NDArray[np.float64]]:
    """Return each effect's coefficients in rad/s units, zero when the effect is off."""
    out = {e: _vec(getattr(g, name), k) if on[e] else np.zeros(3) for e, name, k in _GYRO_FIELDS}
    out['bias'] = out['bias'] + (offset if on['bias'] else 0.0)
    return out


def _drift(g: GyroSpec, on: Mapping[str, bool], coefficients: Mapping[str, NDArray[np.float64]],
           imu_t: NDArray[np.float64], d_t: NDArray[np.float64], die_rate: NDArray[np.float64],
           omega_ref: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the gyro drift (N, 3), rad/s, of the die temperature, its rate and the rate."""
    poly = np.stack((d_t, d_t * d_t, d_t * d_t * d_t), axis=1)            # (N, 3 powers)
    weights = np.stack((coefficients['dT'], coefficients['dT2'], coefficients['dT3']))
    drift = poly @ weights                                                # (N, 3 axes)
    drift += coefficients['bias']
    if on['dTdt']:
        drift += die_rate[:, np.newaxis] * coefficients['dTdt']
    if on['warmup']:
        since = imu_t - g.power_on_s
        drift += np.exp(-np.maximum(since, 0.0) / g.warmup_tau_s)[:, np.newaxis] \
            * coefficients['warmup']
    if on['scale']:
        drift += omega_ref * (d_t[:, np.newaxis] * coefficients['scale'])
    return drift


def _add_noise(gyro: NDArray[np.float64], nz: NoiseSpec,
               rng: Mapping[str, np.random.Generator], rate: float) -> NDArray[np.float64]:
    """Add the enabled noise processes to ``gyro`` in place; return the white noise std."""
    if not nz.enabled:
        return np.zeros(3)
    density = _vec(nz.arw_dps_per_rt_hz, RAD_PER_DEG)
    white_std, n, dt = density * math.sqrt(rate), gyro.shape[0], 1.0 / rate
    if np.any(white_std > 0.0):
        gyro += white_noise(rng['white'], n, density=density, rate_hz=rate)
    if np.any(_vec(nz.bias_instability_dps) > 0.0):
        gyro += gauss_markov(rng['bias_instability'], n,
                             sigma=_vec(nz.bias_instability_dps, RAD_PER_DEG),
                             tau_s=nz.bias_instability_tau_s, dt=dt)
    if np.any(_vec(nz.rrw_dps_per_rt_s) > 0.0):
        gyro += random_walk(rng['rrw'], n, k=_vec(nz.rrw_dps_per_rt_s, RAD_PER_DEG), dt=dt)
    return white_std


def _thermometer(th: ThermometerSpec, thermal: ThermalHistory, duration: float,
                 rng: np.random.Generator
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Return the thermometer's stamps, readings (degC) and reading variance, at its rate."""
    temp_t = _stamps(duration, th.rate_hz)
    temp_c = thermal.at('thermometer_c', temp_t) + th.offset_c
    if th.noise_c > 0.0:
        temp_c += rng.standard_normal(temp_t.size) * th.noise_c
    quantise(temp_c, th.resolution_c)
    return temp_t, temp_c, th.noise_c ** 2 + th.resolution_c ** 2 / 12.0


def simulate_run(scenario: ScenarioLike, *, seed: int = 0, run_index: int = 0,
                 rate_hz: Optional[float] = None) -> SimRun:
    """
    Simulate one run of a scenario.

    Parameters
    ----------
    scenario : Scenario, str, os.PathLike or Mapping
        The scenario, or anything :func:`gyro_tdc.sim.load_scenario` accepts.
    seed : int
        Seed of the run set, >= 0.
    run_index : int
        Which run, ``0 <= run_index < scenario.runs.count``.
    rate_hz : float, optional
        IMU rate overriding ``scenario.imu_rate_hz``.

    Returns
    -------
    SimRun
        The run.

    Raises
    ------
    ScenarioError
        If the scenario, seed, run index or rate is invalid.

    """
    sc = load_scenario(scenario)
    seed = _whole(seed, math.inf, f'Expected `seed` to be an integer >= 0, got {seed!r}.')
    run_index = _whole(run_index, sc.runs.count, f'Expected `run_index` in [0, '
                       f'{sc.runs.count}) for scenario {sc.name!r}, got {run_index!r}.')
    if rate_hz is not None and (not is_number(rate_hz) or float(rate_hz) <= 0.0):
        raise ScenarioError(f'Expected `rate_hz` to be a finite number > 0, got {rate_hz!r}.')
    rate = sc.imu_rate_hz if rate_hz is None else float(rate_hz)
    rng = {name: np.random.default_rng(s) for name, s in zip(
        _STREAMS, np.random.SeedSequence(seed, spawn_key=(run_index,)).spawn(len(_STREAMS)))}
    g = sc.gyro
    on = {k: k in g.effects for k in EFFECT_IDS}
    tau_die = sc.thermal.tau_die_s if on['lag'] else 0.0
    duration = sc.duration_s
    imu_t = _stamps(duration, rate)
    # A vehicle day: the schedule, the set point (the ambient plus self-heating) and the
    # motion, whose true body rate replaces the rate table.
    profile, motion = sc.profile, None
    if sc.vehicle is not None:
        legs = plan_legs(sc.vehicle, duration, rng['vehicle'])
        profile, heating = heated_profile(sc.profile, sc.vehicle, legs, duration)
        motion = vehicle_motion(sc.vehicle, legs, imu_t, rng['vehicle'],
                                gravity_mps2=sc.accel.gravity_mps2, heating=heating)

    # Thermal chain on the internal grid, then onto the IMU stamps.
    thermal = simulate_thermal(
        profile, duration_s=duration, dt=sc.thermal.internal_step_s,
        tau_air_s=sc.thermal.tau_air_s, tau_package_s=sc.thermal.tau_package_s,
        tau_die_s=tau_die, thermometer_location=sc.thermometer.location,
        thermometer_tau_s=sc.thermometer.tau_s)
    die = thermal.at('die_c', imu_t)
    die_rate = thermal.at('die_rate_c_per_s', imu_t)
    d_t = die - g.t_ref_c

    offset = rng['offset'].standard_normal(3) * _vec(sc.runs.bias_offset_dps_std, RAD_PER_DEG)
    coefficients = _coefficients(g, on, offset)

    # Deterministic part: drift (error) and output = reference + drift.
    ref_t, ref = sc.rate_table.arrays()
    keep = ref_t < duration
    ref_t, ref = ref_t[keep], ref[keep]
    omega_ref = _held(ref_t, ref, imu_t)
    if motion is not None:
        ref_t, ref, omega_ref = imu_t, motion.rate, motion.rate
    drift = _drift(g, on, coefficients, imu_t, d_t, die_rate, omega_ref)
    gyro = omega_ref + drift
    white_std = _add_noise(gyro, sc.noise, rng, rate)
    step = g.sensitivity_mdps_per_digit * 1e-3 * RAD_PER_DEG if g.quantise else 0.0
    quantise(gyro, step, limit=g.range_dps * RAD_PER_DEG)

    acc = _accelerometer(sc.accel, rng['accel'], rng['tilt'], imu_t, d_t, rate,
                         force=None if motion is None else motion.force)
    accel = acc.pop('accel')

    temp_t, temp_c, temp_var = _thermometer(sc.thermometer, thermal, duration, rng['thermometer'])

    truth = SimTruth(
        die_c=die, die_rate_c_per_s=die_rate, package_c=thermal.at('package_c', imu_t),
        air_c=thermal.at('air_c', imu_t), drift=drift, effects=g.effects,
        coefficients=coefficients,
        params={'t_ref_c': g.t_ref_c, 'tau_die_s': tau_die,
                'tau_package_s': sc.thermal.tau_package_s, 'tau_air_s': sc.thermal.tau_air_s,
                'thermometer_tau_s': sc.thermometer.tau_s, 'warmup_tau_s': g.warmup_tau_s,
                'power_on_s': g.power_on_s},
        bias_offset=offset if on['bias'] else np.zeros(3), white_std=white_std,
        quant_step=step, noise_std=np.sqrt(white_std ** 2 + step ** 2 / 12.0),
        thermal=thermal, **acc)
    name = sc.name if sc.runs.count == 1 else f'{sc.name}/run{run_index + 1}'
    return SimRun(name=name, imu_t=imu_t, gyro=gyro, accel=accel, temp_t=temp_t, temp_c=temp_c,
                  temp_var=float(temp_var), ref_t=ref_t, ref=ref, truth=truth, scenario=sc.name,
                  seed=seed, run_index=run_index, rate_hz=rate, vehicle=motion)


def _accelerometer(spec: Any, noise_rng: np.random.Generator, tilt_rng: np.random.Generator,
                   imu_t: NDArray[np.float64], d_t: NDArray[np.float64], rate: float, *,
                   force: Optional[NDArray[np.float64]] = None) -> dict[str, Any]:
    """
    Simulate the accelerometer of one run: its output and the truth fields of SimTruth.

    ``d_t`` is the die temperature minus the reference (degC) at the IMU stamps. The white
    noise draws from ``noise_rng`` exactly as before the accelerometer physics existed, so
    a scenario without tilt, offsets and digits gives the same output as then. ``force``
    (a vehicle day's specific force, N x 3) replaces gravity at the fixed tilt.
    """
    accel = white_noise(noise_rng, imu_t.size, density=spec.noise_mps2_per_rt_hz, rate_hz=rate)
    tilt = _vec(spec.tilt_deg) + tilt_rng.standard_normal(2) * spec.tilt_std_deg
    g_before, g_after = gravity_in_sensor(
        spec.gravity_mps2, *np.stack([tilt, tilt + _vec(spec.reorient_tilt_deg)]).T)
    coefficients = {'bias': _vec(spec.bias_mg, MG), 'dT': _vec(spec.dT_mg_per_c, MG),
                    'dT2': _vec(spec.dT2_mg_per_c2, MG)}
    thermal = (d_t[:, None] * coefficients['dT'] + (d_t * d_t)[:, None] * coefficients['dT2'])
    offset = thermal + coefficients['bias']
    reorient = float(spec.reorient_at_s)
    if force is not None:
        accel += force
        g_before, g_after, reorient = force[0], force[-1], 0.0
    elif reorient > 0.0:
        k = int(np.searchsorted(imu_t, reorient, side='left'))
        accel[:k] += g_before
        accel[k:] += g_after
    else:
        accel += g_before
        g_after = g_before
    if np.any(offset):
        accel += offset
    step = spec.sensitivity_mg_per_digit * MG
    quantise(accel, step, limit=spec.range_g * G0)
    white = _vec(spec.noise_mps2_per_rt_hz) * math.sqrt(rate)
    return {'accel': accel, 'accel_offset': offset, 'accel_thermal': thermal,
            'accel_gravity': np.stack([g_before, g_after]), 'accel_tilt_deg': tilt,
            'accel_reorient_s': reorient, 'accel_coefficients': coefficients,
            'accel_white_std': white, 'accel_quant_step': float(step),
            'accel_noise_std': np.sqrt(white ** 2 + step ** 2 / 12.0)}


def simulate_scenario(scenario: ScenarioLike, seed: int = 0, rate_hz: Optional[float] = None,
                      *, runs: Optional[Sequence[int]] = None,
                      overrides: Optional[Mapping[str, Any]] = None) -> list[SimRun]:
    """
    Simulate every run of a scenario (or the ``runs`` chosen, 0-based), one SimRun each.

    ``scenario`` is anything :func:`gyro_tdc.sim.load_scenario` accepts; ``overrides``
    (dotted paths, :meth:`Scenario.with_overrides`) apply first; ``rate_hz`` overrides
    ``scenario.imu_rate_hz``. Run ``i`` of ``seed`` (>= 0) is reproducible on its own.

    Raises
    ------
    ScenarioError
        If the scenario, seed, rate, run indices or overrides are invalid.

    """
    sc = load_scenario(scenario)
    if overrides:
        sc = sc.with_overrides(overrides)
    indices = range(sc.runs.count) if runs is None else list(runs)
    return [simulate_run(sc, seed=seed, run_index=i, rate_hz=rate_hz) for i in indices]


def to_run(simrun: SimRun) -> Run:
    """
    Align a simulated run on its IMU stamps as the compensator sees it live.

    The temperature at each stamp is the latest thermometer reading at or before it
    (zero-order hold), the reference the rate-table rate held there. ``info`` holds
    ``truth``, ``scenario``, ``seed``, ``run_index``, ``source='sim'``.
    """
    return Run(t=simrun.imu_t, temp=_held(simrun.temp_t, simrun.temp_c, simrun.imu_t),
               omega=simrun.gyro, omega_ref=simrun.ref_at(simrun.imu_t), name=simrun.name,
               info={'source': 'sim', 'scenario': simrun.scenario, 'seed': simrun.seed,
                     'run_index': simrun.run_index, 'truth': simrun.truth}, accel=simrun.accel)


class ImuChunk(NamedTuple):
    """IMU samples of one chunk: stamps (K,) s, angular velocity and acceleration (K, 3)."""

    t: NDArray[np.float64]
    gyro: NDArray[np.float64]
    accel: NDArray[np.float64]


class TempChunk(NamedTuple):
    """Thermometer readings of one chunk: stamps (K,) s and readings (K,) degC."""

    t: NDArray[np.float64]
    temp_c: NDArray[np.float64]


class RefChunk(NamedTuple):
    """Rate-table change points of one chunk: times (K,) s, the rate from each on (K, 3) rad/s."""

    t: NDArray[np.float64]
    ref: NDArray[np.float64]


class SimStream:
    """
    Hand out one simulated run in time order.

    Parameters
    ----------
    scenario : Scenario, str, os.PathLike or Mapping
        The scenario, or anything :func:`gyro_tdc.sim.load_scenario` accepts.
    seed : int
        Seed of the run set (the same run as ``simulate_scenario(scenario, seed)``).
    run_index : int
        Which run of a multi-run scenario.
    rate_hz : float, optional
        IMU rate overriding the scenario's.

    """

    def __init__(self, scenario: ScenarioLike, seed: int = 0, run_index: int = 0, *,
                 rate_hz: Optional[float] = None) -> None:
        self.run: SimRun = simulate_run(scenario, seed=seed, run_index=run_index, rate_hz=rate_hz)
        self._stamps = (self.run.imu_t, self.run.temp_t, self.run.ref_t)
        self._i = (0, 0, 0)      # the next IMU, thermometer and reference rows
        self._position = -math.inf

    @property
    def position(self) -> float:
        """Return the time up to which samples were handed out (start: the first stamp)."""
        return self.run.imu_t[0] if self._position == -math.inf else self._position

    @property
    def done(self) -> bool:
        """Return True once every sample was handed out."""
        return all(i >= t.size for i, t in zip(self._i, self._stamps))

    def next_until(self, t: float) -> tuple[ImuChunk, TempChunk, RefChunk]:
        """
        Return the chunks of samples stamped up to and including ``t`` not handed out yet.

        Each chunk in time order, possibly empty (a ``t`` before the last call's).

        Raises
        ------
        ScenarioError
            If ``t`` is not a number (NaN).

        """
        t = float(t)
        if math.isnan(t):
            raise ScenarioError('Expected `t` to be a time in seconds, got nan.')
        run = self.run
        old, self._i = self._i, tuple(max(i, int(np.searchsorted(ts, t, side='right')))
                                      for i, ts in zip(self._i, self._stamps))
        imu, temp, ref = (slice(i, j) for i, j in zip(old, self._i))
        self._position = max(self._position, t)
        return (ImuChunk(run.imu_t[imu], run.gyro[imu], run.accel[imu]),
                TempChunk(run.temp_t[temp], run.temp_c[temp]),
                RefChunk(run.ref_t[ref], run.ref[ref]))
