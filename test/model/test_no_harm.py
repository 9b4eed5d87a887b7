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

"""The do-no-harm rule: curve kept or offset only, gated re-anchoring, the learner's call."""

from __future__ import annotations

import math

from gyro_tdc.identify import fit_model
from gyro_tdc.model import compensate, load_model, save_model
from gyro_tdc.model.no_harm import (curve_kept, gated_shift, HELD_OUT_KEY, learned_coef,
                                    offset_only, reanchor_kept, reanchor_rule)
from gyro_tdc.runtime import CompensatorCore, Policy
import numpy as np
from synth import synth_run

DEG = math.pi / 180.0


def _model():
    run = synth_run(hours=0.5, rate_hz=2.0, noise_dps=0.01)
    return fit_model([run], kind='rbf', features='dT,dT2', t0=25.0), run


def test_curve_kept_only_where_it_beats_the_offset():
    np.testing.assert_array_equal(curve_kept([1.0, 2.0, math.nan], [2.0, 2.0, 1.0]),
                                  [True, False, True])
    np.testing.assert_array_equal(curve_kept([1.0, 1.9, 3.0], [2.0, 2.0, 2.0], margin=0.9),
                                  [True, False, False])
    # Better pooled, but it loses one session by far: it does not carry (x); a tie within
    # a tenth of the median session is no loss (y); no drift to judge keeps it (z).
    per = [([0.1, 1.0, 0.0], [1.0, 1.0, 0.0]), ([0.1, 1.05, 0.0], [1.0, 1.0, 0.0]),
           ([1.0, 0.5, 0.0], [0.2, 1.0, 0.0])]
    np.testing.assert_array_equal(curve_kept([0.4, 0.85, 0.0], [0.73, 1.0, 0.0], per),
                                  [False, True, True])


def test_reanchoring_is_turned_off_only_where_it_lost_every_session():
    # x: worse pooled and in both sessions; y: worse pooled, better in one; z: better.
    per = [([2.0, 3.0, 0.5], [1.0, 0.5, 1.0]), ([2.0, 0.4, 0.5], [1.0, 0.5, 1.0])]
    np.testing.assert_array_equal(reanchor_kept([2.0, 1.7, 0.5], [1.0, 0.5, 1.0], per),
                                  [False, True, True])
    np.testing.assert_array_equal(reanchor_kept([2.0, 1.7, 0.5], [1.0, 0.5, 1.0]),
                                  [False, False, True])


def test_offset_only_compensates_a_constant_on_those_axes():
    model, run = _model()
    flat = offset_only(model, [False, True, False], level=[0.0, 0.01, 0.0],
                       residual_var=[0.0, 4e-6, 0.0])
    c = compensate(flat, run.t, run.temp, run.omega)
    np.testing.assert_allclose(run.omega[:, 1] - c[:, 1], 0.01, rtol=1e-12)
    np.testing.assert_array_equal(c[:, [0, 2]], compensate(model, run.t, run.temp,
                                                           run.omega)[:, [0, 2]])
    assert flat.residual_var[1] == 4e-6 and flat.residual_var[0] == model.residual_var[0]
    assert offset_only(model, [False] * 3) is model


def test_gated_shift_follows_the_record_and_survives_the_model_file(tmp_path):
    model, _ = _model()
    assert np.all(gated_shift(model, [1e-3, -1e-3, 2e-3]) == [1e-3, -1e-3, 2e-3])
    rec = {'curve': [True, True, False], 'reanchor': [True, False, True],
           'reanchor_min_dps': [0.1, 0.0, None]}
    gated = model.replace(metrics={**model.metrics, HELD_OUT_KEY: rec})
    loaded = load_model(save_model(gated, tmp_path / 'm.yaml'))
    on, least = reanchor_rule(loaded)
    np.testing.assert_array_equal(on, [True, False, True])
    np.testing.assert_allclose(least, [0.1 * DEG, 0.0, 0.0])
    np.testing.assert_allclose(gated_shift(loaded, [0.05 * DEG, 1.0, 3e-3]), [0.0, 0.0, 3e-3])
    np.testing.assert_allclose(gated_shift(loaded, [-0.2 * DEG, 1.0, 0.0]), [-0.2 * DEG, 0, 0])


def test_the_core_takes_no_shift_on_an_axis_the_model_does_not_reanchor():
    model, run = _model()
    rec = {'curve': [True] * 3, 'reanchor': [True, False, True],
           'reanchor_min_dps': [0.0, 0.0, 1.0]}
    gated = model.replace(metrics={**model.metrics, HELD_OUT_KEY: rec})
    offset = np.array([0.2, 0.3, 0.4]) * DEG            # a turn-on offset the models miss
    shifts = {}
    for name, m in (('plain', model), ('gated', gated)):
        core = CompensatorCore(Policy(), m)
        for t, temp, w in zip(run.t[:400], run.temp[:400], run.omega[:400] + offset):
            core.add_temperature(float(t), float(temp))
            core.process(float(t), *w.tolist(), None)
        assert core.anchor is not None
        shifts[name] = np.asarray(core.anchor.delta)
    np.testing.assert_allclose(shifts['plain'], offset, atol=0.02 * DEG)
    # y: not re-anchored; z: 0.4 deg/s is below its 1 deg/s smallest shift.
    np.testing.assert_allclose(shifts['gated'], [shifts['plain'][0], 0.0, 0.0])


def test_learned_coef_zeroes_the_curve_rows_of_the_offset_only_axes():
    model, _ = _model()
    coef = [[0.1, 0.2, 0.3], [1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    assert learned_coef(coef, None) == coef and learned_coef(coef, model) == coef
    prior = model.replace(metrics={**model.metrics, HELD_OUT_KEY: {'curve': [True, False, True]}})
    assert learned_coef(coef, prior) == [[0.1, 0.2, 0.3], [1.0, 0.0, 3.0], [4.0, 0.0, 6.0]]
