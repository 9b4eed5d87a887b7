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

"""The back-ends' shared parts: the polled source, the sample check, the reconnect backoff."""

from __future__ import annotations

import math

from fake_iio import l3gd20_files, make_device
from gyro_tdc.errors import DeviceError
from gyro_tdc.sources import Backoff, check_sample, IioSource, ImuSample
from gyro_tdc.sources.base import PolledSource
from manual_clock import Wall
import pytest


def test_polled_source_yields_one_reading_per_tick_stamped_in_ns(tmp_path):
    clock = Wall(12.25)
    src = IioSource(make_device(tmp_path, l3gd20_files()), clock=clock)
    assert isinstance(src, PolledSource)
    first = list(src.pending())
    clock.t = 12.5
    second = list(src.pending())
    assert [s.t for s in first + second] == [12.25, 12.5]
    assert src.stamp_ns(1.23e-7) == 123 and src.stamp_ns(3.0000000004) == 3_000_000_000
    assert src.stamp_ns(12.5) == 12_500_000_000


def test_check_sample_passes_finite_samples_and_names_a_bad_field():
    good = ImuSample(1.0, (0.1, 0.2, 0.3), (0.0, 0.0, 9.8), 25.0)
    assert check_sample(good) is good
    assert check_sample(ImuSample(1.0, (0.0, 0.0, 0.0))).accel is None
    for bad, name in ((ImuSample(math.nan, (0.0, 0.0, 0.0)), 't'),
                      (ImuSample(1.0, (0.0, math.inf, 0.0)), 'omega'),
                      (ImuSample(1.0, (0.0, 0.0)), 'omega'),
                      (ImuSample(1.0, (0.0, 0.0, 0.0), (0.0, 'x', 0.0)), 'accel'),
                      (ImuSample(1.0, (0.0, 0.0, 0.0), temp_c=math.nan), 'temp_c')):
        with pytest.raises(DeviceError, match=f'`{name}`'):
            check_sample(bad)


def test_backoff_doubles_up_to_the_maximum_and_resets():
    backoff = Backoff(0.5, 3.0)
    assert [backoff.next_delay() for _ in range(5)] == [0.5, 1.0, 2.0, 3.0, 3.0]
    backoff.reset()
    assert backoff.next_delay() == 0.5
    with pytest.raises(ValueError, match='initial'):
        Backoff(2.0, 1.0)
