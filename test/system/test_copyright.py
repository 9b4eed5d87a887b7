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
Copyright check in the spirit of ament_copyright (there is no ament_copyright wheel on PyPI).

Every ``.py`` file under ``gyro_tdc/``, ``test/``, ``bench/``, ``tools/`` and ``setup.py`` must
start with the Apache-2.0 header of ``HEADER.txt`` (after an optional ``#!`` line). Only the
year(s) on the copyright line may differ.
"""

from __future__ import annotations

from pathlib import Path
import re

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHECKED_DIRS = ('gyro_tdc', 'test', 'bench', 'tools')
CHECKED_FILES = ('setup.py',)
YEAR = re.compile(r'\b\d{4}(?:-\d{4})?\b')


def header_lines() -> list[str]:
    """Return the lines of ``HEADER.txt`` without trailing whitespace."""
    return [line.rstrip() for line in (ROOT / 'HEADER.txt').read_text().splitlines()]


def python_files() -> list[Path]:
    """Return every checked ``.py`` file, skipping hidden and ``__pycache__`` directories."""
    files = [ROOT / name for name in CHECKED_FILES if (ROOT / name).is_file()]
    for name in CHECKED_DIRS:
        for path in sorted((ROOT / name).rglob('*.py')):
            parts = path.relative_to(ROOT).parts
            if any(part.startswith(('.', '__pycache__')) for part in parts[:-1]):
                continue
            files.append(path)
    return files


def header_problem(path: Path, expected: list[str]) -> str | None:
    """
    Return why ``path`` does not start with the expected header, or ``None`` if it does.

    Parameters
    ----------
    path : pathlib.Path
        Python file to check.
    expected : list of str
        Header lines; the year on the first (copyright) line may differ.

    Returns
    -------
    str or None
        One-line description of the first mismatch.

    """
    try:
        lines = [line.rstrip() for line in path.read_text(encoding='utf-8').splitlines()]
    except UnicodeDecodeError as exc:
        return f'not UTF-8 ({exc})'
    if lines and lines[0].startswith('#!'):
        lines = lines[1:]
    if len(lines) < len(expected):
        return 'file shorter than the copyright header'
    copyright_line = YEAR.sub('YEAR', expected[0])
    if YEAR.sub('YEAR', lines[0]) != copyright_line:
        return f'line 1 is {lines[0]!r}, expected {expected[0]!r} (any year)'
    for number, (got, want) in enumerate(zip(lines[1:], expected[1:]), start=2):
        if got != want:
            return f'header line {number} is {got!r}, expected {want!r}'
    return None


def test_header_file_is_apache_2():
    lines = header_lines()
    assert lines[0].startswith('# Copyright '), lines[0]
    assert any('Apache License, Version 2.0' in line for line in lines)


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright():
    expected = header_lines()
    files = python_files()
    assert files, 'no Python files found to check'
    problems = [f'{path.relative_to(ROOT)}: {problem}' for path in files
                if (problem := header_problem(path, expected)) is not None]
    assert not problems, (
        f'{len(problems)} of {len(files)} files lack the Apache-2.0 header of HEADER.txt:\n'
        + '\n'.join(problems))
