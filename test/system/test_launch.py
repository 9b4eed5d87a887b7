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
launch/gyro_tdc.launch.xml against the package: executables, parameter files, names, topics.

There is no ``launch``/``launch_ros`` wheel on PyPI, so the file is parsed with
``xml.etree`` and every reference in it is resolved the way ``ros2 launch`` would on an
install tree: ``$(find-pkg-share gyro_tdc)`` is the repository (whose ``config/`` setup.py
installs unchanged) and ``$(var X)`` the argument's default or each of its choices. Where
``launch_ros`` is importable (an apt-installed Jazzy), the description is also loaded with
launch's own XML front end.
"""

from __future__ import annotations

import inspect
import os
from pathlib import Path
import xml.etree.ElementTree as ET

from gyro_tdc.nodes import compensator_node, driver_node
from gyro_tdc.runtime import TEMPERATURE_TYPES
from launch_xml import resolve, SUBST
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'launch' / 'gyro_tdc.launch.xml'
NODES = {'driver_node': driver_node, 'compensator_node': compensator_node}
# Tags and attributes this file may use (launch's XML front end knows these).
TAGS = {'launch': set(), 'arg': {'name', 'default', 'description'}, 'choice': {'value'},
        'node': {'pkg', 'exec', 'name', 'namespace', 'output', 'if'},
        'param': {'from', 'name', 'value', 'type'},
        'remap': {'from', 'to'}}


@pytest.fixture(scope='module')
def tree():
    return ET.parse(LAUNCH).getroot()


@pytest.fixture(scope='module')
def args(tree):
    """Return ``{name: (default or None, [choices], description)}`` of the declared args."""
    out = {}
    for arg in tree.findall('arg'):
        out[arg.get('name')] = (arg.get('default'), [c.get('value') for c in arg],
                                arg.get('description', ''))
    return out


def installed_files(setup_kwargs) -> dict:
    """Return ``{source path: install directory}`` of setup.py's data_files."""
    return {src: dest for dest, srcs in setup_kwargs['data_files'] for src in srcs}


def test_only_known_tags_and_attributes(tree):
    for element in tree.iter():
        assert element.tag in TAGS, element.tag
        assert set(element.attrib) <= TAGS[element.tag], (element.tag, element.attrib)


def test_arguments_are_declared_described_and_used(tree, args):
    text = LAUNCH.read_text()
    used = {m.group(2) for m in SUBST.finditer(text) if m.group(1) == 'var'}
    assert used == set(args)
    for name, (default, choices, description) in args.items():
        assert description, name
        if choices:
            assert default in choices, name
    # No model by default: a robot gets a model trained on its own IMU, never silently the
    # shipped simulated one.
    assert args['model_file'][0] is None
    assert args['temperature_type'][1] == list(TEMPERATURE_TYPES)


def test_nodes_are_the_package_executables(tree, setup_kwargs):
    scripts = dict(e.replace(' ', '').split('=')
                   for e in setup_kwargs['entry_points']['console_scripts'])
    nodes = tree.findall('node')
    assert sorted(n.get('exec') for n in nodes) == sorted(NODES)
    for node in nodes:
        assert node.get('pkg') == 'gyro_tdc'
        assert scripts[node.get('exec')] == f'gyro_tdc.nodes.{node.get("exec")}:main'
        assert node.get('name') == node.get('exec')   # the key of its parameter file


def argument_settings(args):
    """Yield the argument values to check: the defaults, then each choice of each argument."""
    defaults = {k: v[0] if v[0] is not None else 'my_model.yaml' for k, v in args.items()}
    yield defaults
    for name, (_, choices, _) in args.items():
        for choice in choices:
            yield {**defaults, name: choice}


def test_parameter_files_exist_are_installed_and_fit_the_node(tree, args, setup_kwargs):
    installed = installed_files(setup_kwargs)
    for values in argument_settings(args):
        for node in tree.findall('node'):
            exe = node.get('exec')
            specs = {s.name: s for s in NODES[exe].PARAMS}
            for param in node.findall('param'):
                if param.get('from') is None:
                    continue
                path = Path(resolve(param.get('from'), values))
                assert path.is_file(), path
                rel = path.relative_to(ROOT).as_posix()
                assert installed[rel] == 'share/gyro_tdc/' + os.path.dirname(rel), rel
                doc = yaml.safe_load(path.read_text())
                assert list(doc) == ['/**'], path       # any namespace, any node name
                params = doc['/**']['ros__parameters']
                assert set(params) <= set(specs), path
                if exe == 'driver_node':   # driver_<backend>.yaml is that back-end's
                    assert params['backend'] == values['backend']
                    assert values['backend'] in specs['backend'].choices


def test_named_parameters_are_declared_strings(tree):
    for node in tree.findall('node'):
        specs = {s.name: s for s in NODES[node.get('exec')].PARAMS}
        for param in node.findall('param'):
            if param.get('name') is None:
                continue
            if param.get('name') == 'use_sim_time':     # rclpy's own, a bool
                assert param.get('value') == '$(var use_sim_time)'
                continue
            spec = specs[param.get('name')]
            # type="str": an id such as 0042 or a path stays a string, never YAML's int.
            assert param.get('type') == 'str' and isinstance(spec.default, str)


def test_remaps_name_the_nodes_topics(tree):
    for node in tree.findall('node'):
        source = inspect.getsource(NODES[node.get('exec')])
        remaps = [r.get('from') for r in node.findall('remap')]
        assert remaps and len(set(remaps)) == len(remaps)
        for topic in remaps:
            assert f"'{topic}'" in source, (node.get('exec'), topic)


def test_setup_installs_the_launch_file(setup_kwargs):
    assert installed_files(setup_kwargs)['launch/gyro_tdc.launch.xml'] == 'share/gyro_tdc/launch'


def test_launch_front_end_loads_it(args):
    """With launch and launch_ros importable (apt Jazzy): launch's own parser reads it."""
    pytest.importorskip('launch_ros')
    launch = pytest.importorskip('launch')
    from launch.frontend import Parser

    root, parser = Parser.load(str(LAUNCH))
    description = parser.parse_description(root)
    declared = {a.name for a in description.get_launch_arguments()}
    assert declared == set(args)
    assert isinstance(description, launch.LaunchDescription)
