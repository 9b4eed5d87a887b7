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

"""
A held-out gyro axis constant by ``train``'s rule, and the ``px4`` baseline on a constant axis.

``evaluate`` flags a held-out axis whose readings never vary beyond one quantum, at any
value (not only at the reference, nor only where the model passes the axis through): its
BS/BS1 is NaN for every model (``const`` on the console, null in JSON), the other axes'
figures are those of the same bag without it, no warning; a bag constant on every axis is
refused in one line. The ``px4`` cubic does not fit a constant training axis: it passes it
through, its other axes are those fitted with the axis at its reference.
"""

from __future__ import annotations

import json
import re
import warnings

from bags import bag_from_run
from constant_axes import axis_sets, quanta, values, with_constant as _with
from gyro_tdc.errors import DatasetError
from gyro_tdc.evaluate.report import evaluation_json, format_bag, format_means
from gyro_tdc.evaluate.score import (evaluate, evaluate_run, held_out_constant, load_models,
                                     NamedModel, PX4)
from gyro_tdc.identify import fit_model, MIN_SAMPLES
from gyro_tdc.model import compensate
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run

AXES = 'xyz'


@pytest.fixture(scope='module')
def runs():
    """Return a training run and a held-out run with a known drift on every axis."""
    return (synth_run(seed=31, hours=0.5, rate_hz=2.0, noise_dps=0.02),
            synth_run(seed=32, hours=0.5, rate_hz=2.0, noise_dps=0.02, name='held'))


@pytest.fixture(scope='module')
def model(runs):
    """Return a model fitted on every axis' real signal (no identity axis)."""
    return fit_model([runs[0]], kind='poly', features=('dT', 'dT2'), t0=25.0)


@given(axes=axis_sets, value=values, quantum=quanta, seed=st.integers(0, 1000))
@settings(max_examples=20)
def test_a_held_out_constant_axis_is_flagged_whatever_it_reads(runs, model, axes, value,
                                                               quantum, seed):
    """Flag the axes, NaN their ratios, keep the other axes' figures, warn nowhere."""
    _, held = runs
    stuck = _with(held, axes, value, quantum, seed)
    named = [NamedModel('m.yaml', 'm', model), NamedModel('n.yaml', 'n', model)]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        b = evaluate_run(stuck, named, label='h')
        anchored = evaluate_run(stuck, named, label='h', reanchor_s='auto')
        text, means = format_bag(anchored, 0), format_means([b, anchored])
        doc = json.dumps(evaluation_json([b, anchored]), allow_nan=False)
    ref = evaluate_run(held, named, label='h')
    names = [AXES[i] for i in axes]
    others = [i for i in range(3) if i not in axes]
    assert b.constant_axes == names and ref.constant_axes == []
    assert held_out_constant(stuck).tolist() == [i in axes for i in range(3)]
    for ev, ev_ref in zip(b.models, ref.models):
        assert ev.constant_axes == []               # the model fits them: not its doing
        assert np.all(np.isnan(ev.p_vs_raw[axes]))
        assert np.array_equal(ev.p_vs_raw[others], ev_ref.p_vs_raw[others])
        assert np.array_equal(ev.bs[others], ev_ref.bs[others])
        assert np.all(np.isfinite(ev.bs)) and np.all(np.isfinite(ev.rms_dps))
    assert not re.search(r'\bnan\b|\binf\b', text + means, re.I), text
    rows = [r.split() for r in text.splitlines() if r.split()[:1] in (['raw'], ['m'], ['n'])]
    assert all([r[7 + i] == 'const' for i in range(3)] == [i in axes for i in range(3)]
               for r in rows[:3]), text
    for i in axes:                          # at the reference (0): raw BS 0
        exact = not b.raw.bs[i] > 0
        assert re.search(r'reads? the reference rate exactly' if exact
                         else r'never var(y|ies) beyond one quantum', text), text
    assert anchored.constant_axes == names
    assert all(np.all(np.isnan(ev.p_vs_raw[axes])) for ev in anchored.models)
    parsed = json.loads(doc)['bags'][0]
    assert parsed['constant_axes'] == names
    assert all(m['p_vs_raw'][i] is None for m in parsed['models'] for i in axes)
    assert all(m['p_vs_raw'][i] is not None for m in parsed['models'] for i in others)


def test_a_short_run_is_not_judged_constant_by_its_readings(runs, model):
    """Below the samples train needs, two values per axis are a quiet axis, not a constant."""
    _, held = runs
    stuck = _with(held, [0], 0.1, 1e-4)
    b = evaluate_run(stuck.slice(0, MIN_SAMPLES - 1), [NamedModel('m.yaml', 'm', model)])
    assert b.constant_axes == [] and np.all(np.isfinite(b.models[0].p_vs_raw))
    assert evaluate_run(stuck.slice(0, MIN_SAMPLES),
                        [NamedModel('m.yaml', 'm', model)]).constant_axes == ['x']


def test_a_bag_constant_on_every_axis_is_refused_in_one_line(runs, model, tmp_path):
    """Refuse in evaluate (one line naming the bag); evaluate_run scores it without NaN text."""
    _, held = runs
    dead = _with(held, [0, 1, 2], 0.01, 0.0)
    bag = bag_from_run(dead, tmp_path / 'dead')
    named = [NamedModel('m.yaml', 'm', model)]
    with pytest.raises(DatasetError) as err:
        evaluate([bag], named)
    text = str(err.value)
    assert '\n' not in text and 'every axis' in text and str(bag) in text
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        b = evaluate_run(dead, named)
        out = format_bag(b) + format_means([b])
    assert b.constant_axes == list(AXES) and not re.search(r'\bnan\b', out, re.I)


@given(value=values, quantum=quanta)
@settings(max_examples=6)
def test_px4_passes_a_constant_training_axis_through(runs, tmp_path_factory, value, quantum):
    """Fit the cubic on the other axes only (as with the axis at its reference); log it."""
    train_run, held = runs
    stuck = _with(train_run, [2], value, quantum)
    folder = tmp_path_factory.mktemp('px4')
    bag = bag_from_run(stuck, folder / 'train')
    lines = []
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        px4 = load_models([PX4], train_bags=[bag], log=lines.append)[0].model
    assert px4.metrics['constant_axes'] == ['z']
    assert not np.any(px4.linear[:, 2]) and px4.intercept[2] == 0.0
    comp = compensate(px4, held.t, held.temp, held.omega)
    assert np.array_equal(comp[:, 2], held.omega[:, 2])
    # The other axes: the cubic fitted on the same bag read back with z at its reference.
    read = load_models([PX4], train_bags=[bag_from_run(_with(train_run, [2], 0.0, 0.0),
                                                       folder / 'ref')])[0].model
    np.testing.assert_array_equal(px4.linear[:, :2], read.linear[:, :2])
    np.testing.assert_array_equal(px4.intercept[:2], read.intercept[:2])
    np.testing.assert_array_equal(px4.residual_var[:2], read.residual_var[:2])
    assert any('gyro axis z constant: not fitted' in x for x in lines), lines
    # Training figures of the identity axis are its raw ones.
    raw = np.degrees(np.sqrt(np.mean((stuck.omega[:, 2] - stuck.omega_ref[:, 2]) ** 2)))
    assert px4.metrics['train_rms_dps'][2] == pytest.approx(raw, rel=1e-6, abs=1e-12)


def test_px4_refuses_training_bags_constant_on_every_axis(runs, tmp_path):
    """Refuse, in one line, a px4 baseline with no gyro to fit."""
    bag = bag_from_run(_with(runs[0], [0, 1, 2], 0.0, 1e-4), tmp_path / 'dead')
    with pytest.raises(DatasetError) as err:
        load_models([PX4], train_bags=[bag])
    assert '\n' not in str(err.value) and 'every axis' in str(err.value)
