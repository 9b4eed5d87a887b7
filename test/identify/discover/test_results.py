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

"""What discovery found: its JSON document, its text summary, and a result without noise."""

from __future__ import annotations

from dataclasses import replace
import json

from gyro_tdc.errors import DatasetError
from gyro_tdc.identify.discover import discover, format_summary
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def found():
    """Return a discovery that names the curvature of a synthetic run (dT2 hidden)."""
    return discover([synth_run(seed=4, hours=0.5, rate_hz=2.0)], candidates='dT2,dT3',
                    allan=False, max_steps=1)


def test_json_is_plain_and_names_the_step(found):
    doc = json.loads(json.dumps(found.to_json('m.yaml')))
    assert list(doc) == ['base_effects', 'noise_floor_dps', 'steps', 'final_effects',
                         'unidentifiable', 'model_file']
    (step,) = doc['steps']
    assert step['effect'] == 'dT2' == found.named[0]
    assert step['p_value'] == found.steps[0].best.p_value
    assert step['flagged_bins_after'] <= step['flagged_bins_before']
    assert doc['model_file'] == 'm.yaml' and doc['final_effects'] == ['bias', 'dT', 'dT2']


def test_summary_says_each_step_and_the_final_gap(found):
    text = format_summary(found)
    assert text.endswith('\n')
    lines = text.splitlines()
    assert lines[0].startswith('discover: 1 run(s), ') and 'T0 = ' in lines[0]
    assert any(x.startswith('step 1: add dT2') for x in lines)
    assert any(x.startswith('  evidence: HAC p = ') for x in lines)
    final = next(x for x in lines if x.startswith('final model: bias, dT, dT2; gap '))
    assert f'{found.gap_dps / found.noise_floor_dps:.2f} x noise floor' in final


def test_a_result_without_noise_is_refused(found):
    with pytest.raises(DatasetError, match='noise floor 0: a constant sensor'):
        replace(found, noise_floor_dps=0.0)
