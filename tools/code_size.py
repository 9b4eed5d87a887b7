#!/usr/bin/env python3
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
The size of ``gyro_tdc/`` as issue 33 measures it.

Usage: ``python tools/code_size.py [ROOT]``. Prints the lines of code per package (lines
holding a token that is not a comment, without docstrings and blank lines), the modules over
600 lines, the function bodies over 80 lines, the docstrings of 15 lines or more that are
longer than their function's (or class's) body, and the modules that call a linear
least-squares solver.
"""

from __future__ import annotations

import ast
import collections
import io
from pathlib import Path
import re
import sys
import tokenize

MAX_MODULE_LINES = 600
MAX_BODY_LINES = 80
#: A docstring of at least this many lines that is longer than its body is counted: what and
#: why fit in a few lines (a record class's fields are its body's docs, counted apart).
LONG_DOC_LINES = 15
#: A linear solve of numpy or scipy (lstsq, solve, cho_solve, pinv); calls of the estimator's
#: own solvers (``gyro_tdc.signal.solve_normal``, ``pinv_fit``) are not one.
SOLVER = re.compile(r'\b(?:lstsq|linalg\.solve|cho_solve|linalg\.pinv)\(')
_SKIP = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
         tokenize.ENDMARKER}


def _docstring(node: ast.AST) -> ast.Expr | None:
    body = getattr(node, 'body', None)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        return body[0]
    return None


def measure(path: Path) -> dict:
    """Return the code lines, the long function bodies and docstrings, the solver use."""
    src = path.read_text()
    tree = ast.parse(src)
    docs: set[int] = set()
    long_bodies, long_docs = [], []
    for node in ast.walk(tree):
        doc = _docstring(node) if isinstance(
            node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) else None
        if doc is not None:
            docs.update(range(doc.lineno, doc.end_lineno + 1))
            rest = node.body[1:]
            size = doc.end_lineno - doc.lineno + 1
            if not isinstance(node, ast.Module) and size >= LONG_DOC_LINES and size > (
                    rest[-1].end_lineno - rest[0].lineno + 1 if rest else 0):
                long_docs.append((isinstance(node, ast.ClassDef), node.name))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body[1:] if doc is not None and len(node.body) > 1 else node.body
            length = node.end_lineno - body[0].lineno + 1
            if length > MAX_BODY_LINES:
                long_bodies.append((length, node.name))
    code = {line for tok in tokenize.generate_tokens(io.StringIO(src).readline)
            if tok.type not in _SKIP for line in range(tok.start[0], tok.end[0] + 1)}
    return {'code': len(code - docs), 'lines': src.count('\n'), 'long_bodies': long_bodies,
            'long_docs': long_docs, 'solver': bool(SOLVER.search(src))}


def survey(root: Path) -> dict:
    """Measure every module below ``root``; return the totals and what breaks the limits."""
    per_package: collections.Counter = collections.Counter()
    big, long_bodies, long_docs, solvers = [], [], [], []
    for path in sorted(root.rglob('*.py')):
        m = measure(path)
        rel = path.relative_to(root)
        per_package[rel.parts[0] if len(rel.parts) > 1 else '(top)'] += m['code']
        if m['lines'] > MAX_MODULE_LINES:
            big.append((m['lines'], str(rel)))
        long_bodies += [(n, f'{rel}:{name}') for n, name in m['long_bodies']]
        long_docs += [(cls, f'{rel}:{name}') for cls, name in m['long_docs']]
        if m['solver']:
            solvers.append(str(rel))
    return {'per_package': per_package, 'total': sum(per_package.values()), 'big': big,
            'long_bodies': long_bodies, 'long_docs': long_docs, 'solvers': solvers}


def main(argv: list[str] | None = None) -> int:
    """Print the survey of ``gyro_tdc/`` (or ROOT)."""
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0]) if args else Path(__file__).resolve().parent.parent / 'gyro_tdc'
    s = survey(root)
    for name, n in s['per_package'].most_common():
        print(f'{n:7d}  {name}')
    print(f"{s['total']:7d}  lines of code in {root.name}/ (no docstrings, comments, blanks)")
    print(f'modules over {MAX_MODULE_LINES} lines: '
          + (', '.join(f'{p} ({n})' for n, p in s['big']) or 'none'))
    print(f'function bodies over {MAX_BODY_LINES} lines: '
          + (', '.join(f'{p} ({n})' for n, p in s['long_bodies']) or 'none'))
    classes = sum(cls for cls, _ in s['long_docs'])
    print(f'docstrings of {LONG_DOC_LINES}+ lines longer than their body: '
          f"{len(s['long_docs']) - classes} of functions, {classes} of classes")
    print(f"least-squares solves in {len(s['solvers'])} modules: {', '.join(s['solvers'])}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
