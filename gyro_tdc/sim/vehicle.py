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
Vehicle scenarios: a day of ordinary operation instead of a thermal chamber.

A ``vehicle:`` section simulates an IMU on a vehicle that drives and parks through a day:
the ambient plus self-heating drives the thermal chain, parked stops sit on slopes, drives
speed up, turn and vibrate, and ``cmd_vel`` can be written beside. No rate table and no
reference topic. Every field: ``doc/internals/sim.md``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
import math

from gyro_tdc.base import plain, RAD_PER_DEG
from gyro_tdc.model import first_order_lag
from gyro_tdc.sim.chamber import Profile
from gyro_tdc.sim.specs import section_fields, spec_field
import numpy as np
from numpy.typing import NDArray

__all__ = ['CMD_VEL_TOPIC', 'Leg', 'TRUTH_TOPIC', 'VEHICLE_DEFAULTS', 'VEHICLE_FIELDS',
           'VehicleMotion', 'VehicleSpec', 'gravity_in_sensor', 'heated_profile', 'plan_legs',
           'vehicle_motion']

#: Topic of the true body rate in simulated vehicle bags (evaluation only, never trained on).
TRUTH_TOPIC = '/truth/angular_velocity'
#: Topic of the commanded motion (geometry_msgs/Twist) in simulated vehicle bags.
CMD_VEL_TOPIC = '/cmd_vel'

#: Grid step of the heated set point, s (the self-heating moves over minutes).
_HEAT_STEP_S = 5.0
#: Ramp of a turn's yaw rate in and out, s.
_TURN_RAMP_S = 1.0


@dataclass(frozen=True)
class VehicleSpec:
    """
    The ``vehicle:`` section of a scenario (see the module docstring for every field).

    Durations in s, rates in deg/s, slopes in deg, speeds in m/s, accelerations in m/s^2,
    temperatures in degC, ranges as ``(low, high)``. Each field carries the kind the scenario
    schema checks and its default: 'range' is [low, high] with 0 <= low <= high, 'prange' the
    same with low > 0.
    """

    start_parked_s: float = spec_field('nonneg', 1800.0)
    drive_s: tuple[float, float] = spec_field('prange', [600.0, 1800.0])
    park_s: tuple[float, float] = spec_field('prange', [600.0, 3000.0])
    slope_deg: float = spec_field('nonneg', 4.0)
    slope_change_s: float = spec_field('pos', 10.0)
    speed_mps: float = spec_field('pos', 10.0)
    accel_mps2: float = spec_field('pos', 1.5)
    straight_s: tuple[float, float] = spec_field('prange', [5.0, 60.0])
    turn_s: tuple[float, float] = spec_field('prange', [3.0, 20.0])
    turn_rate_dps: tuple[float, float] = spec_field('range', [2.0, 20.0])
    vibration_dps: float = spec_field('nonneg', 0.5)
    vibration_mps2: float = spec_field('nonneg', 0.8)
    self_heating_c: float = spec_field('num', 10.0)
    self_heating_tau_s: float = spec_field('pos', 900.0)
    cmd_vel_rate_hz: float = spec_field('nonneg', 5.0)

    def to_dict(self) -> dict:
        """Return the section as plain YAML-safe types."""
        return plain(asdict(self))


#: Each field of the ``vehicle:`` section as (kind, default), and the defaults alone.
VEHICLE_FIELDS = section_fields(VehicleSpec)
VEHICLE_DEFAULTS: dict = {key: default for key, (_, default) in VEHICLE_FIELDS.items()}


@dataclass(frozen=True)
class Leg:
    """
    One part of the day: parked or driving.

    Parameters
    ----------
    kind : str
        ``'park'`` or ``'drive'``.
    t0_s, t1_s : float, s
        Start and end.
    roll_deg, pitch_deg : float, deg
        The slope parked on (a park), or reached at the end (a drive).

    """

    kind: str
    t0_s: float
    t1_s: float
    roll_deg: float
    pitch_deg: float


def plan_legs(spec: VehicleSpec, duration_s: float, rng: np.random.Generator) -> tuple[Leg, ...]:
    """
    Draw the day's schedule: parked first, then drives and stops until ``duration_s``.

    Legs in time order covering ``[0, duration_s]`` (the last cut at the end), drawn from
    ``rng``, the run's ``vehicle`` stream.
    """
    def slope() -> tuple[float, float]:
        r, p = rng.standard_normal(2) * spec.slope_deg
        return float(r), float(p)

    roll, pitch = slope()
    legs = [Leg('park', 0.0, min(spec.start_parked_s, duration_s), roll, pitch)]
    while legs[-1].t1_s < duration_s:     # a drive to a new slope, a stop on it, and so on
        t, driving = legs[-1].t1_s, legs[-1].kind == 'park'
        d = float(rng.uniform(*(spec.drive_s if driving else spec.park_s)))
        if driving:
            roll, pitch = slope()
        legs.append(Leg('drive' if driving else 'park', t, min(t + d, duration_s), roll, pitch))
    return tuple(legs)


def _driving(legs: tuple[Leg, ...], t: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Return True at the times inside a drive."""
    out = np.zeros(t.shape[0], dtype=bool)
    for leg in legs:
        if leg.kind == 'drive':
            out |= (t >= leg.t0_s) & (t < leg.t1_s)
    return out


def heated_profile(ambient: Profile, spec: VehicleSpec, legs: tuple[Leg, ...],
                   duration_s: float) -> tuple[Profile, Profile]:
    """
    Return the set point of the thermal chain: the ambient plus the self-heating.

    Returns the heated set point and the self-heating alone (degC above ``ambient``, the
    daily cycle), on a :data:`_HEAT_STEP_S` grid.
    """
    n = int(math.ceil(duration_s / _HEAT_STEP_S)) + 1
    t = np.arange(n, dtype=np.float64) * _HEAT_STEP_S
    drive = _driving(legs, t).astype(np.float64) * spec.self_heating_c
    heat = first_order_lag(_HEAT_STEP_S, drive, spec.self_heating_tau_s, hold='step', y0=0.0)
    return Profile(t, ambient.value(t) + heat), Profile(t, heat)


def gravity_in_sensor(gravity_mps2: float, roll_deg: NDArray[np.float64],
                      pitch_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """
    Return the specific force of gravity at rest in the sensor frame, (N, 3), m/s^2.

    ``g (-sin p, sin r cos p, cos r cos p)`` for arrays of roll r (about x) and pitch p
    (about y) in degrees: ``(0, 0, g)`` when level.
    """
    r, p = np.radians(roll_deg), np.radians(pitch_deg)
    return gravity_mps2 * np.stack([-np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)],
                                   axis=1)


@dataclass(frozen=True, eq=False)
class VehicleMotion:
    """
    The motion of a simulated vehicle day at the IMU stamps (what a real day does not record).

    The run holds it as ``SimRun.vehicle``; the run's reference rate is then ``rate``.
    """

    #: The schedule, a tuple of :class:`Leg`.
    legs: tuple
    #: True body rate (N, 3), rad/s (manoeuvres, slope changes, vibration).
    rate: NDArray[np.float64]
    #: Specific force (N, 3), m/s^2, gravity in the sensor frame plus the vehicle's
    #: acceleration.
    force: NDArray[np.float64]
    #: Speed (N,), m/s.
    speed: NDArray[np.float64]
    #: Roll (N,), deg.
    roll_deg: NDArray[np.float64]
    #: Pitch (N,), deg.
    pitch_deg: NDArray[np.float64]
    #: Samples where the vehicle is parked (still) (N,).
    parked: NDArray[np.bool_]
    #: Self-heating above the ambient (N,), degC.
    heating_c: NDArray[np.float64]
    #: Stamps of the commanded motion (M,), s (empty without cmd_vel).
    cmd_t: NDArray[np.float64]
    #: Twist components (M, 6), linear x, y, z (m/s) and angular x, y, z (rad/s).
    cmd: NDArray[np.float64]


def _drive_profile(spec: VehicleSpec, leg: Leg, rng: np.random.Generator
                   ) -> tuple[list[float], list[float], list[float], list[float]]:
    """Return the knots (t, speed) and (t, yaw rate rad/s) of one drive."""
    ramp = min(spec.speed_mps / spec.accel_mps2, 0.5 * (leg.t1_s - leg.t0_s))
    vmax = spec.accel_mps2 * ramp
    vt = [leg.t0_s, leg.t0_s + ramp, leg.t1_s - ramp, leg.t1_s]
    vv = [0.0, vmax, vmax, 0.0]
    yt, yv = [leg.t0_s], [0.0]
    t, end = leg.t0_s + ramp, leg.t1_s - ramp
    while True:
        t += float(rng.uniform(*spec.straight_s))
        dur = float(rng.uniform(*spec.turn_s))
        if t + dur + 2.0 * _TURN_RAMP_S >= end:
            break
        sign = 1.0 if rng.random() < 0.5 else -1.0
        w = float(rng.uniform(*spec.turn_rate_dps)) * RAD_PER_DEG * sign
        yt += [t, t + _TURN_RAMP_S, t + _TURN_RAMP_S + dur, t + 2.0 * _TURN_RAMP_S + dur]
        yv += [0.0, w, w, 0.0]
        t += 2.0 * _TURN_RAMP_S + dur
    return vt, vv, yt + [leg.t1_s], yv + [0.0]


def _pl(tk: list[float], vk: list[float], t: NDArray[np.float64]
        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the piecewise-linear function through knots (from 0 s) and its slope at ``t``."""
    f = Profile(np.asarray(tk, dtype=np.float64), np.asarray(vk, dtype=np.float64))
    return f.value(t), f.slope(t)


def vehicle_motion(spec: VehicleSpec, legs: tuple[Leg, ...], imu_t: NDArray[np.float64],
                   rng: np.random.Generator, *, gravity_mps2: float,
                   heating: Profile) -> VehicleMotion:
    """
    Simulate the vehicle's motion at the IMU stamps.

    Parameters
    ----------
    spec : VehicleSpec
        The vehicle section.
    legs : tuple of Leg
        The schedule (:func:`plan_legs`).
    imu_t : NDArray[np.float64], shape (N,), s
        IMU stamps.
    rng : numpy.random.Generator
        The run's ``vehicle`` stream (after :func:`plan_legs`).
    gravity_mps2 : float, m/s^2
        Gravity (the accelerometer section's).
    heating : Profile
        The self-heating (:func:`heated_profile`).

    Returns
    -------
    VehicleMotion
        Rates, specific force, speed, attitude and the commanded motion.

    """
    t = np.asarray(imu_t, dtype=np.float64)
    vt, vv, yt, yv = [0.0], [0.0], [0.0], [0.0]
    at, ar, ap = [0.0], [legs[0].roll_deg], [legs[0].pitch_deg]
    for prev, leg in zip((None,) + legs[:-1], legs):
        if leg.kind != 'drive':
            continue
        for knots, more in zip((vt, vv, yt, yv), _drive_profile(spec, leg, rng)):
            knots += more
        c = min(spec.slope_change_s, 0.5 * (leg.t1_s - leg.t0_s))
        r0, p0 = (prev.roll_deg, prev.pitch_deg) if prev is not None else (0.0, 0.0)
        at += [leg.t0_s, leg.t0_s + c, leg.t1_s - c, leg.t1_s]
        ar += [r0, 0.0, 0.0, leg.roll_deg]
        ap += [p0, 0.0, 0.0, leg.pitch_deg]
    speed, dspeed = _pl(vt, vv, t)
    yaw_rate, _ = _pl(yt, yv, t)
    roll, droll = _pl(at, ar, t)
    pitch, dpitch = _pl(at, ap, t)
    phi, th, dphi, dth = np.radians([roll, pitch, droll, dpitch])
    # Euler (yaw-pitch-roll) kinematics: body rates from the attitude rates.
    rate = np.stack([dphi - yaw_rate * np.sin(th),
                     dth * np.cos(phi) + yaw_rate * np.sin(phi) * np.cos(th),
                     -dth * np.sin(phi) + yaw_rate * np.cos(phi) * np.cos(th)], axis=1)
    force = gravity_in_sensor(gravity_mps2, roll, pitch)
    force[:, 0] += dspeed
    force[:, 1] += speed * yaw_rate
    shake = np.clip(speed / spec.speed_mps, 0.0, 1.0)[:, None]
    n = t.shape[0]
    rate += rng.standard_normal((n, 3)) * (spec.vibration_dps * RAD_PER_DEG) * shake
    force += rng.standard_normal((n, 3)) * spec.vibration_mps2 * shake
    cmd_t = np.zeros(0)
    if spec.cmd_vel_rate_hz > 0.0 and n:
        duration = float(t[-1]) + (float(t[1] - t[0]) if n > 1 else 0.0)
        cmd_t = np.arange(int(math.ceil(duration * spec.cmd_vel_rate_hz - 1e-9)),
                          dtype=np.float64) / spec.cmd_vel_rate_hz
    cmd = np.zeros((cmd_t.size, 6))
    cmd[:, 0], cmd[:, 5] = _pl(vt, vv, cmd_t)[0], _pl(yt, yv, cmd_t)[0]
    return VehicleMotion(legs=legs, rate=rate, force=force, speed=speed, roll_deg=roll,
                         pitch_deg=pitch, parked=~_driving(legs, t), heating_c=heating.value(t),
                         cmd_t=cmd_t, cmd=cmd)
