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
Upfront size checks of options that size arrays, before any memory is spent.

``train --bin``, ``--centers`` and ``simulate --rate-hz`` are checked against the plausible
temperature span and the sample budget; a refusal is one :class:`~gyro_tdc.errors.LimitError`
line naming the option, the estimate, the limit and a value that fits.
See ``doc/internals/base.md``.
"""

from __future__ import annotations

import math

from gyro_tdc.errors import LimitError

__all__ = ['MAX_ACCEL_DRIFT_MPS2', 'MAX_CENTERS', 'MAX_COVERAGE_BINS', 'MAX_DRIFT_RAD_S',
           'MAX_RATE_RAD_S', 'MAX_SIM_RUNS', 'MAX_SIM_SAMPLES', 'MAX_TEMP_LEAD_S',
           'MAX_TEMP_RATE_C_S', 'MAX_TEMP_SLEW_C_S', 'RESTART_BACK_S', 'SESSION_GAP_PERIODS',
           'SESSION_GAP_S', 'SIM_BYTES_PER_SAMPLE', 'TEMP_PLAUSIBLE_C', 'TEMP_SLEW_MARGIN_C',
           'check_bin_width', 'check_centers', 'check_sim_samples']

#: Temperatures a MEMS die can read, degC: outside, a reading is a glitch (one home for the
#: trainer, the driver, the compensator and the learner).
TEMP_PLAUSIBLE_C = (-100.0, 200.0)
#: Rates beyond any gyro's range, rad/s (about 5,700 deg/s).
MAX_RATE_RAD_S = 100.0
#: The largest zero-rate drift a model may compute, rad/s (about 290 deg/s): beyond any MEMS
#: gyro's zero-rate level (datasheets: tens of deg/s at most) plus its temperature drift.
MAX_DRIFT_RAD_S = 5.0
#: The largest accelerometer offset change a model may compute, m/s^2 (about 2 g; datasheets:
#: about 1 mg/degC).
MAX_ACCEL_DRIFT_MPS2 = 20.0
#: The fastest a die's temperature plausibly changes in service, degC/s (a chamber ramps at
#: a few degC/min, self-heating after power-on slower still): a model's ``dTdt`` terms are
#: checked up to it.
MAX_TEMP_RATE_C_S = 2.0
#: The fastest a thermometer reading may move from the last plausible one, degC/s: beyond it
#: a reading is a glitch (``gyro_tdc.base.plausible``). Generous on purpose: a die's time
#: constant is about 17.5 s (the paper's t_s = C rho L^2 / k), so even a full-range thermal
#: shock (a 100 degC liquid-to-liquid step) moves it at about 6 degC/s; 20 degC/s leaves that
#: three times over, and a real run never comes near it.
MAX_TEMP_SLEW_C_S = 20.0
#: A change any two readings may show however close their stamps, degC: the thermometer's
#: noise and quantisation (registers of 0.5-1 degC per digit exist) on top of the slew.
TEMP_SLEW_MARGIN_C = 2.0
#: How far a thermometer stamp may lead the last IMU stamp, s, when ``temperature_timeout``
#: is shorter: a node that stays up while its IMU pauses (a vehicle parked overnight) takes the
#: first reading of the next run before its first IMU sample, so the lead may be a night; a
#: reading stamped further ahead (a clock a day off) is refused, or it would stand for the
#: future in the priming history and the slew check.
MAX_TEMP_LEAD_S = 12 * 3600.0
#: A session (one power cycle) ends at a stamp gap longer than this (s) ... (one home for the
#: dataset's cut and the compensator's re-anchoring)
SESSION_GAP_S = 600.0
#: ... and than this many sample periods ...
SESSION_GAP_PERIODS = 100
#: ... or where IMU stamps step back by more than this (s): the device's clock restarted.
RESTART_BACK_S = 1.0
#: RBF centres a model file may hold.
MAX_CENTERS = 10_000
MAX_COVERAGE_BINS = 10_000
MAX_SIM_SAMPLES = 20_000_000
#: Runs (power cycles) a scenario may ask for: a campaign of any chamber, far below what
#: would never end (simulate names every run before the first).
MAX_SIM_RUNS = 1_000
SIM_BYTES_PER_SAMPLE = 350


def check_bin_width(bin_c: float, *, option: str = '--bin') -> float:
    """
    Return ``bin_c`` (degC) when the coverage table it implies is small enough.

    LimitError when the plausible temperature span would need more than ``MAX_COVERAGE_BINS``.
    """
    span = TEMP_PLAUSIBLE_C[1] - TEMP_PLAUSIBLE_C[0]
    smallest = span / MAX_COVERAGE_BINS
    if not bin_c >= smallest:
        bins = span / bin_c if bin_c > 0 else math.inf
        raise LimitError(f'{option} {bin_c:g} degC makes up to {bins:.3g} coverage bins over the '
                         f'{span:g} degC plausible range; at most {MAX_COVERAGE_BINS} '
                         f'(use {option} >= {smallest:g})')
    return bin_c


def check_centers(n_centers: int, *, option: str = '--centers') -> int:
    """Return ``n_centers`` when a model file may hold that many RBF centres (else LimitError)."""
    if n_centers > MAX_CENTERS:
        raise LimitError(f'{option} {n_centers}: at most {MAX_CENTERS} RBF centres (the limit '
                         'of a model file)')
    return n_centers


def check_sim_samples(duration_s: float, rate_hz: float, *,
                      option: str = '--rate-hz') -> int:
    """
    Return the IMU samples of one simulated run (``duration_s`` at ``rate_hz``).

    LimitError, naming ``option``, when the run would exceed ``MAX_SIM_SAMPLES`` samples.
    """
    n = duration_s * rate_hz
    if not n <= MAX_SIM_SAMPLES:
        gb = n * SIM_BYTES_PER_SAMPLE / 1e9
        raise LimitError(f'{option} {rate_hz:g}: {n:.3g} IMU samples per run ({duration_s:g} s '
                         f'at {rate_hz:g} Hz) would need about {gb:.3g} GB; at most '
                         f'{MAX_SIM_SAMPLES:.3g} samples per run (use {option} <= '
                         f'{MAX_SIM_SAMPLES / duration_s:.3g})')
    return int(math.ceil(n))
