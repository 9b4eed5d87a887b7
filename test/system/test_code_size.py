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


"""The limits of issue 33 on ``gyro_tdc/``, measured by ``tools/code_size.py``."""

from __future__ import annotations

from pathlib import Path
import runpy

import pytest

ROOT = Path(__file__).resolve().parents[2]
SIZE = runpy.run_path(str(ROOT / 'tools' / 'code_size.py'))


@pytest.fixture(scope='module')
def survey():
    return SIZE['survey'](ROOT / 'gyro_tdc')


def test_no_module_over_600_lines(survey):
    assert survey['big'] == []


def test_no_function_body_over_80_lines(survey):
    assert survey['long_bodies'] == []


def test_linear_solves_only_in_the_estimator_the_fc_export_and_the_fleet_statistics(survey):
    assert set(survey['solvers']) <= {'signal/estimator.py', 'identify/export.py',
                                      'fleet/stats.py'}


def test_the_count_sees_code_not_docstrings_comments_or_blanks(tmp_path):
    pkg = tmp_path / 'pkg'
    pkg.mkdir()
    (pkg / 'a.py').write_text('"""Doc.\n\nMore doc.\n"""\n\n# comment\nx = (1,\n     2)\n\n\n'
                              'def f():\n    """One line."""\n    return np.linalg.lstsq(a, b)\n')
    (pkg / 'b.py').write_text('from pathlib import Path\nPath(".").resolve()\n' * 301)
    s = SIZE['survey'](tmp_path)
    assert s['per_package']['pkg'] == 4 + 602        # a: x = (1, / 2) / def / return
    assert s['solvers'] == ['pkg/a.py']               # resolve() is no solve
    assert s['big'] == [(602, 'pkg/b.py')]
    long_body = 'def g():\n    """Doc."""\n' + '    y = 1\n' * 81
    (pkg / 'c.py').write_text(long_body)
    assert SIZE['survey'](tmp_path)['long_bodies'] == [(81, 'pkg/c.py:g')]


def test_no_function_docstring_of_15_lines_is_longer_than_its_body(survey):
    assert [name for cls, name in survey['long_docs'] if not cls] == []


def test_long_docstrings_are_counted_against_their_body(tmp_path):
    pkg = tmp_path / 'pkg'
    pkg.mkdir()
    doc = '    """Doc.\n' + '\n' * 13 + '    """\n'         # 15 lines
    (pkg / 'a.py').write_text('def f():\n' + doc + '    return 1\n\n\n'
                              'class C:\n' + doc + '    x: int = 1\n\n\n'
                              'def g():\n' + doc + '    y = 1\n' * 15)
    assert SIZE['survey'](tmp_path)['long_docs'] == [(False, 'pkg/a.py:f'), (True, 'pkg/a.py:C')]
