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

"""Tests of gyro_tdc.identify.train: bags in, a saved model and the coverage of the data out."""

from __future__ import annotations

from bags import bag_from_run
from gyro_tdc.base.limits import MAX_CENTERS
from gyro_tdc.data.options import BagOptions
from gyro_tdc.errors import DatasetError, FeatureError, FitError, LimitError
from gyro_tdc.evaluate.report import format_training
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.train import train
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp('train') / 'runs'
    folder.mkdir()
    runs = [synth_run(seed=21, hours=1.0, cooling=True), synth_run(seed=22, hours=1.0)]
    for k, run in enumerate(runs, start=1):
        bag_from_run(run, folder / f'run{k}')
    return folder, runs


def test_train_saves_the_model_it_returns(bags, tmp_path):
    folder, runs = bags
    lines = []
    result = train([folder], tmp_path / 'm.yaml', TrainOptions(features='dT,dT2', kind='poly'),
                   command='python -m gyro_tdc train ...', log=lines.append)
    assert result.path == tmp_path / 'm.yaml'
    assert load_model(result.path) == result.model
    assert result.bags == [str(folder / 'run1'), str(folder / 'run2')]
    total = sum(len(r) for r in runs)
    assert total - 10 <= result.samples < total   # the IMU tail after the last thermometer
    assert [line.split(':')[0] for line in lines] == [f'read {b}' for b in result.bags]
    assert result.model.created['command'] == 'python -m gyro_tdc train ...'
    assert result.model.kind == 'poly' and result.model.features == ('dT', 'dT2')
    # The model removes the drift of a held-out run to the white-noise floor.
    held = synth_run(seed=23, hours=1.0)
    bs = bias_stability(compensate(result.model, held.t, held.temp, held.omega),
                        held.omega_ref)
    assert np.all(bs < 1.5 * held.info['noise_dps'] ** 2)
    # Coverage of both runs: heating on both, cooling on the first.
    c = result.coverage
    assert c.heating_min > 0 and c.cooling_min > 0 and int(c.samples.sum()) == result.samples
    text, warns = format_training(result)
    assert text.startswith('model: poly f(dT, dT2), T0 = ')
    assert 'training data: 2 bag(s)' in text and warns == []
    # Two bags, two power cycles with one curve: validated across them, every curve kept.
    held = result.held_out
    assert held.validated and held.curve == (True, True, True) and held.wins == (2, 2, 2)
    assert result.model.metrics['held_out']['curve'] == [True, True, True]
    assert 'held out across power cycles: each of 2 sessions' in text
    assert 'axis x: curve kept' in text and 'OFFSET ONLY' not in text


def test_the_options_reach_the_model(bags, tmp_path):
    folder, _ = bags
    options = TrainOptions(features='dT', kind='rbf', n_centers=5, t0=31.5, seed=4,
                           sensor_id='imu-7', accel=False)
    result = train([folder / 'run2'], tmp_path / 'm.yaml', options)
    m = result.model
    assert (m.kind, m.features, m.n_centers, m.t0_c, m.sensor_id) == ('rbf', ('dT',), 5, 31.5,
                                                                      'imu-7')
    assert result.accel is None and result.choice is None
    # The bag options say how to read: a topic the bag lacks is refused by name.
    with pytest.raises(DatasetError, match='/other/temperature'):
        train([folder / 'run2'], tmp_path / 'n.yaml', options,
              BagOptions(temperature_topic='/other/temperature'))
    assert not (tmp_path / 'n.yaml').exists()


def test_options_are_checked_when_built():
    assert TrainOptions().auto and TrainOptions(features=' auto ').features == 'auto'
    assert TrainOptions(features='dT2, dT').features == ('dT', 'dT2')     # catalog order
    assert TrainOptions(features=['lag', 'dT']).features == ('dT', 'lag')
    with pytest.raises(FeatureError, match='bogus'):
        TrainOptions(features='dT,bogus')
    with pytest.raises(FitError, match="Expected `kind` to be one of rbf, poly, got 'spline'"):
        TrainOptions(kind='spline')
    with pytest.raises(FitError, match='ridge'):
        TrainOptions(ridge=-1.0)
    with pytest.raises(FitError, match='thermal'):
        TrainOptions(thermal='third_order')
    with pytest.raises(LimitError, match='centres'):
        TrainOptions(n_centers=MAX_CENTERS + 1)
    with pytest.raises(LimitError, match='bin'):
        TrainOptions(bin_c=0.0)
