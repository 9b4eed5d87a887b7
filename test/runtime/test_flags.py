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

"""The flags of one processed sample and their names."""

from __future__ import annotations

from gyro_tdc.runtime.flags import (describe_flags, FLAG_NAMES, NO_ACCEL_DATA, NO_MODEL,
                                    PASSTHROUGH, STALE)


def test_flags_are_distinct_bits_and_described_in_order():
    bits = list(FLAG_NAMES) + [NO_ACCEL_DATA]
    assert len(set(bits)) == len(bits) and all(b & (b - 1) == 0 for b in bits)
    assert describe_flags(0) == ''
    assert describe_flags(NO_MODEL | STALE | PASSTHROUGH) == (
        'temperature stale, no model loaded, raw rate passed through')
    assert describe_flags(NO_ACCEL_DATA) == ''       # not a gyro flag: no name
