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
A package's face: the names other packages use, each imported from its module on first use.

A face imports nothing until a name is asked for, so importing one name of a package loads
one module (the compensator never loads the trainer's scipy or rosbags). A name that is also
the name of its module (``plain`` in ``base/plain.py``) is bound when the face is built: the
import of the module would otherwise set the package attribute to the module itself.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping, Sequence

__all__ = ['lazy']


def lazy(package: str, modules: Mapping[str, Sequence[str]]
         ) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """
    Build ``__all__``, ``__getattr__`` and ``__dir__`` of a package from its modules' names.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    modules : mapping of str to sequence of str
        Module (relative to ``package``) -> the public names it defines that the face shows.

    Returns
    -------
    tuple
        ``(__all__, __getattr__, __dir__)`` for the package's ``__init__``.

    """
    where = {name: module for module, names in modules.items() for name in names}
    names = sorted(where, key=str.lower)

    def __getattr__(name: str) -> Any:
        try:
            module = where[name]
        except KeyError:
            raise AttributeError(f'module {package!r} has no attribute {name!r}') from None
        value = getattr(importlib.import_module(f'{package}.{module}'), name)
        setattr(importlib.import_module(package), name, value)
        return value

    for name, module in where.items():
        if name == module:
            __getattr__(name)
    return names, __getattr__, names.copy       # __dir__: a new list of the names each time
