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

"""Tests of gyro_tdc.evaluate.score: scores against hand-computed BS, models, labels, bags."""

from __future__ import annotations

import math

from gyro_tdc.data import write_bag
from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FitError, ModelFileError
from gyro_tdc.evaluate.score import (bag_labels, evaluate, evaluate_run, load_models, mean_scores,
                                     model_labels, NamedModel, PX4, rate_hz, safe_label, score)
from gyro_tdc.model.compensation import CompensationModel
from gyro_tdc.runtime.reanchor import reanchor_shift
import numpy as np
import pytest

DEG = math.pi / 180.0
# Error patterns in deg/s, one column per axis; their BS (mean square) by hand:
# x: +-3 -> 9; y: four +1 then four -1 -> 1; z: seven 0 and one 4 -> 16/8 = 2.
ERR_DPS = np.array([[3, 1, 0], [-3, 1, 0], [3, 1, 0], [-3, 1, 0],
                    [3, -1, 0], [-3, -1, 0], [3, -1, 0], [-3, -1, 4]], dtype=float)
BS_HAND = np.array([9.0, 1.0, 2.0])


def _run(err_dps, *, temp=None, ref_dps=(10.0, 0.0, -5.0), rate=10.0, name='bags/run7'):
    n = len(err_dps)
    t = 100.0 + np.arange(n) / rate
    ref = np.tile(np.asarray(ref_dps) * DEG, (n, 1))
    temp = np.full(n, 25.0) if temp is None else np.asarray(temp, dtype=float)
    return Run(t, temp, ref + np.asarray(err_dps) * DEG, ref, name, {'reference': 'constant'})


def _linear_model(intercept_dps, slope_dps_per_c, *, t0=25.0, lo=-40.0, hi=85.0):
    """Return a poly f(dT) model: drift = intercept + slope * (T - t0), deg/s."""
    return CompensationModel(
        kind='poly', features=('dT',), effect_params={}, t0_c=t0, input_mean=np.zeros(1),
        input_std=np.ones(1), centers=np.zeros((0, 1)), widths=np.zeros(0),
        weights=np.zeros((0, 3)), intercept=np.asarray(intercept_dps, dtype=float) * DEG,
        linear=np.asarray([slope_dps_per_c], dtype=float) * DEG, scale=np.zeros(3),
        temp_range_c=(lo, hi), residual_var=np.zeros(3))


def test_score_is_the_hand_computed_bias_stability():
    run = _run(ERR_DPS)
    raw = score(run.omega, run)
    np.testing.assert_allclose(raw.bs, BS_HAND, rtol=1e-12)
    np.testing.assert_allclose(raw.rms_dps, np.sqrt(BS_HAND), rtol=1e-12)
    np.testing.assert_array_equal(raw.p_vs_raw, np.ones(3))
    assert (raw.label, raw.model, raw.features) == ('raw', 'raw', [])
    assert raw.omega is run.omega
    half = score(run.omega_ref + 0.5 * ERR_DPS * DEG, run, label='m', model='m.yaml',
                 features=('dT',), bs_raw=raw.bs)
    np.testing.assert_allclose(half.bs, BS_HAND / 4, rtol=1e-12)
    np.testing.assert_allclose(half.p_vs_raw, [0.25, 0.25, 0.25], rtol=1e-12)
    assert (half.label, half.model, half.features) == ('m', 'm.yaml', ['dT'])


def test_score_allan_curve_only_from_four_samples():
    run = _run(ERR_DPS[:3])
    ev = score(run.omega, run)
    assert ev.adev_tau_s.shape == (0,) and ev.adev_dps.shape == (0, 3)
    ev = score(_run(np.tile(ERR_DPS, (50, 1))).omega, _run(np.tile(ERR_DPS, (50, 1))))
    assert ev.adev_tau_s[0] == pytest.approx(0.1)          # one sample at 10 Hz
    assert ev.adev_dps.shape == (len(ev.adev_tau_s), 3)


def test_rate_from_the_median_step():
    assert rate_hz(np.array([0.0, 0.1, 0.2, 0.35, 0.45])) == pytest.approx(10.0)
    assert rate_hz(np.array([3.0])) == 1.0


def test_evaluate_run_removes_a_known_drift_to_the_hand_computed_bs():
    n = 160
    temp = np.linspace(20.0, 40.0, n)
    err = np.tile(ERR_DPS, (n // 8, 1))
    drift_dps = np.array([0.3, -0.2, 0.1]) + (temp - 25.0)[:, None] * [0.02, -0.01, 0.03]
    run = _run(err + drift_dps, temp=temp)
    exact = NamedModel('exact.yaml', 'exact', _linear_model([0.3, -0.2, 0.1],
                                                            [0.02, -0.01, 0.03]))
    b = evaluate_run(run, [exact])
    np.testing.assert_allclose(b.models[0].bs, BS_HAND, rtol=1e-9)
    raw_hand = np.mean((err + drift_dps) ** 2, axis=0)
    np.testing.assert_allclose(b.raw.bs, raw_hand, rtol=1e-12)
    np.testing.assert_allclose(b.models[0].p_vs_raw, BS_HAND / raw_hand, rtol=1e-9)
    assert b.models[0].outside_fraction == 0.0
    assert (b.bag, b.label, b.samples, b.reference) == ('bags/run7', 'run7', n, 'constant')
    assert b.temperature_c == (20.0, 40.0)
    assert b.duration_s == pytest.approx((n - 1) / 10.0)
    assert b.run is run
    b.release()
    assert b.run is None and b.raw.omega is None and b.models[0].omega is None
    np.testing.assert_allclose(b.models[0].bs, BS_HAND, rtol=1e-9)  # scores kept


def test_outside_the_trained_range_is_clamped_and_counted():
    n = 80
    temp = np.linspace(20.0, 40.0, n)
    run = _run(np.tile(ERR_DPS, (n // 8, 1)) + (temp - 25.0)[:, None] * 0.02, temp=temp)
    narrow = NamedModel('narrow', 'narrow', _linear_model([0, 0, 0], [0.02] * 3, hi=30.0))
    b = evaluate_run(run, [narrow], out_of_range='clamp')
    ev = b.models[0]
    assert b.out_of_range == 'clamp'
    assert ev.outside_fraction == pytest.approx(np.count_nonzero(temp > 30.0) / n)
    assert ev.temp_range_c == (-40.0, 30.0)
    # Clamped at 30 degC the model leaves 0.02 * (T - 30) deg/s above the range.
    left = np.tile(ERR_DPS, (n // 8, 1)) + np.clip(temp - 30.0, 0.0, None)[:, None] * 0.02
    np.testing.assert_allclose(ev.bs, np.mean(left ** 2, axis=0), rtol=1e-9)
    # The default, linear: a straight line continues exactly, up to 15 degC beyond.
    b = evaluate_run(run, [narrow])
    assert b.out_of_range == 'linear'
    np.testing.assert_allclose(b.models[0].bs, BS_HAND, rtol=1e-9)
    short = evaluate_run(run, [narrow], max_extrapolation_c=4.0).models[0]
    left = np.tile(ERR_DPS, (n // 8, 1)) + np.clip(temp - 34.0, 0.0, None)[:, None] * 0.02
    np.testing.assert_allclose(short.bs, np.mean(left ** 2, axis=0), rtol=1e-9)
    with pytest.raises(ValueError, match="'linear', 'clamp' or 'extrapolate'"):
        evaluate_run(run, [narrow], out_of_range='hold')


def test_reanchor_removes_the_start_up_offset_of_models_only():
    err = np.tile(ERR_DPS, (10, 1))
    run = _run(err + [1.0, -2.0, 0.5])                # a run-to-run offset the model lacks
    model = NamedModel('m', 'm', _linear_model([0, 0, 0], [0, 0, 0]))
    plain = evaluate_run(run, [model])
    # mean((e + c)^2) = BS + 2 c mean(e) + c^2, with mean(e) = (0, 0, 0.5) deg/s.
    np.testing.assert_allclose(plain.models[0].bs, [9 + 1, 1 + 4, 2 + 0.5 + 0.25], rtol=1e-9)
    # The first 0.35 s hold samples 0-3, whose errors average (0, 1, 0) deg/s.
    anchored = evaluate_run(run, [model], reanchor_s=0.35)
    np.testing.assert_allclose(anchored.models[0].bs, BS_HAND + [0.0, 1.0, 0.0], rtol=1e-9)
    np.testing.assert_allclose(anchored.raw.bs, plain.raw.bs)
    assert anchored.models[0].reanchor is None


def test_reanchor_auto_is_the_compensators_rule():
    rng = np.random.default_rng(4)
    n = 20 * 300                                     # 300 s at 20 Hz
    offset = np.array([0.05, -0.03, 0.02])           # deg/s, the session offset
    err = rng.normal(0.0, 0.02, (n, 3)) + offset
    run = _run(err, rate=20.0)
    sd = 0.05 * DEG                                  # the model's residual std
    model = _linear_model([0, 0, 0], [0, 0, 0]).replace(residual_var=np.full(3, sd ** 2))
    ev = evaluate_run(run, [NamedModel('m', 'm', model)], reanchor_s='auto').models[0]
    r = ev.reanchor
    want = reanchor_shift(run.t, run.omega - run.omega_ref, tolerance=[0.1 * sd] * 3)
    assert r['samples'] == want.samples and r['reason'] == want.reason == 'precision'
    np.testing.assert_allclose(r['shift_dps'], np.degrees(want.delta), rtol=1e-12)
    np.testing.assert_allclose(r['tolerance_dps'], [0.005] * 3, rtol=1e-12)
    # 0.02 deg/s white noise needs (0.02 / 0.005)^2 = 16 samples: the first 10 s window does.
    assert r['duration_s'] == pytest.approx(10.0, abs=0.06)
    assert max(r['se_dps']) <= 0.005
    np.testing.assert_allclose(r['shift_dps'], offset, atol=4 * 0.005)
    head = err[:r['samples']].mean(axis=0)
    np.testing.assert_allclose(ev.bs, np.mean((err - head) ** 2, axis=0), rtol=1e-9)


def test_labels_are_safe_and_unique():
    assert safe_label('models/My Model.yaml') == 'My_Model'
    assert safe_label('bags/run1/') == 'run1'
    assert safe_label('...') == 'unnamed'
    assert model_labels(['a/m.yaml', 'b/m.yaml', PX4, 'raw.yaml', 'b/m.yml']) == \
        ['m', 'm_2', 'px4', 'raw_model', 'm_3']
    assert bag_labels(['x/run1', 'y/run1', 'z/run2']) == ['x_run1', 'y_run1', 'run2']


def test_load_models(tmp_path):
    models = load_models(['l3gd20_modified'])
    assert [(m.name, m.label) for m in models] == [('l3gd20_modified', 'l3gd20_modified')]
    assert isinstance(models[0].model, CompensationModel)
    with pytest.raises(FitError, match='px4 baseline needs training bags'):
        load_models([PX4])
    with pytest.raises(ModelFileError):
        load_models([str(tmp_path / 'missing.yaml')])


def test_mean_scores_average_bs_and_ratios_per_bag():
    m = NamedModel('m', 'm', _linear_model([0, 0, 0], [0, 0, 0]))
    a = evaluate_run(_run(ERR_DPS), [m])
    b = evaluate_run(_run(2 * ERR_DPS), [m])
    rows = mean_scores([a, b])
    assert [r[0] for r in rows] == ['raw', 'm']
    np.testing.assert_allclose(rows[0][1], (BS_HAND + 4 * BS_HAND) / 2)
    np.testing.assert_allclose(rows[1][2], [1.0, 1.0, 1.0])


def _small_bag(path, seed):
    rng = np.random.default_rng(seed)
    n = 600
    imu_t = 10.0 + np.arange(n) * 0.1
    temp_t = 10.0 + np.arange(n // 10 + 1) * 1.0
    temp_c = np.linspace(20.0, 40.0, len(temp_t))
    gyro = (0.5 + 0.01 * (np.interp(imu_t, temp_t, temp_c) - 25.0))[:, None] * DEG \
        + rng.normal(0.0, 0.01 * DEG, size=(n, 3))
    write_bag(path, imu_t=imu_t, gyro=gyro, accel=np.zeros((n, 3)), temp_t=temp_t,
              temp_c=temp_c)


def test_evaluate_bags_one_at_a_time_equals_evaluate_run(tmp_path):
    for k in (1, 2):
        _small_bag(tmp_path / 'runs' / f'run{k}', seed=k)
    model = NamedModel('lin', 'lin', _linear_model([0.5] * 3, [0.01] * 3))
    seen, lines = [], []

    def each(b):
        assert b.run is not None and b.models[0].omega is not None
        seen.append(b.label)

    results = evaluate([tmp_path / 'runs'], [model], log=lines.append, each=each)
    assert seen == ['run1', 'run2']
    assert [line.split(':')[0] for line in lines] == \
        [f'read {tmp_path / "runs" / f"run{k}"}' for k in (1, 2)]
    for k, b in enumerate(results, start=1):
        assert b.run is None
        want = evaluate_run(load_run(tmp_path / 'runs' / f'run{k}'), [model])
        np.testing.assert_array_equal(b.models[0].bs, want.models[0].bs)
        np.testing.assert_array_equal(b.raw.bs, want.raw.bs)
        assert b.models[0].bs.max() < 1e-3 < b.raw.bs.min()   # the drift is removed
