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

"""``gyro-tdc`` (``python -m gyro_tdc``): the command list, --version, dispatch, exit codes."""

from __future__ import annotations

import os
import subprocess
import sys

from gyro_tdc import __version__
from gyro_tdc.__main__ import main
from gyro_tdc.cli import COMMANDS
import pytest


def test_no_command_prints_the_list_on_stderr_and_exits_2(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err
    assert all(name in err for name in COMMANDS)


@pytest.mark.parametrize('flag', ['-h', '--help', 'help'])
def test_help_lists_every_command_on_stdout(capsys, flag):
    assert main([flag]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in COMMANDS)


def test_version_and_an_unknown_command(capsys):
    assert main(['--version']) == 0
    assert capsys.readouterr().out.strip() == f'gyro_tdc {__version__}'
    assert main(['frobnicate']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown command 'frobnicate'" in err[0] and 'simulate' in err[0]


def test_a_command_gets_the_rest_and_its_exit_code_is_returned(capsys):
    assert main(['simulate', '--help']) == 0
    assert capsys.readouterr().out.startswith('usage: gyro-tdc simulate ')
    assert main(['simulate', '--scenario', 'no_such_scenario', '--out', 'x']) == 2
    assert capsys.readouterr().err.startswith('gyro-tdc simulate: error: ')


def test_openblas_idle_threads_sleep_unless_the_environment_says_otherwise(monkeypatch, capsys):
    monkeypatch.setenv('OPENBLAS_THREAD_TIMEOUT', '28')
    assert main(['--version']) == 0
    assert os.environ['OPENBLAS_THREAD_TIMEOUT'] == '28'        # the user's own value
    monkeypatch.delenv('OPENBLAS_THREAD_TIMEOUT')
    assert main(['--version']) == 0
    assert os.environ['OPENBLAS_THREAD_TIMEOUT'] == '16'
    # Set in time: OpenBLAS reads it when numpy loads it, after the entry point is imported.
    out = subprocess.run([sys.executable, '-c', 'import sys, gyro_tdc.__main__; '
                          "print('numpy' in sys.modules)"], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == 'False'
