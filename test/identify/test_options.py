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


"""Tests of gyro_tdc.identify.options: the training choices, checked once, and the result."""

from __future__ import annotations

from dataclasses import fields

from gyro_tdc.base.limits import MAX_CENTERS
from gyro_tdc.errors import FeatureError, FitError, LimitError
from gyro_tdc.identify.fit import FitOptions
from gyro_tdc.identify.options import TrainOptions, TrainResult
import pytest


def test_options_are_checked_when_built():
    assert TrainOptions().auto and TrainOptions(features=' auto ').features == 'auto'
    assert TrainOptions(features='dT2, dT').features == ('dT', 'dT2')     # catalog order
    assert TrainOptions(features=['lag', 'dT']).features == ('dT', 'lag')
    with pytest.raises(FeatureError, match='bogus'):
        TrainOptions(features='dT,bogus')
    with pytest.raises(FitError, match="Expected `kind` to be one of rbf, poly, got 'spline'"):
        TrainOptions(kind='spline')
    with pytest.raises(FitError, match='ridge'):
        TrainOptions(ridge=-1.0)
    with pytest.raises(FitError, match="Expected `thermal` to be one of none, .*'third_order'"):
        TrainOptions(thermal='third_order')
    with pytest.raises(LimitError, match='centres'):
        TrainOptions(n_centers=MAX_CENTERS + 1)
    with pytest.raises(LimitError, match='bin'):
        TrainOptions(bin_c=0.0)


def test_fit_keywords_are_the_training_choices_fit_model_shares():
    o = TrainOptions(kind='poly', n_centers=5, refine=True, ridge=1e-3, seed=4,
                     thermal='first_order', sensor_id=7, bin_c=2.0, accel=False)
    assert o.fit_kw() == {'kind': 'poly', 'n_centers': 5, 'refine': True, 'ridge': 1e-3,
                          'seed': 4, 'thermal': 'first_order', 'sensor_id': '7'}
    assert set(o.fit_kw()) <= {f.name for f in fields(FitOptions)}


@pytest.mark.parametrize('constant, line', [
    ({}, ''),
    ({'z': 0.0}, 'gyro axis z: constant at 0 rad/s'),
    ({'x': 0.5, 'z': -1e-3}, 'gyro axes x, z: constant at 0.5, -0.001 rad/s')])
def test_the_constant_line_names_each_constant_axis(constant, line):
    res = TrainResult(model=None, path=None, coverage=None, bags=[], samples=0,
                      constant=constant)
    assert res.constant_line().startswith(line)
    if constant:
        assert ('passes them through' if len(constant) > 1 else 'passes it through') in \
            res.constant_line()
