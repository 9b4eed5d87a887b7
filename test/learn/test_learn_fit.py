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

"""The online learner's fit: growth rule, sessions, outliers, learned models, the check."""

from __future__ import annotations

from gyro_tdc.learn.fit import (fit_points, fit_sessions, grow_features, inliers, learned_model,
                                model_of, prediction_mse)
from gyro_tdc.model.compensation import drift
from gyro_tdc.model.modelfile import model_from_dict, model_to_dict, stored
from gyro_tdc.model.thermal_state import ThermalState
import numpy as np
import pytest


def _table(temps, session=0.0, shift=0.0):
    """Point-table rows of a drift 0.01 + 1e-3 dT + 2e-5 dT^2 about 20 degC (x axis)."""
    d = np.asarray(temps, dtype=np.float64) - 20.0
    b = 0.01 + shift + 1e-3 * d + 2e-5 * d ** 2
    z = np.zeros_like(d)
    return np.column_stack([np.arange(d.size) * 100.0, np.full(d.size, 500.0), d + 20.0,
                            b, z, z, np.full(d.size, session)])


def test_growth_rule():
    assert grow_features(np.array([]), 0) == ()
    assert grow_features(np.array([20.0, 21.5]), 2) == ()
    assert grow_features(np.array([20.0, 22.0]), 2) == ('dT',)
    assert grow_features(np.arange(20.0, 29.0), 4) == ('dT',)
    assert grow_features(np.arange(20.0, 29.0), 5) == ('dT', 'dT2')
    assert grow_features(np.arange(20.0, 36.0), 10) == ('dT', 'dT2', 'dT3')


def test_sessions_share_the_shape_and_an_outlier_goes():
    e = np.vstack([_table(np.arange(10.0, 30.0, 2.0)),
                   _table(np.arange(15.0, 35.0, 2.5), session=1.0, shift=3e-3)])
    coef, res = fit_sessions(e, e[:, 1], ('dT', 'dT2'), 20.0)
    np.testing.assert_allclose(coef[:, 0], [0.013, 1e-3, 2e-5], rtol=1e-9)
    coef0, _ = fit_sessions(e, e[:, 1], ('dT', 'dT2'), 20.0, session=0.0)
    assert coef0[0, 0] == pytest.approx(0.01)
    assert np.abs(res).max() < 1e-12
    e[4, 3] += 0.05                         # one entry far off
    keep = inliers(e, e[:, 1], ('dT', 'dT2'), 20.0, 1e-3)
    assert keep.tolist() == [i != 4 for i in range(e.shape[0])]
    fit = fit_points(e, ('dT', 'dT2'), e[:, 0].max(), 86400.0, 1e-3)
    assert fit['points'] == e.shape[0] - 1
    temps = np.array([12.0, 20.0, 33.0])          # the newest session's intercept
    want = 0.013 + 1e-3 * (temps - 20.0) + 2e-5 * (temps - 20.0) ** 2
    got = drift(model_of(fit), np.zeros(3), temps, clamp=False)[:, 0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


@pytest.mark.parametrize('thermal', [None, ThermalState('none'),
                                     ThermalState('first_order', (300.0,))])
def test_learned_models_carry_the_thermal_section(thermal):
    fit = {'features': [], 't0_c': 20.0, 'coef': [[0.01, 0.0, 0.0]], 'range_c': [19.0, 21.0],
           'resid_var': [1e-8] * 3, 'points': 1}
    m = model_of(fit, thermal)
    assert m.thermal == (thermal or ThermalState()) and m.format_version == 2
    lagged = thermal is not None and thermal.kind != 'none'
    assert m.features == (('dT', 'lag') if lagged else ('dT',))
    if lagged:
        assert m.effect_params == {'lag': {'tau_s': 300.0}}
    assert model_from_dict(model_to_dict(m)) == m == stored(m)    # a model file like any other
    t = np.arange(0.0, 100.0)
    np.testing.assert_allclose(drift(m, t, np.full(100, 20.0)), [[0.01, 0.0, 0.0]] * 100)


def test_prediction_check_evaluates_at_the_windows_model_temperature():
    fo = ThermalState('first_order', (300.0,))
    m = learned_model(np.array([[0.01, 0, 0], [1e-3, 0, 0]]), ('dT',), 20.0, (0.0, 40.0),
                      np.zeros(3), fo)
    # Windows at model temperatures 15 and 25 degC whose means the model predicts exactly.
    rows = [[100.0, 15.0, 0.005, 0.0, 0.0, 10.0], [100.0, 25.0, 0.015, 0.0, 0.0, 110.0]]
    assert prediction_mse(m, rows, fo) == pytest.approx(0.0, abs=1e-20)
    # Taken as thermometer readings, the lag runs over them: not exact.
    assert prediction_mse(m, rows, None) > 1e-6
