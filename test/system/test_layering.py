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
The layering of gyro_tdc, read from the source: packages along the data flow, declared once.

:data:`LAYERS` is the graph of the packages: which package may import which. Every import of
every module (at the top, inside a function, under ``TYPE_CHECKING``) is checked against it;
so are the faces (other packages import ``from gyro_tdc.<package> import name``), the module
graph (no circle, type-only imports included), ROS (only ``gyro_tdc.nodes``) and private names
(never across modules).
"""

from __future__ import annotations

import ast
import json
from pathlib import Path
import re
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / 'gyro_tdc'

#: The packages of gyro_tdc and what each may import, the path data take: recordings and
#: simulations become runs (data), runs a model (identify, learn), the model compensates
#: (runtime), is scored (evaluate) and calibrated by the fleet; cli and nodes are the shells.
#: ``gyro_tdc`` is the top package (``__version__``), ``errors`` its exception classes.
#: cli may import nodes: ``gyro-tdc demo`` starts the two nodes (inside its live step, so the
#: other commands never load rclpy); nodes never import cli. cli may import learn: a
#: learn_file's learned model is taken wherever a model file is (evaluate, export).
LAYERS: dict[str, frozenset] = {k: frozenset(v.split()) for k, v in {
    'gyro_tdc': '',
    'errors': '',
    'base': 'errors',
    'signal': 'base',
    'data': 'base errors model signal',
    'model': 'base errors',
    'identify': 'gyro_tdc base data errors model runtime signal',
    'runtime': 'base model signal',
    'learn': 'base errors model runtime signal',
    'evaluate': 'base data errors identify model runtime signal',
    'sim': 'base data errors model',
    'sources': 'base errors sim',
    'fleet': 'gyro_tdc base data errors evaluate identify model signal',
    'nodes': 'base data errors learn model runtime signal sim sources',
    'cli': 'base data errors evaluate fleet identify learn model nodes signal sim',
    '__main__': 'gyro_tdc cli',
}.items()}

#: The shells: no other package reaches them.
SHELL = ('cli', 'nodes', '__main__')

#: Top-level names of ROS client and interface packages (only gyro_tdc.nodes imports them).
ROS = ('rclpy', 'launch', 'launch_ros', 'message_filters', 'tf2_ros')
ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces')


def _modules() -> list:
    """Return (dotted module name, package of the module, path) for every module."""
    out = []
    for path in sorted(PACKAGE.rglob('*.py')):
        parts = path.relative_to(ROOT).with_suffix('').parts
        if parts[-1] == '__init__':
            name = '.'.join(parts[:-1])
            out.append((name, name, path))
        else:
            name = '.'.join(parts)
            out.append((name, name.rsplit('.', 1)[0], path))
    return out


def _all_imports(path: Path) -> list:
    """Return (imported module, [names]) for every absolute import in a file, anywhere."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.ImportFrom):
            assert node.level == 0, f'{path}: relative import (use absolute gyro_tdc imports)'
            out.append((node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
    return out


def _imports(path: Path) -> list:
    """Return (imported module, [names]) for every gyro_tdc import in a file."""
    return [(m, names) for m, names in _all_imports(path)
            if m == 'gyro_tdc' or m.startswith('gyro_tdc.')]


def _in(module: str, prefixes) -> bool:
    return any(module == p or module.startswith(p + '.') for p in prefixes)


def _private(name: str) -> bool:
    return name.startswith('_') and not name.startswith('__')


def _layer(module: str) -> str:
    """Return the node of :data:`LAYERS` a dotted module belongs to."""
    parts = module.split('.')
    return parts[1] if len(parts) > 1 else parts[0]


MODULES = _modules()
NAMES = {m for m, _, _ in MODULES}
PACKAGES = {m for m, p, _ in MODULES if m == p}


def _init(package: str) -> ast.Module:
    return ast.parse(ROOT.joinpath(*package.split('.'), '__init__.py').read_text(encoding='utf-8'))


def _face_lists(package: str) -> dict | None:
    """Return module -> names of a lazy face (``base.face.lazy``), None for an eager package."""
    for node in ast.walk(_init(package)):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'lazy':
            return ast.literal_eval(node.args[1])
    return None


def _face(package: str) -> dict | None:
    """Return name -> defining module of a lazy face, None for an eager package."""
    modules = _face_lists(package)
    if modules is None:
        return None
    return {n: f'{package}.{m}' for m, names in modules.items() for n in names}


def _listed(package: str) -> list | None:
    """Return the names a package shows (``__all__``), None when it has no ``__all__``."""
    face = _face(package)
    if face is not None:
        return sorted(face)
    for node in _init(package).body:
        if isinstance(node, ast.Assign) and [getattr(t, 'id', None) for t in node.targets] == [
                '__all__']:
            return ast.literal_eval(node.value)
    return None


FACES = {p: _face(p) for p in PACKAGES}
SHOWN = {p: _listed(p) for p in PACKAGES}


def _targets(module: str, names: list) -> list:
    """Return the modules an import loads by name (a lazy face: the defining modules)."""
    if module not in PACKAGES:
        return [module]
    out = []
    for n in names:
        if f'{module}.{n}' in NAMES:
            out.append(f'{module}.{n}')
        elif FACES[module] is not None and n in FACES[module]:
            out.append(FACES[module][n])
        else:
            out.append(module)
    return out or [module]


def _graph() -> dict:
    """Return module -> the set of gyro_tdc modules it imports."""
    return {m: {t for target, names in _imports(path) for t in _targets(target, names)} - {m}
            for m, _, path in MODULES}


def _circles(graph: dict) -> list:
    """Return the strongly connected components of more than one module (Tarjan)."""
    index: dict = {}
    low: dict = {}
    stack: list = []
    out = []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def test_every_module_is_found():
    assert {'gyro_tdc', 'gyro_tdc.evaluate.score', 'gyro_tdc.cli.common',
            'gyro_tdc.nodes.compensator_node', 'gyro_tdc.identify.discover.search'} <= NAMES


def test_every_package_is_declared_once():
    assert {_layer(m) for m in NAMES} == set(LAYERS)
    for layer, deps in LAYERS.items():
        assert deps <= set(LAYERS) - {layer}, layer


def test_declared_graph_is_tight():
    used: dict = {layer: set() for layer in LAYERS}
    for module, _, path in MODULES:
        here = _layer(module)
        used[here] |= {_layer(m) for m, _ in _imports(path)} - {here}
    loose = {layer: sorted(deps - used[layer]) for layer, deps in LAYERS.items()
             if deps - used[layer]}
    assert loose == {}, f'declared but imported by no module: {loose}'


def test_internals_page_shows_the_declared_graph():
    page = (ROOT / 'doc' / 'internals' / 'index.md').read_text(encoding='utf-8')
    rows = re.findall(r'^\| `([\w]+)`[^|]* \| (.*) \|$', page, flags=re.M)
    shown = {layer: frozenset(re.findall(r'`(\w+)`', deps)) for layer, deps in rows}
    assert shown == LAYERS


def test_declared_graph_is_acyclic():
    order, left = [], dict(LAYERS)
    while left:
        ready = sorted(k for k, deps in left.items() if deps <= set(order))
        assert ready, f'the declared package graph has a circle among {sorted(left)}'
        order += ready
        for k in ready:
            del left[k]
    assert order.index('errors') < order.index('base') < order.index('signal')
    assert order[-1] == '__main__'


def _reach(layer: str) -> set:
    out, todo = set(), [layer]
    while todo:
        for dep in LAYERS[todo.pop()] - out:
            out.add(dep)
            todo.append(dep)
    return out


def test_declared_graph_keeps_the_shell_on_top():
    for layer in set(LAYERS) - set(SHELL):
        assert not _reach(layer) & set(SHELL), layer
    assert 'cli' not in _reach('nodes')


@pytest.mark.parametrize('module, package, path', MODULES, ids=[m[0] for m in MODULES])
def test_imports_follow_the_declared_graph(module, package, path):
    here = _layer(module)
    bad = sorted({m for m, _ in _imports(path) if _layer(m) != here
                  and _layer(m) not in LAYERS[here]})
    assert bad == [], f'{module} ({here}) imports {bad}; {here} may import {sorted(LAYERS[here])}'


CORE = [m for m in MODULES if _layer(m[0]) not in SHELL]


@pytest.mark.parametrize('module, package, path', CORE, ids=[m[0] for m in CORE])
def test_core_never_imports_the_command_line_or_the_nodes(module, package, path):
    shell = [f'gyro_tdc.{s}' for s in SHELL]
    bad = [m for m, names in _imports(path)
           if _in(m, shell) or any(_in(f'{m}.{n}', shell) for n in names)]
    assert bad == [], f'{module} imports {bad}'


@pytest.mark.parametrize('module, package, path', MODULES, ids=[m[0] for m in MODULES])
def test_other_packages_are_imported_through_their_face(module, package, path):
    here = _layer(module)
    bad = []
    for target, names in _imports(path):
        there = _layer(target)
        face = FACES.get(target)
        if there == here:
            # Inside a package, a sibling comes from its defining module, not the face.
            if face is not None and target != module:
                bad += [f'{target}.{n} (own face)' for n in names if n in face]
            continue
        if target == 'gyro_tdc.base.face' and module in PACKAGES and names == ['lazy']:
            continue                    # every face is built with base.face.lazy
        home = 'gyro_tdc' if there == 'gyro_tdc' else f'gyro_tdc.{there}'
        if target != home or not names:
            bad.append(f'{target} (import from {home})')
        elif SHOWN.get(target) is not None:
            bad += [f'{target}.{n} (not on the face)' for n in names if n not in SHOWN[target]]
    assert bad == [], f'{module}: {bad}'


FACE_CHECK = r"""
import importlib, json, sys, types
out = {}
for package in sys.argv[1:]:
    pkg = importlib.import_module(package)
    for name in pkg.__all__:
        try:
            value = getattr(pkg, name)
        except Exception as exc:
            out[f'{package}.{name}'] = f'{type(exc).__name__}: {exc}'
            continue
        if isinstance(value, types.ModuleType):
            out[f'{package}.{name}'] = 'a module'
print(json.dumps(out))
"""


def test_every_face_name_resolves():
    faces = sorted(p for p in PACKAGES if SHOWN[p] is not None)
    assert {'gyro_tdc.base', 'gyro_tdc.model', 'gyro_tdc.nodes', 'gyro_tdc.sim'} <= set(faces)
    for package in faces:
        lists = _face_lists(package) or {}
        names = [n for listed in lists.values() for n in listed]
        assert len(names) == len(set(names)), f'{package}: a name listed under two modules'
        for module in lists:
            assert f'{package}.{module}' in NAMES, f'{package}: no module {module}'
    # A child interpreter: resolving the nodes face imports rclpy, which pure tests never load.
    proc = subprocess.run([sys.executable, '-c', FACE_CHECK, *faces], cwd=ROOT,
                          capture_output=True, text=True, check=False, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.splitlines()[-1]) == {}


def test_no_module_imports_itself_through_a_circle():
    graph = _graph()
    assert 'gyro_tdc.model.effects' in graph['gyro_tdc.model.compensation']
    assert _circles(graph) == []


def test_circles_are_found():
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}, 'e': set()}
    assert _circles(graph) == [['a', 'b', 'c']]


def _ros(module: str) -> bool:
    top = module.partition('.')[0]
    return top in ROS or top.endswith(ROS_SUFFIXES) or top.startswith('rosidl')


def test_ros_names_are_recognised():
    assert _ros('rclpy.node') and _ros('sensor_msgs.msg') and _ros('rosidl_runtime_py')
    assert not _ros('rosbags.typesys') and not _ros('numpy')


@pytest.mark.parametrize('module, package, path', MODULES, ids=[m[0] for m in MODULES])
def test_only_the_nodes_import_ros(module, package, path):
    bad = [m for m, _ in _all_imports(path) if m and _ros(m)]
    assert _layer(module) == 'nodes' or bad == [], f'{module} imports {bad}'


@pytest.mark.parametrize('module, package, path', MODULES, ids=[m[0] for m in MODULES])
def test_no_private_imports_across_modules(module, package, path):
    bad = []
    for target, names in _imports(path):
        if target != module:
            bad += [f'{target}.{n}' for n in names if _private(n)]
        # A private module (``nodes/_params.py``) serves its own package only.
        parent, _, last = target.rpartition('.')
        if _private(last) and not _in(package, [parent]):
            bad.append(target)
    assert bad == [], f'{module} imports private names of other modules: {bad}'


#: Modules of dependencies that are their implementation, though no underscore marks them.
IMPLEMENTATION = ('rclpy.impl',)


def _dependency_private(source: str) -> list:
    """Return the private names of dependencies a module's source imports or reads."""
    tree, bad, aliases = ast.parse(source), [], set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            target = node.module if isinstance(node, ast.ImportFrom) else None
            for a in node.names:
                full = f'{target}.{a.name}' if target else a.name
                if full.startswith(('gyro_tdc.', '__future__.')) or full == 'gyro_tdc':
                    continue
                if any(_private(p) for p in full.split('.')) or _in(full, IMPLEMENTATION):
                    bad.append(full)
                aliases.add(a.asname or a.name.partition('.')[0])
    bad += [f'{n.value.id}.{n.attr}' for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)
            and n.value.id in aliases and _private(n.attr)]
    return bad


def test_private_names_of_dependencies_are_found():
    src = ('import numpy as np\nfrom scipy.signal import _sigtools\n'
           'from rclpy.impl.implementation_singleton import rclpy_implementation\n'
           'np._set_madvise_hugepage(False)\nnp.__version__\n')
    assert _dependency_private(src) == [
        'scipy.signal._sigtools', 'rclpy.impl.implementation_singleton.rclpy_implementation',
        'np._set_madvise_hugepage']


@pytest.mark.parametrize('module, package, path', MODULES, ids=[m[0] for m in MODULES])
def test_no_private_name_of_a_dependency(module, package, path):
    bad = _dependency_private(path.read_text(encoding='utf-8'))
    assert bad == [], f'{module} uses private names of its dependencies: {bad}'
