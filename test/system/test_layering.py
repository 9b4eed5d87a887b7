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
The layering of gyro_tdc, read from the source: the core never reaches up into cli/ or nodes/.

The core (every module but ``gyro_tdc.cli``, ``gyro_tdc.nodes`` and ``gyro_tdc.__main__``)
is what the command line and the nodes call; it imports neither of them, not even inside a
function. No module imports another module's private names (``_name``) or a private module
of another package: what is shared has a public home.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / 'gyro_tdc'
SHELL = ('gyro_tdc.cli', 'gyro_tdc.nodes', 'gyro_tdc.__main__')


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


def _imports(path: Path) -> list:
    """Return (imported module, [names]) for every absolute gyro_tdc import in a file."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
    return [(m, names) for m, names in out if m == 'gyro_tdc' or m.startswith('gyro_tdc.')]


def _in(module: str, prefixes) -> bool:
    return any(module == p or module.startswith(p + '.') for p in prefixes)


def _private(name: str) -> bool:
    return name.startswith('_') and not name.startswith('__')


MODULES = _modules()


def test_every_module_is_found():
    names = {m for m, _, _ in MODULES}
    assert {'gyro_tdc', 'gyro_tdc.evaluate.score', 'gyro_tdc.cli.common',
            'gyro_tdc.nodes.compensator_node'} <= names


CORE = [m for m in MODULES if not _in(m[0], SHELL)]


@pytest.mark.parametrize('module, package, path', CORE, ids=[m[0] for m in CORE])
def test_core_never_imports_the_command_line_or_the_nodes(module, package, path):
    bad = [m for m, names in _imports(path)
           if _in(m, SHELL) or any(_in(f'{m}.{n}', SHELL) for n in names)]
    assert bad == [], f'{module} imports {bad}'


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
