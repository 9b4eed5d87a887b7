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

"""Model file: exact round trip, and every malformed file rejected naming its field."""

from gyro_tdc.errors import FeatureError, ModelFileError
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate, CompensationModel, drift
from gyro_tdc.model.modelfile import load_model, model_to_dict, save_model
from gyro_tdc.model.thermal_state import ThermalState
import numpy as np
import pytest
from synth import synth_run
import yaml


@pytest.fixture(scope='module')
def model():
    return fit_model([synth_run(seed=21, hours=0.5, tau_die=200.0)], features='dT,dT2,lag',
                     created={'command': 'test'})


@pytest.mark.parametrize('kind', ['rbf', 'poly'])
def test_round_trip_is_exact(tmp_path, kind):
    run = synth_run(seed=22, hours=0.5)
    m = fit_model([run], kind=kind, features='dT,dT2,warmup')
    path = save_model(m, tmp_path / 'sub' / 'm.yaml')
    back = load_model(path)
    assert back == m and back.model_id == m.model_id
    np.testing.assert_array_equal(compensate(back, run.t, run.temp, run.omega),
                                  compensate(m, run.t, run.temp, run.omega))
    assert back.metrics == m.metrics and back.created['gyro_tdc_version']


def test_a_model_built_without_a_thermal_front_end_is_saved_with_kind_none(tmp_path):
    # The shape of a flight controller's cubic or the learner's fit before it has a prior.
    run = synth_run(seed=23, hours=0.3)
    coef = np.array([[0.01, -0.02, 0.0], [1e-3, 2e-4, 0.0], [1e-5, 0.0, -2e-5]])
    m = CompensationModel.polynomial(('dT', 'dT2'), 20.0, coef, temp_range_c=(15.0, 35.0),
                                     residual_var=np.full(3, 1e-8))
    back = load_model(save_model(m, tmp_path / 'm.yaml'))
    assert back.thermal == ThermalState() and back == m and back.model_id == m.model_id
    data = yaml.safe_load((tmp_path / 'm.yaml').read_text())
    assert data['format_version'] == 2 and data['thermal']['kind'] == 'none'
    for clamp in (True, False):
        np.testing.assert_array_equal(drift(back, run.t, run.temp + 15.0, clamp=clamp),
                                      drift(m, run.t, run.temp + 15.0, clamp=clamp))


def test_a_model_cannot_be_built_without_a_thermal_front_end(model):
    # `lag` is the lagged state every term is of; an additive lag column has no model form.
    with pytest.raises(FeatureError, match='`thermal` must be a ThermalState, got NoneType'):
        model.replace(thermal=None)
    with pytest.raises(FeatureError, match="thermal kind 'none' does not match the features"):
        model.replace(thermal=ThermalState())


def test_file_has_every_documented_field(tmp_path, model):
    data = yaml.safe_load(save_model(model, tmp_path / 'm.yaml').read_text())
    for key in ('format_version', 'kind', 'model_id', 'features', 'effect_params', 't0_c',
                'temp_range_c', 'normalization', 'centers', 'widths', 'weights', 'intercept',
                'linear', 'scale', 'residual_var_rad2_s2', 'sensor', 'training', 'created'):
        assert key in data
    assert data['effect_params']['lag']['tau_s'] > 0
    assert data['training']['train_bs_dps2'] and data['created']['command'] == 'test'


def _broken(model, **edit):
    d = model_to_dict(model)
    for key, value in edit.items():
        if value is KeyError:
            d.pop(key)
        else:
            d[key] = value
    return d


@pytest.mark.parametrize('edit, message', [
    ({'format_version': 3}, r'`format_version` must be 2 \(the format this gyro_tdc reads\), '
                            r'got 3'),
    ({'format_version': 1}, r'`format_version` must be 2 \(the format this gyro_tdc reads\), '
                            r'got 1'),
    ({'thermal': KeyError}, r'missing field `thermal`'),
    ({'kind': 'mlp'}, r'`kind` must be one of rbf, poly'),
    ({'features': ['dT', 'dT9']}, r"Unknown effect id\(s\) 'dT9'"),
    ({'features': 'dT'}, r'`features` must be a list'),
    ({'t0_c': 'cold'}, r'`t0_c` must be a finite number'),
    ({'t0_c': KeyError}, r'missing field `t0_c`'),
    ({'widths': [1.0]}, r'`widths` must have shape \(12,\)'),
    ({'weights': [[0.0, 0.0]]}, r'`weights` must have shape \(12, 3\)'),
    ({'intercept': [0.0, float('nan'), 0.0]}, r'`intercept` has non-finite values'),
    ({'intercept': [0.0, 10 ** 400, 0.0]}, r'`intercept` must be numbers'),
    ({'temp_range_c': [50.0, -10.0]}, r'`temp_range_c` must be \[min, max\]'),
    ({'residual_var_rad2_s2': [-1.0, 0.0, 0.0]}, r'must be non-negative'),
    ({'normalization': {'mean': [0, 0], 'std': [1, 0]}}, r'`std` must be positive'),
    ({'effect_params': {'lag': {'tau_s': -5}}}, r'lag.tau_s must be a positive'),
    ({'model_id': 'deadbeef0000'}, r'does not match the parameters'),
    ({'sensor': 'imu'}, r'`sensor` must be a mapping'),
])
def test_malformed_model_rejected_with_field_name(tmp_path, model, edit, message):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(_broken(model, **edit)))
    with pytest.raises(ModelFileError, match=message) as info:
        load_model(path)
    assert str(path) in str(info.value) and '\n' not in str(info.value)


@pytest.mark.parametrize('text, message', [
    ('kind: [rbf\n', r'malformed YAML at line 2'),
    ('- 1\n- 2\n', r'expected a mapping at the top level, got list'),
    ('!!python/object:os.system {}\n', r'malformed YAML'),
    ('', r'expected a mapping at the top level, got NoneType'),
])
def test_unparseable_or_unsafe_yaml_rejected(tmp_path, text, message):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(ModelFileError, match=message):
        load_model(path)


def test_missing_file_rejected(tmp_path):
    with pytest.raises(ModelFileError, match='cannot read model file'):
        load_model(tmp_path / 'nope.yaml')


def test_a_model_loading_would_refuse_is_not_written(tmp_path, model):
    """An implausible fit (a real log's steep curve extrapolated) leaves no file behind."""
    good = model
    bad = good.replace(intercept=good.intercept + np.array([0.0, 100.0, 0.0]))
    out = tmp_path / 'm.yaml'
    with pytest.raises(ModelFileError) as info:
        save_model(bad, out)
    text = str(info.value)
    assert '\n' not in text and 'not written' in text and str(out) in text
    assert 'the drift it computes is' in text and '(axis y)' in text
    assert not out.exists() and not list(tmp_path.iterdir())
    assert load_model(save_model(good, out)).model_id == good.model_id
