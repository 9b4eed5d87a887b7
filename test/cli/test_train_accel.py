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
The accelerometer through the commands: bags read, ``train``, ``evaluate``, ``discover``.

Bags of the ``accel_chamber`` scenario (two runs at 1 Hz) are written in ``tmp_path``; the
gyro model is ``dT, dT2, lag`` so each command runs in seconds.
"""

from __future__ import annotations

import json

from bags import assert_bad_input, bag_from_run, bag_from_sim
from gyro_tdc.cli.discover import main as discover_main
from gyro_tdc.cli.evaluate import main as evaluate_main
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.options import BagOptions
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.sim import load_scenario, simulate_scenario
import numpy as np
import pytest

RATE_HZ = 1.0
FEATURES = ['--features', 'dT,dT2,lag']


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two chamber runs as bags, the simulated runs, and one with a mid-run reorientation."""
    d = tmp_path_factory.mktemp('accel')
    sims = simulate_scenario('accel_chamber', seed=2, rate_hz=RATE_HZ)
    paths = [bag_from_sim(s, d / f'run{i + 1}') for i, s in enumerate(sims)]
    turned = simulate_scenario(load_scenario('accel_chamber').with_overrides(
        {'accel.reorient_at_s': 6000.0, 'accel.reorient_tilt_deg': [0.0, 12.0]}), seed=2,
        rate_hz=RATE_HZ, runs=[0])[0]
    return {'dir': d, 'sims': sims, 'train': paths[0], 'test': paths[1],
            'turned': bag_from_sim(turned, d / 'turned')}


@pytest.fixture(scope='module')
def models(bags, tmp_path_factory):
    """Train a model with the accelerometer and one with --no-accel; return their paths."""
    d = tmp_path_factory.mktemp('models')
    out = {}
    for name, extra in (('with', []), ('without', ['--no-accel'])):
        path = d / f'{name}.yaml'
        assert train_main([str(bags['train']), '--out', str(path), '--no-progress']
                          + FEATURES + extra) == 0
        out[name] = path
    return out


def test_load_run_reads_the_accelerometer_only_when_asked(bags):
    run = load_run(bags['train'], BagOptions(accel=True))
    sim = bags['sims'][0]
    k = np.searchsorted(sim.imu_t, run.t)
    np.testing.assert_array_equal(run.accel, sim.accel[k])
    assert load_run(bags['train']).accel is None


def test_load_run_without_accelerometer_data_has_none(tmp_path):
    from synth import synth_run
    bag = bag_from_run(synth_run(seed=3, hours=0.2), tmp_path / 'zeros')   # accel all zero
    assert load_run(bag, BagOptions(accel=True)).accel is None


def test_train_fits_and_reports_the_accelerometer_part(bags, tmp_path, capsys):
    out = tmp_path / 'm.yaml'
    assert train_main([str(bags['train']), '--out', str(out), '--no-progress'] + FEATURES) == 0
    text = capsys.readouterr().out
    assert 'accelerometer: rbf f(dT, dT2) of the thermal state shared with the gyro' in text
    assert 'accelerometer bias stability BS' in text and 'change/degC' in text
    assert "accelerometer coverage: the gyro's (100 % of the samples still)" in text
    model = load_model(out)
    assert model.accel is not None and model.accel.thermal == model.thermal
    raw = model.accel.metrics['raw_bs_m2_s4']
    assert all(a < r / 100.0 for a, r in zip(model.accel.metrics['train_bs_m2_s4'], raw))


def test_no_accel_leaves_the_gyro_part_unchanged(models):
    with_accel, without = load_model(models['with']), load_model(models['without'])
    assert without.accel is None and with_accel.accel is not None
    # The same gyro fit: only the accelerometer part (and the command line) differ.
    assert with_accel.replace(accel=None).model_id == without.model_id


def test_evaluate_reports_accel_bs_within_the_floor_and_below_px4(
        bags, models, tmp_path, capsys):
    out = tmp_path / 'e.json'
    assert evaluate_main([str(bags['test']), '--model', str(models['with']), '--model', 'px4',
                          '--train', str(bags['train']), '--model', str(models['without']),
                          '--json', str(out), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'accelerometer (still run)' in text and 'accelerometer cubic too' in text
    b = json.loads(out.read_text())['bags'][0]
    floor = bags['sims'][1].truth.accel_noise_std ** 2
    raw = np.array(b['raw']['accel_bs'])
    ours, px4 = (np.array(m['accel_bs']) for m in b['models'][:2])
    assert np.all(raw > 100.0 * floor)
    assert np.all(ours <= 1.05 * floor) and np.all(ours <= px4)
    assert b['models'][2]['accel_bs'] is None               # trained with --no-accel


def test_train_reports_an_orientation_change(bags, tmp_path, capsys):
    out = tmp_path / 'turned.yaml'
    assert train_main([str(bags['turned']), '--out', str(out), '--no-progress']
                      + FEATURES) == 0
    text = capsys.readouterr().out
    assert 'orientation changed in' in text and 'split there' in text
    changes = load_model(out).accel.metrics['orientation_changes']
    assert len(changes) == 1 and 6000.0 <= changes[0]['t_s'] <= 6030.0


def test_discover_names_the_missing_accelerometer_effects(bags, tmp_path, capsys):
    out = tmp_path / 'd.json'
    assert discover_main([str(bags['train']), str(bags['test']), '--sensor', 'accel',
                          '--json', str(out), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'figures in mg' in text and 'deg/s' not in text
    doc = json.loads(out.read_text())
    assert doc['sensor'] == 'accel' and doc['unit'] == 'mg'
    assert {'dT2', 'lag'} <= set(doc['final_effects'])
    lag = [s for s in doc['steps'] if s['effect'] == 'lag'][0]
    assert 270.0 < lag['params']['tau_s'] < 330.0           # the die's 300 s


@pytest.mark.parametrize('extra, needle', [
    (['--out', 'x.yaml'], '--out is for the gyro'),
    (['--base', 'bias,dT,scale'], 'scale cannot be an accelerometer effect'),
])
def test_discover_accel_bad_options(bags, capsys, extra, needle):
    assert_bad_input(capsys, [bags['train'], '--sensor', 'accel'] + extra, needle,
                     entry=discover_main)
