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
``python -m gyro_tdc evaluate``: held-out scores, the paper's tables, JSON, plots, CSV, errors.

Bags are written in ``tmp_path`` from ``synth.py`` runs and from the simulator (helpers in
``test/cli/test_train.py``); models come from ``train``'s ``main``. A real ArduCopter log
(``test/support/files/flightlogs``) is scored on its still stretch, and its report says so.
"""

from __future__ import annotations

import csv
import json

from bags import assert_bad_input, bag_from_run, sim_bags
from flightlogs import sd_card
from gyro_tdc.cli.evaluate import main
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data.dataset import load_run
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from synth import synth_run

DEG = np.pi / 180.0


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two synthetic heating runs (sqlite3 and mcap) and models trained on the first."""
    d = tmp_path_factory.mktemp('eval')
    train = bag_from_run(synth_run(seed=31, hours=1.0), d / 'train')
    test = bag_from_run(synth_run(seed=32, hours=1.0), d / 'test', storage='mcap')
    conv, modi = d / 'conv.yaml', d / 'mod.yaml'
    assert train_main([train, '--out', conv, '--features', 'dT', '--kind', 'poly']) == 0
    assert train_main([train, '--out', modi, '--features', 'dT,dT2', '--kind', 'poly']) == 0
    return {'train': train, 'test': test, 'conv': conv, 'mod': modi, 'dir': d}


def test_json_has_exactly_the_documented_shape(bags, tmp_path, capsys):
    out = tmp_path / 'sub' / 'eval.json'
    rc = main([bags['test'], bags['train'], '--model', bags['mod'], '--model', 'px4',
               '--train', bags['train'], '--model', bags['conv'], '--json', out])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads(out.read_text())
    assert list(doc) == ['bags', 'out_of_range'] and doc['out_of_range'] == 'linear'
    assert [b['bag'] for b in doc['bags']] == [str(bags['test']), str(bags['train'])]
    for b in doc['bags']:
        assert list(b) == ['bag', 'samples', 'temperature_c', 'raw', 'models']
        assert isinstance(b['samples'], int) and b['samples'] > 10_000
        assert len(b['temperature_c']) == 2 and b['temperature_c'][0] < b['temperature_c'][1]
        assert list(b['raw']) == ['bs', 'accel_bs', 'rms_dps']
        assert b['raw']['accel_bs'] is None      # the synthetic bags carry no accelerometer
        assert all(len(b['raw'][k]) == 3 for k in ('bs', 'rms_dps'))
        assert [m['model'] for m in b['models']] == [str(bags['mod']), 'px4', str(bags['conv'])]
        assert [m['features'] for m in b['models']] == [['dT', 'dT2'], ['dT', 'dT2', 'dT3'],
                                                        ['dT']]
        for m in b['models']:
            assert list(m) == ['model', 'features', 'bs', 'accel_bs', 'rms_dps', 'p_vs_raw',
                               'adev']
            assert m['accel_bs'] is None
            for key in ('bs', 'rms_dps', 'p_vs_raw'):
                assert len(m[key]) == 3 and all(isinstance(v, float) for v in m[key])
            assert list(m['adev']) == ['tau_s', 'dps']
            assert len(m['adev']['tau_s']) == len(m['adev']['dps']) > 5
            assert all(len(row) == 3 for row in m['adev']['dps'])
            assert np.allclose(m['p_vs_raw'], np.array(m['bs']) / np.array(b['raw']['bs']))
            assert np.allclose(np.sqrt(m['bs']), m['rms_dps'])  # zero reference: BS = RMS^2
    # The numbers are the held-out BS of the model file.
    run = load_run(bags['test'])
    model = load_model(bags['mod'])
    bs = bias_stability(compensate(model, run.t, run.temp, run.omega), run.omega_ref)
    assert np.allclose(doc['bags'][0]['models'][0]['bs'], bs)
    assert np.allclose(doc['bags'][0]['raw']['bs'], bias_stability(run.omega, run.omega_ref))


def test_two_models_print_the_paper_table(bags, capsys):
    assert main([bags['test'], '--model', bags['conv'], '--model', bags['mod']]) == 0
    text = capsys.readouterr().out
    assert 'paper table' in text and 'BS2 conv (conventional), BS3 mod (modified)' in text
    rows = {line.split()[0]: line.split()[1:] for line in text.splitlines()
            if line.strip().startswith(('x-axis', 'y-axis', 'z-axis'))}
    assert sorted(rows) == ['x-axis', 'y-axis', 'z-axis']
    for cells in rows.values():
        bs1, bs2, bs3, p1, p2 = (float(c) for c in cells[:5])
        p3 = float(cells[5].rstrip('%')) / 100
        assert p1 == pytest.approx(bs2 / bs1, rel=1e-3)
        assert p2 == pytest.approx(bs3 / bs1, rel=1e-3)
        assert p3 == pytest.approx(bs3 / bs2, rel=1e-3)
        assert p3 < 0.9   # the drift has a dT^2 term a line cannot follow
    assert 'Allan deviation' in text and 'ARW x' in text and 'BI z' in text
    # One model: no paper table; --baseline picks the conventional model explicitly.
    assert main([bags['test'], '--model', bags['mod']]) == 0
    assert 'paper table' not in capsys.readouterr().out
    assert main([bags['test'], '--model', bags['mod'], '--baseline', bags['conv']]) == 0
    assert 'BS2 conv (conventional), BS3 mod (modified)' in capsys.readouterr().out


def test_plots_and_export(bags, tmp_path, capsys):
    plots, export = tmp_path / 'png', tmp_path / 'csv'
    rc = main([bags['test'], '--model', bags['conv'], '--model', bags['mod'], '--plots', plots,
               '--export', export])
    assert rc == 0, capsys.readouterr().err
    pngs = sorted(p.name for p in plots.iterdir())
    assert pngs == ['test_allan.png', 'test_residual_vs_temperature.png',
                    'test_timeseries.png']
    for p in plots.iterdir():
        assert p.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and p.stat().st_size > 10_000
    with open(export / 'test.csv', newline='') as fh:
        rows = list(csv.reader(fh))
    axes = ('x', 'y', 'z')
    assert rows[0] == (['t_s', 'temp_c'] + [f'{who}_{a}_rad_s' for who in
                                            ('raw', 'ref', 'conv', 'mod') for a in axes])
    run = load_run(bags['test'])
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (len(run), 2 + 4 * 3)
    assert np.allclose(data[:, 0], run.t, atol=1e-6, rtol=0)
    assert np.allclose(data[:, 2:5], run.omega, rtol=1e-8, atol=0)
    comp = compensate(load_model(bags['mod']), run.t, run.temp, run.omega)
    assert np.allclose(data[:, 11:14], comp, rtol=1e-8, atol=1e-15)


def test_out_of_range_temperature_is_clamped_and_said(bags, tmp_path, capsys):
    warm = bag_from_run(synth_run(seed=33, hours=0.5, t_lo=40.0, t_hi=60.0), tmp_path / 'warm')
    assert main([warm, '--model', bags['mod']]) == 0
    text = capsys.readouterr().out
    note = next(line for line in text.splitlines() if 'note:' in line)
    assert 'outside the trained range of mod' in note and 'clamped' in note


def test_constant_and_stepped_reference_rates(tmp_path, capsys):
    # The paper's I3G4250D case: 10, 5, 20 deg/s on the rate table, constant ...
    const = synth_run(seed=41, hours=1.0, ref_dps=(10.0, 5.0, 20.0))
    train = bag_from_run(const, tmp_path / 'const_train')
    test = bag_from_run(synth_run(seed=42, hours=1.0, ref_dps=(10.0, 5.0, 20.0)),
                        tmp_path / 'const_test')
    model = tmp_path / 'c.yaml'
    assert train_main([train, '--out', model, '--kind', 'poly',
                       '--reference', '10,5,20dps']) == 0
    out = tmp_path / 'c.json'
    assert main([test, '--model', model, '--reference', '10,5,20 deg/s', '--json', out]) == 0
    doc = json.loads(out.read_text())['bags'][0]
    floor = 0.05 ** 2
    assert np.all(np.array(doc['models'][0]['bs']) < 1.2 * floor), doc
    assert np.all(np.array(doc['raw']['bs']) > 10 * floor)
    assert 'constant reference rate' in capsys.readouterr().out
    # ... and stepped (+1, 0, -1, 0.5 times those rates every 5 min) on the reference topic.
    kw = dict(hours=1.0, ref_dps=(10.0, 5.0, 20.0), ref_period_s=300.0)
    train = bag_from_run(synth_run(seed=43, **kw), tmp_path / 'step_train', reference='topic')
    test = bag_from_run(synth_run(seed=44, **kw), tmp_path / 'step_test', reference='topic',
                        storage='mcap')
    model = tmp_path / 's.yaml'
    assert train_main([train, '--out', model, '--kind', 'poly']) == 0
    out = tmp_path / 's.json'
    assert main([test, '--model', model, '--json', out]) == 0
    doc = json.loads(out.read_text())['bags'][0]
    assert np.all(np.array(doc['models'][0]['bs']) < 1.2 * floor), doc
    assert 'reference rate from the reference topic' in capsys.readouterr().out
    # Ignoring the table (zero reference) would count the commanded rate as error.
    assert main([test, '--model', model, '--reference', '0,0,0', '--json', out]) == 0
    capsys.readouterr()
    assert np.all(np.array(json.loads(out.read_text())['bags'][0]['models'][0]['bs']) > 1.0)


def test_held_out_simulated_run_within_noise_floor_and_lag_beats_px4(tmp_path, capsys):
    # Heating and cooling, die lagging the thermometer by 180 s: trained on run 1, scored on
    # run 2 after start-up re-anchoring (the run-to-run bias offset of the simulator).
    folder, sims = sim_bags(tmp_path, 'lag_heat_cool', rate_hz=2.0, storage='mcap')
    lag, static = tmp_path / 'lag.yaml', tmp_path / 'static.yaml'
    assert train_main([folder / 'run1', '--out', lag, '--features', 'lag']) == 0
    assert train_main([folder / 'run1', '--out', static, '--features', 'dT,dT2']) == 0
    out = tmp_path / 'lag.json'
    assert main([folder / 'run2', '--model', static, '--model', 'px4', '--train',
                 folder / 'run1', '--model', lag, '--reanchor', '600', '--json', out]) == 0
    assert 're-anchored' in capsys.readouterr().out
    floor = np.degrees(sims[1].truth.noise_std) ** 2
    doc = json.loads(out.read_text())
    bs = {m['model']: np.array(m['bs']) for m in doc['bags'][0]['models']}
    assert np.all(bs[str(lag)] < 1.2 * floor), (bs, floor)
    assert np.all(bs['px4'][:2] > 1.5 * floor[:2]), (bs, floor)
    assert np.all(bs[str(static)][:2] > 1.5 * floor[:2]), (bs, floor)


def test_held_out_paper_run_within_noise_floor(tmp_path, capsys):
    folder, sims = sim_bags(tmp_path, 'l3gd20_paper', rate_hz=1.0,
                            overrides={'runs.count': 2, 'runs.bias_offset_dps_std': 0.0})
    model = tmp_path / 'mod.yaml'
    assert train_main([folder / 'run1', '--out', model, '--kind', 'poly']) == 0
    out = tmp_path / 'p.json'
    assert main([folder / 'run2', '--model', model, '--json', out]) == 0
    capsys.readouterr()
    floor = np.degrees(sims[1].truth.noise_std) ** 2
    bs = np.array(json.loads(out.read_text())['bags'][0]['models'][0]['bs'])
    assert np.all(bs < 1.2 * floor), (bs, floor)


def test_floor_prints_and_writes_bs_over_floor(bags, tmp_path, capsys):
    # A known white-noise floor (one value: every axis) adds BS / floor per model.
    out = tmp_path / 'floor.json'
    assert main([bags['test'], '--model', bags['conv'], '--model', bags['mod'], '--floor',
                 '0.0025', '--json', out, '--no-progress']) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert doc['floor'] == [0.0025] * 3 and 'accel_floor' not in doc
    rows = {}      # the first row of each label: the summary (the Allan table follows)
    for line in text.splitlines():
        if line.startswith(('  raw ', '  conv ', '  mod ')):
            rows.setdefault(line.split()[0], line.split())
    assert 'BS/fl against the floor 0.0025 (deg/s)^2 (--floor)' in text
    for entry, label in [(doc['bags'][0]['raw'], 'raw')] + [
            (m, lb) for m, lb in zip(doc['bags'][0]['models'], ('conv', 'mod'))]:
        assert np.allclose(entry['bs_over_floor'], np.array(entry['bs']) / 0.0025)
        # The console prints the same ratios (4 significant digits), last three columns.
        assert np.allclose([float(v) for v in rows[label][-3:]], entry['bs_over_floor'],
                           rtol=1e-3)
    # Three values, one per axis; --accel-floor on a bag without accelerometer: null ratios.
    assert main([bags['test'], '--model', bags['mod'], '--floor', '0.001, 0.002,0.004',
                 '--accel-floor', '2.25e-5', '--json', out, '--no-progress']) == 0
    capsys.readouterr()
    doc = json.loads(out.read_text())
    assert doc['floor'] == [0.001, 0.002, 0.004] and doc['accel_floor'] == [2.25e-5] * 3
    m = doc['bags'][0]['models'][0]
    assert np.allclose(m['bs_over_floor'], np.array(m['bs']) / [0.001, 0.002, 0.004])
    assert m['accel_bs'] is None and m['accel_bs_over_floor'] is None


@pytest.mark.parametrize('option', ['--floor', '--accel-floor'])
@pytest.mark.parametrize('value', ['0', '-0.009', '1,2', '1,2,3,4', 'abc', 'nan', 'inf',
                                   '0.009,0,0.009'])
def test_bad_floor_is_one_line_exit_2(bags, capsys, option, value):
    assert_bad_input(capsys, [bags['test'], '--model', bags['mod'], option, value],
                     option, 'expected one number > 0 or three x,y,z', entry=main)


# --------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------

def test_malformed_model_file(bags, tmp_path, capsys):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('kind: [unclosed\n')
    assert_bad_input(capsys, [bags['test'], '--model', bad], 'gyro-tdc evaluate: error:',
                     'malformed YAML', entry=main)
    edited = tmp_path / 'edited.yaml'
    edited.write_text(bags['mod'].read_text().replace('kind: poly', 'kind: spline'))
    assert_bad_input(capsys, [bags['test'], '--model', edited], 'field `kind`', entry=main)
    assert_bad_input(capsys, [bags['test'], '--model', tmp_path / 'none.yaml'],
                     'does not exist', entry=main)


def test_px4_needs_training_bags_and_training_bags_need_px4(bags, capsys):
    assert_bad_input(capsys, [bags['test'], '--model', 'px4'], '--train', entry=main)
    assert_bad_input(capsys, [bags['test'], '--model', bags['mod'], '--train', bags['train']],
                     '--train is only used by --model px4', entry=main)


def test_bad_bags(bags, tmp_path, capsys):
    assert_bad_input(capsys, [tmp_path / 'missing', '--model', bags['mod']], 'does not exist',
                     entry=main)
    (tmp_path / 'empty').mkdir()
    assert_bad_input(capsys, [tmp_path / 'empty', '--model', bags['mod']],
                     'not a rosbag2 directory', entry=main)
    assert_bad_input(capsys, [bags['test'], '--model', bags['mod'], '--temperature-topic',
                              '/t'], "no topic '/t'", '/imu/temperature', entry=main)
    assert_bad_input(capsys, [bags['test']], 'required: --model', entry=main)


def test_a_real_flight_log_says_the_range_it_scored(tmp_path, capsys):
    # ArduCopter 3.3, IMU3: 40 s still on the ground while it warms 28 -> 32 degC, a 10 s
    # flight, 5 s still at 33 degC; the log spans more. What evaluate scored is the still
    # stretches, and it says so.
    from real_logs import ARDUPILOT_AC33

    log = [str(ARDUPILOT_AC33), '--imu-instance', '2', '--no-progress']
    model = tmp_path / 'm.yaml'
    assert train_main([*log, '--out', str(model)]) == 0
    capsys.readouterr()
    out = tmp_path / 'e.json'
    assert main([*log, '--model', str(model), '--json', str(out), '--export',
                 str(tmp_path / 'csv')]) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())['bags'][0]
    s = doc['still']
    assert (doc['samples'], s['samples'], s['total_samples']) == (2103, 2103, 3854)
    assert doc['temperature_c'] == s['temperature_c'] == s['sessions'][0]['temperature_c']
    lo, hi = doc['temperature_c']
    whole_lo, whole_hi = s['total_temperature_c']
    assert 27.9 < lo < 28.1 and 33.2 < hi < 33.4           # IMU3 warming on the ground
    assert whole_lo < lo - 2.0 and whole_hi > hi + 0.5     # the whole log spans more
    assert s['still_s'] < 0.55 * s['total_s']
    assert (f'scored 2103 still samples over {s["still_s"]:.0f} s of still time at '
            f'{lo:.2f} .. {hi:.2f} degC (the whole bag: 3854 samples over '
            f'{s["total_s"]:.0f} s at {whole_lo:.2f} .. {whole_hi:.2f} degC)') in text
    assert (f'at {lo:.2f} .. {hi:.2f} degC; the whole bag: 3854 samples at {whole_lo:.2f} .. '
            f'{whole_hi:.2f} degC') in text
    # Trained on that stretch, the model is inside its range on every sample scored.
    assert 'outside the trained range' not in text
    assert 'does not apply' not in text
    # --reanchor is not what anchors the still stretches: it says so rather than claim it.
    assert main([*log, '--model', str(model), '--reanchor', '10']) == 0
    assert ('ardupilot_ac33_three_imus.bin: --reanchor 10 does not apply to it (scored on its '
            'still stretches, each session anchored on its first)') in capsys.readouterr().out
    # The CSV holds the samples scored.
    rows = (tmp_path / 'csv' / 'ardupilot_ac33_three_imus.bin.csv').read_text().splitlines()
    assert len(rows) == 1 + 2103
    temp = np.array([float(r.split(',')[1]) for r in rows[1:]])
    assert (temp.min(), temp.max()) == pytest.approx((lo, hi), abs=1e-3)


def test_a_folder_skips_the_logs_it_cannot_read_and_scores_the_rest(tmp_path, capsys):
    root = tmp_path / 'card'
    good, bad = sd_card(root)
    model, out = tmp_path / 'm.yaml', tmp_path / 'scores.json'
    assert train_main([str(good[1]), '--out', str(model), '--features', 'dT,dT2',
                       '--no-progress']) == 0
    capsys.readouterr()
    args = ['--model', str(model), '--no-progress']
    assert main([str(root), *args, '--json', str(out)]) == 0
    said = capsys.readouterr()
    lines = said.out.splitlines()
    for path in bad:
        mine = [ln for ln in lines if str(path) in ln]
        assert len(mine) == 1 and mine[0].startswith(f'warning: skipped {path}: '), lines
    assert 'read 2 of the 4 bags and logs, skipped 2 that cannot be read' in said.out
    assert said.err.strip() == ''
    assert [b['bag'] for b in json.loads(out.read_text())['bags']] == [str(p) for p in good]
    assert_bad_input(capsys, [bad[0], *args], 'damaged bytes inside the log', entry=main)
    for path in good:
        path.unlink()
    assert_bad_input(capsys, [root, *args], 'None of the 2 bags and logs found can be read',
                     entry=main)


def test_a_folder_is_walked_once(tmp_path, capsys, monkeypatch):
    """The progress bar's count, the labels and the reading share one walk of the folder."""
    import gyro_tdc.data.dataset as dataset
    root = tmp_path / 'card'
    good, _ = sd_card(root)
    model = tmp_path / 'm.yaml'
    assert train_main([str(good[1]), '--out', str(model), '--features', 'dT,dT2',
                       '--no-progress']) == 0
    walked, walk = [], dataset._walk
    monkeypatch.setattr(dataset, '_walk', lambda folder: walked.append(folder) or walk(folder))
    assert main([str(root), '--model', str(model)]) == 0
    assert walked.count(root) == 1, walked
    assert 'read 2 of the 4 bags and logs' in capsys.readouterr().out
