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
Parameter tables as plain data: each node parameter spelled once, free of rclpy.

A node's parameters are one tuple of :class:`ParamSpec` rows, from which the node declares
them, :func:`spec_dataclass` builds the frozen dataclass it reads them into and
:func:`format_help` prints its ``--help``. See ``doc/internals/base.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, make_dataclass
import math
import re
import textwrap
from typing import Any, Callable, Mapping, Sequence

__all__ = ['format_help', 'help_requested', 'INPUT_FRAMES', 'ParamSpec', 'spec_dataclass',
           'TEMPERATURE_QUIRKS']

#: Width of the ``--help`` text [columns].
HELP_WIDTH = 79

#: Axes of a driver's gyro (``input_frame``, ``--input-frame``): REP 103's FLU (x forward,
#: y left, z up) or PX4's FRD (z down), turned to FLU. Here because the compensator's table
#: (runtime) and the bag reader (data) both offer them.
INPUT_FRAMES = ('flu', 'frd')
#: Temperature encodings of drivers, undone before use (``temperature_quirk``; '' none):
#: the BNO055's register read as an unsigned byte (flynneva/bno055: below 0 degC it reads
#: 256 + T) and the SBG legacy IMU log's temperature divided by 256 (sbg_ros2_driver).
TEMPERATURE_QUIRKS = ('', 'bno055_unsigned_byte', 'sbg_legacy_div256')


@dataclass(frozen=True)
class ParamSpec:
    """
    One parameter: name, default, what it means, its unit and its valid range.

    Parameters
    ----------
    name : str
        Parameter name.
    default : bool, int, float or str
        Default value; its type is the parameter's type.
    description : str
        What it does, ending with the unit in brackets where there is one.
    lo, hi : float or int, optional
        Inclusive range the node declares (numbers only). The pure logic checks only
        what ``lo`` says of the sign: > 0 when ``lo`` > 0, else >= 0 (and finite).
    choices : sequence of str, optional
        Allowed string values.
    read_only : bool
        True when a change needs a restart.
    policy : bool
        True when the field of the same name of the compensator's ``Policy`` takes it.

    """

    name: str
    default: Any
    description: str
    lo: float | int | None = None
    hi: float | int | None = None
    choices: Sequence[str] = ()
    read_only: bool = True
    policy: bool = False

    @property
    def unit(self) -> str:
        """Return the unit in brackets at the end of the description ('' when none)."""
        head, bracket, tail = self.description.rpartition('[')
        return tail.rstrip('].') if bracket else ''

    @property
    def meaning(self) -> str:
        """Return the description without its unit in brackets."""
        head, bracket, _ = self.description.rpartition('[')
        return head.rstrip() + '.' if bracket else self.description

    def check(self, value: Any) -> None:
        """
        Check a value the pure logic is given: one of the choices, or finite with the sign.

        Raises
        ------
        ValueError
            The value is not one of the choices, or not finite and > 0 (``lo`` > 0) or
            >= 0 (``lo`` == 0); the message names the parameter.

        """
        if self.choices:
            if value not in self.choices:
                raise ValueError(f'Expected `{self.name}` '
                                 f'{" or ".join(map(repr, self.choices))}, got {value!r}.')
        elif type(self.default) is float and self.lo is not None and not (
                math.isfinite(value) and (value > 0.0 if self.lo > 0 else value >= 0.0)):
            raise ValueError(f'Expected `{self.name}` > 0 {self.unit}, got {value!r}.'
                             if self.lo > 0 else f'Expected `{self.name}` >= 0, got {value!r}.')


def spec_dataclass(name: str, specs: Sequence[ParamSpec], summary: str, *, module: str,
                   check: bool = False,
                   methods: Mapping[str, Callable[..., Any]] | None = None) -> type:
    """
    Build the frozen dataclass ``name`` of a parameter table: one field per row, in order.

    ``summary`` is the docstring's first line; a numpydoc ``Parameters`` section follows from
    the rows. ``module`` is the caller's ``__name__``; ``check`` checks every value with
    :meth:`ParamSpec.check` on construction; ``methods`` are added to the class.
    """
    namespace = dict(methods or {})
    if check:
        def __post_init__(self: Any) -> None:
            for spec in specs:
                spec.check(getattr(self, spec.name))
        namespace['__post_init__'] = __post_init__
    cls = make_dataclass(name, [(s.name, type(s.default), field(default=s.default))
                                for s in specs], frozen=True, namespace=namespace)
    cls.__module__ = module
    rows = ''.join(f'{s.name} : {type(s.default).__name__}\n    {s.description}\n' for s in specs)
    cls.__doc__ = f'{summary}\n\nParameters\n----------\n{rows}'
    return cls


def help_requested(argv: Sequence[str]) -> bool:
    """
    Say whether a node's command line ``argv`` (program first) asks for ``-h``/``--help``.

    Only the node's own arguments count: from ``--ros-args`` to the next ``--`` (or the end)
    the arguments belong to ROS.
    """
    in_ros = False
    for arg in list(argv)[1:]:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--':
            in_ros = False
        elif not in_ros and arg in ('-h', '--help'):
            return True
    return False


def _value_text(value: Any, like: Any) -> str:
    """Return ``value`` as typed after ``-p NAME:=`` for a parameter of ``like``'s type."""
    if isinstance(like, str):
        return repr(value)
    if isinstance(like, bool):
        return str(value).lower()
    return repr(float(value)) if isinstance(like, float) else str(int(value))


def _fill(text: str, indent: str = '', subsequent: str | None = None) -> str:
    return textwrap.fill(text, HELP_WIDTH, initial_indent=indent,
                         subsequent_indent=indent if subsequent is None else subsequent,
                         break_long_words=False, break_on_hyphens=False)


def format_help(prog: str, summary: str, specs: Sequence[ParamSpec], *,
                epilog: str = '') -> str:
    """
    Return a node's ``--help`` text: usage, summary and one entry per parameter.

    Each entry gives name, type, default, unit, choices or range, whether it can be set at
    run time, and the description; lines are at most 79 columns but for long words.

    Parameters
    ----------
    prog : str
        Executable name.
    summary : str
        Paragraphs separated by a blank line (reST literals and roles are printed plain).
    specs : sequence of ParamSpec
        The node's parameter table.
    epilog : str
        A closing paragraph (parameter files...).

    """
    lines = [_fill(f'usage: {prog} [-h] [--ros-args [-p NAME:=VALUE]... '
                   '[--params-file FILE]...]', '', ' ' * (8 + len(prog))), '']
    for paragraph in summary.split('\n\n'):
        plain = re.sub(r':\w+:`~?([^`]+)`', r'\1', paragraph).replace('``', '')
        lines += [_fill(plain), '']
    lines.append('parameters (name: type, default, unit; meaning):')
    for spec in specs:
        facts = [type(spec.default).__name__, f'default {_value_text(spec.default, spec.default)}']
        if spec.unit:
            facts.append(spec.unit)
        if spec.choices:
            facts.append('one of ' + ', '.join(spec.choices))
        elif spec.lo is not None and spec.hi is not None:
            facts.append(f'{_value_text(spec.lo, spec.default)}..'
                         f'{_value_text(spec.hi, spec.default)}')
        if not spec.read_only:
            facts.append('settable at run time')
        lines.append(_fill(f'{spec.name}: ' + '; '.join(facts), '  ', ' ' * 4))
        lines.append(_fill(spec.meaning, ' ' * 6))
    if epilog:
        lines += ['', _fill(epilog)]
    return '\n'.join(lines)
