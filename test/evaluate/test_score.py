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
Tests of gyro_tdc.evaluate.score: hand-computed scores, constant axes, still-only scoring.

Scores against hand-computed BS, re-anchoring, bags one at a time. A held-out gyro axis
constant by ``train``'s rule (readings never varying beyond one quantum, at any value) has
BS/BS1 NaN for every model (``const`` on the console, null in JSON), the other axes' figures
those of the same bag without it, no warning; a bag constant on every axis is refused in one
line. Data without a reference that move are scored on their still stretches only, each
session re-anchored, and the record says how much, in all and per session: every sample
count, duration and temperature range of the scored part beside the whole bag's.
"""

from __future__ import annotations

import json
import math
import re
import warnings

from bags import bag_from_run
from constant_axes import axis_sets, quanta, values, with_constant as _with
from flightlogs import flight_day, flight_logs, write_dataflash
from gyro_tdc.data import write_bag
from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import DatasetError, FitError
from gyro_tdc.evaluate.report import evaluation_json, format_bag, format_means
from gyro_tdc.evaluate.score import (evaluate, evaluate_run, held_out_constant, mean_scores,
                                     NamedModel, rate_hz, score, still_rows)
from gyro_tdc.identify import fit_model, MIN_SAMPLES
from gyro_tdc.identify.train import train_still_only, TrainOptions
from gyro_tdc.model.compensation import CompensationModel
from gyro_tdc.runtime.reanchor import reanchor_shift
from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run

DEG = math.pi / 180.0
# Error patterns in deg/s, one column per axis; their BS (mean square) by hand:
# x: +-3 -> 9; y: four +1 then four -1 -> 1; z: seven 0 and one 4 -> 16/8 = 2.
ERR_DPS = np.array([[3, 1, 0], [-3, 1, 0], [3, 1, 0], [-3, 1, 0],
                    [3, -1, 0], [-3, -1, 0], [3, -1, 0], [-3, -1, 4]], dtype=float)
BS_HAND = np.array([9.0, 1.0, 2.0])
AXES = 'xyz'


def _run(err_dps, *, temp=None, ref_dps=(10.0, 0.0, -5.0), rate=10.0, name='bags/run7'):
    n = len(err_dps)
    t = 100.0 + np.arange(n) / rate
    ref = np.tile(np.asarray(ref_dps) * DEG, (n, 1))
    temp = np.full(n, 25.0) if temp is None else np.asarray(temp, dtype=float)
    return Run(t, temp, ref + np.asarray(err_dps) * DEG, ref, name, {'reference': 'constant'})


def _linear_model(intercept_dps, slope_dps_per_c, *, t0=25.0, lo=-40.0, hi=85.0):
    """Return a poly f(dT) model: drift = intercept + slope * (T - t0), deg/s."""
    coef = np.array([intercept_dps, slope_dps_per_c], dtype=float) * DEG
    return CompensationModel.polynomial(('dT',), t0, coef, temp_range_c=(lo, hi),
                                        residual_var=np.zeros(3))


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
@example(axes=[0], value=2.2103057084258616e-163, quantum=0.0, seed=0)   # raw BS subnormal
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


@pytest.fixture(scope='module')
def logs(tmp_path_factory):
    """Three power cycles with flights; a model trained on the first two."""
    root = tmp_path_factory.mktemp('logs')
    days, paths = flight_logs(root, 3, legs=5)
    model = train_still_only(paths[:2], root / 'm.yaml', TrainOptions()).model
    return days, paths, NamedModel('m.yaml', 'm', model)


def test_a_flight_log_is_scored_on_its_still_stretches_only(logs):
    days, paths, nm = logs
    run = load_run(paths[2])
    still = still_rows(run)
    assert still is not None and 0 < still.sum() < len(run)
    assert np.all(days[2].still[still])              # nothing of a flight is scored
    assert still.sum() > 0.6 * days[2].still.sum()
    b = evaluate_run(run, [nm], still=still)
    assert b.samples == int(still.sum()) == len(b.raw.omega)
    assert b.still['stretches'] >= 4 and b.still['sessions'] == 1
    assert 0.0 < b.still['still_s'] < b.still['total_s']
    # Re-anchored on the first still stretch: it averages to zero there, raw and model.
    first = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8)])) == -1)
    n_first = int(first[0]) - int(np.flatnonzero(still)[0]) if first.size else int(still.sum())
    np.testing.assert_allclose(b.raw.omega[:n_first].mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(b.models[0].omega[:n_first].mean(axis=0), 0.0, atol=1e-12)
    # The flights would be hundreds of (deg/s)^2; the still stretches are the drift and noise.
    whole = evaluate_run(run, [nm])
    assert np.all(whole.raw.bs > 100.0 * b.raw.bs)
    assert np.all(b.raw.bs < 0.02)
    assert np.all(b.models[0].p_vs_raw < 0.9)       # the model removes drift held out
    assert b.raw.adev_dps.size == 0                 # no Allan deviation across the gaps


def test_evaluate_scores_still_only_where_the_data_move_and_all_otherwise(logs, tmp_path):
    days, paths, nm = logs
    got = evaluate([paths[2]], [nm])
    assert got[0].still is not None and got[0].samples < len(days[2].imu.t)
    quiet = flight_day(7, legs=1, still_s=(200.0, 200.0))
    path = write_dataflash(tmp_path / 'quiet.bin', [quiet.imu])
    got = evaluate([path], [nm])
    assert got[0].still is None and got[0].samples == len(quiet.imu.t)
    flying = flight_day(8, legs=2, still_s=(2.0, 3.0), flight_s=(200.0, 200.0))
    path = write_dataflash(tmp_path / 'flying.bin', [flying.imu])
    with pytest.raises(FitError, match='no reference rate and no still stretch to score'):
        evaluate([path], [nm])
    # Beside a log that has still stretches it is skipped, said; the other is scored.
    said = []
    got = evaluate([paths[2], path], [nm], log=said.append)
    assert [b.bag for b in got] == [str(paths[2])]
    assert any(line.startswith(f'warning: skipped {path}: no reference rate and no still '
                               'stretch to score') for line in said), said


def test_two_power_cycles_in_one_log_are_scored_and_reported_per_session(logs, tmp_path):
    from flightlogs import Imu
    from gyro_tdc.evaluate.report import evaluation_json, format_still

    days, _paths, nm = logs
    a, b = days[0].imu, days[1].imu
    shift = a.t[-1] - b.t[0] + 1800.0                  # half an hour off between them
    imu = Imu(np.concatenate([a.t, b.t + shift]), np.vstack([a.gyro, b.gyro]),
              np.concatenate([a.temp, b.temp]), np.vstack([a.accel, b.accel]))
    path = write_dataflash(tmp_path / 'two.bin', [imu])
    got = evaluate([path], [nm])[0]
    s = got.still
    assert s['sessions'] == 2 and len(s['per_session']) == 2
    for key in ('samples', 'stretches'):
        assert sum(p[key] for p in s['per_session']) == s[key] > 0
    assert s['samples'] == got.samples
    for p in s['per_session'] + [s]:
        assert 0.0 < p['still_s'] <= p['total_s'] and 0.0 < p['share'] <= 1.0
        np.testing.assert_allclose(p['share'], p['still_s'] / p['total_s'])
        lo, hi = p['temperature_c']
        assert p['total_temperature_c'][0] <= lo <= hi <= p['total_temperature_c'][1]
        assert 0 < p['samples'] < p['total_samples']
    # Whole-bag figures: the sessions' own add up to them (the half hour between is no one's).
    assert sum(p['total_samples'] for p in s['per_session']) == s['total_samples'] == len(imu.t)
    assert s['total_temperature_c'] == [float(imu.temp.min()), float(imu.temp.max())]
    assert got.temperature_c == (min(p['temperature_c'][0] for p in s['per_session']),
                                 max(p['temperature_c'][1] for p in s['per_session']))
    doc = evaluation_json([got])['bags'][0]['still']
    assert [x['stretches'] for x in doc['sessions']] == [
        p['stretches'] for p in s['per_session']]
    assert doc['share'] == s['share'] and doc['samples'] == got.samples
    lines = format_still(got)
    assert len(lines) == 3 and 'scored the still stretches only' in lines[0]
    assert lines[1].startswith('  session 1: ') and lines[2].startswith('  session 2: ')
    pct = [float(x.split(' %)')[0].rsplit('(', 1)[1]) for x in lines]
    assert all(0.0 < v <= 100.0 for v in pct)
    assert evaluation_json(evaluate([_paths[2]], [nm]))['bags'][0]['still']['sessions'][0][
        'samples'] > 0


def test_a_log_ending_in_flight_reports_the_range_and_time_it_scored(tmp_path):
    # Still, flight, still, flight: the last flight warms the board beyond anything scored.
    from flightlogs import Imu
    from gyro_tdc.evaluate.report import format_still, format_summary

    day = flight_day(11, legs=3, still_s=(60.0, 60.0), flight_s=(300.0, 300.0), tau_s=600.0)
    end = int(np.flatnonzero(np.diff(day.still.astype(np.int8)) == 1)[-1]) + 1
    imu = Imu(day.imu.t[:end], day.imu.gyro[:end], day.imu.temp[:end], day.imu.accel[:end])
    run = load_run(write_dataflash(tmp_path / 'ends_in_flight.bin', [imu]))
    still = still_rows(run)
    assert still is not None and not still[-1]
    scored = run.temp[still]
    hi = float(np.median(scored))             # a model trained up to the middle of them
    nm = NamedModel('lin.yaml', 'lin', _linear_model([0] * 3, [0] * 3, hi=hi))
    b = evaluate_run(run, [nm], still=still)
    # Every figure of the scored part is of the still samples; the whole bag's beside it.
    assert b.temperature_c == (scored.min(), scored.max())
    assert b.temperature_c[1] < run.temp.max() - 3.0
    s = b.still
    assert s['temperature_c'] == list(b.temperature_c) == s['per_session'][0]['temperature_c']
    assert s['total_temperature_c'] == [run.temp.min(), run.temp.max()]
    assert s['total_samples'] == len(run) > b.samples == int(still.sum())
    assert b.duration_s == s['still_s'] < 0.3 * s['total_s']
    # The share outside the trained range is of the samples scored, not of the flights.
    outside = np.mean(scored > hi)
    assert b.models[0].outside_fraction == pytest.approx(outside)
    assert np.mean(run.temp > hi) > outside + 0.2
    lo_s, hi_s = b.temperature_c
    whole = f'{run.temp.min():.2f} .. {run.temp.max():.2f} degC'
    assert (f'at {lo_s:.2f} .. {hi_s:.2f} degC; the whole bag: {len(run)} samples at '
            f'{whole}') in format_still(b)[0]
    head, *rest = format_summary(b).splitlines()
    assert head.startswith(f'bag {run.name}: scored {b.samples} still samples over ')
    assert f'at {lo_s:.2f} .. {hi_s:.2f} degC (the whole bag: {len(run)} samples over ' in head
    assert f'at {whole}), reference rate zero' in head
    assert any(f'{100 * outside:.3g} % of the still samples scored lie outside' in line
               for line in rest)
    doc = evaluation_json([b])['bags'][0]
    assert doc['temperature_c'] == list(b.temperature_c) and doc['samples'] == b.samples
    assert list(doc['still']) == ['samples', 'stretches', 'still_s', 'temperature_c',
                                  'total_samples', 'total_s', 'total_temperature_c', 'share',
                                  'sessions']
    assert doc['still']['total_temperature_c'] == s['total_temperature_c']


def test_a_logging_gap_ends_a_still_stretch_as_the_still_test_ends_it():
    # Two stops at 50 Hz logged back to back in the samples, 5 min apart in time, then a
    # flight: two stretches scored, the first alone anchoring the session.
    rng = np.random.default_rng(7)
    t = np.r_[np.arange(0.0, 60.0, 0.02), np.arange(360.0, 420.0, 0.02),
              np.arange(420.0, 720.0, 0.02)]
    still = t < 420.0
    omega = rng.normal(0.0, 1e-3, (t.size, 3)) + np.where(t[:, None] < 360.0, 0.0, 0.01)
    omega[~still] += rng.normal(0.0, 0.5, (int((~still).sum()), 3))
    run = Run(t, 25.0 + t / 720.0, omega, np.zeros_like(omega), 'gap',
              {'reference': 'zero'})
    nm = NamedModel('lin.yaml', 'lin', _linear_model([0] * 3, [0] * 3))
    b = evaluate_run(run, [nm], still=still)
    assert b.still['stretches'] == 2 and b.samples == int(still.sum())
    n = int((t < 60.0).sum())
    np.testing.assert_allclose(b.raw.omega[:n].mean(axis=0), 0.0, atol=1e-12)
    # The second stop keeps its step against the first: the anchor spans the first only.
    np.testing.assert_allclose(b.raw.omega[n:].mean(axis=0), 0.01, atol=1e-3)
