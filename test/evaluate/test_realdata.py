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
Tests of gyro_tdc.evaluate.realdata: held-out evaluation on the real PAN CubeSat TVAC recording.

The recording ships beside the repository in ``shared/data/pan_cubesat_tvac``; the tests that
need it skip only when that file is absent. One synthetic bursty run checks the machinery
without it.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.realdata import pan_cubesat_to_bag, read_pan_cubesat_csv
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FitError
from gyro_tdc.evaluate.realdata import (burst_holdout, burst_index, fit_full_series,
                                        format_holdout, HOLDOUT_MODELS, HoldoutModel, pan_holdout)
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PAN_CSV = ROOT / 'data' / 'pan_cubesat_tvac' / 'TVCtest3_7_20.csv'   # shipped in the repository
needs_pan = pytest.mark.skipif(
    not PAN_CSV.is_file(),
    reason=f'real recording {PAN_CSV} is absent (it ships beside the repository in CI)')

# The documented JSON shape (doc/real_data.md).
TOP_KEYS = {'source', 'samples', 'bursts', 'samples_per_burst', 'burst_period_s',
            'temperature_c', 'temperature_first_last_c', 't0_c', 'noise', 'drift_dps',
            'models', 'schemes', 'rows_removed'}
NOISE_KEYS = {'within_burst_sd_dps', 'floor_bs_dps2', 'diff_sd_dps', 'burst_mean_se_dps'}
SCHEME_KEYS = {'name', 'n_blocks', 'bursts_per_block', 'folds', 'summary'}
FOLD_KEYS = {'block', 'bursts', 'samples', 'position', 'temperature_c',
             'train_temperature_c', 'outside_fraction', 'floor_bs_dps2', 'models'}
SCORE_KEYS = {'bs', 'rms_dps', 'floor_ratio', 'bs_unclamped', 'floor_ratio_unclamped'}
SUMMARY_KEYS = {'folds', 'samples', 'floor_bs_dps2', 'models'}
NAMES = [m.name for m in HOLDOUT_MODELS]
# The prediction of a model varies within a burst through the temperature register's noise
# (0.02 degC sd), which correlates by chance with the gyro noise: BS may dip under the floor
# by about 1 %, never more.
FLOOR_TOL = 0.98


@pytest.fixture(scope='module')
def pan():
    """Run the evaluation once: 5 blocks of 5 bursts and leave-one-burst-out."""
    return pan_holdout(PAN_CSV, n_blocks=5)


def _scheme(result, name):
    return next(s for s in result['schemes'] if s['name'] == name)


@needs_pan
def test_json_has_the_documented_keys(pan):
    assert set(pan) == TOP_KEYS
    assert set(pan['noise']) == NOISE_KEYS
    assert pan['samples'] == 6247 and pan['bursts'] == 25 and pan['rows_removed'] == 3
    assert [m['name'] for m in pan['models']] == NAMES
    assert [s['name'] for s in pan['schemes']] == ['leave_one_block_out', 'leave_one_burst_out']
    blocks, loo = pan['schemes']
    assert blocks['n_blocks'] == 5 and blocks['bursts_per_block'] == [5]
    assert loo['n_blocks'] == 25 and loo['bursts_per_block'] == [1]
    for s in pan['schemes']:
        assert set(s) == SCHEME_KEYS and len(s['folds']) == s['n_blocks']
        assert set(s['summary']) == {'interior', 'end', 'all'}
        for f in s['folds']:
            assert set(f) == FOLD_KEYS and f['position'] in ('interior', 'end')
            assert list(f['models']) == NAMES
            for name, m in f['models'].items():
                assert SCORE_KEYS <= set(m)
                assert all(len(m[k]) == 3 for k in SCORE_KEYS)
        for sm in s['summary'].values():
            assert set(sm) == SUMMARY_KEYS and list(sm['models']) == NAMES
            for m in sm['models'].values():
                assert SCORE_KEYS | {'p_vs_raw', 'p_vs_bias'} == set(m)
        assert s['summary']['all']['samples'] == 6247
    # Held-out folds cover every burst exactly once.
    covered = [b for f in blocks['folds'] for b in range(f['bursts'][0], f['bursts'][1] + 1)]
    assert covered == list(range(25))
    assert json.loads(json.dumps(pan)) == pan


@needs_pan
def test_noise_floor_is_the_within_burst_scatter(pan):
    sd = np.array(pan['noise']['within_burst_sd_dps'])
    # LSM6DSM at 50 Hz: about 0.015 deg/s on every axis (the whole-recording sd, 0.08 / 0.04
    # / 0.016 deg/s, is the drift, not the noise).
    assert np.all((sd > 0.012) & (sd < 0.019)), sd
    np.testing.assert_allclose(pan['noise']['floor_bs_dps2'], sd ** 2)
    for s in pan['schemes']:
        for f in s['folds']:
            for name, m in f['models'].items():
                for key in ('floor_ratio', 'floor_ratio_unclamped'):
                    assert min(m[key]) >= FLOOR_TOL, (s['name'], f['block'], name, key, m[key])
                np.testing.assert_allclose(np.array(m['bs']) / f['floor_bs_dps2'],
                                           m['floor_ratio'])
                np.testing.assert_allclose(np.sqrt(m['bs']), m['rms_dps'])


@needs_pan
def test_summaries_pool_the_held_out_samples_of_their_folds(pan):
    # A group's BS (and its floor) is over all held-out samples of its folds together: the
    # sample-weighted mean of the folds' figures.
    for s in pan['schemes']:
        for g, sm in s['summary'].items():
            folds = [f for f in s['folds'] if g in ('all', f['position'])]
            n = np.array([f['samples'] for f in folds], dtype=float)[:, None]
            assert sm['samples'] == int(n.sum()) and sm['folds'] == len(folds)
            np.testing.assert_allclose(
                sm['floor_bs_dps2'], (n * [f['floor_bs_dps2'] for f in folds]).sum(0) / n.sum(),
                rtol=1e-12)
            for name, m in sm['models'].items():
                for key in ('bs', 'bs_unclamped'):
                    fold_bs = np.array([f['models'][name][key] for f in folds])
                    np.testing.assert_allclose(m[key], (n * fold_bs).sum(0) / n.sum(),
                                               rtol=1e-12)
                np.testing.assert_allclose(np.sqrt(m['bs']), m['rms_dps'])
                np.testing.assert_allclose(np.array(m['bs']) / sm['models']['raw']['bs'],
                                           m['p_vs_raw'])


@needs_pan
def test_raw_bs_is_the_constant_offset(pan):
    raw = pan['schemes'][0]['summary']['all']['models']['raw']
    # BS1 around the reference 0 is dominated by the zero-rate offset (about -2, 1.7 and
    # 0.8 deg/s): thousands of noise floors on every axis, even z where nothing is thermal.
    assert raw['rms_dps'][0] == pytest.approx(1.97, abs=0.05)
    assert min(raw['floor_ratio']) > 1000.0


@needs_pan
@pytest.mark.parametrize('scheme', ['leave_one_block_out', 'leave_one_burst_out'])
def test_thermal_models_beat_the_bias_only_baseline_on_interior_blocks(pan, scheme):
    interior = _scheme(pan, scheme)['summary']['interior']['models']
    bias_x = interior['bias']['bs'][0]
    for name in ('conventional', 'modified', 'px4', 'lag'):
        m = interior[name]
        # x: the 0.25 deg/s thermal drift is removed down to a few % above the noise floor.
        assert m['bs'][0] < 0.1 * bias_x, (name, m['bs'][0], bias_x)
        assert m['floor_ratio'][0] < 1.15, (name, m['floor_ratio'])
        # y: a 0.12 deg/s drift, removed as well.
        assert m['bs'][1] < 0.4 * interior['bias']['bs'][1]
        assert m['floor_ratio'][1] < 1.1
    # z: the drift (about 0.01 deg/s) is within the non-thermal wander; bias-only is already
    # within 20 % of the floor and no model does much better or worse.
    assert interior['bias']['floor_ratio'][2] < 1.25
    for name in ('conventional', 'modified', 'px4', 'lag'):
        assert interior[name]['floor_ratio'][2] < 1.2


@needs_pan
def test_every_interior_block_beats_bias_only_on_x(pan):
    for f in _scheme(pan, 'leave_one_block_out')['folds']:
        if f['position'] != 'interior':
            continue
        assert f['outside_fraction'] == 0.0
        for name in ('conventional', 'modified'):
            assert f['models'][name]['bs'][0] < f['models']['bias']['bs'][0], (f['block'], name)


@needs_pan
def test_end_blocks_extrapolate_and_clamping_shows(pan):
    s = _scheme(pan, 'leave_one_block_out')
    ends = [f for f in s['folds'] if f['position'] == 'end']
    assert [f['block'] for f in ends] == [0, 4]
    assert all(f['outside_fraction'] == 1.0 for f in ends)
    end = s['summary']['end']['models']
    # Clamped to the training range the model is flat over 1.3 degC: several floors on x.
    assert end['modified']['floor_ratio'][0] > 2.0
    # Allowed to extrapolate, the polynomial follows the drift, and so does the K = 12 RBF:
    # its ridge, chosen by cross-validation over held-out segments, keeps it from wiggling.
    assert end['modified']['floor_ratio_unclamped'][0] < 1.3
    assert end['rbf']['floor_ratio_unclamped'][0] < 1.3
    # Still far better than the bias-only baseline, clamped or not.
    assert end['modified']['bs'][0] < 0.2 * end['bias']['bs'][0]


@needs_pan
def test_default_rbf_does_not_overfit_a_hole_in_the_training_temperatures(pan):
    # With a fixed tiny ridge the 12-centre network wiggled across the 1.6 degC hole a held-out
    # block leaves (4x the floor on x); the cross-validated ridge brings it to the polynomial.
    interior = _scheme(pan, 'leave_one_block_out')['summary']['interior']['models']
    assert interior['rbf']['floor_ratio'][0] < 1.1 * interior['modified']['floor_ratio'][0]
    assert interior['rbf4']['floor_ratio'][0] < 1.3


@needs_pan
def test_lag_time_constant_spans_several_bursts(pan):
    period = pan['burst_period_s']
    for s in pan['schemes']:
        for f in s['folds']:
            tau = f['models']['lag']['effect_params']['lag']['tau_s']
            assert 2 * period < tau < 20 * period, (s['name'], f['block'], tau)


@needs_pan
def test_full_series_fit_equals_fit_model_on_static_features():
    data = read_pan_cubesat_csv(PAN_CSV)
    run = Run(data.t, data.temp_c, data.gyro, np.zeros_like(data.gyro), 'pan')
    burst = burst_index(run.t)
    train = ~np.isin(burst, [10, 11, 12])
    idx = np.flatnonzero(train)
    sub = Run(run.t[idx], run.temp[idx], run.omega[idx], run.omega_ref[idx])
    for feats in (('dT',), ('dT', 'dT2')):
        ours = fit_full_series(run, train, features=feats, t0=23.8)
        core = fit_model([sub], kind='poly', features=feats, t0=23.8)
        assert ours.temp_range_c == core.temp_range_c
        np.testing.assert_allclose(ours.compensate(run.t, run.temp, run.omega),
                                   compensate(core, run.t, run.temp, run.omega),
                                   rtol=0, atol=1e-12)


@needs_pan
def test_tool_prints_tables_and_writes_json(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location('pan_holdout_tool',
                                                  ROOT / 'tools' / 'pan_holdout.py')
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    out_json = tmp_path / 'sub' / 'holdout.json'
    assert tool.main(['--csv', str(PAN_CSV), '--blocks', '5', '--json', str(out_json)]) == 0
    out = capsys.readouterr().out
    for text in ('leave_one_block_out: 5 blocks of 5 bursts', 'leave_one_burst_out',
                 'interior (interpolation)', 'end (extrapolation', 'NOT clamped',
                 'white noise (within-burst sd at 50 Hz)', 'ratio x', '/bias x'):
        assert text in out, text
    result = json.loads(out_json.read_text())
    assert set(result) == TOP_KEYS and result['source'] == str(PAN_CSV)


def test_tool_bad_input_exits_2(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location('pan_holdout_tool',
                                                  ROOT / 'tools' / 'pan_holdout.py')
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(['--csv', str(tmp_path / 'none.csv')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('pan_holdout: error: Cannot read PAN CubeSat CSV')
    assert err.count('\n') == 1
    with pytest.raises(SystemExit) as exc:
        tool.main(['--blocks', '1'])
    assert exc.value.code == 2
    assert 'expected at least 2 blocks' in capsys.readouterr().err


def _bursty_run(seed: int = 3) -> tuple[Run, float]:
    """Return 12 bursts of 100 samples cooling 24 -> 13 degC (quadratic drift), noise sd."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([300.0 * k + 0.02 * np.arange(100) for k in range(12)])
    temp = 24.0 - 11.0 * (t / t[-1]) ** 1.3
    dt = temp - 24.0
    drift = np.radians(0.5 + 0.02 * dt + 0.004 * dt ** 2)
    sd = np.radians(0.01)
    omega = drift[:, None] * np.array([1.0, -0.5, 0.0]) + rng.normal(0.0, sd, (t.size, 3))
    return Run(t, temp, omega, np.zeros_like(omega), 'synthetic'), math.degrees(sd)


def test_synthetic_bursts_reach_the_floor_where_the_model_is_right():
    run, sd = _bursty_run()
    keep = ('raw', 'bias', 'conventional', 'modified', 'lag')
    models = [m for m in HOLDOUT_MODELS if m.name in keep]
    res = burst_holdout(run, n_blocks=4, leave_one_out=False, models=models)
    assert res['bursts'] == 12 and len(res['schemes']) == 1
    np.testing.assert_allclose(res['noise']['within_burst_sd_dps'], [sd] * 3, rtol=0.1)
    interior = res['schemes'][0]['summary']['interior']['models']
    # The drift is quadratic in dT: the modified model reaches the floor, the linear one not.
    assert interior['modified']['floor_ratio'][0] < 1.05
    assert interior['conventional']['floor_ratio'][0] > 10.0
    assert interior['bias']['floor_ratio'][0] > 20.0
    text = format_holdout(res)
    assert 'leave_one_block_out: 4 blocks of 3 bursts' in text
    assert 'leave_one_burst_out' not in text


def test_block_lines_give_the_temperatures_low_to_high():
    run, _ = _bursty_run()
    models = [m for m in HOLDOUT_MODELS if m.name in ('raw', 'bias')]
    res = burst_holdout(run, n_blocks=4, leave_one_out=False, models=models)
    text = format_holdout(res)
    for f in res['schemes'][0]['folds']:
        lo, hi = f['temperature_c']
        assert lo < hi
        assert f'bursts {f["bursts"][0]}-{f["bursts"][1]}, {lo:.2f}..{hi:.2f} degC, ' in text


def test_bad_arguments_name_the_argument():
    run, _ = _bursty_run()
    with pytest.raises(FitError, match=r'`n_blocks` between 2 and the number of bursts \(12\), '
                       r'got 13'):
        burst_holdout(run, n_blocks=13)
    with pytest.raises(FitError, match='unique names'):
        burst_holdout(run, models=[HoldoutModel('a', 'a', 'raw'), HoldoutModel('a', 'b', 'raw')])
    with pytest.raises(FitError, match='`train` of shape'):
        fit_full_series(run, np.ones(3, dtype=bool), features=('dT',), t0=24.0)


@needs_pan
def test_the_bag_route_gives_the_same_figures(pan, tmp_path):
    pan_cubesat_to_bag(PAN_CSV, tmp_path / 'pan')
    via_bag = burst_holdout(load_run(tmp_path / 'pan'), n_blocks=5, leave_one_out=False)
    ours, theirs = pan['schemes'][0]['summary'], via_bag['schemes'][0]['summary']
    for g in ('interior', 'end', 'all'):
        for name in NAMES:
            np.testing.assert_allclose(theirs[g]['models'][name]['bs'],
                                       ours[g]['models'][name]['bs'], rtol=1e-6)
