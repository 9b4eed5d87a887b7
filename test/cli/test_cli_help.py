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


"""``gyro-tdc <command> --help``: one program name, and the lists a newcomer needs."""

from __future__ import annotations

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.cli import COMMANDS, load_main
from gyro_tdc.model.effects import EFFECTS
import pytest


def _help(capsys, name):
    assert load_main(name)(['--help']) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_every_command_names_itself_gyro_tdc(capsys, name):
    assert _help(capsys, name).startswith(f'usage: gyro-tdc {name} ')


@pytest.mark.parametrize('name', ['train', 'discover'])
def test_train_and_discover_list_the_effect_ids(capsys, name):
    tail = _help(capsys, name).split('\neffect ids', 1)[1]
    for eid, effect in EFFECTS.items():
        assert f'\n  {eid} ' in tail, eid
        assert effect.excited_by.split()[0] in tail


def test_simulate_lists_the_scenarios(capsys):
    tail = _help(capsys, 'simulate').split('\nshipped scenarios', 1)[1]
    assert [line.split(':')[0].strip() for line in tail.splitlines()
            if line.startswith('  ') and not line.startswith('      ')] == scenario_names()
