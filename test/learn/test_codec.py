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

"""The learner's state as plain types and back (``learn.codec``), every field checked."""

from __future__ import annotations

import copy
import json
import math
import re

from gyro_tdc.learn.codec import decode_state, encode_state
from gyro_tdc.learn.learner import LearnConfig, Learner
from gyro_tdc.model.thermal_state import ThermalState
from learn_states import curved_prior, fresh_learner, learned, plain_state, with_field
import numpy as np
import pytest


@pytest.fixture(scope='module')
def base():
    """Return a learner that learned two still stretches, and its state as a file holds it."""
    learner = learned()
    return learner, plain_state(learner)


def test_the_held_out_record_round_trips(base):
    learner, state = base
    held = state['fit']['held_out']
    assert held == learner.fit['held_out'] and held['sessions'] == 1 and held['folds'] == 0
    values, _ = decode_state(state)
    assert values['fit']['held_out'] == held
    judged = {**held, 'folds': 2, 'points': 5, 'curve_ms_dps2': [1e-4, 2e-4, 3e-4],
              'offset_ms_dps2': [2e-4, 1e-4, 3e-4], 'offset_only': ['y', 'z']}
    values, _ = decode_state(with_field(state, ('fit', 'held_out'), judged))
    assert values['fit']['held_out'] == judged


def test_the_start_up_shift_gate_round_trips(base):
    learner, state = base
    gate = state['fit']['reanchor']
    assert gate == learner.fit['reanchor'] == learner.model.metrics['reanchor']
    assert gate['sessions'] == 1 and gate['held_out'] == 0       # one power cycle: kept
    assert gate['min_shift_dps'] == pytest.approx(2.0 * np.array(gate['anchor_error_dps']))
    values, _ = decode_state(state)
    assert values['fit']['reanchor'] == gate
    # A learn file written before the gate: the model takes any shift, as it did.
    old = copy.deepcopy(state)
    del old['fit']['reanchor']
    fresh = fresh_learner()
    fresh.load_state(old)
    assert 'reanchor' not in fresh.model.metrics


def test_thermal_section_is_kept():
    thermal = ThermalState('first_order', (120.0,))
    values, got = decode_state({**encode_state(learned(temps=(20.0,))),
                                'thermal': thermal.to_dict()})
    assert got == thermal and values['session'] == 0


@pytest.mark.parametrize('keys,value,field', [
    (('fit', 'coef', 0, 0), math.nan, 'fit.coef[0][0]'),
    (('fit', 'coef', 1, 2), math.inf, 'fit.coef[1][2]'),
    (('fit', 't0_c'), 1e308, 'fit.t0_c'),
    (('fit', 'coef', 0, 1), 1e6, 'fit'),               # bounded, but a drift of 1e6 rad/s
    (('fit', 'resid_var'), [1e-8, 1e-8], 'fit.resid_var'),
    (('power_ups', 0, 4), math.nan, 'power_ups[0][4] (mean rate)'),
    (('power_ups', 0, 3), 1e30, 'power_ups[0][3] (temperature)'),
    (('power_ups', 0, 0), -1, 'power_ups[0][0] (session)'),
    (('power_ups', 0), [0, 1, 10.0], 'power_ups[0]'),
    (('power_ups',), [[0, 1, 10.0, 20.0, 0.0, 0.0, 0.0]] * 101, 'power_ups'),
    (('session',), -1, 'session'),
    (('stretches',), 2.5, 'stretches'),
    (('still_s',), math.nan, 'still_s'),
    (('check', 'candidate_mse'), -1.0, 'check.candidate_mse'),
    (('recent', 0, 2, 0, 1), 1e30, 'recent[0][2][0][1] (temperature)'),
    (('motion', 0, 1), 'yes', 'motion[0][1]'),
    (('thermal_state',), [0.0, [20.0]], 'thermal_state'),
    (('fit', 'held_out'), None, 'fit.held_out'),
    (('fit', 'held_out', 'folds'), -1, 'fit.held_out.folds'),
    (('fit', 'held_out', 'curve_ms_dps2'), [1.0, math.nan, 0.0],
     'fit.held_out.curve_ms_dps2[1]'),
    (('fit', 'held_out', 'offset_only'), ['x', 'w'], 'fit.held_out.offset_only'),
    (('fit', 'held_out', 'offset_only'), ['x', 'x'], 'fit.held_out.offset_only'),
    (('fit', 'held_out', 'offset_only'), [['x']], 'fit.held_out.offset_only'),     # unhashable
    (('fit', 'reanchor', 'min_shift_dps'), [0.0, -1.0, 0.0], 'fit.reanchor.min_shift_dps[1]'),
    (('fit', 'reanchor', 'held_out'), 1.5, 'fit.reanchor.held_out'),
    (('fit', 'reanchor', 'gate'), 1.0, 'fit.reanchor'),
    (('config', 'min_still_s'), 'auto', 'config.min_still_s'),     # null is the auto rule
    (('config', 'min_still_s'), -5.0, 'config.min_still_s'),
    (('config', 'window_s'), None, 'config.window_s'),            # null there is not
])
def test_every_field_is_checked_and_named(base, keys, value, field):
    """Refuse NaN or Inf anywhere, negative counts, wrong shapes, naming the field."""
    _, state = base
    with pytest.raises(ValueError, match=re.escape(f'field `{field}`')):
        fresh_learner().load_state(with_field(state, keys, value))


def test_the_auto_stretch_rule_round_trips(base):
    """Save and load a learner whose ``min_still_s`` is None (the default: the auto rule)."""
    _, state = base
    assert state['config']['min_still_s'] is None
    learner = fresh_learner()
    learner.load_state(json.loads(json.dumps(state)))
    assert learner.state()['config']['min_still_s'] is None


def test_a_fit_holding_nan_is_not_loaded(base):
    """A learn_file whose fit holds NaN: refused, not a model emitting NaN for every sample."""
    _, state = base
    nan = with_field(state, ('fit', 'coef', 0), [math.nan, 0.0, 0.0])
    learner = fresh_learner()
    with pytest.raises(ValueError, match='field `fit.coef'):
        learner.load_state(nan)
    assert learner.take_model() is None


@pytest.fixture(scope='module')
def corrected():
    """Return a learner that learned a correction to its prior, and its state."""
    learner = learned(prior=curved_prior())
    return learner, plain_state(learner)


def test_a_correction_keeps_the_prior_it_corrects(corrected):
    learner, state = corrected
    prior = learner.prior
    assert state['fit']['prior'] == prior.model_id == state['prior']['model_id']
    values, _ = decode_state(state)
    assert values['prior'].model_id == prior.model_id and values['fit'] == learner.fit
    # Without a correction there is no prior in the file (a learn file as before).
    assert 'prior' not in plain_state(learned())


@pytest.mark.parametrize('keys, value, field', [
    (('fit', 'prior'), 'abcdef012345', 'fit.prior'),
    (('fit', 'prior'), 7, 'fit.prior'),
    (('prior',), None, 'fit.prior'),
    (('prior',), {'kind': 'rbf'}, 'prior'),
    (('prior', 'intercept'), [0.0, 0.0, 0.0], 'prior'),
    (('prior', 'thermal'), {'kind': 'first_order', 'tau_s': [100.0]}, 'prior'),
])
def test_a_hostile_correction_is_refused_naming_the_field(corrected, keys, value, field):
    """A wrong id, no prior, a prior that is no model (or was edited): one line, no change."""
    learner, state = corrected
    bad = with_field(state, keys, value)
    fresh = Learner(LearnConfig(temperature_timeout=1e9), prior=learner.prior)
    before = fresh.state()
    with pytest.raises(ValueError, match=re.escape(f'field `{field}`')) as err:
        fresh.load_state(bad)
    assert '\n' not in str(err.value) and fresh.state() == before
