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
The README's commands run as written: every program exists, every option parses.

Fast checks over every ```` ```bash ```` block (``readme_check.readme_blocks``): programs,
options, outputs under ``out/`` with one folder per section, robot-only blocks marked; the
demo's step list; two blocks run end to end in ``tmp_path``: "Model file" (the shipped
``model_id`` is rebuilt) and "Real data" (the figures the README quotes are printed).
``make readme-check`` runs every block for real in a fresh clone.
"""

from __future__ import annotations

import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

from gyro_tdc.cli import COMMANDS, demo as demo_cli, load_main
from gyro_tdc.model.modelfile import load_model
import pytest
import readme_check
from readme_check import commands, readme_blocks, units

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / 'README.md').read_text(encoding='utf-8')
BLOCKS = readme_blocks(README)
RUNNABLE = [b for b in BLOCKS if b.skip is None]
BIN = Path(sys.executable).parent
OUTPUT_OPTIONS = ('--out', '--json', '--plots', '--export', '--report')


def _commands(block):
    return [(u.line, argv) for u in units(block) for argv in commands(u)]


def _section(name):
    return next(b for b in BLOCKS if b.section == name)


def _parser(name):
    """Return the argparse parser of a gyro-tdc command (its module's build_parser)."""
    load_main(name)                                     # imports the module
    return sys.modules[COMMANDS[name].module].build_parser()


def _make_targets():
    text = (ROOT / 'Makefile').read_text(encoding='utf-8')
    return set(re.findall(r'^([A-Za-z][\w-]*):', text, flags=re.M))


def test_blocks_are_found_and_robot_blocks_are_marked():
    assert len(BLOCKS) >= 10 and len(RUNNABLE) >= 7
    for b in BLOCKS:
        text = '\n'.join(b.lines)
        needs_ros = re.search(r'^\s*(ros2 |colcon |sudo apt|apt-get |rosdep )', text, re.M)
        if needs_ros:
            assert b.skip is not None and b.skip.startswith('robot only'), (b.line, text)
        if b.skip is not None:
            assert len(b.skip.split(':', 1)[-1].strip()) > 10, f'no reason given: {b.skip}'
    # The first runnable block creates and activates the venv every later block uses.
    first = [argv for _, argv in _commands(RUNNABLE[0])]
    assert first[:2] == [['make', 'venv'], ['.', '.venv/bin/activate']]


@pytest.mark.parametrize('block', RUNNABLE, ids=lambda b: f'README:{b.line}')
def test_every_program_exists_and_every_option_parses(block, capsys):
    for line, argv in _commands(block):
        prog, args = argv[0], argv[1:]
        where = f'README.md:{line}: {" ".join(argv)}'
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
                assert value.startswith('out/'), f'README.md:{line}: {opt} {value}'
                folder = value.split('/')[1]
                owner.setdefault(folder, block.section)
                assert owner[folder] == block.section, \
                    f'out/{folder} is written by "{owner[folder]}" and "{block.section}"'
    assert len(owner) >= 5, owner


def test_commands_use_the_one_entry_point_and_no_outside_paths():
    for block in BLOCKS:
        text = '\n'.join(block.lines)
        assert 'python -m gyro_tdc' not in text, block.line
        assert '/tmp/' not in text and '../shared' not in text, block.line
    assert 'DESIGN.md' not in README
    assert not re.search(r'^(simulate|train|evaluate|discover|demo|fleet) ', README, re.M)


def test_the_demo_steps_in_the_readme_are_the_demos():
    section = README.split('\n## The demo\n', 1)[1].split('\n## ', 1)[0]
    titles = [' '.join(t.split()) for t in re.findall(r'^\d+\. \*\*(.+?)\*\*', section,
                                                      flags=re.M | re.S)]
    assert titles == [' '.join(t.split()) for t in demo_cli.STEPS]
    assert f'[i/{len(demo_cli.STEPS)}]' in section


def test_the_checker_stops_at_the_first_failing_command_and_names_its_line(tmp_path):
    repo = tmp_path / 'repo'
    repo.mkdir()
    (repo / 'README.md').write_text(
        '# t\n\n## One\n\n```bash\necho first > made.txt\n```\n\n## Two\n\n'
        '```bash\n# robot only: needs ros2\nros2 run x y\n```\n\n```bash\n'
        'for k in a b; do\n  test -f made.txt\ndone\nfalse   # this fails\necho never\n```\n')
    env = dict(os.environ, GIT_AUTHOR_NAME='t', GIT_AUTHOR_EMAIL='t@t', GIT_COMMITTER_NAME='t',
               GIT_COMMITTER_EMAIL='t@t')
    for cmd in (['git', 'init', '-q'], ['git', 'add', 'README.md'],
                ['git', 'commit', '-q', '-m', 'readme']):
        subprocess.run(cmd, cwd=repo, env=env, check=True)
    done = subprocess.run([sys.executable, readme_check.__file__, '--repo', str(repo),
                           '--workdir', str(tmp_path)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr
    assert 'skip README.md:12 (Two): robot only: needs ros2' in done.stdout
    assert '$ echo first > made.txt' in done.stdout and 'never' not in done.stdout
    assert 'readme-check: FAILED (exit 1) at README.md:20: false' in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ['repo']      # clone removed
    # --keep-going (diagnosis) reports the failure and runs the rest.
    done = subprocess.run([sys.executable, readme_check.__file__, '--repo', str(repo),
                           '--workdir', str(tmp_path), '--keep-going'], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 1 and 'at README.md:20: false' in done.stderr
    assert '$ echo never' in done.stdout and '\nnever\n' in done.stdout


def _run_block(block, cwd, timeout):
    """Run a README block with bash in ``cwd``, the venv first on PATH; return its output."""
    env = dict(os.environ, PATH=f'{BIN}{os.pathsep}{os.environ["PATH"]}',
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    text = 'set -e -o pipefail\n' + '\n'.join(block.lines) + '\n'
    done = subprocess.run(['bash', '-c', text], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_model_file_commands_rebuild_the_shipped_model_id(tmp_path):
    block = _section('Model file')
    out = _run_block(block, tmp_path, timeout=600)
    shipped = load_model(ROOT / 'config' / 'models' / 'l3gd20_modified.yaml')
    built = load_model(tmp_path / 'out' / 'model' / 'l3gd20_modified.yaml')
    assert built.model_id == shipped.model_id
    assert f'(model_id {shipped.model_id})' in out
    section = README.split('\n## Model file\n', 1)[1].split('\n## ', 1)[0]
    assert f'model_id `{shipped.model_id}`' in ' '.join(section.split())
    # Nothing but out/ was written: the tracked file is never overwritten by the commands.
    assert sorted(p.name for p in tmp_path.iterdir()) == ['out']


def test_real_data_block_prints_the_figures_the_readme_quotes(tmp_path):
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
    section = README.split('\n## Real data\n', 1)[1].split('\n## ', 1)[0]
    assert 'gap 0.003377\n  deg/s = 2.85 x noise floor' in section or \
        'gap 0.003377 deg/s = 2.85 x noise floor' in ' '.join(section.split())
    for name in ('pan', 'pan_discovery.json', 'pan_datasheet.yaml', 'pan_holdout.json'):
        assert (tmp_path / 'out' / 'real' / name).exists(), name
