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

"""Tests of gyro_tdc.base.preload: background imports never cross the caller's."""

import sys
import textwrap

from gyro_tdc.base import need, preload, start_imports
import pytest


@pytest.fixture
def modules(tmp_path, monkeypatch):
    """Two modules importing each other, the first slow: imports that cross break them."""
    names = [f'gtdc_cross_{tmp_path.name[-6:]}_{k}' for k in 'ab']
    a, b = names
    (tmp_path / f'{a}.py').write_text(textwrap.dedent(f"""
        import time
        time.sleep(0.5)
        from {b} import B
        A = B + 1
    """))
    (tmp_path / f'{b}.py').write_text(textwrap.dedent(f"""
        import {a}
        B = 1
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield names
    for name in names:
        sys.modules.pop(name, None)
    monkeypatch.setattr(preload, '_thread', None)


def test_need_waits_for_the_background_import(modules):
    """The caller's import starts only once the thread's is done: both modules are whole."""
    a, b = modules
    start_imports([a])
    mod_b = need(b)                    # without the wait, b would cross a's import
    assert not preload._thread.is_alive()
    assert mod_b.B == 1 and sys.modules[a].A == 2


def test_a_background_failure_is_the_callers_to_report(modules, tmp_path):
    """The thread swallows a failed import; the caller's own import raises it."""
    start_imports(['gtdc_no_such_module', modules[0]])
    with pytest.raises(ModuleNotFoundError, match='gtdc_no_such_module'):
        need('gtdc_no_such_module')
    assert modules[0] not in sys.modules          # the thread stopped at the failure
    assert need(modules[0]).A == 2
