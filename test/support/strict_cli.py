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

"""The installed ``gyro-tdc`` run as a user runs it, with every Python warning an error."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

#: The console script pip installed beside this interpreter (the real entry point).
GYRO_TDC = Path(sys.executable).with_name('gyro-tdc')


def strict_cli(*argv, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """Run the installed ``gyro-tdc`` with every warning an error; return the process."""
    env = dict(os.environ, PYTHONWARNINGS='error', OPENBLAS_NUM_THREADS='1')
    return subprocess.run([str(GYRO_TDC), *map(str, argv)], capture_output=True, text=True,
                          timeout=timeout, env=env)
