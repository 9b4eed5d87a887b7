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
The ``gyro-tdc-cli`` directive: ``gyro-tdc --help`` and every command's ``--help``.

The commands are the registry :data:`gyro_tdc.cli.COMMANDS`; each command module's
``build_parser()`` gives the parser, whose ``format_help()`` is what ``gyro-tdc <command>
--help`` prints. Nothing is run. The help is formatted 92 columns wide, whatever the
terminal of the build.
"""

from __future__ import annotations

import importlib
import os
from typing import Any

from gyro_tdc_docs_util import escape, GeneratedDirective, heading

#: Width argparse formats the help to [columns].
WIDTH = 92


def command_help(module_name: str) -> str:
    """
    Return the ``--help`` text of a command module's parser, ``WIDTH`` columns wide.

    Parameters
    ----------
    module_name : str
        Dotted module holding ``build_parser() -> argparse.ArgumentParser``.

    Returns
    -------
    str
        The parser's ``format_help()``.

    """
    module = importlib.import_module(module_name)
    build = getattr(module, 'build_parser', None)
    if not callable(build):
        raise ValueError(f'Expected {module_name}.build_parser(), the parser of the '
                         'command; it has none.')
    saved = os.environ.get('COLUMNS')
    os.environ['COLUMNS'] = str(WIDTH)
    try:
        return build().format_help()
    finally:
        if saved is None:
            del os.environ['COLUMNS']
        else:
            os.environ['COLUMNS'] = saved


def _block(text: str) -> list[str]:
    return ['.. code-block:: text', ''] + ['   ' + line for line in text.splitlines()] + ['']


class CliDirective(GeneratedDirective):
    """``.. gyro-tdc-cli::``: the top-level help, then one section per registered command."""

    def generate(self) -> list[str]:
        from gyro_tdc.cli import COMMANDS, format_help, PROG
        import gyro_tdc.cli
        self.env.note_dependency(gyro_tdc.cli.__file__)
        lines = [f'``{PROG} --help``:', ''] + _block(format_help(PROG))
        for command in COMMANDS.values():
            module = importlib.import_module(command.module)
            self.env.note_dependency(module.__file__)
            lines += heading(f'{PROG} {command.name}', '-')
            lines += [escape(command.help[:1].upper() + command.help[1:]) + '.',
                      f'(:py:mod:`{command.module}`)', '']
            lines += _block(command_help(command.module))
        return lines


def setup(app: Any) -> dict[str, Any]:
    """Register the directive."""
    app.add_directive('gyro-tdc-cli', CliDirective)
    return {'version': '1', 'parallel_read_safe': True, 'parallel_write_safe': True}
