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

"""`python -m gyro_tdc demo`: the whole offline pipeline runs and shows what it should."""

import json

from gyro_tdc.cli import demo
import numpy as np


def test_demo_offline_pipeline(tmp_path, capsys):
    out = tmp_path / 'demo'
    assert demo.main(['--out', str(out), '--skip-live']) == 0
    text = capsys.readouterr().out
    # Every step prints the command a user would type.
    for cmd in ('simulate --scenario l3gd20_paper', 'train ', 'evaluate ', 'discover '):
        assert f'$ python -m gyro_tdc {cmd}' in text
    assert 'paper table (eq. 31-32)' in text

    tables = json.loads((out / 'report' / 'paper_tables.json').read_text())
    assert [b['bag'].rsplit('/', 1)[-1] for b in tables['bags']] == ['run2', 'run3', 'run4',
                                                                     'run5']
    for bag in tables['bags']:
        raw = np.array(bag['raw']['bs'])
        conv, modi = (np.array(m['bs']) for m in bag['models'])
        assert np.all(modi < conv) and np.all(conv < raw)
        # Held out, the modified model reaches the white-noise floor of the 10 Hz L3GD20
        # ((0.03 dps/sqrt(Hz))^2 * 10 Hz = 0.009 (deg/s)^2) within the run-to-run offset.
        assert np.all(modi < 2.0 * 0.009)

    found = json.loads((out / 'report' / 'discovery.json').read_text())
    named = {s['effect'] for s in found['steps']} | {
        a for s in found['steps'] for a in s['aliases']}
    assert 'lag' in named
    last = found['steps'][-1]
    assert last['heldout_gap_after_dps'] < 1.3 * found['noise_floor_dps']
    assert (out / 'models' / 'discovered.yaml').is_file()
    assert (out / 'report' / 'discovery' / 'report.md').is_file()
    assert sorted(p.name for p in (out / 'report' / 'evaluate').glob('*.png'))
