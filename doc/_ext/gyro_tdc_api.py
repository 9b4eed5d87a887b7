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
The ``gyro-tdc-package`` directive: a package's API page from its face and its modules.

``.. gyro-tdc-package:: gyro_tdc.model`` gives the package docstring, its face (every name
of ``__all__``, linked to where it is defined, with the first line of its documentation:
the lazy faces of :mod:`gyro_tdc.base.face` name their modules in a literal dict, the
others import from them, so both are read from ``__init__.py`` without running it) and then
each module of the package with autodoc (napoleon reads the numpydoc sections; a module's
``__all__`` chooses its members).

Checks, which ``-W`` makes errors: every package of gyro_tdc has an API page (the
directive naming it, in ``reference/api/``; ``gyro_tdc_api_every_package = False`` turns
this one off for a build of some pages only), and every face name is documented where the
face says it is defined.
"""

from __future__ import annotations

import ast
import functools
import importlib
import inspect
import pkgutil
from typing import Any

from gyro_tdc_docs_util import GeneratedDirective, heading, list_table
from sphinx.pycode import ModuleAnalyzer
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util import logging

logger = logging.getLogger(__name__)

#: The root package.
ROOT = 'gyro_tdc'

#: Longest value shown after a constant's name [characters]; a longer one (a table of
#: parameter rows...) is left out, its documentation says what it holds.
MAX_VALUE = 100


def packages() -> list[str]:
    """Return every package of gyro_tdc (the root included), in name order."""
    root = importlib.import_module(ROOT)
    found = [ROOT]
    for info in pkgutil.walk_packages(root.__path__, ROOT + '.'):
        if info.ispkg:
            found.append(info.name)
    return sorted(found)


def modules(package: str) -> list[str]:
    """List the modules of ``package``, sub-packages left out, in name order."""
    pkg = importlib.import_module(package)
    return sorted(f'{package}.{info.name}' for info in pkgutil.iter_modules(pkg.__path__)
                  if not info.ispkg)


def subpackages(package: str) -> list[str]:
    """Return the direct sub-packages of ``package``, in name order."""
    pkg = importlib.import_module(package)
    return sorted(f'{package}.{info.name}' for info in pkgutil.iter_modules(pkg.__path__)
                  if info.ispkg)


def face_sources(package: str) -> dict[str, str]:
    """
    Return name -> module it is taken from, read from the ``__init__.py`` of ``package``.

    Parameters
    ----------
    package : str
        Dotted package name.

    Returns
    -------
    dict of str to str
        The names of a ``lazy(__name__, {module: [names]})`` call and of ``from X import``
        statements (relative modules made absolute).

    """
    pkg = importlib.import_module(package)
    tree = ast.parse(inspect.getsource(pkg))
    where: dict[str, str] = {}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id == 'lazy' and len(node.args) == 2
                and isinstance(node.args[1], ast.Dict)):
            for key, value in zip(node.args[1].keys, node.args[1].values):
                for name in ast.literal_eval(value):
                    where[name] = f'{package}.{ast.literal_eval(key)}'
        elif isinstance(node, ast.ImportFrom) and node.module:
            base = node.module if not node.level else '.'.join(
                package.split('.')[:len(package.split('.')) - node.level + 1] + [node.module])
            for alias in node.names:
                where.setdefault(alias.asname or alias.name, base)
    return where


def own_names(module: str) -> list[str]:
    """Return the public names the source of ``module`` defines itself (not imports), in order."""
    tree = ast.parse(inspect.getsource(importlib.import_module(module)))
    names: list[str] = []

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.append(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names.extend(t.id for t in targets if isinstance(t, ast.Name))
            elif isinstance(node, (ast.If, ast.Try, ast.With)):
                for part in ('body', 'orelse', 'finalbody'):
                    visit(getattr(node, part, []))
                for handler in getattr(node, 'handlers', []):
                    visit(handler.body)

    visit(tree.body)
    return [n for n in dict.fromkeys(names) if not n.startswith('_')]


def members(module: str, extra: list[str]) -> list[str] | None:
    """
    Return the members to document of ``module``, or None to let autodoc choose.

    Parameters
    ----------
    module : str
        Dotted module name.
    extra : list of str
        Face names defined in ``module``, documented whether or not its ``__all__`` has them.

    Returns
    -------
    list of str or None
        With an ``__all__``: its names the module defines (re-exports are documented where
        they are defined), then ``extra``; without one, None (autodoc's choice, the public
        names defined there) unless ``extra`` holds a name it would not take.

    """
    mod = importlib.import_module(module)
    own = own_names(module)
    names = getattr(mod, '__all__', None)
    if names is None:
        if all(n in own for n in extra):
            return None
        names = own
    chosen = [n for n in names if n in own]
    return chosen + [n for n in extra if n not in chosen]


def defined_in(package: str, name: str) -> str | None:
    """Return the module that defines face name ``name`` of ``package`` (faces followed)."""
    seen = set()
    while package not in seen:
        seen.add(package)
        if name in own_names(package):
            return package
        module = face_sources(package).get(name)
        if module is None:
            return None
        if not hasattr(importlib.import_module(module), '__path__'):
            return module
        package = module
    return None


def summary(module: str, name: str) -> str:
    """Return the first line of the documentation of ``module.name`` (docstring or ``#:``)."""
    obj = getattr(importlib.import_module(module), name)
    if inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj):
        doc = inspect.getdoc(obj) or ''
    else:
        attr_docs = ModuleAnalyzer.for_module(module).find_attr_docs()
        doc = '\n'.join(attr_docs.get(('', name), []))
    return doc.strip().split('\n\n')[0].replace('\n', ' ')


class PackageDirective(GeneratedDirective):
    """``.. gyro-tdc-package:: NAME``: the package docstring, its face, then its modules."""

    required_arguments = 1

    def generate(self) -> list[str]:
        package = self.arguments[0]
        pkg = importlib.import_module(package)
        self.env.note_dependency(pkg.__file__)
        self.env.domaindata.setdefault('gyro_tdc_api', {}).setdefault('pages', {})[
            package] = self.env.docname
        faces = self.env.domaindata['gyro_tdc_api'].setdefault('faces', {})
        lines = automodule(package, own_names(package))
        names = list(getattr(pkg, '__all__', []))
        if names:
            lines += heading('Face', '-')
            lines += [f'What other packages import: ``from {package} import NAME``, each '
                      'name defined in the module linked.', '']
            rows = []
            for name in names:
                module = defined_in(package, name)
                if module is None:
                    logger.warning(f'{package}.__all__ names {name!r}, which its '
                                   '__init__.py neither imports nor lists in lazy()',
                                   location=self.get_location())
                    continue
                faces[f'{package}.{name}'] = (f'{module}.{name}', self.env.docname,
                                              self.lineno)
                rows.append([f':py:obj:`{name} <{module}.{name}>`', summary(module, name)])
            lines += list_table(['Name', 'Summary'], rows, widths=[30, 70])
        subs = subpackages(package)
        if subs:
            lines += heading('Sub-packages', '-')
            lines += [f'* :py:mod:`{sub}`' for sub in subs] + ['']
        for module in modules(package):
            mod = importlib.import_module(module)
            self.env.note_dependency(mod.__file__)
            extra = [n for n in names if defined_in(package, n) == module]
            chosen = members(module, extra)
            lines += heading(module, '-')
            lines += automodule(module, chosen, extra)
        return lines


def undocumented_data(module: str, names: list[str]) -> list[str]:
    """Return the names of ``names`` that are data of ``module`` without a ``#:`` comment."""
    mod = importlib.import_module(module)
    attr_docs = ModuleAnalyzer.for_module(module).find_attr_docs()
    return [n for n in names if ('', n) not in attr_docs and not (
        inspect.isclass(getattr(mod, n)) or inspect.isroutine(getattr(mod, n))
        or inspect.ismodule(getattr(mod, n)))]


def automodule(module: str, chosen: list[str] | None, extra: list[str] = ()) -> list[str]:
    """
    Return an ``automodule`` of ``module`` documenting ``chosen``, then its bare data.

    Autodoc takes a module-level constant only when a ``#:`` comment documents it; an
    ``autodata`` each documents the chosen ones without one.

    Parameters
    ----------
    module : str
        Dotted module name.
    chosen : list of str or None
        The members (None: autodoc's choice; empty: the docstring only).
    extra : sequence of str
        With ``chosen`` None, the names whose bare data still need an ``autodata``.

    Returns
    -------
    list of str
        reST lines.

    """
    lines = [f'.. automodule:: {module}']
    if chosen is None:
        lines.append('   :members:')
    elif chosen:
        lines.append('   :members: ' + ', '.join(chosen))
    if chosen is None or chosen:
        lines += ['   :undoc-members:', '   :show-inheritance:']
    lines.append('')
    for name in undocumented_data(module, list(extra) if chosen is None else chosen):
        lines += [f'.. autodata:: {module}.{name}', '']
    return lines


def _purge(app: Any, env: Any, docname: str) -> None:
    data = env.domaindata.get('gyro_tdc_api', {})
    for package, page in list(data.get('pages', {}).items()):
        if page == docname:
            del data['pages'][package]
    for face, (_, page, _line) in list(data.get('faces', {}).items()):
        if page == docname:
            del data['faces'][face]


def _merge(app: Any, env: Any, docnames: Any, other: Any) -> None:
    data = env.domaindata.setdefault('gyro_tdc_api', {})
    theirs = other.domaindata.get('gyro_tdc_api', {})
    for key in ('pages', 'faces'):
        data.setdefault(key, {}).update(theirs.get(key, {}))


def _check(app: Any, env: Any) -> None:
    """Warn for a package without an API page and a face name documented nowhere."""
    data = env.domaindata.get('gyro_tdc_api', {})
    pages = data.get('pages', {})
    for package in packages() if app.config.gyro_tdc_api_every_package else ():
        if package not in pages:
            logger.warning(f'package {package} has no API page: add reference/api/'
                           f'{package}.rst with ".. gyro-tdc-package:: {package}"')
    objects = env.get_domain('py').objects
    for face, (target, page, line) in sorted(data.get('faces', {}).items()):
        if target not in objects:
            logger.warning(f'{face} (face) is documented nowhere: {target} is not in the '
                           "API pages (is it in its module's __all__?)",
                           location=(page, line))


def _hide_long_values(app: Any, doctree: Any) -> None:
    """Drop the ``= value`` of a constant's signature when it is longer than ``MAX_VALUE``."""
    from sphinx import addnodes
    for desc in doctree.findall(addnodes.desc):
        if desc.get('domain') != 'py' or desc.get('objtype') not in ('data', 'attribute'):
            continue
        for signature in desc.findall(addnodes.desc_signature):
            for annotation in list(signature.findall(addnodes.desc_annotation)):
                text = annotation.astext().strip()
                if text.startswith('=') and len(text) > MAX_VALUE:
                    annotation.parent.remove(annotation)


def _no_type_docstring(app: Any, what: str, name: str, obj: Any, options: Any,
                       lines: list[str]) -> None:
    """Drop the docstring a constant only has from its type (dict's, tuple's...)."""
    if what in ('data', 'attribute') and not inspect.isclass(obj):
        doc = inspect.getdoc(type(obj))
        if doc and '\n'.join(lines).strip() == doc.strip():
            lines.clear()


@functools.lru_cache(maxsize=None)
def imported_names(module: str) -> dict[str, str]:
    """Return name -> dotted target of every ``from X import name`` in ``module``'s source."""
    try:
        tree = ast.parse(inspect.getsource(importlib.import_module(module)))
    except (ImportError, OSError, TypeError):
        return {}
    return {alias.asname or alias.name: f'{node.module}.{alias.name}'
            for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
            and node.module and not node.level for alias in node.names}


class ImportedTypeNames(SphinxPostTransform):
    """
    Resolve a bare name in a type hint through the imports of the module it stands in.

    With postponed annotations a hint such as ``dict[int, Vec3]`` reaches Sphinx as text: the
    Python domain then looks for any object ending in ``.Vec3``, and finds one per module
    that defines such a name. The module's own ``from X import Vec3`` says which it is.
    """

    default_priority = 5   # before the ReferencesResolver (10)

    def run(self, **kwargs: Any) -> None:
        from sphinx import addnodes
        for node in self.document.findall(addnodes.pending_xref):
            target = node.get('reftarget', '')
            module = node.get('py:module')
            if node.get('refdomain') != 'py' or not module or '.' in target:
                continue
            full = imported_names(module).get(target)
            if full and full.startswith(ROOT + '.'):
                node['reftarget'] = full
                node['refspecific'] = False


def setup(app: Any) -> dict[str, Any]:
    """Register the directive and the checks."""
    app.add_directive('gyro-tdc-package', PackageDirective)
    # False: a build of some pages only (the docs test) does not ask for every package's.
    app.add_config_value('gyro_tdc_api_every_package', True, 'env', types=frozenset({bool}))
    app.connect('env-purge-doc', _purge)
    app.connect('env-merge-info', _merge)
    app.connect('env-check-consistency', _check)
    app.connect('doctree-read', _hide_long_values)
    app.connect('autodoc-process-docstring', _no_type_docstring)
    app.add_post_transform(ImportedTypeNames)
    return {'version': '1', 'parallel_read_safe': True, 'parallel_write_safe': True}
