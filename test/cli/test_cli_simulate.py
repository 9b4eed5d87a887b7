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


"""
``gyro-tdc simulate``: --force replaces its own earlier output only; --help lists scenarios.

A replacing run killed with ``kill -9`` before any of its file-system changes leaves the old or
the new output, complete, at its path; the next run removes what the killed one left.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.cli.simulate import main
from pause_at import PausingRunner
import pytest
from rosbags.rosbag2 import Reader
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


def _digest(out: Path) -> str:
    """Return a hash of every message of the bag (or of the run bags) at ``out``, via rosbags."""
    sha = hashlib.sha256()
    bags = sorted(out.glob('run*')) if (out / 'run1').is_dir() else [out]
    for bag in bags:
        with Reader(bag) as reader:
            assert reader.message_count > 0
            for con, stamp, raw in reader.messages():
                sha.update(f'{bag.name} {con.topic} {stamp}'.encode())
                sha.update(raw)
    return sha.hexdigest()


def _hidden(folder: Path) -> list:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith('.'))


def test_force_killed_before_any_change_keeps_the_old_or_the_new_bag(tmp_path):
    scenario = tmp_path / 'tiny.yaml'
    scenario.write_text(yaml.safe_dump({**TINY, 'runs': {'count': 1}}))
    out = tmp_path / 'w' / 'bags'
    args = ['simulate', '--scenario', scenario, '--out', out, '--no-progress', '--force']
    assert main([*args[1:], '--seed', '2']) == 0
    new = _digest(out)
    assert main([*args[1:], '--seed', '1']) == 0
    old = _digest(out)
    assert old != new
    seen = []

    def only_its_own(pid, paused):
        # This run has removed what the killed one before it left beside the output.
        assert all(f'-{pid}-' in name for name in _hidden(out.parent)), paused

    with PausingRunner() as runner:
        for stop in range(40):
            paused, code = runner.run(stop, out.parent, [*args, '--seed', '2'], only_its_own)
            if paused is None:           # ran to its end: every change has been tried
                assert code == 0
                break
            assert code == -9, paused
            # The path holds a complete bag, the old or the new one.
            assert out.is_dir(), f'{out} missing after kill -9 {paused}'
            got = _digest(out)
            assert got in (old, new), paused
            seen.append('old' if got == old else 'new')
            if got == new:                  # back to the old output for the next change
                assert main([*args[1:], '--seed', '1']) == 0
                assert _digest(out) == old and _hidden(out.parent) == [], paused
    assert paused is None, 'more changes than expected'
    assert _digest(out) == new and _hidden(out.parent) == []
    assert len(seen) >= 5 and 'old' in seen and 'new' in seen, seen
    assert seen == sorted(seen, key=('old', 'new').index), seen     # old until the swap


def test_next_run_puts_back_a_bag_lost_by_a_kill_and_removes_leftovers(tmp_path, caplog):
    from gyro_tdc.base.atomicio import _HOST
    import subprocess
    import sys
    dead = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                          capture_output=True, text=True, check=True).stdout.strip()
    scenario = tmp_path / 'tiny.yaml'
    scenario.write_text(yaml.safe_dump({**TINY, 'runs': {'count': 1}}))
    folder = tmp_path / 'w'
    out = folder / 'bags'
    assert main(['--scenario', scenario, '--out', out, '--seed', '1']) == 0
    old = _digest(out)
    # What a kill -9 during a replacing write leaves: the old bag moved aside and a
    # half-written new one.
    out.rename(folder / f'.bags.{_HOST}-{dead}-00000000.old')
    staging = folder / f'.bags.{_HOST}-{dead}-0123abcd.tmp'
    staging.mkdir()
    (staging / 'bags.db3').write_bytes(b'x' * 1000)
    running = folder / f'.bags.{_HOST}-{os.getpid()}-89abcdef.tmp'     # a live owner
    running.mkdir()
    unknown = folder / f'.bags.{"eeee" if _HOST == "ffff" else "ffff"}-1-0123abcd.tmp'
    unknown.mkdir()                                                  # another host's
    other = folder / '.bagsX.ffff-1-00000000.tmp'
    other.mkdir()
    # Without --force: the bag is back, so it exists.
    with caplog.at_level(logging.WARNING, logger='gyro_tdc.base.atomicio'):
        assert main(['--scenario', scenario, '--out', out, '--seed', '2']) == 2
    assert _digest(out) == old
    assert _hidden(folder) == sorted([running.name, unknown.name, other.name])
    assert len(caplog.records) == 1 and unknown.name in caplog.records[0].getMessage()
