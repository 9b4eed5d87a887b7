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

"""A constant accelerometer (a driver filling exactly (0, 0, g)) is absent, not fitted."""

from __future__ import annotations

import subprocess
import sys

from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import write_bag
from gyro_tdc.identify.accel import constant_axes, G0
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from synth import synth_run


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
