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
The ``gyro-tdc-nodes`` directive: one section per ROS 2 node, generated from its module.

A node is a module of :mod:`gyro_tdc.nodes` with a ``main`` and a ``PARAMS`` table of
:class:`gyro_tdc.base.paramspec.ParamSpec` rows. Its section gives the module docstring, the
topics and services its node class creates (read from the ``create_publisher``,
``create_subscription`` and ``create_service`` calls of the class and its mixins, with the
condition each call is made under; a type ``x.<name>_cls`` is a class loaded by the
``<name>_type`` parameter) and the parameter table (name, type, default, unit,
range or choices, whether it can be set at run time, meaning).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
import importlib
import inspect
import pkgutil
import re
import textwrap
from types import ModuleType
from typing import Any

from gyro_tdc_docs_util import escape, GeneratedDirective, heading, list_table, literal

#: Node method -> what the entity is.
CALLS = {'create_publisher': 'publishes', 'create_subscription': 'subscribes',
         'create_service': 'service'}


@dataclass(frozen=True)
class Interface:
    """One topic or service a node creates: direction, name, type and condition (reST)."""

    kind: str
    name: str
    types: str
    condition: str
    where: str


def node_modules() -> list[ModuleType]:
    """Return the node modules of :mod:`gyro_tdc.nodes`, in name order."""
    import gyro_tdc.nodes
    from gyro_tdc.base.paramspec import ParamSpec
    found = []
    for info in pkgutil.iter_modules(gyro_tdc.nodes.__path__):
        module = importlib.import_module(f'gyro_tdc.nodes.{info.name}')
        params = getattr(module, 'PARAMS', None)
        if (callable(getattr(module, 'main', None)) and isinstance(params, tuple)
                and params and all(isinstance(p, ParamSpec) for p in params)):
            found.append(module)
    return sorted(found, key=lambda m: m.__name__)


def node_class(module: ModuleType) -> type:
    """Return the rclpy Node subclass defined in ``module``."""
    from rclpy.node import Node
    classes = [c for c in vars(module).values() if isinstance(c, type)
               and issubclass(c, Node) and c is not Node and c.__module__ == module.__name__]
    if len(classes) != 1:
        raise ValueError(f'Expected one rclpy Node class in {module.__name__}, '
                         f'got {[c.__name__ for c in classes]}.')
    return classes[0]


def ros_type(cls: Any) -> str:
    """Return a message or service class as ``pkg/msg/Name`` (or its Python name)."""
    parts = getattr(cls, '__module__', '').split('.')
    if len(parts) >= 2 and parts[1] in ('msg', 'srv', 'action'):
        return f'{parts[0]}/{parts[1]}/{cls.__name__}'
    return getattr(cls, '__qualname__', repr(cls))


#: A parameter read in a condition's source (``p.x``, ``self.params.x``), shown as its name.
_PARAM = re.compile(r'\b(?:self\.params|p)\.(\w+)')


def _parameter(expr: ast.expr) -> str | None:
    """Return the parameter an expression reads (``p.x``, ``self.params.x``) or None."""
    if isinstance(expr, ast.Attribute):
        base = expr.value
        if isinstance(base, ast.Name) and base.id == 'p':
            return expr.attr
        if (isinstance(base, ast.Attribute) and base.attr == 'params'
                and isinstance(base.value, ast.Name) and base.value.id == 'self'):
            return expr.attr
    return None


class _Resolver:
    """Turn the arguments of one ``create_*`` call into reST, in its module's namespace."""

    def __init__(self, namespace: dict[str, Any], assigned: dict[str, ast.expr]) -> None:
        self.namespace = namespace
        self.assigned = assigned

    def types(self, expr: ast.expr) -> str:
        if isinstance(expr, ast.Name) and expr.id in self.assigned:
            return self.types(self.assigned[expr.id])
        if isinstance(expr, ast.Name) and expr.id in self.namespace:
            return literal(ros_type(self.namespace[expr.id]))
        if isinstance(expr, ast.Attribute) and expr.attr.endswith('_cls'):
            # A class loaded at run time by name: ``reader.imu_cls`` from ``imu_type``.
            return f'any installed type (by {literal(expr.attr[:-4] + "_type")})'
        if (isinstance(expr, ast.Subscript) and isinstance(expr.value, ast.Name)
                and isinstance(self.namespace.get(expr.value.id), dict)):
            table = self.namespace[expr.value.id]
            choice = _parameter(expr.slice)
            text = ', '.join(literal(ros_type(cls)) for cls in table.values())
            return f'{text} (by {literal(choice)})' if choice else text
        return literal(ast.unparse(expr))

    def name(self, expr: ast.expr) -> str:
        if isinstance(expr, ast.Constant) and isinstance(expr.value, str):
            return literal(expr.value)
        parameter = _parameter(expr)
        if parameter:
            return f'parameter {literal(parameter)}'
        return literal(ast.unparse(expr))


def _calls(body: list[ast.stmt], conditions: tuple[str, ...], found: list) -> None:
    """Collect ``(call, conditions)`` of every ``self.create_*`` call in ``body``."""
    guards = list(conditions)
    for stmt in body:
        if isinstance(stmt, ast.If):
            test = ast.unparse(stmt.test)
            _calls(stmt.body, tuple(guards) + (test,), found)
            _calls(stmt.orelse, tuple(guards) + (f'not ({test})',), found)
            if stmt.body and isinstance(stmt.body[-1], ast.Return) and not stmt.orelse:
                guards.append(ast.unparse(ast.UnaryOp(ast.Not(), stmt.test))
                              .replace('not not ', ''))
            continue
        for node in ast.walk(stmt):
            if isinstance(node, ast.IfExp):
                for call in ast.walk(node.body):
                    if _is_create(call):
                        found.append((call, tuple(guards) + (ast.unparse(node.test),)))
                for call in ast.walk(node.orelse):
                    if _is_create(call):
                        found.append((call, tuple(guards)
                                      + (f'not ({ast.unparse(node.test)})',)))
        in_ifexp = {id(c) for n in ast.walk(stmt) if isinstance(n, ast.IfExp)
                    for c in ast.walk(n)}
        for node in ast.walk(stmt):
            if _is_create(node) and id(node) not in in_ifexp:
                found.append((node, tuple(guards)))


def _is_create(node: ast.AST) -> bool:
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and node.func.attr in CALLS and isinstance(node.func.value, ast.Name)
            and node.func.value.id == 'self' and len(node.args) >= 2)


def interfaces(cls: type) -> list[Interface]:
    """
    Return the topics and services ``cls`` and its gyro_tdc mixins create, in MRO order.

    Parameters
    ----------
    cls : type
        A node class.

    Returns
    -------
    list of Interface
        One entry per ``self.create_publisher/create_subscription/create_service`` call.

    """
    import sys
    found = []
    for klass in cls.__mro__:
        if not klass.__module__.startswith('gyro_tdc.'):
            continue
        namespace = vars(sys.modules[klass.__module__])
        tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        for function in ast.walk(tree):
            if not isinstance(function, ast.FunctionDef):
                continue
            assigned = {t.id: n.value for n in ast.walk(function) if isinstance(n, ast.Assign)
                        for t in n.targets if isinstance(t, ast.Name)}
            resolver = _Resolver(namespace, assigned)
            calls: list = []
            _calls(function.body, (), calls)
            for call, conditions in calls:
                found.append(Interface(
                    kind=CALLS[call.func.attr], name=resolver.name(call.args[1]),
                    types=resolver.types(call.args[0]),
                    condition=' and '.join(literal(_PARAM.sub(r'\1', c)) for c in conditions),
                    where=f':py:meth:`~{klass.__module__}.{klass.__qualname__}.'
                          f'{function.name}`'))
    return found


def _value(value: Any) -> str:
    """Return a default as written after ``-p name:=`` (strings quoted, bools lower case)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, str):
        return repr(value)
    return repr(value)


def parameter_rows(specs: Any) -> list[list[str]]:
    """Return the parameter table rows of a ``PARAMS`` tuple (reST cells; read-only yes/no)."""
    rows = []
    for spec in specs:
        if spec.choices:
            valid = 'one of ' + ', '.join(literal(c or "''") for c in spec.choices)
        elif spec.lo is not None and spec.hi is not None:
            valid = literal(f'{_value(spec.lo)} .. {_value(spec.hi)}')
        else:
            valid = ''
        default = literal(_value(spec.default))
        if spec.unit:
            default += ' ' + escape(spec.unit)
        rows.append([literal(spec.name), type(spec.default).__name__, default, valid,
                     'yes' if spec.read_only else 'no', escape(spec.meaning)])
    return rows


class NodesDirective(GeneratedDirective):
    """``.. gyro-tdc-nodes::``: every node's section (docstring, interfaces, parameters)."""

    def generate(self) -> list[str]:
        lines: list[str] = []
        for module in node_modules():
            self.env.note_dependency(module.__file__)
            name = module.__name__.rpartition('.')[2]
            cls = node_class(module)
            for klass in cls.__mro__:
                if klass.__module__.startswith('gyro_tdc.'):
                    self.env.note_dependency(inspect.getfile(klass))
            lines += heading(name, '-')
            lines += [f'``ros2 run gyro_tdc {name}`` (:py:func:`{module.__name__}.main`, '
                      f'node class :py:class:`{cls.__module__}.{cls.__qualname__}`).', '']
            lines += inspect.cleandoc(module.__doc__ or '').splitlines() + ['']
            lines += heading('Topics and services', '~')
            lines += list_table(
                ['Direction', 'Name', 'Type', 'Only when', 'Created in'],
                [[i.kind, i.name, i.types, i.condition, i.where] for i in interfaces(cls)],
                widths=[10, 22, 32, 14, 22])
            lines += heading('Parameters', '~')
            lines += [f'The rows of :py:data:`{module.__name__}.PARAMS` '
                      f'(``ros2 run gyro_tdc {name} --help`` prints the same table).', '']
            lines += list_table(
                ['Parameter', 'Type', 'Default [unit]', 'Valid values', 'Read-only', 'Meaning'],
                parameter_rows(module.PARAMS), widths=[22, 6, 14, 16, 8, 34])
        return lines


def setup(app: Any) -> dict[str, Any]:
    """Register the directive."""
    app.add_directive('gyro-tdc-nodes', NodesDirective)
    return {'version': '1', 'parallel_read_safe': True, 'parallel_write_safe': True}
