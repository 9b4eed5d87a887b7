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


"""Tests of gyro_tdc.identify.axes: constant gyro and accelerometer axes pass through unfitted."""

from __future__ import annotations

from dataclasses import replace
import json
import math
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import warnings

from bags import bag_from_run
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import write_bag
from gyro_tdc.errors import DatasetError
from gyro_tdc.evaluate.report import evaluation_json, format_bag, format_means
from gyro_tdc.evaluate.score import evaluate_run, NamedModel
from gyro_tdc.identify.accel import G0
from gyro_tdc.identify.axes import constant_axes, constant_axes_of
from gyro_tdc.identify.train import train, train_still_only, TrainOptions
from gyro_tdc.model.compensation import compensate, StreamingCompensator
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run


AXES = 'xyz'
OPTIONS = TrainOptions(features='dT,dT2', n_centers=6)

#: One axis, two or three (three: refused) of x, y, z.
axis_sets = st.sets(st.sampled_from(range(3)), min_size=1, max_size=3).map(sorted)
values = st.floats(-5.0, 5.0, allow_nan=False)
quanta = st.one_of(st.just(0.0), st.floats(1e-9, 1e-2))


def _constant_column(n: int, value: float, quantum: float, seed: int) -> np.ndarray:
    """Return ``value``, or it and the next quantum up, in random order (one quantum)."""
    rng = np.random.default_rng(seed)
    return value + quantum * rng.integers(0, 2, n)


@given(axes=axis_sets, value=values, quantum=quanta, nan=st.integers(0, 20),
       runs=st.integers(1, 3), seed=st.integers(0, 2 ** 16))
@settings(max_examples=60)
def test_constant_axes_of_finds_exactly_the_constant_axes(axes, value, quantum, nan, runs,
                                                          seed):
    rng = np.random.default_rng(seed)
    arrays = []
    for k in range(runs):
        a = rng.standard_normal((80, 3))
        for i in axes:
            a[:, i] = _constant_column(80, value, quantum, seed + k)
        a[rng.integers(0, 80, nan), rng.integers(0, 3, nan)] = np.nan
        arrays.append(a)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        found = constant_axes_of(arrays)
    assert found.tolist() == [i in axes for i in range(3)]
    assert constant_axes(arrays[0]).tolist() == found.tolist()


def test_two_quanta_apart_is_not_constant():
    a = np.zeros((100, 3))
    a[::3, 1] = 1e-3
    a[1::3, 1] = 2e-3                 # three values: a change of two quanta
    assert constant_axes_of([a[:50], a[50:]]).tolist() == [True, False, True]
    # Constant in each run, another value in each: three values together vary; two are
    # one quantum apart by definition (the smallest step seen).
    runs = [np.full((10, 3), v) for v in (0.0, 7.0, 3.0)]
    assert constant_axes_of(runs).tolist() == [False] * 3
    assert constant_axes_of(runs[:2]).tolist() == [True] * 3


@pytest.fixture(scope='module')
def runs():
    """Return a short training run and a held-out run with a known drift on every axis."""
    return (synth_run(seed=21, hours=0.5, rate_hz=2.0, noise_dps=0.02),
            synth_run(seed=22, hours=0.5, rate_hz=2.0, noise_dps=0.02))


def _train(folder, run, options=OPTIONS):
    """Write ``run`` as a bag in ``folder``, train on it; return the result."""
    bag = bag_from_run(run, folder / 'bag')
    return train([bag], folder / 'model.yaml', options)


def _with(run, axes, value, quantum, nan_rows=(), seed=0):
    """Return ``run`` with ``axes`` constant (``value`` within one quantum), NaN rows."""
    omega = run.omega.copy()
    for i in axes:
        omega[:, i] = _constant_column(len(run), value, quantum, seed)
    omega[list(nan_rows), 0] = np.nan
    return replace(run, omega=omega)


def _columns(model, axes):
    """Return every coefficient of the model's ``axes`` (and what all axes share)."""
    keep = list(axes)
    return (model.intercept[keep], model.linear[:, keep], model.weights[:, keep],
            model.scale[keep], model.centers, model.widths, model.input_mean,
            model.input_std, model.temp_range_c, model.t0_c)


@given(axes=axis_sets.filter(lambda a: len(a) < 3), value=values, quantum=quanta,
       nan_rows=st.lists(st.integers(0, 3599), max_size=8, unique=True),
       seed=st.integers(0, 1000))
@settings(max_examples=15)
def test_train_passes_constant_axes_through_and_fits_the_others_as_without_them(
        runs, axes, value, quantum, nan_rows, seed):
    run, held = runs
    other = [i for i in range(3) if i not in axes]
    tmp = tempfile.mkdtemp()
    try:
        root = Path(tmp)
        (root / 'a').mkdir()
        (root / 'b').mkdir()
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            res = _train(root / 'a', _with(run, axes, value, quantum, nan_rows, seed))
            # The same data with the constant axes reading exactly their reference (0).
            ref = _train(root / 'b', _with(run, axes, 0.0, 0.0, nan_rows))
        model = load_model(res.path)
    finally:
        shutil.rmtree(tmp)
    names = [AXES[i] for i in axes]
    assert list(res.constant) == names and model.metrics['constant_axes'] == names
    line = res.constant_line()
    assert line.startswith(f'gyro ax{"es" if len(axes) > 1 else "is"} {", ".join(names)}: '
                           'constant at ') and 'not fitted' in line
    # Identity: every coefficient of a constant axis is exactly zero.
    for part in (model.intercept[axes], model.linear[:, axes], model.weights[:, axes],
                 model.scale[axes]):
        assert not np.any(part)
    comp = compensate(model, held.t, held.temp, _with(held, axes, value, quantum).omega)
    assert np.array_equal(comp[:, axes], _with(held, axes, value, quantum).omega[:, axes])
    # The other axes: bit for bit the model of the training with the axes at 0.
    for a, b in zip(_columns(model, other), _columns(ref.model, other)):
        assert np.array_equal(np.asarray(a), np.asarray(b))
    # Every figure finite; the identity axes' training figures are the raw ones.
    for key in ('raw_bs_dps2', 'train_bs_dps2', 'train_rms_dps'):
        assert all(math.isfinite(v) for v in model.metrics[key])
    for i in axes:
        assert model.metrics['train_bs_dps2'][i] == model.metrics['raw_bs_dps2'][i]
    assert np.all(np.isfinite(model.residual_var))


def test_the_other_axes_are_as_accurate_as_with_the_real_signal(runs, tmp_path):
    run, held = runs
    (tmp_path / 'full').mkdir()
    (tmp_path / 'z').mkdir()
    full = _train(tmp_path / 'full', run).model
    dead = _train(tmp_path / 'z', _with(run, [2], 0.0, 0.0)).model
    bs_full = bias_stability(compensate(full, held.t, held.temp, held.omega), held.omega_ref)
    bs_dead = bias_stability(compensate(dead, held.t, held.temp, held.omega), held.omega_ref)
    # The ridge and centres are shared, so the x and y columns may differ in the last bits
    # from those of the full training; held out they are as accurate (within 2 %).
    assert np.allclose(bs_dead[:2], bs_full[:2], rtol=0.02), (bs_dead, bs_full)
    assert bs_dead[2] == pytest.approx(bias_stability(held.omega, held.omega_ref)[2])


def test_features_auto_and_lag_leave_the_constant_axis_identity(runs, tmp_path):
    run, _ = runs
    for i, options in enumerate((TrainOptions(), TrainOptions(features='dT,dT2,lag'))):
        (tmp_path / str(i)).mkdir()
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            res = _train(tmp_path / str(i), _with(run, [1], -0.3, 1e-4), options)
        assert res.constant == pytest.approx({'y': -0.3}, abs=1e-4)
        assert not np.any(res.model.weights[:, 1]) and not np.any(res.model.linear[:, 1])
        assert res.model.intercept[1] == 0.0


@pytest.mark.parametrize('value', [34.9, -5.01])
@pytest.mark.parametrize('still_only', [False, True])
def test_an_axis_stuck_beyond_any_drift_is_passed_through(runs, tmp_path, value, still_only):
    """A saturated axis (2000 deg/s full scale): passed through, its variance the file's cap."""
    run, held = runs
    stuck = _with(run, [1], value, 1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        res = (train_still_only(['stuck'], tmp_path / 'model.yaml', OPTIONS, runs=[stuck])
               if still_only else _train(tmp_path, stuck))
    model = load_model(res.path)
    assert model.metrics['constant_axes'] == ['y']
    assert model.residual_var[1] == 25.0            # MAX_DRIFT_RAD_S ** 2, what a file holds
    assert model.metrics['train_rms_dps'][1] == pytest.approx(math.degrees(abs(value)), rel=1e-3)
    held_stuck = _with(held, [1], value, 1e-3)
    comp = compensate(model, held.t, held.temp, held_stuck.omega)
    assert np.array_equal(comp[:, 1], held_stuck.omega[:, 1])


def test_every_axis_constant_is_refused_in_one_line(runs, tmp_path):
    run, _ = runs
    with pytest.raises(DatasetError) as exc:
        _train(tmp_path, _with(run, [0, 1, 2], 0.0, 1e-3))
    text = str(exc.value)
    assert '\n' not in text and 'every axis' in text and 'constant' in text
    assert not (tmp_path / 'model.yaml').exists()


@given(axes=axis_sets.filter(lambda a: len(a) < 3), value=values,
       quantum=st.sampled_from([0.0, 1e-4]))
@settings(max_examples=10)
def test_evaluate_scores_a_constant_axis_without_warning_or_nan(runs, axes, value, quantum):
    run, held = runs
    tmp = tempfile.mkdtemp()
    try:
        model = _train(Path(tmp), _with(run, axes, 0.0, 0.0)).model
    finally:
        shutil.rmtree(tmp)
    # The held-out axis at its reference (a 2-axis gyro's 0) and at another constant.
    bags = []
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for v, q in ((0.0, 0.0), (value, quantum)):
            bag = _with(held, axes, v, q)
            b = evaluate_run(bag, [NamedModel('m.yaml', 'm', model),
                                   NamedModel('m2.yaml', 'm2', model)], label='h')
            text = format_bag(b, 0)
            bags.append(b)
        means = format_means(bags)
        doc = json.dumps(evaluation_json(bags), allow_nan=False)
    names = [AXES[i] for i in axes]
    first = bags[0]
    assert first.constant_axes == names and first.models[0].constant_axes == names
    assert 'nan' not in text.lower() and 'nan' not in means.lower()
    assert 'const' in format_bag(first, 0) and 'gyro ax' in format_bag(first, 0)
    for ev in first.models:
        assert np.all(np.isfinite(ev.bs)) and np.all(np.isfinite(ev.rms_dps))
        assert np.all(np.isfinite(ev.p_vs_raw[[i for i in range(3) if i not in axes]]))
        assert np.all(np.isnan(ev.p_vs_raw[axes]))
    parsed = json.loads(doc)['bags'][0]
    assert parsed['constant_axes'] == names
    assert all(parsed['models'][0]['p_vs_raw'][i] is None for i in axes)
    # Passed through: the compensated constant axis is the raw one (BS equal).
    assert np.array_equal(first.models[0].bs[axes], first.raw.bs[axes])


def test_streaming_form_and_session_offsets_of_an_identity_axis(runs, tmp_path):
    run, held = runs
    bags = [bag_from_run(_with(r, [0], 0.02, 1e-5, seed=k), tmp_path / f'b{k}')
            for k, r in enumerate((run, replace(held, name='held')))]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        res = train(bags, tmp_path / 'm.yaml', OPTIONS)
    model = load_model(res.path)
    sessions = model.metrics['sessions']
    assert sessions['count'] == 2
    assert [o[0] for o in sessions['offset_dps']] == [0.0, 0.0]
    assert sessions['spread_dps'][0] == 0.0 and sessions['spread_dps'][1] > 0.0
    stream = StreamingCompensator(model)
    drifts = np.array([stream.drift(t, c) for t, c in zip(held.t[::50], held.temp[::50])])
    assert np.all(drifts[:, 0] == 0.0) and np.all(drifts[:, 1:] != 0.0)


def _bag(path, run, accel):
    write_bag(path, imu_t=run.t + 100.0, gyro=run.omega, accel=accel,
              temp_t=run.t[::5] + 100.0, temp_c=run.temp[::5])
    return path


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two still runs whose accelerometer reads exactly (0, 0, g) throughout."""
    d = tmp_path_factory.mktemp('const')
    out = []
    for i in range(2):
        run = synth_run(seed=10 + i, hours=0.5, rate_hz=5.0)
        acc = np.zeros((len(run), 3))
        acc[:, 2] = G0
        out.append(_bag(d / f'run{i + 1}', run, acc))
    return out


def test_constant_axes_by_quantum():
    rng = np.random.default_rng(0)
    q = 0.0383                                  # one LSB
    a = np.zeros((500, 3))
    a[:, 0] = q * rng.integers(0, 2, 500)        # toggles between two adjacent values
    a[:, 1] = q * rng.integers(0, 3, 500)        # spans two quanta: varies
    a[:, 2] = G0
    a[7] = np.nan
    assert constant_axes(a).tolist() == [True, False, True]
    assert constant_axes(rng.standard_normal((50, 3))).tolist() == [False] * 3


def test_train_reports_the_accelerometer_constant_and_fits_no_part(bags, tmp_path, capsys):
    out = tmp_path / 'model.yaml'
    assert train_main([str(bags[0]), '--out', str(out), '--features', 'dT,dT2',
                       '--no-progress']) == 0
    text = capsys.readouterr().out
    line = [x for x in text.splitlines() if x.startswith('accelerometer')]
    assert len(line) == 1 and 'constant' in line[0] and 'not fitted' in line[0], text
    assert '2.2e-24' not in text and 'e-2' not in line[0]
    assert load_model(out).accel is None


def test_evaluate_prints_no_warning_and_no_accelerometer_rows(bags, tmp_path):
    model = tmp_path / 'model.yaml'
    assert train_main([str(bags[0]), '--out', str(model), '--features', 'dT,dT2',
                       '--no-progress']) == 0
    res = subprocess.run([sys.executable, '-W', 'error::RuntimeWarning', '-m', 'gyro_tdc',
                          'evaluate', str(bags[1]), '--model', str(model)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert 'Warning' not in res.stderr and 'Traceback' not in res.stderr, res.stderr
    assert 'aBS' not in res.stdout and 'BS x' in res.stdout
