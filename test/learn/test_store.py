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

"""The learner's learn_file: state encoded, decoded, written and read (pure)."""

from __future__ import annotations

import json

from gyro_tdc.learn import learner as learning
from gyro_tdc.learn.learner import LearnConfig, Learner
from gyro_tdc.learn.store import decode_state, encode_state, FORMAT, read_state, write_state
from gyro_tdc.model.thermal_state import ThermalState
import numpy as np
import pytest


def _learned(temps=(20.2, 23.4)):
    """Return a learner that learned one still stretch (100 Hz, 120 s) per temperature."""
    learner = Learner(LearnConfig(temperature_timeout=1e9))
    rng = np.random.default_rng(4)
    t = 0.0
    for temp in temps:
        tt = t + np.arange(12000) / 100.0
        learner.add_temperature(tt[0], temp)
        still = [0.01, -0.02, 0.005] + 1e-4 * rng.standard_normal((tt.size, 3))
        for ti, w in zip(tt.tolist(), still.tolist()):
            learner.observe(ti, *w)
        tm = tt[-1] + (1 + np.arange(3000)) / 100.0        # then 30 s of motion
        for ti, w in zip(tm.tolist(), (0.3 * rng.standard_normal((tm.size, 3))).tolist()):
            learner.observe(ti, *w)
        learner.step()
        t = tm[-1] + 0.01
    learner.observe_motion(t, True)
    return learner


def test_state_round_trips_through_a_file(tmp_path):
    learner = _learned()
    state = encode_state(learner)
    assert state['format'] == FORMAT and len(state['bins']) == 2 and state['fit'] is not None
    assert state == learner.state()
    path = tmp_path / 'learn.json'
    write_state(path, state)
    assert read_state(path) == json.loads(json.dumps(state))
    values, thermal = decode_state(read_state(path))
    assert thermal is None
    for name, value in values.items():
        if name == 'last_save_t':
            assert value == learner.last_t
        elif isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, getattr(learner, name))
        else:
            assert value == getattr(learner, name), name
    again = Learner(LearnConfig(temperature_timeout=1e9))
    assert again.load(path) and again.state() == json.loads(json.dumps(state))
    assert again.take_model() is not None         # the learned model is current at once


def test_thermal_section_is_kept():
    thermal = ThermalState('first_order', (120.0,))
    values, got = decode_state({**encode_state(_learned(temps=(20.0,))),
                                'thermal': thermal.to_dict()})
    assert got == thermal and values['session'] == 0


def test_bad_states_and_files_are_refused(tmp_path):
    assert read_state(tmp_path / 'missing.json') is None
    bad = tmp_path / 'bad.json'
    bad.write_text('{"format": ')
    with pytest.raises(ValueError, match='not JSON'):
        read_state(bad)
    for state in ({'format': 'gyro_tdc learn 0'}, [FORMAT], None):
        with pytest.raises(ValueError, match='not a learner state'):
            decode_state(state)
    state = {**encode_state(_learned(temps=(20.0,))), 'thermal': {'kind': 'first_order'}}
    with pytest.raises(ValueError, match='`thermal` missing field `tau_s`'):
        decode_state(state)


def test_learning_re_exports_the_format():
    assert learning.FORMAT is FORMAT
