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

"""Tests of gyro_tdc.base.limits: options that size arrays are refused before memory is spent."""

from __future__ import annotations

from gyro_tdc.base.limits import (check_bin_width, check_centers, check_sim_samples, MAX_CENTERS,
                                  MAX_COVERAGE_BINS, MAX_SIM_SAMPLES, TEMP_PLAUSIBLE_C)
from gyro_tdc.errors import GyroTdcError, LimitError
import pytest

SPAN = TEMP_PLAUSIBLE_C[1] - TEMP_PLAUSIBLE_C[0]


def test_bin_width_at_the_limit_passes_below_is_refused_naming_a_value_that_fits():
    smallest = SPAN / MAX_COVERAGE_BINS
    assert check_bin_width(5.0) == 5.0 and check_bin_width(smallest) == smallest
    with pytest.raises(LimitError) as info:
        check_bin_width(smallest / 2, option='--coverage-bin')
    text = str(info.value)
    assert text.startswith(f'--coverage-bin {smallest / 2:g} degC makes up to 2e+04 coverage')
    assert f'at most {MAX_COVERAGE_BINS}' in text and f'>= {smallest:g})' in text


@pytest.mark.parametrize('bad', [0.0, -1.0, float('nan')])
def test_bin_width_zero_negative_or_nan_is_refused(bad):
    with pytest.raises(LimitError, match='makes up to inf coverage bins|nan'):
        check_bin_width(bad)


def test_centers_up_to_the_model_file_limit():
    assert check_centers(MAX_CENTERS) == MAX_CENTERS
    with pytest.raises(LimitError, match=f'--centers {MAX_CENTERS + 1}: at most {MAX_CENTERS} '
                                         'RBF centres'):
        check_centers(MAX_CENTERS + 1)


def test_sim_samples_counted_and_refused_with_size_and_a_rate_that_fits():
    assert check_sim_samples(3600.0, 100.0) == 360_000
    assert check_sim_samples(0.5, 3.0) == 2                      # rounded up
    assert check_sim_samples(MAX_SIM_SAMPLES / 1000.0, 1000.0) == MAX_SIM_SAMPLES
    with pytest.raises(LimitError) as info:
        check_sim_samples(86_400.0, 1000.0, option='rate_hz')
    text = str(info.value)
    assert text.startswith('rate_hz 1000: 8.64e+07 IMU samples per run (86400 s at 1000 Hz)')
    assert 'about 30.2 GB' in text and f'(use rate_hz <= {MAX_SIM_SAMPLES / 86_400.0:.3g})' in text
    assert issubclass(LimitError, GyroTdcError)
