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

"""The learner's model temperature: held thermometer, streamed thermal state, equality."""

from __future__ import annotations

import math

from gyro_tdc.learn.fit import at_state, learned_model, same_thermal, stream_state
from gyro_tdc.model.compensation import drift
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.signal import hold_readings
import numpy as np
import pytest

LAGS = (ThermalState('first_order', (120.0,)), ThermalState('two_node', (30.0, 200.0)))


@pytest.mark.parametrize('thermal', LAGS)
def test_stream_state_in_any_batches_is_the_streaming_and_batch_state(thermal):
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.005, 2.0, 3000))
    temp = 20.0 + 10.0 * np.sin(t / 500.0) + rng.normal(0.0, 0.01, t.size)
    stream = thermal.stream()
    want = np.array([stream.update(a, b) for a, b in zip(t.tolist(), temp.tolist())])
    np.testing.assert_allclose(thermal.temperature(t, temp), want, rtol=0, atol=1e-9)
    cuts = np.sort(rng.choice(np.arange(1, t.size), 40, replace=False))
    carry, got = None, []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
        s, carry = stream_state(thermal, carry, t[lo:hi], temp[lo:hi])
        got.append(s)
    np.testing.assert_allclose(np.concatenate(got), want, rtol=0, atol=1e-9)
    assert carry[0] == t[-1] and len(carry[1]) == len(thermal.tau_s)


def test_stream_state_skips_missing_temperatures_and_passes_without_a_lag():
    thermal = LAGS[0]
    t = np.arange(10.0)
    temp = np.array([20.0, 21, math.nan, math.nan, 22, 22, 22, math.nan, 23, 23])
    s, carry = stream_state(thermal, None, t, temp)
    ok = np.isfinite(temp)
    assert np.isnan(s[~ok]).all()
    np.testing.assert_allclose(s[ok], thermal.temperature(t[ok], temp[ok]))
    assert carry[0] == 9.0
    for none in (None, ThermalState('none')):
        s, c = stream_state(none, None, t, temp)
        assert s is temp and c is None
    s, c = stream_state(thermal, carry, t[:2], np.full(2, math.nan))
    assert np.isnan(s).all() and c == carry


def test_hold_readings_by_stamp_with_a_timeout():
    readings = [(2.0, 21.0), (0.0, 20.0), (10.0, 22.0)]
    held, keep = hold_readings(readings, np.array([-1.0, 0.0, 1.5, 2.0, 8.0, 11.0]), 5.0)
    np.testing.assert_array_equal(held, [math.nan, 20.0, 20.0, 21.0, math.nan, 22.0])
    assert keep == [(10.0, 22.0)]
    held, keep = hold_readings([], np.array([1.0]), 5.0)
    assert np.isnan(held).all() and keep == []


def test_same_thermal_and_the_model_at_its_state():
    fo = LAGS[0]
    assert same_thermal(None, ThermalState('none')) and same_thermal(None, None)
    assert same_thermal(fo, ThermalState('first_order', (120.0,), ((100.0, 150.0),), True))
    assert not same_thermal(fo, None) and not same_thermal(fo, LAGS[1])
    assert not same_thermal(fo, ThermalState('first_order', (121.0,)))
    m = learned_model(np.array([[0.01, 0, 0], [1e-3, 0, 0], [1e-5, 0, 0]]), ('dT', 'dT2'),
                      20.0, (0.0, 40.0), np.zeros(3), fo)
    t = np.arange(0.0, 2000.0, 1.0)
    temp = 20.0 + 0.01 * t
    flat = at_state(m)
    assert flat.thermal.kind == 'none' and 'lag' not in flat.features
    np.testing.assert_allclose(drift(flat, t, fo.temperature(t, temp)), drift(m, t, temp),
                               rtol=0, atol=1e-15)
    assert at_state(flat) is flat
