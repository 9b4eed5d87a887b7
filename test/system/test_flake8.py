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

"""ament_flake8 on the package, tests, benches and setup.py; setup.cfg has the same settings."""

import multiprocessing
from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

ROOT = Path(__file__).resolve().parents[2]
CHECKED = [ROOT / name for name in ('gyro_tdc', 'test', 'bench', 'tools', 'setup.py')
           if (ROOT / name).exists()]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    # ament_flake8 walks the working directory for AMENT_IGNORE markers: keep it on the repo.
    monkeypatch.chdir(ROOT)
    # flake8 checks files in a multiprocessing pool, which forks by default on Linux. Earlier
    # tests in this process may have left rclpy/DDS threads behind, and fork() in a
    # multi-threaded process can deadlock the child: start the workers from a forkserver.
    monkeypatch.setattr(multiprocessing, 'Pool', multiprocessing.get_context('forkserver').Pool)
    rc, errors = main_with_errors(argv=[str(p) for p in CHECKED])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)
