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
Fast synthetic runs of a gyro whose die lags the thermometer, curvature in die temperature.

The measured temperature follows a chamber profile (holds and ramps); the die follows it
through one first-order conduction lag ``tau_die`` (or two cascaded lags, package then die),
integrated exactly for a piecewise-linear input (``hold='linear'``, not the model's
step-held filter); the drift is a quadratic in the die temperature. Used by
``test_thermal_state.py`` and ``bench/bench_thermal_state.py``.
"""

from __future__ import annotations

import math
from typing import Sequence

from gyro_tdc.data.runs import Run
from gyro_tdc.model.lag import first_order_lag
import numpy as np

DEG = math.pi / 180.0
#: Soaks, steps of rate and direction: everything that excites a lag (3.3 h from 0 degC).
RICH = (('hold', 900.0), ('ramp', 40.0, 40.0), ('hold', 1800.0), ('ramp', 10.0, 60.0),
        ('hold', 1800.0), ('ramp', 30.0, 60.0), ('hold', 900.0))
#: Another profile for held-out runs (3.2 h from 0 degC).
OTHER = (('hold', 600.0), ('ramp', 35.0, 50.0), ('hold', 1200.0), ('ramp', 5.0, 45.0),
         ('hold', 1500.0), ('ramp', 25.0, 40.0), ('hold', 1200.0))
#: Linear and quadratic drift coefficients per axis, deg/s per degC^k (curvature = 1).
A1 = (0.02, -0.015, 0.01)
A2 = (3e-4, -2e-4, 2.5e-4)


def profile(t: np.ndarray, segments: Sequence[tuple], start_c: float = 0.0) -> np.ndarray:
    """Return the chamber temperature at ``t`` for ``('hold', s)``/``('ramp', to, c_per_h)``."""
    knots_t, knots_c = [0.0], [start_c]
    for seg in segments:
        if seg[0] == 'hold':
            knots_t.append(knots_t[-1] + seg[1])
            knots_c.append(knots_c[-1])
        else:
            to, rate = seg[1], seg[2]
            knots_t.append(knots_t[-1] + abs(to - knots_c[-1]) / rate * 3600.0)
            knots_c.append(to)
    return np.interp(t, knots_t, knots_c)


def duration(segments: Sequence[tuple], start_c: float = 0.0) -> float:
    """Return the length of a profile, s."""
    total, c = 0.0, start_c
    for seg in segments:
        if seg[0] == 'hold':
            total += seg[1]
        else:
            total += abs(seg[1] - c) / seg[2] * 3600.0
            c = seg[1]
    return total


def lag_run(*, seed: int, tau_die: float, curvature: float = 1.0,
            segments: Sequence[tuple] = RICH, start_c: float = 0.0, rate_hz: float = 10.0,
            noise_dps: float = 0.05, thermometer_noise_c: float = 0.01,
            tau_package: float = 0.0, skip_s: float = 0.0, t_ref: float = 20.0,
            name: str = 'lag') -> Run:
    """
    Make one run: measured T from ``segments``, die = lag(T), drift quadratic in the die.

    Parameters
    ----------
    seed : int
        Noise seed.
    tau_die : float, s
        Die time constant (0: the die is at the measured temperature).
    curvature : float
        Multiplies the quadratic coefficients :data:`A2` (0: none).
    segments : sequence of tuple
        The temperature profile (:func:`profile`).
    start_c : float, degC
        Starting temperature.
    rate_hz : float, Hz
        IMU rate.
    noise_dps : float, deg/s
        White rate noise per sample (the noise floor is its square).
    thermometer_noise_c : float, degC
        White noise of the measured temperature.
    tau_package : float, s
        A second node before the die (two-node conduction); 0 for one node.
    skip_s : float, s
        Drop the first ``skip_s`` seconds (the run starts with the die already lagging).
    t_ref : float, degC
        Temperature of zero drift.
    name : str
        Run name.

    Returns
    -------
    Run
        Stamps, measured temperature, raw rate (zero true rate); ``info`` has
        ``noise_dps`` and the ``die`` temperature.

    """
    rng = np.random.default_rng(seed)
    total = duration(segments, start_c)
    t = np.arange(0.0, total, 1.0 / rate_hz)
    temp = profile(t, segments, start_c)
    die = temp
    if tau_package > 0:
        die = first_order_lag(t, die, tau_package, hold='linear')
    if tau_die > 0:
        die = first_order_lag(t, die, tau_die, hold='linear')
    d = die - t_ref
    drift = (np.asarray(A1) * d[:, None] + curvature * np.asarray(A2) * d[:, None] ** 2
             + np.array([0.3, -0.2, 0.1])) * DEG
    omega = drift + rng.normal(0.0, noise_dps * DEG, (t.size, 3))
    measured = temp + rng.normal(0.0, thermometer_noise_c, t.size)
    keep = t >= skip_s
    return Run(t[keep] - t[keep][0], measured[keep], omega[keep], np.zeros((keep.sum(), 3)),
               name, {'noise_dps': noise_dps, 'die': die[keep]})
