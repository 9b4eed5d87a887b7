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
``train --still-only`` on a gyro with a constant axis: identity, as ``train``.

A gyro axis whose readings never vary beyond one quantum is not fitted: its columns are
exactly zero (the model passes it through), the other axes' columns are bit for bit those of
the same training with the axis at its reference, its training figures are the raw ones
over the still rows kept, ``TrainResult.constant`` names it; a gyro constant on every axis is
refused with ``train``'s own line. No warning.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
import shutil
import tempfile
import warnings

from bags import bag_from_run
from constant_axes import axis_sets, quanta, values, with_constant as _with
from gyro_tdc.errors import DatasetError
from gyro_tdc.evaluate.score import evaluate_run, NamedModel
from gyro_tdc.identify import constant_gyro_axes, train, TrainOptions
from gyro_tdc.identify.still_only import train_still_only
from gyro_tdc.model import compensate
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run

AXES = 'xyz'
OPTIONS = TrainOptions(features='dT,dT2', n_centers=6)


@pytest.fixture(scope='module')
def runs():
    """Return a still training run and a still held-out run, a known drift on every axis."""
    return (synth_run(seed=41, hours=0.5, rate_hz=2.0, noise_dps=0.02),
            synth_run(seed=42, hours=0.5, rate_hz=2.0, noise_dps=0.02, name='held'))


def _still_only(run, options=OPTIONS):
    """Train --still-only on ``run`` in a temporary folder; return the result."""
    folder = Path(tempfile.mkdtemp())
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            return train_still_only([run.name], folder / 'm.yaml', options, runs=[run])
    finally:
        shutil.rmtree(folder)


def _columns(model, keep):
    """Return the coefficients of the axes ``keep`` and what every axis shares."""
    return (model.intercept[keep], model.linear[:, keep], model.weights[:, keep],
            model.scale[keep], model.residual_var[keep], model.centers, model.widths,
            model.input_mean, model.input_std, model.temp_range_c, model.t0_c)


@given(axes=axis_sets, value=values, quantum=quanta, seed=st.integers(0, 1000))
@settings(max_examples=12)
def test_still_only_passes_a_constant_axis_through(runs, axes, value, quantum, seed):
    """Zero columns on the constant axes, the others as with them at their reference."""
    run, held = runs
    res = _still_only(_with(run, axes, value, quantum, seed))
    ref = _still_only(_with(run, axes, 0.0, 0.0))
    m = res.model
    names = [AXES[i] for i in axes]
    others = [i for i in range(3) if i not in axes]
    assert list(res.constant) == names and m.metrics['constant_axes'] == names
    assert res.constant[names[0]] == pytest.approx(value, abs=quantum + 1e-12)
    assert 'not fitted' in res.constant_line() and res.still is not None
    assert not np.any(m.intercept[axes]) and not np.any(m.linear[:, axes])
    assert not np.any(m.weights[:, axes]) and not np.any(m.scale[axes])
    for a, b in zip(_columns(m, others), _columns(ref.model, others)):
        np.testing.assert_array_equal(a, b)
    stuck = _with(held, axes, value, quantum, seed)
    comp = compensate(m, stuck.t, stuck.temp, stuck.omega)
    assert np.array_equal(comp[:, axes], stuck.omega[:, axes])        # bit for bit
    # Its training figures: the raw ones (the reference is 0 while still).
    raw = np.degrees(_with(run, axes, value, quantum, seed).omega[:, axes]) ** 2
    for k, i in enumerate(axes):
        want = raw[:, k].mean()
        assert m.metrics['train_bs_dps2'][i] == pytest.approx(want, rel=1e-9, abs=1e-300)
        assert m.metrics['raw_bs_dps2'][i] == m.metrics['train_bs_dps2'][i]
    assert all(np.isfinite(m.metrics[k]).all() for k in ('train_bs_dps2', 'train_rms_dps'))


def test_the_other_axes_are_as_accurate_as_with_the_real_signal(runs):
    """Held out, x and y compensate within 2 % of a still-only training on z's signal."""
    run, held = runs
    real = _still_only(run).model
    stuck = _still_only(_with(run, [2], 0.25, 1e-4)).model
    named = [NamedModel('real', 'real', real), NamedModel('stuck', 'stuck', stuck)]
    b = evaluate_run(held, named)
    np.testing.assert_allclose(b.models[1].bs[:2], b.models[0].bs[:2], rtol=0.02)
    assert np.all(b.models[1].bs[:2] < 0.05 * b.raw.bs[:2])


def test_auto_features_keep_the_identity(runs):
    """Choose features on the other axes only; the constant axis stays zero."""
    run, _ = runs
    res = _still_only(_with(run, [1], -0.3, 1e-5), replace(OPTIONS, features='auto'))
    assert res.choice is not None and res.model.metrics['constant_axes'] == ['y']
    assert not np.any(res.model.linear[:, 1]) and not np.any(res.model.weights[:, 1])


def test_a_gyro_constant_on_every_axis_is_refused_with_trains_line(runs, tmp_path):
    """Refuse in one line, the line train gives on the same bag; write nothing."""
    dead = _with(runs[0], [0, 1, 2], 0.01, 1e-4)
    bag = bag_from_run(dead, tmp_path / 'dead')
    with pytest.raises(DatasetError) as still:
        train_still_only([bag], tmp_path / 'a.yaml', OPTIONS)
    with pytest.raises(DatasetError) as chamber:
        train([bag], tmp_path / 'b.yaml', OPTIONS)
    assert str(still.value) == str(chamber.value)
    assert '\n' not in str(still.value) and 'every axis' in str(still.value)
    assert not (tmp_path / 'a.yaml').exists()
    with pytest.raises(DatasetError):
        constant_gyro_axes([dead])
