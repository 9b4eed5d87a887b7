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

A node's parameters are one tuple of :class:`ParamSpec` rows. From it
:func:`gyro_tdc.nodes._params.declare` declares them with their ROS descriptors,
:func:`spec_dataclass` builds the frozen dataclass the node reads them into, and the pure
logic builds its own settings from the rows it takes (the compensator's
:class:`gyro_tdc.compensation_logic.Policy` from the rows marked ``policy``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, make_dataclass
import math
from typing import Any, Callable, Mapping, Sequence

__all__ = ['ParamSpec', 'spec_dataclass']


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
        elif type(self.default) is float and self.lo is not None:
            if self.lo > 0:
                if not (math.isfinite(value) and value > 0.0):
                    raise ValueError(f'Expected `{self.name}` > 0 {self.unit}, got {value!r}.')
            elif not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'Expected `{self.name}` >= 0, got {value!r}.')


def spec_dataclass(name: str, specs: Sequence[ParamSpec], summary: str, *, module: str,
                   check: bool = False,
                   methods: Mapping[str, Callable[..., Any]] | None = None) -> type:
    """
    Build the frozen dataclass of a parameter table: one field per row, default included.

    Parameters
    ----------
    name : str
        Class name.
    specs : sequence of ParamSpec
        The rows, in field order.
    summary : str
        First line of the docstring; a numpydoc ``Parameters`` section follows from the rows.
    module : str
        Module the class belongs to (``__name__`` of the caller).
    check : bool
        Check every value with :meth:`ParamSpec.check` on construction.
    methods : mapping of str to callable, optional
        Methods to add to the class.

    Returns
    -------
    type
        The dataclass.

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
    rows = ''.join(f'{s.name} : {type(s.default).__name__}\n    {s.description}\n'
                   for s in specs)
    cls.__doc__ = f'{summary}\n\nParameters\n----------\n{rows}'
    return cls
