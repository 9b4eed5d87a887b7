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

"""Competing CPU load for tests and benches: child processes spinning."""

import contextlib
import subprocess
import sys
from typing import Iterator

__all__ = ['cpu_hogs']


@contextlib.contextmanager
def cpu_hogs(count: int = 1) -> Iterator[list[subprocess.Popen]]:
    """Keep ``count`` cores busy for the block (child processes spinning); kill them after."""
    hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(count)]
    try:
        yield hogs
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
