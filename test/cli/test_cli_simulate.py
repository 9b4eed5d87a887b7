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


"""``gyro-tdc simulate``: --force replaces its own earlier output only; --help lists scenarios."""

from __future__ import annotations

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.cli.simulate import main
import pytest
from scenarios import TINY as SIM_CLI_TINY
import yaml

# test_sim_cli's tiny scenario without its rate table, two runs.
TINY = {**{k: v for k, v in SIM_CLI_TINY.items() if k != 'rate_table'}, 'runs': {'count': 2}}


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / 'tiny.yaml'
    path.write_text(yaml.safe_dump(TINY))
    return str(path)


def _data(bag):
    """Return the bytes of a bag's storage files."""
    return b''.join(p.read_bytes() for p in sorted(bag.iterdir()) if p.name != 'metadata.yaml')


def _err(capsys):
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_existing_output_needs_force_and_force_replaces_it(tmp_path, tiny, capsys):
    out = tmp_path / 'out' / 'bags'
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '1']) == 0
    first = _data(out / 'run1')
    (out / 'run2' / 'stale.txt').write_text('left from before')
    capsys.readouterr()
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '2']) == 2
    line = _err(capsys)
    assert line.startswith('gyro-tdc simulate: error: --out:') and '--force' in line
    assert main(['--scenario', tiny, '--out', str(out), '--seed', '2', '--force']) == 0
    assert sorted(p.name for p in out.iterdir()) == ['run1', 'run2']
    assert not (out / 'run2' / 'stale.txt').exists()
    assert _data(out / 'run1') != first           # the new seed's data, not the old bag
    # Nothing is left beside the output (no staging or replaced copies).
    assert sorted(p.name for p in out.parent.iterdir()) == ['bags']


@pytest.mark.parametrize('make', ['file', 'dir_with_file', 'empty_dir', 'foreign_subdir'])
def test_force_refuses_what_simulate_did_not_write(tmp_path, tiny, capsys, make):
    out = tmp_path / 'precious'
    if make == 'file':
        out.write_text('keep me')
    else:
        out.mkdir()
        if make == 'dir_with_file':
            (out / 'notes.txt').write_text('keep me')
        elif make == 'foreign_subdir':
            (out / 'run1').mkdir()       # looks like a run but holds no bag
    before = sorted(p.name for p in tmp_path.rglob('*'))
    assert main(['--scenario', tiny, '--out', str(out), '--force']) == 2
    assert 'not a bag or a folder of run bags' in _err(capsys)
    assert sorted(p.name for p in tmp_path.rglob('*')) == before


def test_help_lists_every_shipped_scenario(capsys):
    assert main(['--help']) == 0
    text = capsys.readouterr().out
    assert 'usage: gyro-tdc simulate' in text and '--force' in text
    listing = text.split('shipped scenarios', 1)[1]
    for name in scenario_names():
        assert f'\n  {name}: ' in listing
    assert '  l3gd20_paper: 5 runs of 8.11 h at 10 Hz' in listing
