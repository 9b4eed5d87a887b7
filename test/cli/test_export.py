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

"""``gyro-tdc export``: the parameter file, the clamp report and the held-out comparison."""

from __future__ import annotations

import re

from bags import assert_bad_input, bag_from_run
from gyro_tdc.cli import COMMANDS
from gyro_tdc.cli.export import main
from gyro_tdc.data import load_runs
from gyro_tdc.identify import fit_model
from gyro_tdc.identify.export import from_params, read_params, score_export
from gyro_tdc.model import load_model, save_model
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp('export')
    train = synth_run(hours=1.5, rate_hz=2.0, cooling=True, seed=1, tau_die=300.0)
    held = synth_run(hours=1.5, rate_hz=2.0, cooling=True, seed=2, tau_die=300.0)
    model = fit_model([train], kind='poly', features=('dT', 'dT2', 'dT3', 'lag'),
                      sensor_id='2293768')
    return save_model(model, root / 'model.yaml'), bag_from_run(held, root / 'held'), root


def test_export_px4_writes_the_params_and_reports_what_the_form_keeps(files, capsys):
    model_file, bag, root = files
    out = root / 'tc.params'
    assert main(['--px4', str(model_file), '--out', str(out), '--eval', str(bag),
                 '--no-progress']) == 0
    text = capsys.readouterr().out
    params = read_params(out)
    assert params['TC_G_ENABLE'] == 1 and params['TC_G0_ID'] == 2293768   # the sensor_id
    assert 'export' in COMMANDS
    model = load_model(model_file)
    form = from_params(params, 'px4')
    assert form.gyro.tmin == pytest.approx(model.temp_range_c[0], abs=1e-5)
    # The figure printed is the held-out share of the improvement the file's form keeps.
    s = score_export(model, {'px4': form}, load_runs([bag]))[0]
    kept = float(re.search(r'px4 keeps ([0-9.]+) %', text).group(1))
    assert kept == pytest.approx(100 * s.kept('px4'), abs=0.0051)
    assert 50 < kept < 100                            # a gap to the full model, stated
    bs = re.search(r'  px4 +BS +(\S+) +(\S+) +(\S+)', text).groups()
    np.testing.assert_allclose([float(v) for v in bs], s.bs['px4'], rtol=1e-3)
    assert 'clamp: outside TMIN..TMAX' in text and 'outside TMIN..TMAX' in text


def test_export_ardupilot_writes_the_parm_with_the_instance_asked(files, capsys):
    model_file, _, root = files
    out = root / 'tc.parm'
    assert main(['--ardupilot', str(model_file), '--out', str(out), '--instance', '1']) == 0
    text = capsys.readouterr().out
    params = read_params(out)
    assert params['INS_TCAL2_ENABLE'] == 1 and 'INS_TCAL2_GYR1_X' in params
    assert 'INS_TCAL1_ENABLE' not in params
    assert f'wrote {out}' in text and 'INS_GYR2_CALTEMP' in text


def test_export_bad_input_is_one_line(files, capsys, tmp_path):
    model_file, bag, _ = files
    out = tmp_path / 'x.params'
    assert_bad_input(capsys, ['--px4', model_file, '--ardupilot', model_file, '--out', out],
                     'not allowed with', entry=main)
    assert_bad_input(capsys, ['--ardupilot', model_file, '--out', out, '--instance', '3'],
                     '--instance 3', entry=main)
    assert_bad_input(capsys, ['--px4', model_file, '--out', out, '--reanchor', '10'],
                     '--eval', entry=main)
    assert_bad_input(capsys, ['--px4', tmp_path / 'missing.yaml', '--out', out], entry=main)
    assert not out.exists()
