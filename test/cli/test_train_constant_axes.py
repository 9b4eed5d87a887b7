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
The installed ``gyro-tdc`` on a gyro axis stuck off its reference (0.25 rad/s), and dead gyros.

``train --still-only`` passes the stuck axis through and says so on ``train``'s one line;
``evaluate`` of an ordinary model (and of ``px4`` fitted on the stuck bags) on a held-out
bag with the stuck axis shows ``const`` and the notes, with every warning an error; a gyro
constant on every axis exits 2 with one line in ``train --still-only`` (``train``'s line)
and in ``evaluate``.
"""

from __future__ import annotations

import json
import re

from gyro_tdc.data import write_bag
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest
from strict_cli import strict_cli as _cli

STUCK = 0.25


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write ordinary runs, runs with z stuck at 0.25 rad/s and a dead gyro."""
    root = tmp_path_factory.mktemp('stuck')
    for seed in (1, 2):
        sim = simulate_scenario('demo_fast', seed=seed, rate_hz=2.0)[0]
        write_bag(root / f'ok{seed}', imu_t=sim.imu_t, gyro=sim.gyro, accel=sim.accel,
                  temp_t=sim.temp_t, temp_c=sim.temp_c)
        gyro = sim.gyro.copy()
        gyro[:, 2] = STUCK
        write_bag(root / f'z{seed}', imu_t=sim.imu_t, gyro=gyro, accel=sim.accel,
                  temp_t=sim.temp_t, temp_c=sim.temp_c)
        dead = np.zeros_like(sim.gyro)
        dead[:, 0] = STUCK
        write_bag(root / f'dead{seed}', imu_t=sim.imu_t, gyro=dead, accel=sim.accel,
                  temp_t=sim.temp_t, temp_c=sim.temp_c)
    return root


def test_still_only_passes_the_stuck_axis_through(bags, tmp_path):
    """Exit 0, train's one line, --json constant_axes, zero columns, no NaN printed."""
    model, doc = tmp_path / 'm.yaml', tmp_path / 'train.json'
    res = _cli('train', '--still-only', bags / 'z1', bags / 'z2', '--out', model,
               '--json', doc, '--no-progress')
    assert res.returncode == 0, res.stderr
    assert res.stderr == '', res.stderr
    lines = [x for x in res.stdout.splitlines() if 'constant' in x and 'gyro' in x]
    assert lines == ['gyro axis z: constant at 0.25 rad/s (never varying beyond one quantum: '
                     'a 2-axis gyro or a dead axis); not fitted: the model passes it through '
                     'unchanged'], res.stdout
    assert 'still time:' in res.stdout
    assert not re.search(r'\bnan\b|\binf\b', res.stdout), res.stdout
    assert json.loads(doc.read_text())['constant_axes'] == {'z': STUCK}
    m = load_model(model)
    assert m.metrics['constant_axes'] == ['z'] and m.metrics['still']['stretches'] >= 1
    assert not np.any(m.weights[:, 2]) and not np.any(m.linear[:, 2]) and m.intercept[2] == 0


def test_evaluate_shows_the_held_out_stuck_axis_as_constant(bags, tmp_path):
    """An ordinary model and px4 (fitted on stuck bags): const on z, notes, JSON nulls."""
    model, doc = tmp_path / 'm.yaml', tmp_path / 'eval.json'
    assert _cli('train', bags / 'ok1', '--out', model, '--no-progress').returncode == 0
    res = _cli('evaluate', bags / 'z2', '--model', model, '--model', 'px4',
               '--train', bags / 'z1', '--reanchor', 'auto', '--json', doc,
               '--plots', tmp_path / 'plots', '--no-progress')
    assert res.returncode == 0, res.stderr
    assert 'Warning' not in res.stderr and 'Traceback' not in res.stderr, res.stderr
    out = res.stdout
    assert not re.search(r'\bnan\b|\binf\b', out), out
    assert 'gyro axis z never varies beyond one quantum' in out, out
    assert 'px4 passes gyro axis z through unchanged' in out
    assert 'm passes gyro axis z' not in out             # m was fitted on a real z
    assert 'gyro axis z constant: not fitted' in out     # the px4 fit's log line
    rows = [r for r in (x.split() for x in out.splitlines())
            if len(r) == 10 and r[0] in ('raw', 'm', 'px4')]     # BS, RMS, BS/BS1 x y z
    assert len(rows) == 3 and all(r[9] == 'const' and r[7] != 'const' for r in rows), out
    data = json.loads(doc.read_text())
    b = data['bags'][0]
    assert b['constant_axes'] == ['z']
    assert all(m['p_vs_raw'][2] is None and None not in m['p_vs_raw'][:2]
               for m in b['models'])
    assert [m.get('constant_axes') for m in b['models']] == [None, ['z']]


@pytest.mark.parametrize('argv', [('train', '--still-only', '{dead1}', '--out', '{out}'),
                                  ('evaluate', '{dead1}', '--model', '{model}')])
def test_a_dead_gyro_exits_2_with_one_line(bags, tmp_path, argv):
    """Every axis constant: one line naming what is read, exit 2, nothing written."""
    model = tmp_path / 'ok.yaml'
    if argv[0] == 'evaluate':
        assert _cli('train', bags / 'ok1', '--out', model, '--no-progress').returncode == 0
    paths = {'dead1': bags / 'dead1', 'out': tmp_path / 'm.yaml', 'model': model}
    res = _cli(*[a.format(**paths) for a in argv], '--no-progress')
    assert res.returncode == 2, (res.returncode, res.stderr)
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'gyro-tdc {argv[0]}: error: '), res.stderr
    assert 'every axis' in err[0] and f'x {STUCK:g}' in err[0], err[0]
    assert not (tmp_path / 'm.yaml').exists()
    if argv[0] == 'train':
        chamber = _cli('train', bags / 'dead1', '--out', tmp_path / 'm.yaml', '--no-progress')
        assert chamber.returncode == 2
        assert chamber.stderr.strip() == res.stderr.strip()        # train's own line
