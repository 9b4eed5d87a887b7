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

"""Tests of gyro_tdc.model.out_of_range: policies beyond the trained range, the tangent slope."""

from __future__ import annotations

from gyro_tdc.model.compensation import drift, rbf_design
from gyro_tdc.model.effects import batch_features
from gyro_tdc.model.out_of_range import (added_variance, check_policy, MAX_EXTRAPOLATION_C,
                                         OUT_OF_RANGE_POLICIES, range_shortfall, split, Tangent,
                                         variance_growth)
from hostile_helpers import small_model
import numpy as np
import pytest


def test_check_policy_names_the_argument():
    assert [check_policy(p) for p in OUT_OF_RANGE_POLICIES] == list(OUT_OF_RANGE_POLICIES)
    with pytest.raises(ValueError, match=r"Expected `out_of_range` 'linear', 'clamp' or "
                                         r"'extrapolate', got 'hold'\."):
        check_policy('hold')


@pytest.mark.parametrize('policy, s_eval, reach', [
    ('extrapolate', [-30.0, -12.0, 5.0, 32.0, 80.0], [0.0] * 5),
    ('clamp', [-10.0, -10.0, 5.0, 30.0, 30.0], [0.0] * 5),
    ('linear', [-10.0, -10.0, 5.0, 30.0, 30.0], [-15.0, -2.0, 0.0, 2.0, 15.0]),
])
def test_split_scalar_and_array_agree(policy, s_eval, reach):
    s = np.array([-30.0, -12.0, 5.0, 32.0, 80.0])
    got_s, got_r = split(s, -10.0, 30.0, policy)
    np.testing.assert_array_equal(got_s, s_eval)
    np.testing.assert_array_equal(got_r, reach)
    for k, v in enumerate(s):
        assert split(float(v), -10.0, 30.0, policy) == (s_eval[k], reach[k])
    assert split(40.0, -10.0, 30.0, 'linear', max_c=4.0) == (30.0, 4.0)


def test_added_variance_grows_with_distance_only_for_linear():
    assert added_variance(2e-6, 0.0, 'linear') == 2e-6
    assert added_variance(2e-6, 5.0, 'linear') == pytest.approx(4e-6)     # doubles at 5 degC
    assert added_variance(2e-6, -10.0, 'linear') == pytest.approx(10e-6)  # sign ignored
    for policy in ('clamp', 'extrapolate'):
        assert added_variance(2e-6, 10.0, policy) == 2e-6
        assert variance_growth(2e-6, 10.0, policy) == 0.0
    assert variance_growth(1.0, 2.5, 'linear') == pytest.approx(0.25)


def _drift_at(model, temps, policy):
    temps = np.asarray(temps, dtype=float)
    return drift(model, np.arange(temps.size, dtype=float), temps, out_of_range=policy)


def test_linear_follows_the_tangent_at_the_range_end_then_holds():
    model = small_model()                                   # rbf f(dT, dT2), -10 .. 50 degC
    h = 1e-4
    lo_hi = _drift_at(model, [50.0 - h, 50.0 + h], 'extrapolate')
    slope = (lo_hi[1] - lo_hi[0]) / (2 * h)                 # numerical db/dS at 50 degC
    end = _drift_at(model, [50.0], 'extrapolate')[0]
    beyond = _drift_at(model, [53.0, 50.0 + MAX_EXTRAPOLATION_C, 90.0], 'linear')
    np.testing.assert_allclose(beyond[0], end + 3.0 * slope, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(beyond[1], end + MAX_EXTRAPOLATION_C * slope, rtol=1e-6,
                               atol=1e-12)
    np.testing.assert_array_equal(beyond[2], beyond[1])     # held beyond the reach
    assert not np.allclose(beyond[0], _drift_at(model, [53.0], 'extrapolate')[0])
    np.testing.assert_array_equal(_drift_at(model, [90.0], 'clamp')[0], end)


def test_tangent_batch_and_streaming_slopes_agree():
    model = small_model(k=6)
    temps = np.array([-10.0, 0.0, 37.5, 50.0])
    x = batch_features(model.features, np.arange(4.0), temps, t0=model.t0_c,
                       params=model.effect_params)
    design = rbf_design(model, x)
    d = temps - model.t0_c
    tangent = Tangent(model)
    batch = tangent.slope(design, d)
    assert batch.shape == (4, 3) and np.all(np.isfinite(batch))
    for k in range(4):
        np.testing.assert_allclose(tangent.slope_one(design[k], d[k]), batch[k], rtol=1e-12)
    h = 1e-4
    up = _drift_at(model, temps + h, 'extrapolate')
    down = _drift_at(model, temps - h, 'extrapolate')
    step = up - down
    np.testing.assert_allclose(batch, step / (2 * h), rtol=1e-5, atol=1e-12)


def test_range_shortfall_names_what_is_missing():
    assert range_shortfall((-10.5, 49.2)) == ''                 # within the 1 degC margin
    assert range_shortfall((2.0, 41.5)) == ('12.0 degC below (-10 .. 2.0) and 8.5 degC above '
                                            '(41.5 .. 50)')
    assert range_shortfall((0.0, 60.0)) == '10.0 degC below (-10 .. 0.0)'
    assert range_shortfall((5.0, 25.0), (0.0, 30.0), margin_c=0.0) == \
        '5.0 degC below (0 .. 5.0) and 5.0 degC above (25.0 .. 30)'
    assert range_shortfall((float('nan'), float('inf'))) == ''
