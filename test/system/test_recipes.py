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
The driver recipes of launch/recipes: each one's compensator fed as that driver publishes.

There is no ``launch`` wheel: each recipe is read with ``xml.etree`` (as test_launch.py reads
the main launch file), its node's remaps, namespace and parameters resolved with the
arguments' defaults (the parameter file as ``--params-file`` would apply it), and a real
CompensatorNode started with them. A publisher that mimics the driver (its topic names,
types, QoS and frame, independent of the recipe) feeds it; every input gives one output.
"""

from __future__ import annotations

from pathlib import Path
import re
import xml.etree.ElementTree as ET

from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import PARAMS
from gyro_tdc.runtime.flags import PASSTHROUGH
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from rosutil import spin_until
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float32
import yaml

ROOT = Path(__file__).resolve().parents[2]
RECIPES = ROOT / 'launch' / 'recipes'
SUBST = re.compile(r'\$\((\S+) ([^)]*)\)')
MODEL = 'l3gd20_modified'
RELIABLE_10 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE)
OUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                     reliability=ReliabilityPolicy.RELIABLE)

# What each driver publishes, from its own sources and documentation (doc/drivers.md):
# IMU topic, QoS and frame; temperature topic and message class (None: the driver has none);
# whether the recipe compensates the rate (False: passed through, upstream already corrects).
DRIVERS = {
    'mavros': dict(imu='/mavros/imu/data_raw', qos=qos_profile_sensor_data, frame='base_link',
                   temp='/mavros/imu/temperature_imu', temp_cls=Temperature, compensates=True),
    'xsens': dict(imu='/imu/data', qos=RELIABLE_10, frame='imu_link', temp='/temperature',
                  temp_cls=Temperature, compensates=True),
    'microstrain': dict(imu='/imu/data_raw', qos=RELIABLE_10, frame='imu_link',
                        temp='/imu/temperature_c', temp_cls=Float32, compensates=True),
    'realsense': dict(imu='/camera/camera/imu', qos=qos_profile_sensor_data,
                      frame='camera_imu_optical_frame', temp=None, temp_cls=None,
                      compensates=False),
    'bno055': dict(imu='/bno055/imu_raw', qos=RELIABLE_10, frame='bno055',
                   temp='/bno055/temp', temp_cls=Temperature, compensates=True),
}


def recipe(name: str) -> ET.Element:
    return ET.parse(RECIPES / f'{name}.launch.xml').getroot()


def resolve(text: str, values: dict) -> str:
    def one(match):
        kind, what = match.group(1), match.group(2)
        if kind == 'var':
            return values[what]
        assert (kind, what) == ('find-pkg-share', 'gyro_tdc'), match.group(0)
        return str(ROOT)
    for _ in range(5):
        text = SUBST.sub(one, text)
    assert '$(' not in text, text
    return text


def node_settings(root: ET.Element, **overrides) -> dict:
    """Return the compensator's namespace, parameters and remaps as ros2 launch gives them."""
    values = {a.get('name'): a.get('default') for a in root.findall('arg')}
    values.update(overrides)
    (node,) = root.findall('node')
    params: dict = {}
    for param in node.findall('param'):
        if param.get('from') is not None:
            doc = yaml.safe_load(Path(resolve(param.get('from'), values)).read_text())
            (section,) = doc.values()      # the file's one node entry
            params.update(section['ros__parameters'])
            continue
        value = resolve(param.get('value'), values)
        params[param.get('name')] = value if param.get('type') == 'str' else \
            yaml.safe_load(value)
    remaps = {r.get('from'): resolve(r.get('to'), values) for r in node.findall('remap')}
    return dict(namespace=resolve(node.get('namespace', ''), values) or None,
                name=node.get('name'), params=params, remaps=remaps)


@pytest.mark.parametrize('name', sorted(DRIVERS))
def test_recipe_is_complete(name, setup_kwargs):
    root = recipe(name)
    args = {a.get('name'): a for a in root.findall('arg')}
    assert {'namespace', 'use_sim_time', 'compensator_params', 'model_file'} <= set(args)
    assert args['model_file'].get('default') is None    # a model of this IMU, never a default
    for arg in args.values():
        assert arg.get('description'), arg.get('name')
    used = {m.group(2) for m in SUBST.finditer((RECIPES / f'{name}.launch.xml').read_text())
            if m.group(1) == 'var'}
    assert used == set(args)
    (node,) = root.findall('node')
    assert (node.get('pkg'), node.get('exec')) == ('gyro_tdc', 'compensator_node')
    settings = node_settings(root, model_file=MODEL)
    specs = {s.name: s for s in PARAMS}
    for key, value in settings['params'].items():
        if key == 'use_sim_time':
            assert value is False
            continue
        spec = specs[key]
        if spec.choices:
            assert value in spec.choices, (key, value)
    assert set(settings['remaps']) == {'imu/data_raw', 'imu/temperature',
                                       'imu/data_compensated'}
    installed = {src: dest for dest, srcs in setup_kwargs['data_files'] for src in srcs}
    assert installed[f'launch/recipes/{name}.launch.xml'] == 'share/gyro_tdc/launch/recipes'


def _imu(frame: str, ns: int) -> Imu:
    msg = Imu()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10 ** 9)
    msg.header.frame_id = frame
    msg.orientation.w = 1.0
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = 0.01, -0.02, 0.03
    msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
    msg.angular_velocity_covariance[8] = 1e-6
    msg.linear_acceleration.z = 9.81
    return msg


@pytest.mark.parametrize('name', sorted(DRIVERS))
def test_recipe_compensates_what_the_driver_publishes(ros_context, name):
    driver = DRIVERS[name]
    s = node_settings(recipe(name), model_file=MODEL, namespace='robot1')
    args = ['--ros-args'] + [x for a, b in s['remaps'].items() for x in ('-r', f'{a}:={b}')]
    executor = make_executor('single', ros_context)
    node = CompensatorNode(context=ros_context, namespace=s['namespace'], cli_args=args,
                           parameter_overrides=[Parameter(k, value=v)
                                                for k, v in s['params'].items()])
    io = rclpy.create_node('mimic_' + name, context=ros_context)
    out: list[Imu] = []
    output = node.resolve_topic_name('imu/data_compensated')
    assert output == '/robot1/imu/data_compensated'
    io.create_subscription(Imu, output, out.append, OUT_QOS)
    imu_pub = io.create_publisher(Imu, driver['imu'], driver['qos'])
    temp_pub = (io.create_publisher(driver['temp_cls'], driver['temp'], driver['qos'])
                if driver['temp'] else None)
    try:
        for n in (node, io):
            executor.add_node(n)
        spin_until(executor, lambda: imu_pub.get_subscription_count() > 0
                   and (temp_pub is None or temp_pub.get_subscription_count() > 0)
                   and node.count_subscribers(output) > 0, 10.0, what='discovery')
        t0 = 1_700_000_000 * 10 ** 9
        sent = 0
        for k in range(6):
            ns = t0 + k * 10_000_000
            if temp_pub is not None:
                before = node.core.temps.received
                if driver['temp_cls'] is Temperature:
                    msg = Temperature()
                    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10 ** 9)
                    msg.header.frame_id = driver['frame']
                    msg.temperature = 31.0
                    temp_pub.publish(msg)
                    spin_until(executor, lambda: node.core.temps.received > before, 10.0,
                               what='temperature in')
                elif k:          # a Float reading takes the latest IMU stamp: after one
                    temp_pub.publish(Float32(data=31.0))
                    spin_until(executor, lambda: node.core.temps.received > before, 10.0,
                               what='temperature in')
            imu_pub.publish(_imu(driver['frame'], ns))
            sent += 1
            spin_until(executor, lambda: len(out) >= sent, 10.0, what=f'output {sent}')
        executor.spin_once(timeout_sec=0.05)
        assert len(out) == sent == 6          # one compensated output per input
        assert all(m.header.frame_id == driver['frame'] for m in out)
        last = out[-1]
        flags = node.core.stream.flags
        if driver['compensates']:
            assert not flags & PASSTHROUGH, flags
            assert (last.angular_velocity.x, last.angular_velocity.y,
                    last.angular_velocity.z) != (0.01, -0.02, 0.03)
        else:                   # no thermometer: the rate passes through, said so
            assert flags & PASSTHROUGH
            assert (last.angular_velocity.x, last.angular_velocity.y,
                    last.angular_velocity.z) == (0.01, -0.02, 0.03)
    finally:
        executor.shutdown()
        io.destroy_node()
        node.destroy_node()
