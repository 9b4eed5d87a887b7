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

"""Declare parameters once, with descriptors, from a table of specs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node


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
        Inclusive range (numbers only).
    choices : sequence of str, optional
        Allowed string values (checked by the node, listed in the descriptor).
    read_only : bool
        True when a change needs a restart.

    """

    name: str
    default: Any
    description: str
    lo: float | int | None = None
    hi: float | int | None = None
    choices: Sequence[str] = ()
    read_only: bool = True

    def descriptor(self) -> ParameterDescriptor:
        """Return the ROS descriptor of this parameter."""
        d = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.choices:
            d.additional_constraints = 'one of: ' + ', '.join(self.choices)
        if self.lo is not None and self.hi is not None:
            if isinstance(self.default, float):
                d.floating_point_range = [FloatingPointRange(
                    from_value=float(self.lo), to_value=float(self.hi), step=0.0)]
            elif isinstance(self.default, int) and not isinstance(self.default, bool):
                d.integer_range = [IntegerRange(
                    from_value=int(self.lo), to_value=int(self.hi), step=1)]
        return d


def declare(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """
    Declare every parameter of ``specs`` on ``node`` and return their values.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    specs : sequence of ParamSpec
        The parameter table.

    Returns
    -------
    dict
        ``{name: value}`` after overrides (parameter files, ``parameter_overrides``).

    Raises
    ------
    ValueError
        A string parameter is not one of its choices.

    """
    values = {}
    for spec in specs:
        value = node.declare_parameter(spec.name, spec.default, spec.descriptor()).value
        if spec.choices and value not in spec.choices:
            raise ValueError(f'Expected parameter `{spec.name}` to be one of '
                             f'{", ".join(spec.choices)}, got {value!r}.')
        values[spec.name] = value
    return values
