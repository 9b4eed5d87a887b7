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

"""The start-up shift gate of a learned model (:mod:`gyro_tdc.learn.gate`)."""

from gyro_tdc.learn.gate import learned_gate, PointRun
from gyro_tdc.learn.store import model_from_file
from gyro_tdc.runtime import SIGNIFICANCE
import numpy as np
import pytest
from still_logs import learn_directly, still_log

FIELD_DAY_S = 3 * 3600.0


def test_a_point_run_is_a_still_run_of_the_table_rows():
    """Stamps, model temperatures and still means from the point columns; reference zero."""
    rows = np.arange(21, dtype=np.float64).reshape(3, 7)
    run = PointRun(rows)
    assert len(run) == 3
    np.testing.assert_array_equal(run.t, rows[:, 0])
    np.testing.assert_array_equal(run.temp, rows[:, 2])
    np.testing.assert_array_equal(run.omega, rows[:, 3:6])
    assert run.omega_ref.shape == (3, 3) and not run.omega_ref.any()


def test_one_power_cycle_keeps_the_gate():
    """Nothing held out: the gate is twice the anchors' error on every axis, as trained."""
    log = still_log(rate_hz=1.0, days=1.0, day_s=FIELD_DAY_S, seed=6, power_cycles=1,
                    accel=False)
    learner = learn_directly(log)
    rec = learner.model.metrics['reanchor']
    assert (rec['sessions'], rec['held_out']) == (1, 0)
    assert 'always_dps' not in rec
    np.testing.assert_allclose(rec['min_shift_dps'],
                               SIGNIFICANCE * np.array(rec['anchor_error_dps']))
    assert np.all(np.array(rec['min_shift_dps']) > 0.0)


def test_a_power_cycle_the_others_cannot_refit_is_not_held_out():
    """Where the fit of the others fails, no cycle is judged and the gate is kept."""
    log = still_log(rate_hz=1.0, days=3.0, day_s=FIELD_DAY_S / 2, seed=6, power_cycles=3,
                    turn_on_dps=0.3, accel=False)
    learner = learn_directly(log)

    def too_little(table):
        raise ValueError('too few points')

    rec = learned_gate(learner.model, learner.entries(), too_little, learner.thermal)
    assert (rec['sessions'], rec['held_out']) == (3, 0)
    np.testing.assert_allclose(rec['min_shift_dps'],
                               SIGNIFICANCE * np.array(rec['anchor_error_dps']))
    # With the learner's own fit the turn-on offsets are seen: any shift is taken.
    assert learner.model.metrics['reanchor']['min_shift_dps'] == [0.0, 0.0, 0.0]


@pytest.mark.parametrize('turn_on_dps', [0.3, 0.0])
def test_the_learned_model_carries_the_start_up_shift_gate_of_its_points(turn_on_dps, tmp_path):
    """Three power cycles: any shift where they have their own offsets, else the gate."""
    log = still_log(rate_hz=1.0, days=3.0, day_s=FIELD_DAY_S / 2, seed=6, power_cycles=3,
                    turn_on_dps=turn_on_dps, accel=False)
    learner = learn_directly(log)
    rec = learner.model.metrics['reanchor']
    assert rec == learner.fit['reanchor']
    assert (rec['sessions'], rec['held_out']) == (3, 3)
    always, gated, never = (np.array(rec[k]) for k in ('always_dps', 'gated_dps', 'never_dps'))
    gate = 2.0 * np.array(rec['anchor_error_dps'])
    assert np.all((gate > 0.001) & (gate < 0.01)), rec      # still means of one gyro
    np.testing.assert_allclose(rec['min_shift_dps'], np.where(gated < always, gate, 0.0))
    if turn_on_dps:                   # held out, not re-anchoring misses tenths of deg/s
        assert np.all(never > 20.0 * always) and rec['min_shift_dps'] == [0.0, 0.0, 0.0]
    else:                             # a shift within the anchors' error is no offset
        assert np.all(gated < always) and np.all(np.array(rec['min_shift_dps']) > 0.0)
    # The learn file keeps it: the model it gives carries the same gate.
    learner.save(tmp_path / 'learn.json')
    assert model_from_file(tmp_path / 'learn.json').metrics['reanchor'] == rec
