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

"""Effect catalog: ids, parameters, and batch == streaming for every effect."""

from gyro_tdc.effects import (batch_features, EFFECTS, first_order_lag, input_ids,
                              normalise_ids, resolve_params, StreamingFeatures)
from gyro_tdc.errors import FeatureError
import numpy as np
import pytest

DESIGN_IDS = ['bias', 'dT', 'dT2', 'dT3', 'dTdt', 'lag', 'scale', 'warmup']


def test_catalog_has_the_design_ids_with_physics():
    assert list(EFFECTS) == DESIGN_IDS
    for eff in EFFECTS.values():
        assert len(eff.description) > 30 and eff.excited_by
        for name in eff.fitted:
            lo, hi = eff.bounds[name]
            assert 0 < lo < eff.params[name] < hi


def test_ids_parse_and_reject_unknown():
    assert normalise_ids('dT2, dT ,lag') == ('dT', 'dT2', 'lag')
    assert input_ids(['bias', 'scale', 'warmup', 'dT']) == ('dT', 'warmup')
    with pytest.raises(FeatureError, match=r"Unknown effect id\(s\) 'dT4'"):
        normalise_ids('dT,dT4')
    with pytest.raises(FeatureError, match=r'lag.tau_s must be a positive'):
        resolve_params(['lag'], {'lag': {'tau_s': -1.0}})
    with pytest.raises(FeatureError, match=r"'lag' has no parameter"):
        resolve_params(['lag'], {'lag': {'tau': 3.0}})


def _irregular(seed, n=6000):
    rng = np.random.default_rng(seed)
    t = 100.0 + np.cumsum(rng.uniform(0.005, 0.05, n))
    temp = 20.0 + 8.0 * np.sin(t / 40.0) + rng.normal(0.0, 0.02, n)
    return t, temp


@pytest.mark.parametrize('eid', ['dT', 'dT2', 'dT3', 'dTdt', 'lag', 'warmup'])
@pytest.mark.parametrize('seed', [0, 1])
def test_streaming_equals_batch_for_every_effect(eid, seed):
    t, temp = _irregular(seed)
    params = {'lag': {'tau_s': 7.5}, 'dTdt': {'tau_s': 3.0}, 'warmup': {'tau_s': 20.0}}
    params = {k: v for k, v in params.items() if k == eid}
    x = batch_features([eid], t, temp, t0=18.0, params=params)
    s = StreamingFeatures([eid], t0=18.0, params=params)
    y = np.array([s.update(a, b) for a, b in zip(t, temp)])
    assert x.shape == y.shape == (t.size, 1)
    scale = np.max(np.abs(x))
    np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-12 * scale)


def test_streaming_reset_starts_a_new_run():
    t, temp = _irregular(3, 500)
    s = StreamingFeatures(['lag', 'warmup'], t0=0.0)
    first = np.array([s.update(a, b) for a, b in zip(t, temp)])
    s.reset()
    again = np.array([s.update(a, b) for a, b in zip(t, temp)])
    np.testing.assert_array_equal(first, again)


def test_first_order_lag_matches_step_response():
    t = np.arange(0.0, 50.0, 0.01)
    u = np.where(t > 0, 1.0, 0.0)
    u[0] = 0.0
    y = first_order_lag(t, u, 5.0)
    i = np.searchsorted(t, 5.0)
    assert y[i] == pytest.approx(1 - np.exp(-1), abs=2e-3)
    assert y[-1] == pytest.approx(1.0, abs=1e-4)


def test_dtdt_feature_is_the_smoothed_derivative():
    t = np.arange(0.0, 3000.0, 0.5)
    temp = 10.0 + 0.01 * t  # 0.01 degC/s ramp
    x = batch_features(['dTdt'], t, temp, t0=10.0, params={'dTdt': {'tau_s': 30.0}})
    # The discrete filter lags a ramp by tau - dt/2, hence the 1 % tolerance.
    assert x[-1, 0] == pytest.approx(0.01, rel=1e-2)
