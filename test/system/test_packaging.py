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
Packaging: package.xml, setup.py, setup.cfg, the ament marker and ``python -m gyro_tdc``.

colcon builds gyro_tdc as an ament_python package only when catkin_pkg accepts package.xml
(an invalid maintainer e-mail silently downgrades it to a plain Python package), and
``ros2 run gyro_tdc EXE`` only finds executables installed in ``lib/gyro_tdc``.
"""

from __future__ import annotations

import configparser
import os
from pathlib import Path
import re
import subprocess
import sys

from catkin_pkg.package import parse_package
import gyro_tdc
from gyro_tdc.cli import COMMANDS
import pytest

ROOT = Path(__file__).resolve().parents[2]
NODES = ('driver_node', 'compensator_node')


@pytest.fixture(scope='module')
def package():
    warnings = []
    pkg = parse_package(str(ROOT / 'package.xml'), warnings=warnings)
    assert not warnings, warnings
    return pkg


def run_module(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    return subprocess.run([sys.executable, '-m', 'gyro_tdc', *args], cwd=str(ROOT), env=env,
                          capture_output=True, text=True, timeout=120)


def test_package_xml_is_valid_ament_python(package):
    package.validate()
    assert package.package_format == 3
    assert package.name == 'gyro_tdc'
    assert package.get_build_type() == 'ament_python'
    assert [str(lic) for lic in package.licenses] == ['Apache-2.0']
    assert package.maintainers and all(m.email for m in package.maintainers)
    for maintainer in package.maintainers:
        maintainer.validate()  # catkin_pkg's e-mail check


#: rosdep keys of what only training, evaluation, reports and fleet calibration need
#: (rosdistro's rosdep/python.yaml); statsmodels, allantools, dask and pyulog have none.
TRAINING_KEYS = {'python3-scipy', 'python3-matplotlib', 'python3-tqdm', 'python3-rosbags-pip',
                 'python3-pymavlink-pip'}
#: Import names of setup.py's extras_require['train'], which the nodes must never import.
TRAINING_MODULES = ('scipy', 'matplotlib', 'rosbags', 'statsmodels', 'allantools', 'tqdm',
                    'dask', 'distributed', 'pyulog', 'pymavlink')


def _exec_depends(package, **env) -> set:
    package.evaluate_conditions({'ROS_VERSION': '2', 'ROS_PYTHON_VERSION': '3', **env})
    return {d.name for d in package.exec_depends if d.evaluated_condition}


def _ros_imports() -> set:
    """Return the top-level packages the node modules import that are not ours or stdlib."""
    import ast

    found = set()
    for path in (ROOT / 'gyro_tdc' / 'nodes').glob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                found |= {alias.name.split('.')[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                found.add(node.module.split('.')[0])
    return found - set(sys.stdlib_module_names) - {'gyro_tdc', '__future__', 'numpy', 'yaml'}


def test_package_xml_dependencies(package):
    everything = _exec_depends(package)
    robot = _exec_depends(package, GYRO_TDC_TRAINING='0')
    # Every ROS package a node imports directly, for the robot too; numpy and PyYAML.
    assert _ros_imports() >= {'rclpy', 'rcl_interfaces', 'builtin_interfaces', 'sensor_msgs'}
    assert robot == _ros_imports() | {'python3-numpy', 'python3-yaml', 'ros2launch'}
    # Training's rosdep keys unless GYRO_TDC_TRAINING=0 says the robot only compensates.
    assert everything == robot | TRAINING_KEYS
    assert _exec_depends(package, GYRO_TDC_TRAINING='1') == everything
    assert {d.name for d in package.test_depends} >= {
        'ament_copyright', 'ament_flake8', 'ament_pep257', 'python3-pytest'}


def test_setup_splits_the_robot_from_training(setup_kwargs):
    def names(reqs):
        return {re.split(r'[\[<>=]', r)[0].lower() for r in reqs}

    assert names(setup_kwargs['install_requires']) == {'setuptools', 'numpy', 'pyyaml'}
    train = names(setup_kwargs['extras_require']['train'])
    assert train == {m.replace('distributed', 'dask') for m in TRAINING_MODULES} | {'allantools'}
    # requirements.txt pins everything a full install takes.
    pinned = {line.split('==')[0].split('[')[0].strip().lower()
              for line in (ROOT / 'requirements.txt').read_text().splitlines()
              if '==' in line and not line.startswith('#')}
    assert train | {'numpy', 'pyyaml'} <= pinned


# Run in a child interpreter: a meta-path finder refuses every training module, both nodes are
# imported, a CompensatorNode with the shipped model compensates one sample and a DriverNode
# reads a fake IIO gyro; then no training module may be loaded.
_BLOCKED_CHILD = r"""
import importlib.abc
import sys

BLOCKED = set(sys.argv[1].split(','))
refused = []


class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in BLOCKED:
            refused.append(name)
            raise ImportError(f'{name} is a training dependency')
        return None


sys.meta_path.insert(0, Refuse())
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.driver_node import DriverNode
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter

context = Context()
rclpy.init(context=context)
node = CompensatorNode(context=context, parameter_overrides=[
    Parameter('model_file', value=sys.argv[2])])
core = node.core
core.process(100.0, 0.01, 0.02, 0.03)
core.add_temperature(100.0, 30.0)
out = core.process(100.01, 0.01, 0.02, 0.03)
node.destroy_node()
driver = DriverNode(context=context, parameter_overrides=[
    Parameter('backend', value='iio'), Parameter('device_dir', value=sys.argv[3])])
driver.destroy_node()
rclpy.shutdown(context=context)
loaded = sorted({m.split('.')[0] for m in sys.modules} & BLOCKED)
print('flags', out[4], 'refused', refused, 'loaded', loaded)
"""


def test_the_nodes_import_no_training_dependency(tmp_path):
    from fake_iio import l3gd20_files, make_device

    device = make_device(tmp_path, l3gd20_files())
    model = ROOT / 'config' / 'models' / 'l3gd20_modified.yaml'
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([sys.executable, '-c', _BLOCKED_CHILD, ','.join(TRAINING_MODULES),
                           str(model), str(device)], cwd=str(tmp_path), env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == 'flags 0 refused [] loaded []', proc.stdout


def test_versions_agree(package, setup_kwargs):
    assert package.version == setup_kwargs['version'] == gyro_tdc.__version__


def test_setup_data_files(setup_kwargs):
    data_files = {dest: list(srcs) for dest, srcs in setup_kwargs['data_files']}
    assert data_files['share/ament_index/resource_index/packages'] == ['resource/gyro_tdc']
    assert data_files['share/gyro_tdc'] == ['package.xml']
    marker = ROOT / 'resource' / 'gyro_tdc'
    assert marker.is_file() and marker.stat().st_size == 0
    config = ROOT / 'config'
    expected = sorted(p.relative_to(ROOT).as_posix() for p in config.rglob('*')
                      if p.is_file() and not any(part.startswith(('.', '__'))
                                                 for part in p.relative_to(ROOT).parts))
    installed = []
    for dest, srcs in data_files.items():
        for src in srcs:
            if src.startswith('config/'):
                assert dest == 'share/gyro_tdc/' + os.path.dirname(src), (dest, src)
                installed.append(src)
    assert sorted(installed) == expected


def test_setup_packages_and_entry_points(setup_kwargs):
    packages = setup_kwargs['packages']
    assert 'gyro_tdc' in packages and 'gyro_tdc.cli' in packages
    assert not any(p == 'test' or p.startswith('test.') for p in packages)
    scripts = dict(entry.replace(' ', '').split('=')
                   for entry in setup_kwargs['entry_points']['console_scripts'])
    for node in NODES:
        assert scripts[node] == f'gyro_tdc.nodes.{node}:main'
    # One console entry point for the commands, no generic names (train, demo...) in bin/.
    assert scripts.pop('gyro-tdc') == 'gyro_tdc.__main__:main'
    assert set(scripts) == set(NODES)
    assert not set(COMMANDS) & set(scripts)


def test_setup_cfg_installs_executables_for_ros2_run():
    cfg = configparser.ConfigParser(interpolation=None)
    cfg.read(ROOT / 'setup.cfg')
    assert cfg['develop']['script_dir'] == '$base/lib/gyro_tdc'
    assert cfg['install']['install_scripts'] == '$base/lib/gyro_tdc'


def test_setup_cfg_flake8_matches_ament_flake8():
    ament_flake8 = pytest.importorskip('ament_flake8')
    ament = configparser.ConfigParser(interpolation=None)
    ament.read(Path(ament_flake8.__file__).parent / 'configuration' / 'ament_flake8.ini')
    ours = configparser.ConfigParser(interpolation=None)
    ours.read(ROOT / 'setup.cfg')
    for key, value in ament['flake8'].items():
        assert ours['flake8'].get(key, '').replace(' ', '') == value.replace(' ', ''), key


def test_help_lists_every_command():
    proc = run_module('--help')
    assert proc.returncode == 0, proc.stderr
    for name, command in COMMANDS.items():
        assert f'  {name}' in proc.stdout
        assert command.help in proc.stdout
    assert set(COMMANDS) == {'simulate', 'train', 'evaluate', 'discover', 'demo', 'fleet',
                             'export'}


def test_unknown_command_exits_2_with_one_line():
    proc = run_module('no-such-command', '--flag')
    assert proc.returncode == 2
    assert proc.stdout == ''
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert 'no-such-command' in lines[0] and 'simulate' in lines[0]


def test_no_command_prints_usage_and_exits_2():
    proc = run_module()
    assert proc.returncode == 2
    assert 'usage:' in proc.stderr


def _doc_layout() -> set:
    """Return the gyro_tdc/**/*.py paths listed in doc/architecture.md's Layout code block."""
    text = (ROOT / 'doc' / 'architecture.md').read_text(encoding='utf-8')
    section = text.split('\n## Layout\n', 1)[1].split('\n## ', 1)[0]
    block = section.split('```text\n', 1)[1].split('```', 1)[0]
    stack: list = []     # (indent, directory) of the enclosing folders
    paths = set()
    for line in block.splitlines():
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        name = line.split()[0]
        while stack and stack[-1][0] >= indent:
            stack.pop()
        if name.endswith('/'):
            stack.append((indent, name))
        elif name.endswith('.py'):
            path = ''.join(d for _, d in stack) + name
            assert path not in paths, f'{path} is listed twice'
            paths.add(path)
    return paths


def test_doc_layout_lists_every_module():
    listed = _doc_layout()
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / 'gyro_tdc').rglob('*.py')}
    assert sorted(modules - listed) == [], 'modules missing from doc/architecture.md Layout'
    assert sorted(listed - modules) == [], 'doc/architecture.md Layout names missing modules'


def _doc_package_map() -> set:
    """Return the gyro_tdc/**/*.py paths the Package map of doc/architecture.md names."""
    text = (ROOT / 'doc' / 'architecture.md').read_text(encoding='utf-8')
    block = text.split('\n## Package map\n', 1)[1].split('```text\n', 1)[1].split('```', 1)[0]
    paths, package = set(), ''
    for line in block.splitlines()[1:]:          # the first line: the top-level modules
        if line.startswith(' '):                 # the line before, continued
            rest = line
        else:
            package, _, rest = line.partition('/')
        for sub, inner in re.findall(r'(\w+)/\(([^)]*)\)', rest):
            paths |= {f'gyro_tdc/{package.strip()}/{sub}/{m}.py' for m in inner.split()}
        paths |= {f'gyro_tdc/{package.strip()}/{m}.py'
                  for m in re.sub(r'\w+/\([^)]*\)', ' ', rest).split() if not m.endswith('/')}
    return paths


def test_doc_package_map_names_every_module_of_the_core_packages():
    """Every module of a package the map spells out is named there (a package/ alone: none)."""
    named = _doc_package_map()
    spelled = {p.rsplit('/', 1)[0] for p in named}
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / 'gyro_tdc').rglob('*.py')
               if p.name != '__init__.py' and p.parent.relative_to(ROOT).as_posix() in spelled}
    assert sorted(modules - named) == [], 'modules missing from doc/architecture.md Package map'
    assert sorted(named - modules) == [], 'doc/architecture.md Package map names no module'


# -- the apt recipe: what apt gives, what pip adds, and the README that says so ---------------

#: What a robot with apt-installed Jazzy takes from apt (rosdep key: Ubuntu 24.04's version).
APT_PROVIDED = {'numpy': ('python3-numpy', '1.26.4'), 'scipy': ('python3-scipy', '1.11.4'),
                'matplotlib': ('python3-matplotlib', '3.6.3'),
                'pyyaml': ('python3-yaml', '6.0.1')}


def _pins(path: Path) -> dict:
    """Return ``{normalised name: version}`` of a requirements file's ``==`` pins (3.11)."""
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        req, _, marker = line.partition(';')
        if marker and '< "3.11"' in marker:
            continue
        name, sep, version = req.strip().partition('==')
        assert sep, f'{path.name}: {line!r} is not pinned with =='
        pins[name.split('[')[0].strip().lower().replace('_', '-')] = version.strip()
    return pins


def _version(text: str) -> tuple:
    return tuple(int(x) for x in re.findall(r'[0-9]+', text))


def _ranges(setup_kwargs) -> dict:
    """Return ``{normalised name: [(operator, version)]}`` of setup.py's install and train."""
    out = {}
    for req in setup_kwargs['install_requires'] + setup_kwargs['extras_require']['train']:
        name = re.split(r'[\[<>=]', req)[0].strip().lower().replace('_', '-')
        out[name] = re.findall(r'(>=|<=|==|<|>)\s*([0-9][0-9.]*)', req)
    return out


def _within(version: str, bounds: list) -> bool:
    v = _version(version)
    compare = {'>=': v.__ge__, '<=': v.__le__, '==': v.__eq__, '<': v.__lt__, '>': v.__gt__}
    return all(compare[op](_version(b)) for op, b in bounds)


def test_every_pinned_version_is_inside_setup_py_s_range(setup_kwargs):
    ranges = _ranges(setup_kwargs)
    full, robot = _pins(ROOT / 'requirements.txt'), _pins(ROOT / 'requirements-apt.txt')
    apt = {name: version for name, (_, version) in APT_PROVIDED.items()}
    assert _within('2.4.50', [('>=', '2.4.40'), ('<', '2.5')])
    assert not _within('2.5.0', [('>=', '2.4.40'), ('<', '2.5')])
    for source in (full, robot, apt):
        bad = {n: v for n, v in source.items() if n in ranges and not _within(v, ranges[n])}
        assert bad == {}, f'pinned outside setup.py: {bad} ({ranges})'
    assert set(ranges) - {'setuptools'} <= set(full)


def test_package_xml_version_bounds_are_setup_py_s(package, setup_kwargs):
    ranges = _ranges(setup_kwargs)
    package.evaluate_conditions({'ROS_VERSION': '2', 'ROS_PYTHON_VERSION': '3'})
    bounded = {d.name: d for d in package.exec_depends if d.version_gte or d.version_lt}
    assert bounded, 'package.xml bounds no dependency'
    for key, dep in bounded.items():
        name = key.removeprefix('python3-').removesuffix('-pip')
        want = sorted(ranges[name])
        got = sorted([('>=', dep.version_gte)] * bool(dep.version_gte)
                     + [('<', dep.version_lt)] * bool(dep.version_lt))
        assert got == want, (key, got, want)


def test_requirements_apt_adds_to_apt_what_requirements_txt_pins():
    apt, full = _pins(ROOT / 'requirements-apt.txt'), _pins(ROOT / 'requirements.txt')
    assert not set(apt) & set(APT_PROVIDED)          # never pip over apt's builds
    assert not [n for n in apt if n.startswith('ros-')]
    wanted = {n: v for n, v in full.items()
              if n not in APT_PROVIDED and not n.startswith('ros-')}
    assert wanted and {n: apt.get(n) for n in wanted} == wanted
    # pandas 3 needs numpy 2: the pin keeps pip from replacing apt's numpy and scipy.
    assert apt['pandas'].startswith('2.')


def test_package_xml_gets_the_rest_from_apt(package):
    package.evaluate_conditions({'ROS_VERSION': '2', 'ROS_PYTHON_VERSION': '3'})
    exec_depends = {d.name for d in package.exec_depends}
    assert {key for key, _ in APT_PROVIDED.values()} | {'ros2launch'} <= exec_depends
    text = (ROOT / 'package.xml').read_text()
    assert re.findall(r'pip install\s+(\S+)', text) == ['-r'], 'a bare pip install'


def test_make_test_apt_versions_uses_apt_versions():
    text = (ROOT / 'Makefile').read_text()
    pins = re.search(r'^APT_VERSIONS := (.+)$', text, re.M).group(1).split()
    assert {p.split('==')[0].lower(): p.split('==')[1] for p in pins} == \
        {name: version for name, (_, version) in APT_PROVIDED.items()}
    assert re.search(r'^test-apt-versions:', text, re.M)
    assert 'test-apt-versions' not in text.split('\ntest: ', 1)[1].split('\n\n', 1)[0]


def test_readme_apt_recipe_sources_ros_runs_rosdep_and_pips_only_in_a_venv():
    from readme_check import doc_blocks

    readme = (ROOT / 'README.md').read_text(encoding='utf-8')
    section = readme.split('\n## Install\n', 1)[1].split('\n## ', 1)[0]
    for name, (key, version) in APT_PROVIDED.items():
        assert key in section and version in section, key
    blocks = doc_blocks(ROOT)                        # the README's, then every doc page's
    recipe = next(b for b in blocks if any('rosdep install' in line for line in b.lines))
    assert recipe.page == 'README.md' and recipe.section == 'Install'
    assert recipe.skip.startswith('robot only')
    lines = [line.split('#', 1)[0].strip() for line in recipe.lines]
    assert lines.index('source /opt/ros/jazzy/setup.bash') == 1   # first, after the marker
    assert 'cd ~/ws && rosdep install --from-paths src -y --ignore-src' in lines
    venv = next(i for i, line in enumerate(lines) if 'venv --system-site-packages' in line)
    activate = lines.index('. ~/ws/venv/bin/activate')
    assert venv < activate
    for block in blocks:
        for i, line in enumerate(block.lines):
            if re.match(r'\s*(sudo )?pip3? install', line):
                assert block is recipe and i > activate, (block.line, line)
                assert line.split('#')[0].split() == [
                    'pip', 'install', '-r', 'src/gyro_tdc/requirements-apt.txt']
    # The shipped simulated model only with the simulated driver, on every page.
    launches = [line for block in blocks for line in block.lines
                if 'l3gd20_modified' in line and line.startswith('ros2 ')]
    assert launches and all('backend:=sim' in line for line in launches), launches
