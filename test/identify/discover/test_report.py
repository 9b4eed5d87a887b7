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

"""Residual maps, the Allan deviation of the residual and the markdown report."""

from __future__ import annotations

from gyro_tdc.identify.discover import discover, write_report
from gyro_tdc.identify.discover.data import BlockData, LinearModel
from gyro_tdc.identify.discover.report import residual_adev, residual_maps
import numpy as np
from synth import synth_run


def test_maps_flag_what_the_model_misses_and_not_what_it_holds():
    run = synth_run(seed=4, hours=0.5, rate_hz=2.0)
    data = BlockData([run], block_s=10.0, t0=25.0)
    flagged = []
    for effects in (('bias', 'dT'), ('bias', 'dT', 'dT2')):
        model = LinearModel(data, effects, {})
        maps = residual_maps(data, model.residual())
        assert [m.name for m in maps] == ['temperature', 'dTdt', 'time']   # no reference
        for m in maps:
            assert m.mean_dps.shape == m.se_dps.shape == m.count.shape == m.flagged.shape
            assert m.count.sum() == 3 * data.K
        flagged.append(sum(m.n_flagged for m in maps))
        tau, dev = residual_adev(data, model, model.fit())
        assert tau.shape == dev.shape and tau.size > 3 and np.all(dev > 0)
    assert flagged[0] > flagged[1]            # the curvature shows until dT2 is in


def test_report_writes_markdown_tables_and_the_plots(tmp_path):
    res = discover([synth_run(seed=4, hours=0.5, rate_hz=2.0)], candidates='dT2,dT3',
                   max_steps=1)
    path = write_report(res, tmp_path / 'r')
    md = path.read_text()
    assert md.startswith('# Discovery report')
    assert '| step | effect | aliases | parameters | HAC p |' in md
    assert '|---|---|---|---|---|---|---|---|' in md
    assert '| 1 | `dT2` |' in md and '## Step 1: dT2' in md and '## Final model' in md
    for png in ('step1_maps.png', 'final_maps.png', 'allan.png'):
        assert f']({png})' in md and (tmp_path / 'r' / png).stat().st_size > 1000
