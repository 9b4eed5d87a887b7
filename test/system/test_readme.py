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
The commands of the README and the doc pages run as written: programs exist, options parse.

Fast checks over every ```` ```bash ```` block of ``README.md`` and of every page under
``doc/`` (``readme_check.doc_blocks``): programs, options, outputs under ``out/`` with one
folder per section, robot-only blocks marked; the demo's step list; two blocks run end to end
in ``tmp_path``: the shipped model's rebuild (doc/model_file.md, "The shipped model": the
rebuilt model equals the shipped one numerically, and by id where it is bit-identical) and
"Real data" (doc/results.md: the figures the page quotes are printed). ``make readme-check``
runs every block for real in a fresh clone.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

from gyro_tdc.cli import COMMANDS, demo as demo_cli, load_main
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
import readme_check
from readme_check import commands, doc_blocks, doc_pages, readme_blocks, units

ROOT = Path(__file__).resolve().parents[2]
PAGES = doc_pages(ROOT)
TEXTS = {page: (ROOT / page).read_text(encoding='utf-8') for page in PAGES}
README = TEXTS['README.md']
BLOCKS = doc_blocks(ROOT)
RUNNABLE = [b for b in BLOCKS if b.skip is None]
BIN = Path(sys.executable).parent
OUTPUT_OPTIONS = ('--out', '--json', '--plots', '--export', '--report')


def _commands(block):
    return [(u.line, argv) for u in units(block) for argv in commands(u)]


def _section_text(name):
    """Return ``(page, text)`` of the one ``## name`` section among the README and doc pages."""
    found = [(page, text.split(f'\n## {name}\n', 1)[1].split('\n## ', 1)[0])
             for page, text in TEXTS.items() if f'\n## {name}\n' in text]
    assert len(found) == 1, f'section "{name}" in {[p for p, _ in found] or "no page"}'
    return found[0]


def _section(name):
    """Return the first bash block of the one ``## name`` section of any page."""
    page, _ = _section_text(name)
    return next(b for b in BLOCKS if b.page == page and b.section == name)


def _parser(name):
    """Return the argparse parser of a gyro-tdc command (its module's build_parser)."""
    load_main(name)                                     # imports the module
    return sys.modules[COMMANDS[name].module].build_parser()


def _make_targets():
    text = (ROOT / 'Makefile').read_text(encoding='utf-8')
    return set(re.findall(r'^([A-Za-z][\w-]*):', text, flags=re.M))


def test_every_doc_page_is_walked_readme_first():
    assert PAGES[0] == 'README.md'
    on_disk = {p.relative_to(ROOT).as_posix() for p in (ROOT / 'doc').rglob('*')
               if p.suffix in ('.md', '.rst') and '_ext' not in p.parts}
    assert set(PAGES[1:]) == on_disk and len(PAGES) == len(set(PAGES))
    # The site's reading order: the index, then its toctree, each page before its children.
    walked = [p for p in PAGES if p in ('doc/index.rst', 'doc/getting_started.md',
                                        'doc/calibrate_chamber.md', 'doc/discovery.md',
                                        'doc/results.md', 'doc/real_data.md')]
    assert walked == ['doc/index.rst', 'doc/getting_started.md', 'doc/calibrate_chamber.md',
                      'doc/discovery.md', 'doc/results.md', 'doc/real_data.md']
    assert sum(1 for b in BLOCKS if b.page != 'README.md') >= 10
    assert len(README.splitlines()) <= 200


def test_blocks_are_found_and_robot_blocks_are_marked():
    assert len(BLOCKS) >= 10 and len(RUNNABLE) >= 7
    for b in BLOCKS:
        text = '\n'.join(b.lines)
        needs_ros = re.search(r'^\s*(ros2 |colcon |sudo apt|apt-get |rosdep )', text, re.M)
        if needs_ros:
            assert b.skip is not None and b.skip.startswith('robot only'), (b.where, text)
        if b.skip is not None:
            assert len(b.skip.split(':', 1)[-1].strip()) > 10, f'no reason given: {b.skip}'
    # The first runnable block (the README's) creates and activates the venv every later
    # block uses.
    assert RUNNABLE[0].page == 'README.md'
    first = [argv for _, argv in _commands(RUNNABLE[0])]
    assert first[:2] == [['make', 'venv'], ['.', '.venv/bin/activate']]


def test_no_other_fence_hides_a_command_block():
    for page, text in TEXTS.items():
        fences = re.findall(r'^```(\w+)\s*$', text, flags=re.M)
        assert not set(fences) & {'sh', 'shell', 'console', 'zsh'}, (page, fences)


@pytest.mark.parametrize('block', RUNNABLE, ids=lambda b: b.where)
def test_every_program_exists_and_every_option_parses(block, capsys):
    for line, argv in _commands(block):
        prog, args = argv[0], argv[1:]
        where = f'{block.page}:{line}: {" ".join(argv)}'
        if prog == 'gyro-tdc':
            assert (BIN / 'gyro-tdc').is_file(), 'gyro-tdc is not installed in the venv'
            if args[0] in ('-h', '--help'):
                continue
            assert args[0] in COMMANDS, where
            _parser(args[0]).parse_args(args[1:])      # raises UsageError on a bad option
        elif prog == 'python':
            script = ROOT / args[0]
            assert script.is_file(), where
            if script.parts[-2] == 'tools':
                done = subprocess.run([sys.executable, str(script), '--help'],
                                      capture_output=True, text=True, timeout=120)
                assert done.returncode == 0, where
                for opt in (a.split('=')[0] for a in args[1:] if a.startswith('--')):
                    assert opt in done.stdout, (where, opt)
        elif prog == 'make':
            assert set(args) <= _make_targets(), where
        elif prog == '.':
            assert args == ['.venv/bin/activate'], where
        else:
            assert shutil.which(prog), where
    capsys.readouterr()


def test_outputs_go_under_out_one_folder_per_section():
    owner: dict = {}
    for block in RUNNABLE:
        for line, argv in _commands(block):
            for opt, value in zip(argv, argv[1:]):
                if opt not in OUTPUT_OPTIONS:
                    continue
                assert value.startswith('out/'), f'{block.page}:{line}: {opt} {value}'
                folder = value.split('/')[1]
                section = f'{block.page} "{block.section}"'
                owner.setdefault(folder, section)
                assert owner[folder] == section, \
                    f'out/{folder} is written by {owner[folder]} and {section}'
    assert len(owner) >= 5, owner


def test_commands_use_the_one_entry_point_and_no_outside_paths():
    bare = re.compile(r'^\s*(simulate|train|evaluate|discover|demo|fleet) ', re.M)
    for block in BLOCKS:
        text = '\n'.join(block.lines)
        assert 'python -m gyro_tdc' not in text, block.where
        assert '/tmp/' not in text and '../shared' not in text, block.where
        assert not bare.search(text), block.where         # a command without gyro-tdc
    for page, text in TEXTS.items():
        assert 'DESIGN.md' not in text, page
    assert not re.search(r'^(simulate|train|evaluate|discover|demo|fleet) ', README, re.M)


def test_the_demo_steps_in_the_docs_are_the_demos():
    _, section = _section_text('The demo')
    titles = [' '.join(t.split()) for t in re.findall(r'^\d+\. \*\*(.+?)\*\*', section,
                                                      flags=re.M | re.S)]
    assert titles == [' '.join(t.split()) for t in demo_cli.STEPS]
    assert f'[i/{len(demo_cli.STEPS)}]' in section


def _git_repo(repo, files):
    """Write ``files`` ({path: text}) into a new git repository at ``repo`` and commit them."""
    for name, text in files.items():
        (repo / name).parent.mkdir(parents=True, exist_ok=True)
        (repo / name).write_text(text)
    env = dict(os.environ, GIT_AUTHOR_NAME='t', GIT_AUTHOR_EMAIL='t@t', GIT_COMMITTER_NAME='t',
               GIT_COMMITTER_EMAIL='t@t')
    for cmd in (['git', 'init', '-q'], ['git', 'add', '.'],
                ['git', 'commit', '-q', '-m', 'readme']):
        subprocess.run(cmd, cwd=repo, env=env, check=True)


def _check(repo, tmp_path, *options):
    return subprocess.run([sys.executable, readme_check.__file__, '--repo', str(repo),
                           '--workdir', str(tmp_path), *options], capture_output=True,
                          text=True, timeout=120)


def test_the_checker_stops_at_the_first_failing_command_and_names_its_line(tmp_path):
    repo = tmp_path / 'repo'
    repo.mkdir()
    _git_repo(repo, {'README.md':
                     '# t\n\n## One\n\n```bash\necho first > made.txt\n```\n\n## Two\n\n'
                     '```bash\n# robot only: needs ros2\nros2 run x y\n```\n\n```bash\n'
                     'for k in a b; do\n  test -f made.txt\ndone\nfalse   # this fails\n'
                     'echo never\n```\n'})
    done = _check(repo, tmp_path)
    assert done.returncode == 1, done.stdout + done.stderr
    assert 'skip README.md:12 (Two): robot only: needs ros2' in done.stdout
    assert '$ echo first > made.txt' in done.stdout and 'never' not in done.stdout
    assert 'readme-check: FAILED (exit 1) at README.md:20: false' in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ['repo']      # clone removed
    # --keep-going (diagnosis) reports the failure and runs the rest.
    done = _check(repo, tmp_path, '--keep-going')
    assert done.returncode == 1 and 'at README.md:20: false' in done.stderr
    assert '$ echo never' in done.stdout and '\nnever\n' in done.stdout


def test_the_checker_walks_the_doc_pages_after_the_readme_in_toctree_order(tmp_path):
    repo = tmp_path / 'repo'
    repo.mkdir()
    _git_repo(repo, {
        'README.md': '# t\n\n```bash\necho from-readme > order.txt\n```\n',
        'doc/index.rst': 'T\n=\n\n.. toctree::\n   :maxdepth: 2\n\n   zeta\n   Alpha <alpha>\n',
        'doc/zeta.md': '# Zeta\n\n```text\n## not a heading\n```\n\n```bash\n'
                       'echo from-zeta >> order.txt\n```\n\n'
                       '```{toctree}\n:hidden:\n\nsub/child\n```\n',
        'doc/sub/child.md': '# Child\n\n## Deep\n\n```bash\necho from-child >> order.txt\n```\n',
        'doc/alpha.md': '# Alpha\n\n## Part\n\n```bash\necho from-alpha >> order.txt\n'
                        'cat order.txt\nfalse\necho after\n```\n',
        'doc/orphan.md': '# Orphan\n\n```bash\necho from-orphan\n```\n',
        'doc/_ext/x.md': '```bash\nexit 3\n```\n',
    })
    assert doc_pages(repo) == ['README.md', 'doc/index.rst', 'doc/zeta.md', 'doc/sub/child.md',
                               'doc/alpha.md', 'doc/orphan.md']
    blocks = doc_blocks(repo)
    assert [(b.where, b.section) for b in blocks] == [
        ('README.md:4', 't'), ('doc/zeta.md:8', 'Zeta'), ('doc/sub/child.md:6', 'Deep'),
        ('doc/alpha.md:6', 'Part'), ('doc/orphan.md:4', 'Orphan')]
    done = _check(repo, tmp_path)
    assert done.returncode == 1, done.stdout + done.stderr
    assert 'from-readme\nfrom-zeta\nfrom-child\nfrom-alpha\n' in done.stdout
    assert 'readme-check: FAILED (exit 1) at doc/alpha.md:8: false' in done.stderr
    assert 'after' not in done.stdout.replace('$ echo after', '')
    assert '--- doc/sub/child.md:6, Deep (block 3 of 5' in done.stdout
    done = _check(repo, tmp_path, '--keep-going')
    assert done.returncode == 1 and 'at doc/alpha.md:8: false' in done.stderr
    assert '\nfrom-orphan\n' in done.stdout
    done = _check(repo, tmp_path, '--print-script')
    assert done.returncode == 0 and done.stdout.index('from-zeta') < done.stdout.index(
        'from-alpha') < done.stdout.index('from-orphan') and 'exit 3' not in done.stdout


def test_readme_blocks_keeps_its_page_and_skips_other_fences():
    text = '# Title\n\n```yaml\n# a comment, not a heading\n```\n\n```bash\nls\n```\n'
    (block,) = readme_blocks(text, 'doc/x.md')
    assert (block.page, block.line, block.section, block.lines) == ('doc/x.md', 8, 'Title',
                                                                    ('ls',))
    assert units(block)[0].page == 'doc/x.md'


def _run_block(block, cwd, timeout):
    """Run a block with bash in ``cwd``, the venv first on PATH; return its output."""
    env = dict(os.environ, PATH=f'{BIN}{os.pathsep}{os.environ["PATH"]}',
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    text = 'set -e -o pipefail\n' + '\n'.join(block.lines) + '\n'
    done = subprocess.run(['bash', '-c', text], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def _same_value(built, shipped, where):
    """Assert two model fields agree: arrays to a relative 1e-9, other numbers to 1e-12."""
    if isinstance(shipped, np.ndarray):
        assert isinstance(built, np.ndarray), where
        assert built.shape == shipped.shape and built.dtype == shipped.dtype, where
        np.testing.assert_allclose(built, shipped, rtol=1e-9, atol=1e-15, err_msg=where)
    elif dataclasses.is_dataclass(shipped):
        assert type(built) is type(shipped), where
        for field in dataclasses.fields(shipped):
            if field.name != 'created':
                _same_value(getattr(built, field.name), getattr(shipped, field.name),
                            f'{where}.{field.name}')
    elif isinstance(shipped, dict):
        assert isinstance(built, dict) and built.keys() == shipped.keys(), where
        for key in shipped:
            _same_value(built[key], shipped[key], f'{where}.{key}')
    elif isinstance(shipped, (list, tuple)):
        assert type(built) is type(shipped) and len(built) == len(shipped), where
        for k, (a, b) in enumerate(zip(built, shipped)):
            _same_value(a, b, f'{where}[{k}]')
    elif isinstance(shipped, float) and not isinstance(built, bool):
        assert isinstance(built, (int, float)), where
        assert math.isclose(built, shipped, rel_tol=1e-12, abs_tol=1e-15), \
            f'{where}: {built!r} != {shipped!r}'
    else:
        assert built == shipped, f'{where}: {built!r} != {shipped!r}'


def _bit_identical(built, shipped):
    """Return True when every field but ``created`` is equal bit for bit, nested parts too."""
    if isinstance(shipped, np.ndarray):
        return isinstance(built, np.ndarray) and built.dtype == shipped.dtype and \
            np.array_equal(built, shipped)
    if dataclasses.is_dataclass(shipped):
        return all(_bit_identical(getattr(built, f.name), getattr(shipped, f.name))
                   for f in dataclasses.fields(shipped) if f.name != 'created')
    if isinstance(shipped, dict):
        return built.keys() == shipped.keys() and all(
            _bit_identical(built[k], shipped[k]) for k in shipped)
    if isinstance(shipped, (list, tuple)):
        return len(built) == len(shipped) and all(
            _bit_identical(a, b) for a, b in zip(built, shipped))
    return built == shipped


def test_model_file_commands_rebuild_the_shipped_model(tmp_path):
    block = _section('The shipped model')
    out = _run_block(block, tmp_path, timeout=600)
    shipped = load_model(ROOT / 'config' / 'models' / 'l3gd20_modified.yaml')
    built = load_model(tmp_path / 'out' / 'model' / 'l3gd20_modified.yaml')   # id checked
    assert f'(model_id {built.model_id})' in out
    # The same model to the last bits BLAS lets differ between CPUs (weights 7e-17 apart on
    # values of 5e-6 between two machines): every array, the features, kind, ranges, sensor,
    # thermal state, accelerometer part and training figures.
    assert built.accel is not None and shipped.accel is not None
    _same_value(built, shipped, 'model')
    # The content hash covers every bit: equal ids exactly when nothing differs (on the
    # machine that built the shipped file, with OPENBLAS_NUM_THREADS=1 as the page says).
    if _bit_identical(built, shipped):
        assert built.model_id == shipped.model_id
        assert f'(model_id {shipped.model_id})' in out
    _, section = _section_text('The shipped model')
    assert f'model_id `{shipped.model_id}`' in ' '.join(section.split())
    assert 'OPENBLAS_NUM_THREADS=1' in '\n'.join(block.lines)
    # Nothing but out/ was written: the tracked file is never overwritten by the commands.
    assert sorted(p.name for p in tmp_path.iterdir()) == ['out']


def test_real_data_block_prints_the_figures_the_docs_quote(tmp_path):
    (tmp_path / 'tools').symlink_to(ROOT / 'tools')      # the tools find data/ beside them
    block = _section('Real data')
    out = _run_block(block, tmp_path, timeout=900)
    for quoted in ('gap 0.003377 deg/s = 2.85 x noise floor', 'no missing effect found',
                   'white noise (within-burst sd at 50 Hz): 0.0153 0.0157 0.0155 deg/s',
                   '25 bursts of 249-250'):
        assert quoted in out, quoted
    slope = next(line for line in out.splitlines() if line.strip().startswith('drift/degC'))
    assert [round(float(v), 4) for v in slope.split()[1:4]] == [0.0298, -0.0141, 0.0013]
    notes = [line for line in out.splitlines() if 'confounded on this data' in line]
    corr = sorted(abs(float(re.search(r'correlation ([-+]\d\.\d+)', n).group(1)))
                  for n in notes)
    assert corr and corr[0] >= 0.89 and corr[-1] <= 0.99
    _, section = _section_text('Real data')
    assert 'gap 0.003377\n  deg/s = 2.85 x noise floor' in section or \
        'gap 0.003377 deg/s = 2.85 x noise floor' in ' '.join(section.split())
    for name in ('pan', 'pan_discovery.json', 'pan_datasheet.yaml', 'pan_holdout.json'):
        assert (tmp_path / 'out' / 'real' / name).exists(), name
