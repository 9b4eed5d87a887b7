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

"""A learn_file wherever a model goes: ``evaluate --model``, ``export --model`` / ``--px4``."""

from __future__ import annotations

import json

from bags import assert_bad_input
from gyro_tdc.cli.evaluate import main as evaluate_main
from gyro_tdc.cli.export import main as export_main
from gyro_tdc.data import write_bag
from gyro_tdc.learn.learner import Learner
from gyro_tdc.model.modelfile import load_model
from learn_states import BIAS, learned
import numpy as np
import pytest


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    """Return a learn_file with a model, one without, and a still bag at the learned bias."""
    d = tmp_path_factory.mktemp('learnfile')
    learner = learned()
    learner.save(d / 'learn.json')
    Learner().save(d / 'empty.json')
    rng = np.random.default_rng(7)
    t = 100.0 + np.arange(6000) / 10.0
    gyro = np.array(BIAS) + 1e-4 * rng.standard_normal((t.size, 3))
    write_bag(d / 'day', imu_t=t, gyro=gyro, accel=np.zeros((t.size, 3)), temp_t=t[::10],
              temp_c=np.linspace(20.5, 23.0, t[::10].size))
    return {'dir': d, 'learner': learner}


def test_export_model_writes_the_learned_model_as_a_model_file(files, capsys):
    d = files['dir']
    assert export_main(['--model', str(d / 'learn.json'), '--out', str(d / 'm.yaml')]) == 0
    out = capsys.readouterr().out
    assert 'learned, 2 points' in out and 're-anchor' in out
    assert load_model(d / 'm.yaml').model_id == files['learner'].model.model_id


def test_evaluate_takes_a_learn_file_as_the_model_it_holds(files, capsys):
    d = files['dir']
    assert export_main(['--model', str(d / 'learn.json'), '--out', str(d / 'm2.yaml')]) == 0
    capsys.readouterr()
    rc = evaluate_main([str(d / 'day'), '--model', str(d / 'learn.json'),
                        '--model', str(d / 'm2.yaml'), '--json', str(d / 'e.json')])
    assert rc == 0
    doc = json.loads((d / 'e.json').read_text())
    bag = doc['bags'][0]
    models = bag['models']
    assert len(models) == 2
    assert models[0]['bs'] == models[1]['bs']
    # The learned bias removes the raw mean: far below the raw BS around zero.
    raw = np.asarray(bag['raw']['rms_dps'])
    assert np.all(np.asarray(models[0]['rms_dps']) < 0.05 * raw)


def test_a_learn_file_without_a_model_is_one_line_exit_2(files, capsys):
    d = files['dir']
    line = assert_bad_input(capsys, [str(d / 'day'), '--model', str(d / 'empty.json')],
                            'no accepted model yet', entry=evaluate_main)
    assert 'empty.json' in line
    assert_bad_input(capsys, ['--model', str(d / 'empty.json'), '--out', str(d / 'x.yaml')],
                     'no accepted model yet', entry=export_main)
    assert not (d / 'x.yaml').exists()


def test_export_px4_of_a_learn_file(files, capsys):
    d = files['dir']
    assert export_main(['--px4', str(d / 'learn.json'), '--out', str(d / 'p.params')]) == 0
    assert 'TC_G0_X0' in (d / 'p.params').read_text()
