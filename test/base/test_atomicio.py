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
Tests of gyro_tdc.base.atomicio: atomic writes with normal permissions, through symlinks.

Hostile outputs (moved from test_hostile.py): a new file gets the umask's mode, an
overwritten one keeps its mode, a symlink is written through to its target, a failure leaves
the previous content and no temporary behind, a directory appears complete or not at all and
a replaced one stays until its successor is complete; what a dead writer left is removed.
"""

from __future__ import annotations

import errno
import json
import math
import os
from pathlib import Path
import stat

from gyro_tdc.base.atomicio import atomic_dir, atomic_json, atomic_write
from gyro_tdc.errors import OutputError
from gyro_tdc.model.modelfile import load_model, save_model
from hostile_helpers import one_line_error, small_model
import pytest


@pytest.fixture
def umask():
    """Set a umask for the test and restore the old one."""
    old = os.umask(0o022)
    try:
        yield os.umask
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _leftovers(directory: Path) -> list:
    return sorted(p.name for p in directory.iterdir() if p.name.endswith('.tmp'))


@pytest.mark.parametrize('mask, expected', [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_new_model_file_respects_the_umask(tmp_path, umask, mask, expected):
    umask(mask)
    path = save_model(small_model(), tmp_path / 'm.yaml')
    assert _mode(path) == expected


def test_overwriting_keeps_the_mode_of_the_existing_file(tmp_path, umask):
    umask(0o077)
    path = tmp_path / 'm.yaml'
    path.write_text('old')
    path.chmod(0o644)
    save_model(small_model(), path)
    assert _mode(path) == 0o644
    assert load_model(path).model_id == small_model().model_id


def test_symlinked_output_is_written_through_to_its_target(tmp_path):
    target = tmp_path / 'models' / 'real.yaml'
    target.parent.mkdir()
    target.write_text('old')
    target.chmod(0o640)
    link = tmp_path / 'current.yaml'
    link.symlink_to(target)
    save_model(small_model(), link)
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert load_model(target).model_id == small_model().model_id
    assert _mode(target) == 0o640
    assert _leftovers(tmp_path) == [] and _leftovers(target.parent) == []


def test_output_that_is_a_directory_names_it_and_leaves_nothing(tmp_path):
    target = tmp_path / 'm.yaml'
    target.mkdir()
    with pytest.raises(OutputError, match='it is a directory') as info:
        save_model(small_model(), target)
    assert str(target) in one_line_error(info)
    assert _leftovers(tmp_path) == [] and list(target.iterdir()) == []


@pytest.mark.parametrize('exc', [OSError(errno.ENOSPC, 'No space left on device'),
                                 KeyboardInterrupt(), ValueError('writer bug')])
def test_failure_during_the_write_removes_the_temporary(tmp_path, exc):
    path = tmp_path / 'out.csv'
    path.write_text('previous content\n')

    def writer(stream):
        stream.write('half a row,')
        stream.flush()
        raise exc

    if isinstance(exc, OSError):
        with pytest.raises(OutputError, match='No space left on device') as info:
            atomic_write(path, writer, what='CSV file')
        assert f"cannot write CSV file '{path}'" in one_line_error(info)
    else:
        with pytest.raises(type(exc)):
            atomic_write(path, writer)
    assert path.read_text() == 'previous content\n'
    assert _leftovers(tmp_path) == []


def test_binary_writer_and_bytes_content(tmp_path):
    atomic_write(tmp_path / 'a.bin', lambda s: s.write(b'\x00\x01'), binary=True)
    atomic_write(tmp_path / 'b.bin', b'\x02')
    assert (tmp_path / 'a.bin').read_bytes() == b'\x00\x01'
    assert (tmp_path / 'b.bin').read_bytes() == b'\x02'


def test_json_has_one_space_of_indent_a_final_newline_and_the_options_asked(tmp_path):
    doc = {'a': [1, 2.5], 'b': 'µ'}
    path = atomic_json(tmp_path / 'sub' / 'doc.json', doc)
    assert path.read_text(encoding='utf-8') == json.dumps(doc, indent=1) + '\n'
    line = atomic_json(tmp_path / 'line.json', doc, indent=None, ensure_ascii=False)
    assert line.read_text(encoding='utf-8') == '{"a": [1, 2.5], "b": "µ"}\n'
    with pytest.raises(ValueError):
        atomic_json(tmp_path / 'nan.json', {'x': math.nan}, allow_nan=False)
    assert not (tmp_path / 'nan.json').exists()


def test_atomic_dir_appears_complete_or_not_at_all(tmp_path, umask):
    out = tmp_path / 'bags'
    with pytest.raises(OutputError, match='No space left on device'):
        with atomic_dir(out) as build:
            build.mkdir()
            (build / 'run1.db3').write_bytes(b'')
            raise OSError(errno.ENOSPC, 'No space left on device')
    assert list(tmp_path.iterdir()) == []
    with atomic_dir(out) as build:
        build.mkdir()
        (build / 'x').write_text('1')
    assert (out / 'x').read_text() == '1' and [p.name for p in tmp_path.iterdir()] == ['bags']
    assert _mode(out) == 0o755
    with pytest.raises(OutputError, match='exists already'):
        with atomic_dir(out):
            pass


def _tree(path: Path) -> dict:
    return {p.name: p.read_text() for p in path.iterdir()}


def _dead_pid() -> int:
    import subprocess
    import sys
    return int(subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                              capture_output=True, text=True, check=True).stdout)


@pytest.mark.parametrize('exchange', [True, False], ids=['exchange', 'two_renames'])
def test_replaced_dir_stays_until_the_new_one_is_complete(tmp_path, monkeypatch, exchange):
    from gyro_tdc.base import atomicio
    if not exchange:        # a system without renameat2: old -> backup, new -> path
        monkeypatch.setattr(atomicio, '_renameat2_func', lambda: None)
    out = tmp_path / 'bag'
    out.mkdir()
    (out / 'a').write_text('old')
    with pytest.raises(KeyboardInterrupt):
        with atomic_dir(out, replace=True) as build:
            build.mkdir()
            (build / 'b').write_text('new')
            assert _tree(out) == {'a': 'old'}
            raise KeyboardInterrupt
    assert _tree(out) == {'a': 'old'} and os.listdir(tmp_path) == ['bag']
    with atomic_dir(out, replace=True) as build:
        build.mkdir()
        (build / 'b').write_text('new')
        assert _tree(out) == {'a': 'old'}
    assert _tree(out) == {'b': 'new'} and os.listdir(tmp_path) == ['bag']


def test_second_rename_failing_puts_the_old_tree_back(tmp_path, monkeypatch):
    from gyro_tdc.base import atomicio
    monkeypatch.setattr(atomicio, '_renameat2_func', lambda: None)
    out = tmp_path / 'bag'
    out.mkdir()
    (out / 'a').write_text('old')
    real = os.rename

    def rename(src, dst):
        if Path(dst) == out and Path(src).name == 'bag':
            raise OSError(errno.EXDEV, 'Invalid cross-device link')
        real(src, dst)

    monkeypatch.setattr(atomicio.os, 'rename', rename)
    with pytest.raises(OutputError, match='cross-device'):
        with atomic_dir(out, replace=True) as build:
            build.mkdir()
    assert _tree(out) == {'a': 'old'} and os.listdir(tmp_path) == ['bag']


def test_dead_writers_leftovers_are_removed_and_their_backup_put_back(tmp_path):
    from gyro_tdc.base.atomicio import _HOST, clean_leftovers
    dead = _dead_pid()
    out = tmp_path / 'bag'
    backup = tmp_path / f'.bag.{_HOST}-{dead}-0123abcd.old'     # killed between two renames
    backup.mkdir()
    (backup / 'a').write_text('old')
    (tmp_path / f'.bag.{_HOST}-{dead}-4567abcd.tmp').mkdir()    # its complete new tree
    (tmp_path / f'.m.yaml.{_HOST}-{dead}-89abcdef.tmp').write_text('half')
    notes = clean_leftovers(out)
    assert len(notes) == 2 and notes[0].startswith('restored')
    assert _tree(out) == {'a': 'old'}
    assert sorted(os.listdir(tmp_path)) == ['.m.yaml.' + f'{_HOST}-{dead}-89abcdef.tmp', 'bag']
    atomic_write(tmp_path / 'm.yaml', 'whole')     # the next write of m.yaml removes its own
    assert sorted(os.listdir(tmp_path)) == ['bag', 'm.yaml']
