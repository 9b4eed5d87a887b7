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

"""Learner states for learn_file tests: a learner that learned, hostile variants of its file."""

from __future__ import annotations

import copy
import json

from gyro_tdc.learn.learner import LearnConfig, learned_model, Learner
import numpy as np

#: The raw rate of the still stretches, rad/s.
BIAS = (0.01, -0.02, 0.005)
#: The names of :func:`hostile_files`.
HOSTILE_NAMES = ('model_yaml', 'truncated', 'list', 'bins_list', 'deep', 'deep_in_field',
                 'nan_fit', 'negative_session', 'floor_shape', 'inf_temperature', 'text', 'empty',
                 'not_utf8')


def curved_prior():
    """Return a prior whose curve has two terms (dT, dT2) over 10 .. 30 degC."""
    coef = np.array([[0.012, -0.018, 0.004], [2e-4, -1e-4, 5e-5], [1e-5, 2e-5, -1e-5]])
    return learned_model(coef, ('dT', 'dT2'), 20.0, (10.0, 30.0), np.full(3, 1e-8))


def learned(temps=(20.2, 23.4), rate_hz=100.0, prior=None):
    """
    Return a learner that learned one still stretch (120 s) per temperature, then motion.

    With ``prior`` (e.g. :func:`curved_prior`: two stretches support fewer terms than its
    curve has), what it learns is a correction to it.
    """
    learner = Learner(LearnConfig(temperature_timeout=1e9), prior=prior)
    rng = np.random.default_rng(4)
    t = 0.0
    for temp in temps:
        tt = t + np.arange(int(120 * rate_hz)) / rate_hz
        learner.add_temperature(tt[0], temp)
        still = np.array(BIAS) + 1e-4 * rng.standard_normal((tt.size, 3))
        for ti, w in zip(tt.tolist(), still.tolist()):
            learner.observe(ti, *w)
        tm = tt[-1] + (1 + np.arange(int(30 * rate_hz))) / rate_hz     # then 30 s of motion
        for ti, w in zip(tm.tolist(), (0.3 * rng.standard_normal((tm.size, 3))).tolist()):
            learner.observe(ti, *w)
        learner.step()
        t = tm[-1] + 1.0 / rate_hz
    learner.observe_motion(t, True)
    return learner


def fresh_learner():
    """Return a learner that has learned nothing (thermometer readings never go stale)."""
    return Learner(LearnConfig(temperature_timeout=1e9))


def plain_state(learner):
    """Return ``learner``'s state as it reads back from a file (plain JSON types)."""
    return json.loads(json.dumps(learner.state()))


def with_field(state, keys, value):
    """Return a deep copy of ``state`` with the item at ``keys`` (a path) set to ``value``."""
    out = copy.deepcopy(state)
    node = out
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return out


def hostile_files(state):
    """
    Return ``{name: file content (bytes)}``: files a learner cannot take as its state.

    From the defects seen: a model YAML given by mistake, truncated JSON, a JSON list,
    ``"bins": []``, deep nesting, a fit holding NaN, and wrong types, signs and shapes.
    """
    good = json.dumps(state)
    nan_fit = with_field(state, ('fit', 'coef'), [[float('nan')] * 3] * len(state['fit']['coef']))
    first_bin = next(iter(state['bins']))
    texts = {
        'model_yaml': 'format_version: 2\nkind: poly\nfeatures: [dT]\nt0_c: 20.0\n',
        'truncated': good[:len(good) // 2],
        'list': json.dumps([state]),
        'bins_list': json.dumps({**state, 'bins': []}),
        'deep': '[' * 100_000 + ']' * 100_000,
        'deep_in_field': json.dumps({**state, 'check': None})[:-1]
        + ', "extra": ' + '[' * 5000 + ']' * 5000 + '}',
        'nan_fit': json.dumps(nan_fit),
        'negative_session': json.dumps({**state, 'session': -3}),
        'floor_shape': json.dumps({**state, 'gyro_floor': [1e-4, 1e-4]}),
        'inf_temperature': json.dumps(with_field(state, ('bins', first_bin, 0, 2),
                                                 float('inf'))),
        'text': 'root:x:0:0:root:/root:/bin/bash\n',
        'empty': '',
    }
    return {**{k: v.encode() for k, v in texts.items()}, 'not_utf8': b'\xff\xfe{}'}
