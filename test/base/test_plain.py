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

"""Tests of gyro_tdc.base.plain: numpy values into what JSON and yaml.safe_dump accept."""

from __future__ import annotations

import json
import math

from gyro_tdc.base.plain import plain
import numpy as np
import yaml


def test_arrays_scalars_and_tuples_become_plain_types():
    value = {'a': np.arange(3), 'b': (np.float32(1.5), np.int64(7), np.bool_(True)),
             'c': [np.array([[1.0, 2.0]]), 'text', None]}
    got = plain(value)
    assert got == {'a': [0, 1, 2], 'b': [1.5, 7, True], 'c': [[[1.0, 2.0]], 'text', None]}
    assert type(got['b'][0]) is float and type(got['b'][1]) is int
    assert type(got['b'][2]) is bool and type(got['a'][0]) is int
    assert yaml.safe_load(yaml.safe_dump(got)) == got          # safe_dump accepts it


def test_non_finite_floats_to_none_only_when_asked():
    value = [np.nan, np.float64(np.inf), -math.inf, 1.0, np.array([np.nan, 2.0])]
    assert plain(value, nan_to_none=True) == [None, None, None, 1.0, [None, 2.0]]
    kept = plain(value)
    assert math.isnan(kept[0]) and kept[1] == math.inf and kept[3] == 1.0
    json.dumps(plain(value, nan_to_none=True), allow_nan=False)   # strict JSON


def test_mapping_keys_str_by_default_kept_on_request():
    value = {1: np.float64(2.0), np.int64(3): 'x'}
    assert plain(value) == {'1': 2.0, '3': 'x'}
    kept = plain(value, str_keys=False)
    assert kept == {1: 2.0, 3: 'x'} and 1 in kept
    assert plain({'n': {2: np.zeros(1)}}) == {'n': {'2': [0.0]}}     # recursive
