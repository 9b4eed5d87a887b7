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

"""Tests of gyro_tdc.evaluate.training_report: the coverage table and its warnings."""

from __future__ import annotations

from gyro_tdc.data.coverage import Coverage
from gyro_tdc.evaluate.training_report import format_coverage, is_coverage_line
import numpy as np


def _coverage(**kw):
    c = dict(bin_c=5.0, edges=np.array([15.0, 20.0, 25.0, 30.0]),
             samples=np.array([100, 5, 300]), minutes=np.array([10.0, 0.5, 30.0]), sparse=[1],
             temp_range_c=(17.5, 29.0), heating_min=30.0, cooling_min=0.0, steady_min=10.5,
             threshold_c_per_min=0.05)
    c.update(kw)
    return Coverage(**c)


def test_coverage_table_and_warnings():
    table, warns = format_coverage(_coverage())
    lines = table.splitlines()
    assert lines[0] == 'temperature range covered: 17.50 .. 29.00 degC (span 11.50 degC)'
    # The bins in one line: count, least and most minutes (named), median, thin ones counted.
    assert lines[1] == ('coverage per 5 degC bin: 3 bins 15 .. 30 degC; minutes per bin 0.5 '
                        '([20, 25) degC) .. 30.0 ([25, 30) degC), median 10.0; 1 thin (named '
                        'in the warning below)')
    assert lines[2] == ('heating (dT/dt > +0.05 degC/min): 30.0 min; cooling (< -0.05): '
                        '0.0 min; steady: 10.5 min')
    assert len(lines) == 3 and all(is_coverage_line(line) for line in lines)
    assert len(warns) == 2
    assert warns[0].startswith('little data in temperature bin(s) [20, 25) degC')
    assert warns[1].startswith('no cooling data:')
    assert all(is_coverage_line(f'warning: {w}') for w in warns)
    assert not is_coverage_line('training bias stability BS, (deg/s)^2:')
    table, warns = format_coverage(_coverage(sparse=[], cooling_min=12.0))
    assert warns == [] and table.splitlines()[1].endswith('median 10.0; none thin')
    _, warns = format_coverage(_coverage(sparse=[], heating_min=0.0, cooling_min=30.0))
    assert warns[0].startswith('no heating data:')
    _, warns = format_coverage(_coverage(sparse=[], heating_min=0.0, cooling_min=0.0))
    assert warns == []                 # all steady: nothing to tell apart
