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
Sessions on the command line: train's offsets, --sessions, evaluate per session.

The last test is the case sessions exist for: two power cycles of one static sensor, each
with its own turn-on offset, over overlapping ranges; a third power cycle re-anchored.
"""

from __future__ import annotations

import json

from bags import assert_bad_input, bag_from_run
from gyro_tdc.cli.evaluate import main as evaluate_main
from gyro_tdc.cli.simulate import main as simulate_main
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data.runs import Run
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from synth import synth_run
import yaml

OFFSETS = ((0.4, -0.3, 0.1), (-0.5, 0.2, 0.45))
NOISE_DPS = 0.02


def _joined(a: Run, b: Run, gap_s: float, name: str) -> Run:
    """Return ``b`` after ``a`` in one run, ``gap_s`` of silence between them."""
    t = np.concatenate([a.t, b.t + a.t[-1] + gap_s - b.t[0]])
    return Run(t, np.concatenate([a.temp, b.temp]), np.concatenate([a.omega, b.omega]),
               np.concatenate([a.omega_ref, b.omega_ref]), name)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two power cycles in one bag (an hour's gap), and a held-out bag of two more."""
    root = tmp_path_factory.mktemp('sessions')
    one = [synth_run(seed=i, hours=0.5, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=NOISE_DPS,
                     offset_dps=off) for i, (off, (lo, hi)) in
           enumerate(zip(OFFSETS, ((-10.0, 30.0), (15.0, 50.0))))]
    two = [synth_run(seed=5 + i, hours=0.5, rate_hz=2.0, t_lo=0.0, t_hi=40.0,
                     noise_dps=NOISE_DPS, offset_dps=off)
           for i, off in enumerate(((0.3, 0.3, -0.4), (-0.2, -0.45, 0.25)))]
    train = bag_from_run(_joined(*one, 3600.0, 'train'), root / 'train')
    held = bag_from_run(_joined(*two, 3600.0, 'held'), root / 'held')
    return train, held


def test_train_cuts_at_the_gap_prints_the_offsets_and_says_to_reanchor(bags, tmp_path,
                                                                       capsys):
    out = tmp_path / 'm.yaml'
    assert train_main([str(bags[0]), '--out', str(out), '--features', 'dT,dT2',
                       '--kind', 'poly', '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'sessions (auto): 2 (one turn-on offset each' in text
    assert 'train: gap of 3600 s at t = ' in text
    lines = text.splitlines()
    at = lines.index("turn-on offset of each session against the model's (their mean), deg/s:")
    off = np.array(OFFSETS)
    want = off - off.mean(axis=0)
    for k in range(2):
        name, *values = lines[at + 1 + k].split()[:4]
        assert name == f'{bags[0]}@{k + 1}'
        np.testing.assert_allclose([float(v) for v in values], want[k], atol=0.003)
    assert lines[at + 3].split()[0] == 'spread'
    assert 'the turn-on offset changes by up to 0.9' in text
    assert 're-anchor on the vehicle' in text
    at = next(i for i, x in enumerate(lines) if x.startswith('the curve held out on each'))
    assert '(2 sessions,' in lines[at] and lines[at + 1].split()[0] == 'curve'
    assert lines[at + 2].split()[:2] == ['offset', 'only']
    curve, offset = (np.array(lines[at + k].split()[-3:], dtype=float) for k in (1, 2))
    assert np.all(curve < offset)           # the shared curve carries: kept on every axis
    assert 'keeps the offset only' not in text
    info = load_model(out).metrics['sessions']
    assert info['count'] == 2 and info['names'] == [f'{bags[0]}@1', f'{bags[0]}@2']


@pytest.mark.parametrize('option, sessions', [(['--sessions', 'none'], 1),
                                              (['--sessions', 'bag'], 1),
                                              (['--session-gap', '7200'], 1),
                                              (['--session-gap', '60'], 2)])
def test_the_sessions_options_override_the_cut(bags, tmp_path, capsys, option, sessions):
    out = tmp_path / 'm.yaml'
    assert train_main([str(bags[0]), '--out', str(out), '--features', 'dT,dT2',
                       '--kind', 'poly', '--no-progress', *option]) == 0
    text = capsys.readouterr().out
    model = load_model(out)
    assert ('sessions' in model.metrics) == (sessions == 2)
    if option[0] == '--sessions':
        assert f'not cut: --sessions {option[1]}' in text
        assert 'turn-on offset of each session' not in text


def test_bad_session_options_are_one_line(bags, tmp_path, capsys):
    assert_bad_input(capsys, [bags[0], '--out', tmp_path / 'm.yaml', '--sessions', 'split'],
                     '--sessions', 'split', entry=train_main)
    assert_bad_input(capsys, [bags[0], '--out', tmp_path / 'm.yaml', '--session-gap', '-1'],
                     '--session-gap', entry=train_main)
    assert not (tmp_path / 'm.yaml').exists()


def _bs_over_floor(bag, model, tmp_path, *more):
    path = tmp_path / 'e.json'
    assert evaluate_main([str(bag), '--model', str(model), '--no-progress', '--json',
                          str(path), '--floor', str(NOISE_DPS ** 2), *more]) == 0
    return [m['bs_over_floor'] for m in json.loads(path.read_text())['bags'][0]['models']]


def test_evaluate_reanchors_every_session_of_a_held_out_bag(bags, tmp_path, capsys):
    model = tmp_path / 'm.yaml'
    assert train_main([str(bags[0]), '--out', str(model), '--features', 'dT,dT2',
                       '--kind', 'poly', '--no-progress']) == 0
    capsys.readouterr()
    (per_session,) = _bs_over_floor(bags[1], model, tmp_path, '--reanchor', 'auto')
    text = capsys.readouterr().out
    assert 'm re-anchored session 1 on' in text and 'm re-anchored session 2 on' in text
    assert max(per_session) < 1.1
    (first_only,) = _bs_over_floor(bags[1], model, tmp_path, '--reanchor', 'auto',
                                   '--sessions', 'none')
    assert min(first_only) > 10.0        # the second power cycle keeps the first's shift


def _scenario(path, name, lo, hi):
    path.write_text(yaml.safe_dump({
        'format_version': 1, 'name': name, 'sensor': 'l3gd20', 'imu_rate_hz': 2.0,
        'profile': {'start_c': lo, 'segments': [
            {'kind': 'hold', 'duration_s': 300.0},
            {'kind': 'ramp', 'to_c': hi, 'rate_c_per_h': 90.0},
            {'kind': 'hold', 'duration_s': 300.0}]},
        'thermal': {'tau_package_s': 30.0},
        'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.01},
        'gyro': {'effects': ['bias', 'dT', 'dT2', 'dT3']},
        'runs': {'count': 1, 'bias_offset_dps_std': 0.5}}))
    return path


def test_two_power_cycles_over_overlapping_ranges_then_a_third_reanchored(tmp_path, capsys):
    """Trained on -10..30 and 15..50 degC, each its turn-on offset; held out 0..40 degC."""
    bags = []
    for seed, (name, lo, hi) in enumerate((('cold', -10, 30), ('hot', 15, 50),
                                           ('third', 0, 40)), start=11):
        sc = _scenario(tmp_path / f'{name}.yaml', name, lo, hi)
        assert simulate_main(['--scenario', str(sc), '--out', str(tmp_path / name),
                              '--seed', str(seed), '--no-progress']) == 0
        bags.append(str(tmp_path / name))
    model = tmp_path / 'model.yaml'
    assert train_main([bags[0], bags[1], '--out', str(model), '--no-progress']) == 0
    capsys.readouterr()
    floor = 0.03 ** 2 * 2.0                      # the preset's ARW^2 x rate, (deg/s)^2
    path = tmp_path / 'e.json'
    assert evaluate_main([bags[2], '--model', str(model), '--model', 'px4', '--train',
                          bags[0], bags[1], '--reanchor', 'auto', '--floor', str(floor),
                          '--json', str(path), '--no-progress']) == 0
    ours, cubic = [m['bs_over_floor'] for m in
                   json.loads(path.read_text())['bags'][0]['models']]
    assert max(ours) <= 1.2, ours
    assert all(a < b for a, b in zip(ours, cubic)), (ours, cubic)
