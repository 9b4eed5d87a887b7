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
Import slow modules in a thread while the bags are read, never beside the caller's import.

Two threads importing modules that import one another can each get the other's module
partially initialised (CPython breaks the import-lock deadlock that way: "cannot import name
... from partially initialized module"). scipy's packages do import one another: the
trainer's background import of ``scipy.cluster.vq`` and the fit's own, on a loaded machine,
crashed ``train``. :func:`start_imports` imports in a daemon thread; :func:`need` waits for
it before it imports a module in the caller's thread.
"""

from __future__ import annotations

import importlib
import threading
from types import ModuleType
from typing import Sequence

__all__ = ['need', 'start_imports']

_thread: threading.Thread | None = None


def start_imports(names: Sequence[str]) -> None:
    """Import the modules ``names`` in a daemon thread (a failure is left to :func:`need`)."""
    global _thread

    def run() -> None:
        for name in names:
            try:
                importlib.import_module(name)
            except Exception:   # noqa: B902 (raised again where the caller imports it)
                return

    _thread = threading.Thread(target=run, name='gyro_tdc import', daemon=True)
    _thread.start()


def need(name: str) -> ModuleType:
    """Return the module ``name``, imported once no background import runs beside it."""
    thread = _thread
    if thread is not None and thread is not threading.current_thread():
        thread.join()
    return importlib.import_module(name)
