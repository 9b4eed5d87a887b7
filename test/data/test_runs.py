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

"""Tests of gyro_tdc.data.runs: the Run container's shape checks, length, duration and slices."""

from __future__ import annotations

import dataclasses
import re

from gyro_tdc.data.runs import Run
import numpy as np
import pytest


def _run(n=5, **kw):
    t = 10.0 + np.arange(n, dtype=float)
    return Run(t, np.linspace(20.0, 24.0, n), np.ones((n, 3)), np.zeros((n, 3)), **kw)


def test_length_duration_and_defaults():
    run = _run(5)
    assert len(run) == 5 and run.duration_s == 4.0
    assert run.name == 'run' and run.info == {} and run.accel is None
    assert _run(1).duration_s == 0.0 and len(_run(0)) == 0


def test_slice_keeps_name_copies_info_and_cuts_accel():
    accel = np.arange(15.0).reshape(5, 3)
    run = _run(5, name='bag1', info={'rejected': 2}, accel=accel)
    part = run.slice(1, 3)
    assert len(part) == 2 and part.name == 'bag1' and part.duration_s == 1.0
    np.testing.assert_array_equal(part.accel, accel[1:3])
    np.testing.assert_array_equal(part.temp, run.temp[1:3])
    part.info['rejected'] = 99                       # a copy: the original keeps its own
    assert run.info == {'rejected': 2}
    assert run.slice(0, 2, name='head').name == 'head'
    assert _run(5).slice(0, 2).accel is None


def test_a_run_is_frozen():
    run = _run(3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.name = 'other'


@pytest.mark.parametrize('key, bad, shape', [
    ('temp', np.zeros(4), (5,)), ('omega', np.zeros((5, 2)), (5, 3)),
    ('omega_ref', np.zeros(5), (5, 3)), ('accel', np.zeros((4, 3)), (5, 3))])
def test_shape_errors_name_the_argument_and_the_shapes(key, bad, shape):
    n = 5
    args = dict(t=np.arange(n, dtype=float), temp=np.zeros(n), omega=np.zeros((n, 3)),
                omega_ref=np.zeros((n, 3)))
    args[key] = bad
    want = f'Expected `{key}` to have shape {shape}, got {bad.shape}.'
    with pytest.raises(ValueError, match=re.escape(want)):
        Run(**args)


def test_stamps_must_be_one_dimensional_and_strictly_increasing():
    with pytest.raises(ValueError, match=r'Expected `t` to have shape \(N,\), got \(2, 2\)'):
        Run(np.zeros((2, 2)), np.zeros(2), np.zeros((2, 3)), np.zeros((2, 3)))
    for t in ([0.0, 1.0, 1.0], [0.0, 2.0, 1.0]):
        with pytest.raises(ValueError, match='strictly increasing'):
            Run(np.array(t), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3)))
