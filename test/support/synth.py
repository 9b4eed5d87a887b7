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

"""Tiny, exact synthetic runs for the core tests (the full simulator lives in gyro_tdc.sim)."""

from __future__ import annotations

import math

from gyro_tdc.data.runs import Run
from gyro_tdc.model.lag import first_order_lag
import numpy as np

DEG = math.pi / 180.0


def synth_run(*, seed: int = 0, hours: float = 2.0, rate_hz: float = 5.0,
              t_lo: float = -10.0, t_hi: float = 50.0, cooling: bool = False,
              a1=(0.02, -0.015, 0.01), a2=(2e-4, 1.5e-4, -1e-4), b0=(0.3, -0.2, 0.1),
              tau_die: float = 0.0, h=(0.0, 0.0, 0.0), scale=(0.0, 0.0, 0.0),
              ref_dps=(0.0, 0.0, 0.0), noise_dps: float = 0.05, t_ref: float = 25.0,
              offset_dps=(0.0, 0.0, 0.0), ref_period_s: float = 0.0,
              name: str = 'synth') -> Run:
    """
    Make one run whose drift is known exactly (coefficients in deg/s per degC^k).

    The temperature soaks at ``t_lo`` for 5 % of the run, ramps to ``t_hi`` and, with
    ``cooling``, ramps back down in the second half. The die follows the thermometer with a
    first-order lag ``tau_die`` (0: no lag); ``h`` multiplies the die's dT/dt in degC/min.
    With ``ref_period_s`` the rate table steps through +1, 0, -1 and 0.5 times ``ref_dps``.
    """
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * rate_hz)
    t = np.arange(n) / rate_hz
    frac = t / t[-1]
    soak = 0.05
    if cooling:
        up = np.clip((frac - soak) / (0.5 - soak), 0, 1)
        down = np.clip((frac - 0.55) / 0.4, 0, 1)
        temp = t_lo + (t_hi - t_lo) * (up - down)
    else:
        temp = t_lo + (t_hi - t_lo) * np.clip((frac - soak) / (1 - soak), 0, 1)
    die = first_order_lag(t, temp, tau_die) if tau_die > 0 else temp
    d = die - t_ref
    ddt = np.gradient(die, t) * 60.0
    ref = np.tile(np.asarray(ref_dps, dtype=float) * DEG, (n, 1))
    if ref_period_s > 0:  # rate-table steps cycling through +1, 0, -1, 0.5 of ref_dps
        ref *= np.array([1.0, 0.0, -1.0, 0.5])[(t // ref_period_s).astype(int) % 4][:, None]
    drift = (np.asarray(b0) + np.asarray(offset_dps) + d[:, None] * np.asarray(a1)
             + d[:, None] ** 2 * np.asarray(a2) + ddt[:, None] * np.asarray(h)) * DEG
    omega = ref * (1 + d[:, None] * np.asarray(scale)) + drift
    omega += rng.normal(0.0, noise_dps * DEG, size=(n, 3))
    return Run(t, temp, omega, ref, name, {'noise_dps': noise_dps})
