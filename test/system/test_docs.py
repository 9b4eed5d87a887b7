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
The documentation's generated reference pages, built with warnings as errors.

The whole site (``make docs``) takes minutes; these tests build doc/conf.py with the
generated pages only (nodes, command line, one API page) under a small index of their own,
in a subprocess, and read the HTML: the parameter tables hold every row of the nodes'
``PARAMS`` in order, the command-line page every registered command with every option of
its parser. A build that leaves out a package's API page fails.
"""

from html.parser import HTMLParser
from pathlib import Path
import shutil
import subprocess
import sys

from gyro_tdc.cli import COMMANDS, load_main, PROG
import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / 'doc'

INDEX = """Generated pages
===============

.. toctree::

{pages}
"""


class Page(HTMLParser):
    """An HTML page read as its headings and tables (cell text, under which headings)."""

    def __init__(self, text):
        super().__init__()
        self.headings = []            # (level, text) in page order
        self.tables = []              # (headings above, rows of cell texts)
        self._open = {}               # level -> text of the current heading at that level
        self._text = None             # text being collected (heading or cell)
        self._row = None
        self._in_link = False         # inside a heading's permalink (its icon is no text)
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        if tag == 'a' and 'headerlink' in (dict(attrs).get('class') or ''):
            self._in_link = True
        elif tag in ('h1', 'h2', 'h3', 'h4'):
            self._text = []
        elif tag == 'table':
            context = tuple(self._open[level] for level in sorted(self._open))
            self.tables.append((context, []))
        elif tag == 'tr':
            self._row = []
            self.tables[-1][1].append(self._row)
        elif tag in ('td', 'th'):
            self._text = []

    def handle_endtag(self, tag):
        if tag == 'a':
            self._in_link = False
        elif tag in ('h1', 'h2', 'h3', 'h4') and self._text is not None:
            level, text = int(tag[1]), ''.join(self._text).strip()
            self._open = {k: v for k, v in self._open.items() if k < level}
            self._open[level] = text
            self.headings.append((level, text))
            self._text = None
        elif tag in ('td', 'th') and self._text is not None:
            self._row.append(' '.join(''.join(self._text).split()))
            self._text = None

    def handle_data(self, data):
        if self._text is not None and not self._in_link:
            self._text.append(data)

    def table(self, *context):
        """Return the rows of the one table under the headings ``context`` (last ones)."""
        found = [rows for where, rows in self.tables if where[-len(context):] == context]
        assert len(found) == 1, (context, [where for where, _ in self.tables])
        return found[0]


def build(tmp_path, pages, *options):
    """Build doc/conf.py with ``pages`` (doc/ paths, no suffix) with -W; return the result."""
    src = tmp_path / 'src'
    src.mkdir()
    shutil.copy(DOC / 'conf.py', src / 'conf.py')
    shutil.copytree(DOC / '_ext', src / '_ext', ignore=shutil.ignore_patterns('__pycache__'))
    for page in pages:
        (src / page).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(DOC / f'{page}.rst', src / f'{page}.rst')
    (src / 'index.rst').write_text(INDEX.format(pages=''.join(f'   {p}\n' for p in pages)))
    out = tmp_path / 'html'
    result = subprocess.run(
        [sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q', '-b', 'html',
         *options, str(src), str(out)], capture_output=True, text=True, timeout=600)
    return result, out


@pytest.fixture(scope='module')
def reference(tmp_path_factory):
    """Build the node, command-line and runtime API pages; return the HTML directory."""
    result, out = build(tmp_path_factory.mktemp('docs'),
                        ['reference/nodes', 'reference/cli', 'reference/api/gyro_tdc.runtime'],
                        '-D', 'gyro_tdc_api_every_package=0')
    assert result.returncode == 0, result.stderr
    assert 'WARNING' not in result.stderr and 'ERROR' not in result.stderr, result.stderr
    return out


def test_every_node_parameter_is_a_row_of_its_table(reference):
    from gyro_tdc.nodes.driver_node import PARAMS as DRIVER_PARAMS
    from gyro_tdc.runtime.policy import PARAMS as COMPENSATOR_PARAMS

    page = Page((reference / 'reference' / 'nodes.html').read_text(encoding='utf-8'))
    assert [title for level, title in page.headings if level == 2] == \
        ['compensator_node', 'driver_node']
    for node, params in (('compensator_node', COMPENSATOR_PARAMS),
                         ('driver_node', DRIVER_PARAMS)):
        header, *rows = page.table(node, 'Parameters')
        assert header[:3] == ['Parameter', 'Type', 'Default [unit]']
        assert [row[0] for row in rows] == [spec.name for spec in params]
        assert [row[1] for row in rows] == [type(spec.default).__name__ for spec in params]
        read_only = header.index('Read-only')
        assert [row[read_only] == 'yes' for row in rows] == [s.read_only for s in params]


def test_node_topics_come_from_the_node_classes(reference):
    page = Page((reference / 'reference' / 'nodes.html').read_text(encoding='utf-8'))
    header, *rows = page.table('compensator_node', 'Topics and services')
    entries = {(row[0], row[1]): row[2] for row in rows}
    assert entries[('publishes', 'imu/data_compensated')] == 'sensor_msgs/msg/Imu'
    assert entries[('service', '~/reload')] == 'std_srvs/srv/Trigger'
    # A class loaded by name at run time (sensor_msgs' by default): the parameter that names it.
    assert entries[('subscribes', 'imu/data_raw')] == 'any installed type (by imu_type)'
    assert entries[('subscribes', 'imu/temperature')] == 'any installed type (by temperature_type)'
    # A mixin's subscription, its topic a parameter, its type chosen by another.
    motion = entries[('subscribes', 'parameter motion_topic')]
    assert 'nav_msgs/msg/Odometry' in motion and 'motion_type' in motion
    header, *rows = page.table('driver_node', 'Topics and services')
    assert ('publishes', 'imu/data_raw', 'sensor_msgs/msg/Imu') in {tuple(r[:3]) for r in rows}


def test_every_registered_command_is_documented_with_its_options(reference):
    html = (reference / 'reference' / 'cli.html').read_text(encoding='utf-8')
    page = Page(html)
    assert [title for level, title in page.headings if level == 2] == \
        [f'{PROG} {name}' for name in COMMANDS]
    for name, command in COMMANDS.items():
        load_main(name)
        parser = sys.modules[command.module].build_parser()
        for action in parser._actions:
            for option in action.option_strings:
                assert option in html, (name, option)


def test_api_page_lists_the_face(reference):
    import gyro_tdc.runtime

    page = Page((reference / 'reference' / 'api' / 'gyro_tdc.runtime.html')
                .read_text(encoding='utf-8'))
    header, *rows = page.table('gyro_tdc.runtime', 'Face')
    assert [row[0] for row in rows] == list(gyro_tdc.runtime.__all__)


def test_a_package_without_an_api_page_fails_the_build(tmp_path):
    result, _ = build(tmp_path, ['reference/api/gyro_tdc.runtime'])
    assert result.returncode != 0
    assert 'package gyro_tdc.model has no API page' in result.stderr


def _unnamed_modules(package: str) -> list:
    """Return the modules of ``gyro_tdc.<package>`` its internals page does not name."""
    # Named as ``package.module`` (or ``gyro_tdc.package.module``), or as `module` alone.
    text = (DOC / 'internals' / f'{package}.md').read_text(encoding='utf-8')
    out = []
    for path in sorted((ROOT / 'gyro_tdc' / package).rglob('*.py')):
        if path.name == '__init__.py':
            continue
        dotted = '.'.join(path.relative_to(ROOT).with_suffix('').parts)
        if not (dotted[len('gyro_tdc.'):] in text or f'`{path.stem}`' in text):
            out.append(dotted)
    return out


@pytest.mark.parametrize('package', sorted(p.stem for p in (DOC / 'internals').glob('*.md')
                                           if (ROOT / 'gyro_tdc' / p.stem).is_dir()))
def test_internals_page_names_every_module_of_its_package(package):
    assert _unnamed_modules(package) == []
