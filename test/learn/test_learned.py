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

"""A learn_file's learned model read as a model: the same model, never the file changed."""

from __future__ import annotations

import os
import stat

from gyro_tdc.errors import LearnFileError, ModelFileError
from gyro_tdc.learn import is_learn_file, model_from_file, read_model
from gyro_tdc.learn.learner import Learner
from gyro_tdc.model import drift
from gyro_tdc.model.modelfile import load_model, save_model
from learn_states import learned
import numpy as np
import pytest


@pytest.fixture(scope='module')
def learner():
    return learned()


def test_the_file_gives_the_learners_model(learner, tmp_path):
    path = tmp_path / 'learn.json'
    learner.save(path)
    assert is_learn_file(path)
    model = model_from_file(path)
    assert model.model_id == learner.model.model_id
    t, temp = np.arange(5.0), np.linspace(15.0, 30.0, 5)
    np.testing.assert_array_equal(drift(model, t, temp), drift(learner.model, t, temp))
    assert model.created['learn_file'] == str(path) and model.created['points'] == 2
    # A model file written from it reads back as the same model.
    again = load_model(save_model(model, tmp_path / 'm.yaml'))
    assert again.model_id == model.model_id


def test_read_model_takes_model_files_and_learn_files(learner, tmp_path):
    yaml_path = save_model(learner.model, tmp_path / 'model.yaml')
    assert not is_learn_file(yaml_path)
    assert read_model(str(yaml_path)).model_id == learner.model.model_id
    learner.save(tmp_path / 'l.json')
    assert read_model(str(tmp_path / 'l.json')).model_id == learner.model.model_id
    assert read_model('l3gd20_modified').kind        # a shipped name still resolves


def test_no_accepted_model_yet_is_one_line(tmp_path):
    path = tmp_path / 'empty.json'
    Learner().save(path)
    with pytest.raises(ModelFileError, match='no accepted model yet') as err:
        read_model(str(path))
    assert '\n' not in str(err.value)


def test_a_broken_learn_file_is_refused_and_left_as_it_is(learner, tmp_path):
    path = tmp_path / 'bad.json'
    learner.save(path)
    text = path.read_text().replace('"session": 0', '"session": -3')
    path.write_text(text)
    os.chmod(path, 0o400)
    with pytest.raises(LearnFileError, match='session'):
        read_model(str(path))
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o400 and path.read_text() == text
