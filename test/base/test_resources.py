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

"""Tests of gyro_tdc.base.resources: finding config/, shipped names and resolving paths."""

from __future__ import annotations

from pathlib import Path

from gyro_tdc.base import resources
from gyro_tdc.errors import GyroTdcError, ModelFileError, ScenarioError
import pytest

ROOT = Path(__file__).resolve().parents[2]
RESOLVERS = [(resources.scenario_path, 'scenarios', ScenarioError),
             (resources.model_path, 'models', ModelFileError)]


def test_config_dir_found_in_checkout():
    if not (ROOT / 'config').is_dir():
        pytest.skip('no config/ directory yet')
    assert resources.config_dir() == ROOT / 'config'


def test_shipped_names_resolve_to_files_in_config():
    assert 'demo_fast' in resources.scenario_names()
    for name in resources.scenario_names():
        assert resources.scenario_path(name) == resources.config_dir() / 'scenarios' / \
            f'{name}.yaml'
    models = sorted((resources.config_dir() / 'models').glob('*.yaml'))
    assert 'l3gd20_modified' in [p.stem for p in models]
    for path in models:
        assert resources.model_path(path.stem) == path


@pytest.mark.parametrize('resolve, subdir, error', RESOLVERS)
def test_named_resources(tmp_path, resolve, subdir, error):
    (tmp_path / subdir).mkdir()
    for name in ('beta', 'alpha'):
        (tmp_path / subdir / f'{name}.yaml').write_text('{}\n')
    assert resolve('alpha', config=tmp_path) == tmp_path / subdir / 'alpha.yaml'
    explicit = tmp_path / 'elsewhere.yaml'
    explicit.write_text('{}\n')
    assert resolve(explicit, config=tmp_path) == explicit
    assert resolve(str(explicit)) == explicit
    with pytest.raises(error, match=r"unknown .*'gamma'.*alpha, beta"):
        resolve('gamma', config=tmp_path)
    with pytest.raises(error, match='does not exist'):
        resolve(tmp_path / 'missing.yaml', config=tmp_path)
    with pytest.raises(error, match='got int'):
        resolve(3, config=tmp_path)
    assert issubclass(error, GyroTdcError)


def test_resource_names(tmp_path):
    (tmp_path / 'scenarios').mkdir()
    (tmp_path / 'scenarios' / 'ramp.yaml').write_text('{}\n')
    (tmp_path / 'scenarios' / 'notes.txt').write_text('not a scenario\n')
    assert resources.scenario_names(config=tmp_path) == ['ramp']
    with pytest.raises(ModelFileError, match='<none>'):
        resources.model_path('anything', config=tmp_path)


@pytest.mark.parametrize('resolve, subdir, error', RESOLVERS)
def test_yml_suffix_and_what_counts_as_a_path(tmp_path, monkeypatch, resolve, subdir, error):
    (tmp_path / subdir).mkdir()
    (tmp_path / subdir / 'short.yml').write_text('{}\n')
    assert resolve('short', config=tmp_path) == tmp_path / subdir / 'short.yml'
    # A name with a separator or a YAML suffix is a path, never looked up in config/.
    with pytest.raises(error, match="file 'sub/short' does not exist"):
        resolve('sub/short', config=tmp_path)
    with pytest.raises(error, match="file 'short.yml' does not exist"):
        resolve('short.yml', config=tmp_path)
    # A bare name that is no shipped name but a file in the working directory is that file.
    work = tmp_path / 'work'
    work.mkdir()
    (work / 'local').write_text('{}\n')
    monkeypatch.chdir(work)
    assert resolve('local', config=tmp_path) == Path('local')
    # ...and a shipped name wins over a file of the same name in the working directory.
    (work / 'short').write_text('{}\n')
    assert resolve('short', config=tmp_path) == tmp_path / subdir / 'short.yml'


@pytest.mark.parametrize('resolve, subdir, error', RESOLVERS)
def test_empty_name_and_home_relative_path(tmp_path, monkeypatch, resolve, subdir, error):
    with pytest.raises(error, match='got an empty string'):
        resolve('', config=tmp_path)
    monkeypatch.setenv('HOME', str(tmp_path))
    (tmp_path / 'mine.yaml').write_text('{}\n')
    assert resolve('~/mine.yaml') == tmp_path / 'mine.yaml'


def test_missing_config_dir_names_both_places(monkeypatch):
    monkeypatch.setattr(resources, '_checkout_config_dir', lambda: None)
    monkeypatch.setenv('AMENT_PREFIX_PATH', '/nonexistent/prefix')
    with pytest.raises(GyroTdcError, match=r"share/gyro_tdc/config.*'/nonexistent/prefix'"):
        resources.config_dir()
    with pytest.raises(GyroTdcError, match='config directory not found'):
        resources.model_path('l3gd20_modified')
