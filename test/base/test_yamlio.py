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

"""Tests of gyro_tdc.base.yamlio: YAML read within size, depth, node-count and alias limits."""

from __future__ import annotations

import re

from gyro_tdc.base.yamlio import (BAG_METADATA_LIMITS, load_yaml, read_yaml, SCENARIO_LIMITS,
                                  YamlLimits)
from gyro_tdc.errors import DatasetError, GyroTdcError, ScenarioError
import pytest

STRICT = YamlLimits('test file', max_bytes=200, max_depth=3, max_nodes=20, aliases=False)
LOOSE = YamlLimits('test file', max_bytes=1000, max_depth=8, max_nodes=100, aliases=True)


def test_legitimate_aliases_still_load_in_a_scenario(tmp_path):
    limits = YamlLimits('test file', max_bytes=1000, max_depth=8, max_nodes=100, aliases=True)
    assert load_yaml('a: &x [1, 2]\nb: *x\n', limits) == {'a': [1, 2], 'b': [1, 2]}


def test_depth_up_to_the_limit_loads_one_more_names_the_line():
    assert load_yaml('a: {b: [1]}\n', STRICT) == {'a': {'b': [1]}}      # 3 levels
    with pytest.raises(ScenarioError) as info:
        load_yaml('a: {b: [1]}\nc:\n  - [[2]]\n', STRICT, source='s.yaml', error=ScenarioError)
    assert str(info.value) == ('s.yaml: nesting deeper than 3 levels at line 3 (the limit of a '
                               'test file)')


@pytest.mark.parametrize('text, what', [('a: &x 1\n', 'anchor &x'),
                                        ('a: &x [1]\n', 'anchor &x'),
                                        ('a: *x\n', 'alias *x')])
def test_anchors_and_aliases_refused_where_not_allowed(text, what):
    with pytest.raises(GyroTdcError, match=re.escape(f'YAML {what} at line 1: anchors and '
                                                     'aliases are not allowed in a test file')):
        load_yaml(text, STRICT)


def test_node_count_expands_aliases():
    base = 'a: &x [1, 2, 3, 4, 5, 6, 7, 8, 9]\n'            # 10 nodes
    assert len(load_yaml(base + 'b: [*x, *x]\n', LOOSE)['b']) == 2
    limits = YamlLimits('test file', max_bytes=1000, max_depth=8, max_nodes=40, aliases=True)
    load_yaml(base + 'b: [*x, *x]\n', limits)                  # 10 + 1 + 2 * 10 + keys
    with pytest.raises(GyroTdcError, match=r'more than 40 YAML nodes \(aliases expanded\)'):
        load_yaml(base + 'b: [*x, *x, *x]\n', limits)
    with pytest.raises(GyroTdcError, match='more than 20 YAML nodes at line'):
        load_yaml('[' + ', '.join(['0'] * 25) + ']', STRICT)


def test_recursive_alias_and_empty_document():
    with pytest.raises(GyroTdcError, match=r'recursive YAML alias \*p at line 1'):
        load_yaml('p: &p [1, *p]\n', LOOSE)
    assert load_yaml('', STRICT) is None
    assert load_yaml('# only a comment\n', STRICT) is None


def test_read_yaml_errors_are_one_line_in_the_callers_class(tmp_path):
    with pytest.raises(DatasetError, match='cannot read test file') as info:
        read_yaml(tmp_path / 'none.yaml', STRICT, error=DatasetError)
    assert str(tmp_path / 'none.yaml') in str(info.value)
    big = tmp_path / 'big.yaml'
    big.write_text('a: ' + 'x' * 300 + '\n')
    with pytest.raises(DatasetError, match=r'304 bytes, more than the 200-byte limit of a test '
                                           'file'):
        read_yaml(big, STRICT, error=DatasetError)
    latin = tmp_path / 'latin.yaml'
    latin.write_bytes(b'a: caf\xe9\n')
    with pytest.raises(GyroTdcError, match=r'not a text \(UTF-8\) test file'):
        read_yaml(latin, STRICT)
    bad = tmp_path / 'bad.yaml'
    bad.write_text('a: 1\nb: [1, 2\n')
    with pytest.raises(ScenarioError) as info:
        read_yaml(bad, STRICT, error=ScenarioError)
    text = str(info.value)
    assert text.startswith(f'{bad}: malformed YAML at line ') and '\n' not in text
    good = tmp_path / 'good.yaml'
    good.write_text('rate_hz: 100.0\nnames: [a, b]\n')
    assert read_yaml(good, SCENARIO_LIMITS) == {'rate_hz': 100.0, 'names': ['a', 'b']}


def test_shipped_limits_allow_aliases_and_are_generous():
    for limits in (SCENARIO_LIMITS, BAG_METADATA_LIMITS):
        assert limits.aliases and limits.max_depth == 64
        assert limits.max_bytes >= 4 * 1024 * 1024 and limits.max_nodes >= 1_000_000
    assert 'max_depth=3' in repr(STRICT)
