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
A node's parameter table (:mod:`gyro_tdc.base.paramspec`): ROS descriptors, or --help.

:func:`declare` declares the table on a node and returns the values; :func:`print_help`
answers ``--help`` / ``-h`` from the same table before ``rclpy.init``, so asking a node for
its parameters never starts it.
"""

from __future__ import annotations

import sys
from typing import Any, Sequence

from gyro_tdc.base import format_help, help_requested, ParamSpec
from gyro_tdc.errors import ConfigError
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

__all__ = ['declare', 'descriptor', 'print_help']


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """Return the ROS descriptor of one parameter: description, read-only, choices, range."""
    d = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    if spec.choices:
        d.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    if spec.lo is not None and spec.hi is not None:
        if isinstance(spec.default, float):
            d.floating_point_range = [FloatingPointRange(
                from_value=float(spec.lo), to_value=float(spec.hi), step=0.0)]
        elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
            d.integer_range = [IntegerRange(
                from_value=int(spec.lo), to_value=int(spec.hi), step=1)]
    return d


def declare(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """
    Declare every parameter of ``specs`` on ``node``; return ``{name: value}`` after overrides.

    Raises
    ------
    ConfigError
        A string parameter is not one of its choices (a ValueError).

    """
    values = {}
    for spec in specs:
        value = node.declare_parameter(spec.name, spec.default, descriptor(spec)).value
        if spec.choices and value not in spec.choices:
            raise ConfigError(f'Expected parameter `{spec.name}` to be one of '
                              f'{", ".join(spec.choices)}, got {value!r}.')
        values[spec.name] = value
    return values


def print_help(prog: str, doc: str, specs: Sequence[ParamSpec], args: Sequence[str] | None,
               *, epilog: str = '') -> bool:
    """
    Print a node's ``--help`` on stdout when its command line ``args`` asks for it.

    The summary is the first two paragraphs of ``doc`` (the node module's docstring);
    ``args`` None reads ``sys.argv``. Returns True when help was printed: the node must not
    start.
    """
    if not help_requested(sys.argv if args is None else args):
        return False
    text = '\n\n'.join(' '.join(p.split()) for p in doc.strip().split('\n\n')[:2])
    print(format_help(prog, text, specs, epilog=epilog))
    return True
