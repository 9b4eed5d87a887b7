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
The shipped PlotJuggler layout names topics, fields and diagnostics values that exist.

PlotJuggler names a message field ``/topic/field/subfield`` and a diagnostics value
``/diagnostics/<hardware_id>/<status name>/<key>`` (its DiagnosticArray parser; only values
that parse as a number are plotted). Every curve of config/plotjuggler/gyro_tdc.xml is
checked against the message definitions and against the status a real CompensatorNode
publishes after one compensated sample from gyro_tdc's driver (frame imu_link).
"""

from __future__ import annotations

from pathlib import Path
import xml.etree.ElementTree as ET

from gyro_tdc.nodes.compensator_node import CompensatorNode
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, Temperature

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / 'config' / 'plotjuggler' / 'gyro_tdc.xml'
TOPICS = {'/imu/data_raw': Imu, '/imu/data_compensated': Imu, '/imu/temperature': Temperature}


@pytest.fixture(scope='module')
def layout():
    return ET.parse(LAYOUT).getroot()


def curves(layout) -> list[str]:
    return [c.get('name') for c in layout.iter('curve')]


def field_exists(cls, path: list[str]) -> bool:
    """Return whether ``path`` names a numeric field of message class ``cls``."""
    import importlib

    for i, name in enumerate(path):
        fields = cls.get_fields_and_field_types()
        if name not in fields:
            return False
        kind = fields[name]
        if '/' in kind:                 # a nested message: pkg/Type
            pkg, msg = kind.split('/')
            cls = getattr(importlib.import_module(f'{pkg}.msg'), msg)
            continue
        return i == len(path) - 1 and kind in ('double', 'float', 'int32', 'uint32')
    return False


def test_layout_parses_and_subscribes_to_what_it_plots(layout):
    assert layout.tag == 'root' and layout.find('tabbed_widget') is not None
    splitter = layout.find('.//DockSplitter')
    assert int(splitter.get('count')) == len(splitter.findall('DockArea'))
    plotted = {'/diagnostics' if c.startswith('/diagnostics/') else '/'.join(c.split('/')[:3])
               for c in curves(layout)}
    for plugin in layout.iter('plugin'):
        selected = set(plugin.find('selected_topics').get('value').split(';'))
        assert selected == plotted == set(TOPICS) | {'/diagnostics'}, plugin.get('ID')


def test_message_fields_exist(layout):
    names = [c for c in curves(layout) if not c.startswith('/diagnostics/')]
    for axis in 'xyz':                  # raw beside compensated, per axis
        assert f'/imu/data_raw/angular_velocity/{axis}' in names
        assert f'/imu/data_compensated/angular_velocity/{axis}' in names
    assert '/imu/temperature/temperature' in names
    for name in names:
        parts = name.split('/')
        topic = '/'.join(parts[:3])
        assert field_exists(TOPICS[topic], parts[3:]), name
    assert not field_exists(Imu, ['angular_velocity', 'w'])    # the check can fail


def test_diagnostics_values_exist_and_are_numbers(ros_context, layout):
    node = CompensatorNode(context=ros_context, parameter_overrides=[
        Parameter('model_file', value='l3gd20_modified')])
    try:
        msg = Imu()
        msg.header.stamp.sec = 1_700_000_000
        msg.header.frame_id = 'imu_link'
        msg.angular_velocity_covariance[0] = 1e-6
        temp = Temperature()
        temp.header.stamp.sec = 1_700_000_000
        temp.temperature = 30.0
        node._on_temperature(temp)
        node._on_imu(msg)
        status = node.diagnostic_status()
    finally:
        node.destroy_node()
    values = {kv.key: kv.value for kv in status.values}
    prefix = '/diagnostics/' + (f'{status.hardware_id}/' if status.hardware_id else '') + \
        f'{status.name}/'
    names = [c for c in curves(layout) if c.startswith('/diagnostics/')]
    assert len(names) >= 6
    for name in names:
        assert name.startswith(prefix), (name, prefix)
        key = name[len(prefix):]
        assert key in values, key
        float(values[key])              # PlotJuggler plots only what parses as a number
    assert float(values['temperature degC']) == 30.0 and values['compensated'] == '1'
