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
Run every command block of the README and the doc pages, in order, in a fresh clone.

``make readme-check``: the repository's committed state (``HEAD``) is cloned into a
temporary folder; the ```` ```bash ```` blocks of ``README.md`` and then of every page under
``doc/`` (:func:`doc_pages`: the order of the site's table of contents, then any other page)
are turned into one bash script (``set -e -o pipefail``) that prints each command as
``$ ...`` before running it, in a shell that starts from nothing (no ``.venv``: the README's
own ``make venv`` creates it). The first failing command stops the run and is named with its
page and line. A block whose first line is a comment starting with one of
:data:`SKIP_MARKERS` (``# robot only: ...``, ``# not run by make readme-check: ...``) is
skipped, and the rest of that comment is printed as the reason.

Standard library only, so it runs before any venv exists
(``python3 test/support/readme_check.py``). ``test/system/test_readme.py`` uses
:func:`doc_blocks`, :func:`units` and :func:`commands` for its fast checks.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import fnmatch
import os
from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from typing import Optional, Sequence

ROOT = Path(__file__).resolve().parents[2]
SKIP_MARKERS = ('# robot only', '# not run by make readme-check')
_OPENERS = ('for ', 'while ', 'until ', 'if ')
_CLOSERS = ('done', 'fi')
_ASSIGNMENT = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*=')
README = 'README.md'
DOC = 'doc'
#: Folders of doc/ that hold no pages of their own (Sphinx extensions, build output).
DOC_SKIP = ('_ext', '_build')


@dataclass(frozen=True)
class Block:
    """
    One ```` ```bash ```` block of the README or of a doc page.

    Parameters
    ----------
    line : int
        Page line (1-based) of the block's first line inside the fence.
    lines : tuple of str
        The block's lines.
    section : str
        The ``## `` heading the block sits under (the page's ``# `` title before the first).
    skip : str or None
        Why it is not run (its marker comment), or None when it runs.
    page : str
        The page, relative to the repository (``README.md``, ``doc/robot.md``).

    """

    line: int
    lines: tuple
    section: str
    skip: Optional[str]
    page: str = README

    @property
    def where(self) -> str:
        """Return ``page:line`` of the block's first line."""
        return f'{self.page}:{self.line}'


@dataclass(frozen=True)
class Unit:
    """
    One command as the shell sees it: continuation lines joined, a loop kept whole.

    Parameters
    ----------
    line : int
        Page line of its first line.
    lines : tuple of str
        Its page lines.
    page : str
        The page it is on.

    """

    line: int
    lines: tuple
    page: str = README

    @property
    def text(self) -> str:
        """Return the command as one string (backslash-newlines kept)."""
        return '\n'.join(self.lines)


def readme_blocks(text: str, page: str = README) -> list:
    """
    Return every ```` ```bash ```` block of a README or doc page, in order.

    Parameters
    ----------
    text : str
        The page (Markdown: GitHub's or MyST's).
    page : str
        Its path relative to the repository, recorded in each block.

    Returns
    -------
    list of Block
        With their line, section and skip reason. Lines inside other fences (```` ```text ````,
        ```` ```{toctree} ````) are never taken for headings.

    """
    blocks = []
    section = ''
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith('## '):
            section = line[3:].strip()
        elif line.startswith('# ') and not section:
            section = line[2:].strip()
        if line.strip() == '```bash':
            start = i + 1
            j = start
            while j < len(lines) and lines[j].strip() != '```':
                j += 1
            body = tuple(lines[start:j])
            comments = []        # the block's first comment, with lines that continue it
            for b in body:
                if not b.strip().startswith('#') or (comments and
                                                     not comments[-1].endswith(',')):
                    break
                comments.append(b.strip().lstrip('#').strip())
            first = ' '.join(comments)
            skip = None
            for marker in SKIP_MARKERS:
                if ('# ' + first).startswith(marker):
                    skip = first
            blocks.append(Block(start + 1, body, section, skip, page))
            i = j
        elif line.lstrip().startswith('```'):          # another fence: skip its body
            j = i + 1
            while j < len(lines) and lines[j].strip() != '```':
                j += 1
            i = j
        i += 1
    return blocks


def _toctree_entries(text: str, rst: bool) -> list:
    """Return the entries of every toctree of a page, in order (``:glob:`` ones marked)."""
    entries = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        opened = line == '.. toctree::' if rst else line.startswith('```{toctree}')
        i += 1
        if not opened:
            continue
        glob = False
        while i < len(lines):
            raw = lines[i]
            item = raw.strip()
            if rst and item and not raw[:1].isspace():
                break                                   # the directive's body ended
            if not rst and item == '```':
                break
            i += 1
            if item.startswith(':'):
                glob = glob or item == ':glob:'
            elif item:
                target = re.search(r'<([^<>]+)>$', item)
                entries.append((target.group(1) if target else item, glob))
    return entries


def doc_pages(root: Path) -> list:
    """
    Return the pages whose blocks run: ``README.md``, then ``doc/`` in reading order.

    The reading order is the site's: a depth-first walk of the toctrees from
    ``doc/index.rst`` (or ``index.md``), each page followed by the pages of its own toctrees
    (``:glob:`` entries in name order). Pages no toctree reaches follow in name order, so
    every page runs, in a stable order.

    Parameters
    ----------
    root : Path
        The repository.

    Returns
    -------
    list of str
        Paths relative to ``root`` (POSIX), ``README.md`` first when it exists.

    """
    doc = root / DOC
    found = sorted(p.relative_to(doc).as_posix() for p in doc.rglob('*')
                   if p.suffix in ('.md', '.rst') and p.is_file()
                   and not p.relative_to(doc).parts[0] in DOC_SKIP) if doc.is_dir() else []
    by_name = {}
    for rel in found:
        by_name.setdefault(rel.rsplit('.', 1)[0], rel)
    order: list = []

    def visit(name: str) -> None:
        rel = by_name.get(name)
        if rel is None or rel in order:
            return
        order.append(rel)
        base = name.rsplit('/', 1)[0] + '/' if '/' in name else ''
        text = (doc / rel).read_text(encoding='utf-8')
        for entry, glob in _toctree_entries(text, rel.endswith('.rst')):
            target = entry.lstrip('/') if entry.startswith('/') else base + entry
            target = os.path.normpath(target).replace(os.sep, '/')
            if glob:
                for match in sorted(n for n in by_name if fnmatch.fnmatch(n, target)):
                    visit(match)
            else:
                visit(target.rsplit('.', 1)[0] if target.endswith(('.md', '.rst')) else target)

    visit('index')
    order += [rel for rel in found if rel not in order]
    pages = [README] if (root / README).is_file() else []
    return pages + [f'{DOC}/{rel}' for rel in order]


def doc_blocks(root: Path) -> list:
    """
    Return every ```` ```bash ```` block of the README and the doc pages, in run order.

    Parameters
    ----------
    root : Path
        The repository.

    Returns
    -------
    list of Block
        :func:`readme_blocks` of each page of :func:`doc_pages`, in that order.

    """
    return [b for page in doc_pages(root)
            for b in readme_blocks((root / page).read_text(encoding='utf-8'), page)]


def units(block: Block) -> list:
    """
    Split a block into shell commands: continuations joined, ``for ... done`` kept whole.

    Parameters
    ----------
    block : Block
        A README or doc page block.

    Returns
    -------
    list of Unit
        Comment-only and empty lines are left out.

    """
    out = []
    current: list = []
    start = 0
    depth = 0
    for k, line in enumerate(block.lines):
        stripped = line.strip()
        if not current and (not stripped or stripped.startswith('#')):
            continue
        if not current:
            start = block.line + k
        current.append(line)
        head = stripped.split('#', 1)[0].strip()
        if head.startswith(_OPENERS):
            depth += 1
        if head in _CLOSERS or head.startswith(tuple(c + ' ' for c in _CLOSERS)) or \
                head.startswith(tuple(c + ';' for c in _CLOSERS)):
            depth -= 1
        if depth <= 0 and not stripped.endswith('\\'):
            out.append(Unit(start, tuple(current), block.page))
            current, depth = [], 0
    if current:
        out.append(Unit(start, tuple(current), block.page))
    return out


def commands(unit: Unit) -> list:
    """
    Return the simple commands of a unit as argument lists, loop variables substituted.

    ``for k in a b; do ... done`` gives the body's commands with ``$k`` replaced by the first
    value; ``&&``, ``||``, ``;`` and ``|`` separate commands; ``VAR=value`` words before a
    command (its environment) are left out.

    Parameters
    ----------
    unit : Unit
        One shell command of a block.

    Returns
    -------
    list of list of str
        One argument list per simple command (comments dropped).

    """
    words: list = []
    for line in unit.text.replace('\\\n', ' ').split('\n'):     # a newline ends a command
        words += shlex.split(line, comments=True, posix=True) + [';']
    out: list = []
    current: list = []
    loop_vars: dict = {}
    i = 0
    while i < len(words):
        w = words[i]
        if w in ('for', 'while', 'until') and not current:
            if w == 'for':
                var = words[i + 1]
                values = []
                k = i + 3                 # skip "VAR in"
                while k < len(words) and words[k] not in ('do', 'do;'):
                    values.append(words[k].rstrip(';'))
                    k += 1
                loop_vars[var] = values[0] if values else ''
                i = k + 1
                continue
        if w in ('do', 'done', 'then', 'fi', 'else') and not current:
            i += 1
            continue
        ends = w.endswith(';') and w not in (';',)
        token = w[:-1] if ends else w
        if token in ('&&', '||', ';', '|'):
            if current:
                out.append(current)
            current = []
        elif token:
            for var, value in loop_vars.items():
                token = token.replace(f'${var}', value).replace(f'${{{var}}}', value)
            current.append(token)
        if ends and current:
            out.append(current)
            current = []
        i += 1
    if current:
        out.append(current)
    out = [c[next((k for k, w in enumerate(c) if not _ASSIGNMENT.match(w)), len(c)):]
           for c in out]                          # VAR=value prefixes are environment
    return [c for c in out if c and c[0] not in ('do', 'done', 'then', 'fi')]


def script(blocks: Sequence[Block], *, keep_going: bool = False) -> tuple:
    """
    Return the bash script that runs the blocks in order, and its line map.

    Parameters
    ----------
    blocks : sequence of Block
        The blocks of the README and the doc pages; skipped ones are left out.
    keep_going : bool
        Report every failing command and go on (exit 1 at the end when any failed) instead
        of stopping at the first.

    Returns
    -------
    text : str
        The script: ``set -e -o pipefail``, an ERR trap naming the page and line, and for
        each command a ``$ ...`` line then the command.
    line_map : dict
        Script line -> ``page:line`` of the commands.

    """
    body: list = []          # (script text line, page:line or '')
    runnable = [b for b in blocks if b.skip is None]
    for n, block in enumerate(runnable, 1):
        body.append((f'printf "\\n--- %s, %s (block %s of %s, t = %ss)\\n" '
                     f'{shlex.quote(block.where)} {shlex.quote(block.section)} {n} '
                     f'{len(runnable)} "$SECONDS"', ''))
        for unit in units(block):
            for k, line in enumerate(unit.lines):     # one script line per printed line
                shown = '$ ' + line.strip() if k == 0 else '  ' + line.rstrip()
                body.append((f'printf "%s\\n" {shlex.quote(shown)}', ''))
            for k, line in enumerate(unit.lines):
                body.append((line, f'{unit.page}:{unit.line + k}'))
    head = ['#!/bin/bash', 'set -o pipefail' if keep_going else 'set -e -o pipefail',
            'FAILS=0']
    map_line = len(head) + 1
    head.append('')            # the MAP line, filled in below
    head.append('trap \'rc=$?; FAILS=$((FAILS + 1)); echo "readme-check: FAILED (exit $rc) '
                'at ${MAP[$LINENO]:-?}: $BASH_COMMAND" >&2\' ERR')
    line_map = {len(head) + k + 1: where for k, (_, where) in enumerate(body) if where}
    size = len(head) + len(body) + 2
    entries = ' '.join(shlex.quote(line_map.get(k, '?')) for k in range(size))
    head[map_line - 1] = f'MAP=({entries})'
    tail = ['trap - ERR', 'test "$FAILS" -eq 0']
    text = '\n'.join(head + [t for t, _ in body] + tail) + '\n'
    return text, line_map


def _clean_env() -> dict:
    """Return this environment without an activated venv (the clone makes its own)."""
    env = dict(os.environ)
    venv = env.pop('VIRTUAL_ENV', None)
    if venv:
        keep = [p for p in env.get('PATH', '').split(os.pathsep)
                if not p.startswith(str(Path(venv)))]
        env['PATH'] = os.pathsep.join(keep)
    for key in ('PYTHONPATH', 'PYTHONHOME', 'MAKEFLAGS', 'MFLAGS', 'MAKELEVEL'):
        env.pop(key, None)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 101 + 1))
    return env


def run(repo: Path, *, keep: bool = False, workdir: Optional[Path] = None,
        keep_going: bool = False) -> int:
    """
    Clone ``repo`` and run its README's and doc pages' blocks there; 0 when all passed.

    Parameters
    ----------
    repo : Path
        The repository (its committed ``HEAD`` is what is checked).
    keep : bool
        Leave the clone in place afterwards.
    workdir : Path, optional
        Where to make the temporary folder (default: the system's).
    keep_going : bool
        Run every command even after a failure (see :func:`script`).

    Returns
    -------
    int
        0 on success, the failing command's exit status (at least 1) otherwise.

    """
    base = Path(tempfile.mkdtemp(prefix='gyro_tdc-readme-check-', dir=workdir))
    clone = base / 'clone'
    start = time.monotonic()
    try:
        dirty = subprocess.run(['git', '-C', str(repo), 'status', '--porcelain',
                                '--untracked-files=no'], capture_output=True, text=True)
        print(f'readme-check: cloning {repo} (HEAD) into {clone}', flush=True)
        if dirty.stdout.strip():
            print('readme-check: note: uncommitted changes in the working tree are not '
                  'checked', flush=True)
        subprocess.run(['git', 'clone', '--quiet', str(repo), str(clone)], check=True)
        pages = doc_pages(clone)
        blocks = doc_blocks(clone)
        print(f'readme-check: pages in order: {", ".join(pages)}')
        for b in blocks:
            if b.skip is not None:
                print(f'readme-check: skip {b.where} ({b.section}): {b.skip}')
        runnable = [b for b in blocks if b.skip is None]
        n_commands = sum(len(units(b)) for b in runnable)
        print(f'readme-check: {len(blocks)} bash blocks in {len(pages)} pages, '
              f'{len(runnable)} to run ({n_commands} commands), '
              f'{len(blocks) - len(runnable)} skipped', flush=True)
        text, _ = script(blocks, keep_going=keep_going)
        path = base / 'readme.sh'
        path.write_text(text, encoding='utf-8')
        rc = subprocess.run(['bash', str(path)], cwd=clone, env=_clean_env(),
                            stdin=subprocess.DEVNULL).returncode
        minutes = (time.monotonic() - start) / 60.0
        if rc == 0:
            print(f'\nreadme-check: PASSED: {n_commands} commands in {len(runnable)} blocks, '
                  f'in order, in a fresh clone ({minutes:.1f} min)', flush=True)
        else:
            print(f'\nreadme-check: FAILED after {minutes:.1f} min (see the line above)',
                  file=sys.stderr, flush=True)
        return rc
    finally:
        if keep:
            print(f'readme-check: clone kept in {clone}')
        else:
            shutil.rmtree(base, ignore_errors=True)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Parse the arguments and run the check (see the module docstring)."""
    parser = argparse.ArgumentParser(
        prog='readme_check.py',
        description='Run every command block of README.md and doc/, in order, in a fresh '
                    'clone.')
    parser.add_argument('--repo', type=Path, default=ROOT,
                        help='repository to clone (default: this one)')
    parser.add_argument('--keep', action='store_true', help='keep the clone afterwards')
    parser.add_argument('--workdir', type=Path, default=None,
                        help='folder for the temporary clone (default: the system temp)')
    parser.add_argument('--keep-going', action='store_true',
                        help='run every command even after a failure, report each (for '
                             'diagnosis; make readme-check stops at the first)')
    parser.add_argument('--print-script', action='store_true',
                        help='print the bash script of the README and doc pages and exit')
    args = parser.parse_args(argv)
    if args.print_script:
        text, _ = script(doc_blocks(args.repo))
        sys.stdout.write(text)
        return 0
    return run(args.repo, keep=args.keep, workdir=args.workdir, keep_going=args.keep_going)


if __name__ == '__main__':
    sys.exit(main())
