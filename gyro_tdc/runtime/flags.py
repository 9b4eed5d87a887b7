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

"""The flags of one processed sample (a bit set) and their names (pure)."""

from __future__ import annotations

__all__ = ['FLAG_NAMES', 'IMPLAUSIBLE_INPUT', 'IMPLAUSIBLE_OUTPUT', 'NO_ACCEL_DATA', 'NO_MODEL',
           'NO_TEMPERATURE', 'NON_FINITE', 'OUT_OF_RANGE', 'PASSTHROUGH', 'STALE', 'UPSTREAM',
           'describe_flags']

#: Flags of one processed sample (a bit set).
STALE = 1
OUT_OF_RANGE = 2
NON_FINITE = 4
NO_TEMPERATURE = 8
NO_MODEL = 16
PASSTHROUGH = 32

#: The accelerometer's own flag (``CompensatorCore.accel_flags``, not counted per sample in
#: ``flag_counts``): the Imu carried no accelerometer data (covariance[0] == -1).
NO_ACCEL_DATA = 64
#: The gyro is declared thermally corrected upstream (``upstream_correction``): passed through.
UPSTREAM = 128
#: A raw rate beyond any gyro's range (``MAX_RATE_RAD_S``): passed through.
IMPLAUSIBLE_INPUT = 256
#: The compensated rate, its variance or the corrected specific force was not finite, or
#: corrected more than ``MAX_DRIFT_RAD_S`` (``MAX_ACCEL_DRIFT_MPS2``): the raw passed through.
IMPLAUSIBLE_OUTPUT = 512

FLAG_NAMES = {STALE: 'temperature stale', OUT_OF_RANGE: 'temperature out of model range',
              NON_FINITE: 'non-finite input', NO_TEMPERATURE: 'no temperature yet',
              NO_MODEL: 'no model loaded', PASSTHROUGH: 'raw rate passed through',
              UPSTREAM: 'gyro already thermally corrected upstream',
              IMPLAUSIBLE_INPUT: 'input rate beyond any gyro range',
              IMPLAUSIBLE_OUTPUT: 'compensated output not finite or implausible'}


def describe_flags(flags: int) -> str:
    """Return the flags of a sample as a comma-separated text ('' when none)."""
    return ', '.join(name for bit, name in FLAG_NAMES.items() if flags & bit)
