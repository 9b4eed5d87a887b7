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

"""The thermometer held by stamp (pure)."""

import math

from gyro_tdc.signal import TemperatureHold
import numpy as np


def test_temperature_hold_by_stamp():
    hold = TemperatureHold(capacity=4)
    assert hold.at(5.0) is None and hold.latest is None
    assert hold.add(1.0, 20.0) and hold.add(3.0, 22.0)
    assert hold.at(0.5) is None
    assert hold.at(1.0) == (20.0, 1.0)
    assert hold.at(2.9) == (20.0, 1.0)
    assert hold.at(10.0) == (22.0, 3.0)
    # A late, out-of-order sample is slotted in by stamp; a repeated stamp replaces.
    assert hold.add(2.0, 21.0)
    assert hold.at(2.5) == (21.0, 2.0)
    assert hold.add(2.0, 21.5) and hold.at(2.5) == (21.5, 2.0) and len(hold) == 3
    assert not hold.add(4.0, math.nan) and not hold.add(math.inf, 20.0)
    assert hold.rejected == 2 and hold.latest == (22.0, 3.0)
    for k in range(10):
        hold.add(10.0 + k, 30.0 + k)
    assert len(hold) == 4 and hold.at(100.0) == (39.0, 19.0)


def test_the_batch_form_holds_as_the_streaming_form():
    hold = TemperatureHold(capacity=None, gate=False)
    for t, c in ((2.0, 21.0), (0.0, 20.0), (10.0, 22.0), (6.0, math.nan)):
        hold.add(t, c)
    stamps = np.array([-1.0, 0.0, 1.5, 2.0, 6.5, 8.0, 11.0, 16.0])
    held = hold.held(stamps, 5.0)
    for s, h in zip(stamps, held):
        one = hold.at(s)
        want = math.nan if one is None or s - one[1] > 5.0 else one[0]
        np.testing.assert_equal(h, want)
    assert np.isnan(held[4])                     # a NaN reading is held as no temperature
    hold.forget_before(8.0)
    assert hold.readings[1:] == [(10.0, 22.0)] and hold.readings[0][0] == 6.0
