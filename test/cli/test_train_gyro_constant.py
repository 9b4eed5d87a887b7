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
The installed ``gyro-tdc`` on simulated bags whose driver fills the gyro's z axis with 0.

``train`` says so on one line and in ``--json`` and exits 0; ``evaluate`` exits 0 with every
warning an error and shows ``const`` for z; a gyro constant on every axis exits 2 in one line.
"""

from __future__ import annotations

import json
import re

from gyro_tdc.data import write_bag
from gyro_tdc.identify.accel import G0
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest
from strict_cli import GYRO_TDC, strict_cli as _cli


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two simulated runs: z reads exactly 0, the accelerometer exactly (0, 0, g), NaN rows."""
    root = tmp_path_factory.mktemp('zconst')
    out = {}
    for seed in (1, 2):
        sim = simulate_scenario('demo_fast', seed=seed, rate_hz=2.0)[0]
        gyro = sim.gyro.copy()
        gyro[:, 2] = 0.0
        gyro[::50, 0] = np.nan                      # dropped on reading
        accel = np.zeros_like(sim.accel)
        accel[:, 2] = G0
        write_bag(root / f'z{seed}', imu_t=sim.imu_t, gyro=gyro, accel=accel,
                  temp_t=sim.temp_t, temp_c=sim.temp_c)
        dead = np.full_like(sim.gyro, 0.0)
        dead[:, 1] = 0.01
        write_bag(root / f'dead{seed}', imu_t=sim.imu_t, gyro=dead, accel=sim.accel,
                  temp_t=sim.temp_t, temp_c=sim.temp_c)
    out.update(z1=root / 'z1', z2=root / 'z2', dead1=root / 'dead1')
    return out


def test_train_reports_z_constant_in_one_line_and_in_json(bags, tmp_path):
    assert GYRO_TDC.is_file(), GYRO_TDC
    model, doc = tmp_path / 'm.yaml', tmp_path / 'train.json'
    res = _cli('train', bags['z1'], '--out', model, '--json', doc, '--no-progress')
    assert res.returncode == 0, res.stderr
    assert res.stderr == '', res.stderr
    lines = [x for x in res.stdout.splitlines() if 'constant' in x and 'gyro' in x]
    assert lines == ['gyro axis z: constant at 0 rad/s (never varying beyond one quantum: a '
                     '2-axis gyro or a dead axis); not fitted: the model passes it through '
                     'unchanged'], res.stdout
    assert not re.search(r'\bnan\b|\binf\b', res.stdout), res.stdout   # a printed NaN
    data = json.loads(doc.read_text())
    assert data['constant_axes'] == {'z': 0.0}
    assert data['model_id'] == load_model(model).model_id
    assert data['accelerometer']['fitted'] is False
    assert 'constant' in data['accelerometer']['note']
    assert all(v is not None for key in ('raw_bs', 'train_bs', 'train_rms_dps')
               for v in data[key])
    m = load_model(model)
    assert m.metrics['constant_axes'] == ['z'] and m.accel is None
    assert not np.any(m.weights[:, 2]) and not np.any(m.linear[:, 2]) and m.intercept[2] == 0


def test_evaluate_reports_z_constant_without_warning_or_nan(bags, tmp_path):
    model, doc = tmp_path / 'm.yaml', tmp_path / 'eval.json'
    assert _cli('train', bags['z1'], '--out', model, '--no-progress').returncode == 0
    res = _cli('evaluate', bags['z2'], bags['z1'], '--model', model, '--model', 'px4',
               '--train', bags['z1'], '--reanchor', 'auto', '--json', doc,
               '--plots', tmp_path / 'plots', '--no-progress')
    assert res.returncode == 0, res.stderr
    assert 'Warning' not in res.stderr and 'Traceback' not in res.stderr, res.stderr
    out = res.stdout
    assert not re.search(r'\bnan\b|\binf\b', out), out
    assert out.count('gyro axis z reads the reference rate exactly') == 2, out
    assert 'passes gyro axis z through unchanged' in out
    rows = [r for r in (x.split() for x in out.splitlines())
            if len(r) == 10 and r[0] in ('raw', 'm', 'px4')]     # BS, RMS, BS/BS1 x y z
    assert len(rows) == 6 and all(r[9] == 'const' and r[7] != 'const' for r in rows), out
    assert 'aBS' not in out                    # the constant accelerometer: absent
    data = json.loads(doc.read_text())
    for b in data['bags']:
        assert b['constant_axes'] == ['z']
        for m in b['models']:
            assert m['p_vs_raw'][2] is None and None not in m['p_vs_raw'][:2]
        assert b['models'][0]['constant_axes'] == ['z']


def test_train_refuses_a_gyro_constant_on_every_axis(bags, tmp_path):
    res = _cli('train', bags['dead1'], '--out', tmp_path / 'm.yaml', '--no-progress')
    assert res.returncode == 2, res.stderr
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('gyro-tdc train: error: '), res.stderr
    assert 'every axis' in err[0] and 'y 0.01' in err[0]
    assert not (tmp_path / 'm.yaml').exists()
