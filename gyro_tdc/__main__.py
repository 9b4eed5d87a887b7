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
Run a gyro_tdc command: ``gyro-tdc <command> [args...]`` or ``python -m gyro_tdc <command>``.

``gyro-tdc`` is the one console script the package installs besides the two ROS nodes; both
spellings run :func:`main`. The commands are listed in :mod:`gyro_tdc.cli`;
``gyro-tdc --help`` prints them.
"""

from __future__ import annotations

import os
import sys
from typing import Optional, Sequence

from gyro_tdc import __version__
from gyro_tdc.cli import COMMANDS, CommandUnavailable, format_help, load_main, PROG


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Run the command named by the first argument and return its exit code.

    The rest of the arguments go to ``main`` of the command's module in :mod:`gyro_tdc.cli`.

    Parameters
    ----------
    argv : sequence of str, optional
        Command name followed by its arguments; ``sys.argv[1:]`` when omitted.

    Returns
    -------
    int
        The command's exit code; 0 for ``--help``/``--version``, 2 for a missing or unknown
        command (after one line on stderr), 1 when the command is not installed.

    """
    # Before numpy loads OpenBLAS: its idle threads then sleep after ~2^16 cycles instead of
    # spinning ~2^28 after every call (a trainer's CPU spent on nothing, the results the same).
    os.environ.setdefault('OPENBLAS_THREAD_TIMEOUT', '16')
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        sys.stderr.write(format_help(PROG))
        return 2
    name, rest = args[0], args[1:]
    if name in ('-h', '--help', 'help'):
        sys.stdout.write(format_help(PROG))
        return 0
    if name == '--version':
        print(f'gyro_tdc {__version__}')
        return 0
    if name not in COMMANDS:
        print(f'{PROG}: error: unknown command {name!r}; expected one of: '
              f'{", ".join(COMMANDS)} (see {PROG} --help)', file=sys.stderr)
        return 2
    try:
        command_main = load_main(name)
    except CommandUnavailable as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    code = command_main(rest)
    return 0 if code is None else int(code)


if __name__ == '__main__':
    sys.exit(main())
