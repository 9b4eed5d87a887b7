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
Command registry of ``gyro-tdc <command>`` (also ``python -m gyro_tdc <command>``).

Every command lives in ``gyro_tdc.cli.<name>`` and exposes ``main(argv=None) -> int`` (0 on
success, 2 on bad input after one line on stderr); command modules are imported only when
they run, so the listing works while one is broken. See ``doc/internals/cli.md``.
"""

from __future__ import annotations

import importlib
from typing import Callable, NamedTuple, Optional, Sequence

__all__ = ['COMMANDS', 'Command', 'CommandUnavailable', 'PROG', 'format_help', 'load_main']

#: The program name every command's usage, help and error lines start with.
PROG = 'gyro-tdc'


class Command(NamedTuple):
    """One sub-command: its name, the module holding ``main(argv=None) -> int``, its help line."""

    name: str
    module: str
    help: str


COMMANDS: dict[str, Command] = {n: Command(n, f'gyro_tdc.cli.{n}', text) for n, text in (
    ('simulate', 'simulate a thermal-chamber run of a gyro and write it to a rosbag2 bag'),
    ('train', 'identify a compensation model from recorded bags and save it as YAML'),
    ('evaluate', 'score models on held-out bags (bias stability, RMS, Allan deviation)'),
    ('discover', 'find which thermal effect a model is still missing'),
    ('demo', 'the whole pipeline on simulated data, then the two nodes live'),
    ('fleet', 'calibrate many IMUs from a manifest on Dask, with fleet-outlier flags'),
    ('export', 'write a model as PX4 or ArduPilot thermal-calibration parameters, or a '
               "learn_file's learned model as a model file"))}


class CommandUnavailable(LookupError):
    """A registered command's module is not installed (a packaging fault, not bad input)."""


def format_help(prog: str = PROG) -> str:
    """
    Return the top-level usage text listing every command and its one-line help.

    Parameters
    ----------
    prog : str
        Program name shown in the usage line.

    Returns
    -------
    str
        Multi-line help text ending with a newline.

    """
    width = max(map(len, COMMANDS))
    lines = [f'usage: {prog} <command> [args...]', '',
             'Temperature drift compensation for MEMS gyroscopes.', '', 'commands:']
    lines += [f'  {c.name:<{width}}  {c.help}' for c in COMMANDS.values()]
    lines += ['', f'Run "{prog} <command> --help" for the options of a command '
              f'("python -m gyro_tdc" works the same as "{prog}").']
    return '\n'.join(lines) + '\n'


def load_main(name: str) -> Callable[[Optional[Sequence[str]]], Optional[int]]:
    """
    Import the module of command ``name`` (a key of ``COMMANDS``); return its ``main(argv)``.

    An ``ImportError`` raised by a module the command itself imports propagates unchanged.

    Raises
    ------
    KeyError
        If ``name`` is not a registered command.
    CommandUnavailable
        If the command's module (or its ``main``) does not exist in this installation.

    """
    command = COMMANDS[name]
    try:
        module = importlib.import_module(command.module)
    except ModuleNotFoundError as exc:
        if exc.name == command.module:
            raise CommandUnavailable(f'command {name!r} is not available: module '
                                     f'{command.module} is not installed') from exc
        raise
    main = getattr(module, 'main', None)
    if not callable(main):
        raise CommandUnavailable(
            f'command {name!r} is not available: {command.module} has no main(argv) function')
    return main
