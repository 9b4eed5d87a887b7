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

"""``train`` records the frame of the IMU data it saw in the model's ``sensor.frame_id``."""

from __future__ import annotations

from gyro_tdc.data.bag.writer import write_bag
from gyro_tdc.errors import DatasetError
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.train import train
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from synth import synth_run

OPTIONS = TrainOptions(features='dT,dT2', kind='poly')


def bag(path, frame_id, seed=21):
    run = synth_run(seed=seed, hours=1.0, cooling=True)
    write_bag(path, imu_t=run.t + 100.0, gyro=run.omega, accel=np.zeros((len(run), 3)),
              temp_t=run.t[::2] + 100.0, temp_c=run.temp[::2], frame_id=frame_id)
    return path


@pytest.mark.parametrize('frame_id', ['base_link', 'imu_link'])
def test_the_model_takes_the_frame_of_the_bag(tmp_path, frame_id):
    result = train([bag(tmp_path / 'run', frame_id)], tmp_path / 'm.yaml', OPTIONS)
    assert result.model.frame_id == frame_id
    assert load_model(result.path).frame_id == frame_id          # written to the file


def test_data_without_a_frame_make_a_model_that_claims_none(tmp_path):
    result = train([bag(tmp_path / 'run', '')], tmp_path / 'm.yaml', OPTIONS)
    assert result.model.frame_id == '' and load_model(result.path).frame_id == ''


def test_bags_in_two_frames_are_refused(tmp_path):
    bags = [bag(tmp_path / 'a', 'imu_link'), bag(tmp_path / 'b', 'base_link', seed=22)]
    with pytest.raises(DatasetError, match="2 frames .*'imu_link'.*'base_link'"):
        train(bags, tmp_path / 'm.yaml', OPTIONS)
    assert not (tmp_path / 'm.yaml').exists()
    # A frame-less bag beside a framed one is no conflict: the model takes the one frame.
    ok = train([tmp_path / 'a', bag(tmp_path / 'c', '', seed=23)], tmp_path / 'n.yaml', OPTIONS)
    assert ok.model.frame_id == 'imu_link'
