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
types, QoS, frame, covariance and temperature quirk, from the driver's source, independent
of the recipe) feeds it; every input gives one output, equal to the pure core's output for
the same samples in FLU. Types not installed here are mimicked by installed ones of the same
field shape: px4_msgs SensorGyro (x, y, z in FRD and the temperature in one message) by
geometry_msgs QuaternionStamped (quaternion x, y, z and w), MicroStrain's
MipSensorTemperatureStatistics (a float32, stamped by a nested header) by stereo_msgs
DisparityImage (min_disparity, image.header.stamp); the recipes' own field paths are checked
against the drivers' real definitions (their .msg text, read with rosbags).
"""

from __future__ import annotations

from pathlib import Path
import re
import xml.etree.ElementTree as ET

from compensator_rig import stamp_s
from driver_msgs import DRIVER_MSGS, driver_typestore
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from gyro_tdc.data import check_number, check_vector, diagonal_marked, stamp_kind
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import CompensatorCore, PARAMS
from gyro_tdc.runtime.flags import PASSTHROUGH
from launch_xml import resolve, SUBST
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rosutil import matched_readers, matched_writers, spin_until
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float32
from stereo_msgs.msg import DisparityImage
import yaml

ROOT = Path(__file__).resolve().parents[2]
RECIPES = ROOT / 'launch' / 'recipes'
MODEL = 'l3gd20_modified'
RELIABLE_10 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE)
RELIABLE_5 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                        reliability=ReliabilityPolicy.RELIABLE)
RELIABLE_1 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE)
#: PX4 uXRCE-DDS writers (uxrce_dds_client/utilities.hpp): best effort, transient local.
BEST_EFFORT_TRANSIENT = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                                   reliability=ReliabilityPolicy.BEST_EFFORT,
                                   durability=DurabilityPolicy.TRANSIENT_LOCAL)
OUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                     reliability=ReliabilityPolicy.RELIABLE)

# What each driver publishes, from its own sources (cited in each recipe and doc/drivers.md):
# IMU topic, message class and builder (stamp ns, FLU rate) -> message, QoS and frame;
# temperature topic, class and builder (stamp ns, degC) -> message (None: the driver has
# none; an external thermometer when ``external``); ``mimic``: the parameters that replace
# types not installed here (px4_msgs, microstrain_inertial_msgs) by installed ones of the
# same field shape; ``compensates`` (False: passed through); ``unknown_cov``: the driver
# leaves the rate covariance all zero (REP 145 unknown: the output stays so, marked).


def _stamp(header, ns):
    header.stamp.sec, header.stamp.nanosec = divmod(ns, 10 ** 9)


def _imu_builder(frame, cov):
    def build(ns, w):
        msg = Imu()
        _stamp(msg.header, ns)
        msg.header.frame_id = frame
        msg.orientation.w = 1.0
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
        for k in (0, 4, 8):
            msg.angular_velocity_covariance[k] = cov
        msg.linear_acceleration.z = 9.81
        return msg
    return build


def _vector_builder(frame):
    """Return what Xsens publishes on /imu/angular_velocity: a Vector3Stamped."""
    def build(ns, w):
        msg = Vector3Stamped()
        _stamp(msg.header, ns)
        msg.header.frame_id = frame
        msg.vector.x, msg.vector.y, msg.vector.z = w
        return msg
    return build


def _temperature_builder(frame, encode=float):
    def build(ns, value):
        msg = Temperature()
        _stamp(msg.header, ns)
        msg.header.frame_id = frame
        msg.temperature = encode(value)
        return msg
    return build


def _float_builder(ns, value):
    return Float32(data=value)


def _mip_builder(ns, value):
    """Return MicroStrain's temperature statistics' shape: a float32 under a nested header."""
    msg = DisparityImage()
    _stamp(msg.image.header, ns)
    msg.min_disparity = value
    return msg


def _sensor_gyro_builder(ns, w, temp=31.0):
    """
    Return SensorGyro's shape: x, y, z in FRD and the temperature in one message.

    The real SensorGyro has no header (the recipe's frame_id, base_link, names the output);
    the mimic's header carries that frame and the stamp SensorGyro keeps in microseconds.
    """
    msg = QuaternionStamped()
    _stamp(msg.header, ns)
    msg.header.frame_id = 'base_link'
    msg.quaternion.x, msg.quaternion.y, msg.quaternion.z = w[0], -w[1], -w[2]
    msg.quaternion.w = temp
    return msg


DRIVERS = {
    'mavros': dict(imu='/mavros/imu/data_raw', imu_cls=Imu,
                   imu_msg=_imu_builder('base_link', 1.2e-7), qos=qos_profile_sensor_data,
                   frame='base_link', temp='/mavros/imu/temperature_imu', temp_cls=Temperature,
                   temp_msg=_temperature_builder('base_link'), compensates=False),
    'xsens': dict(imu='/imu/angular_velocity', imu_cls=Vector3Stamped,
                  imu_msg=_vector_builder('imu_link'), qos=RELIABLE_5, frame='imu_link',
                  temp='/temperature', temp_cls=Temperature,
                  temp_msg=_temperature_builder('imu_link'), compensates=True,
                  unknown_cov=True),
    'microstrain': dict(imu='/imu/data_raw', imu_cls=Imu, imu_msg=_imu_builder('imu_link', 1e-6),
                        qos=RELIABLE_10, frame='imu_link',
                        temp='/mip/sensor/temperature_statistics', temp_cls=DisparityImage,
                        temp_msg=_mip_builder, compensates=True,
                        mimic=dict(temperature_type='stereo_msgs/msg/DisparityImage',
                                   temperature_field='min_disparity',
                                   temperature_stamp_field='image.header.stamp')),
    'realsense': dict(imu='/camera/camera/imu', imu_cls=Imu,
                      imu_msg=_imu_builder('camera_imu_optical_frame', 1e-6),
                      qos=qos_profile_sensor_data, frame='camera_imu_optical_frame',
                      temp=None, compensates=False),
    'bno055': dict(imu='/bno055/imu_raw', imu_cls=Imu, imu_msg=_imu_builder('bno055', 2e-5),
                   qos=RELIABLE_10, frame='bno055', temp='/bno055/temp', temp_cls=Temperature,
                   # float(buf[44]): the register read unsigned, -5 degC reads 251
                   temp_msg=_temperature_builder('bno055', lambda t: float(int(t) % 256)),
                   temp_c=-5.0, compensates=True),
    'vectornav': dict(imu='/vectornav/imu_uncompensated', imu_cls=Imu,
                      imu_msg=_imu_builder('vectornav', 0.0), qos=RELIABLE_10,
                      frame='vectornav', temp='/vectornav/temperature', temp_cls=Temperature,
                      temp_msg=_temperature_builder('vectornav'), compensates=True,
                      unknown_cov=True),
    'um7': dict(imu='/imu/data', imu_cls=Imu,
                imu_msg=_imu_builder('imu_link', (0.06 * 3.14159 / 180.0) ** 2),
                qos=RELIABLE_1, frame='imu_link', temp='/imu/temperature', temp_cls=Float32,
                temp_msg=_float_builder, compensates=True),
    'sbg': dict(imu='/imu/data', imu_cls=Imu, imu_msg=_imu_builder('imu_link', 0.0),
                qos=RELIABLE_10, frame='imu_link', temp='/imu/temp', temp_cls=Temperature,
                # the legacy IMU log's temperature divided by 256 once too often
                temp_msg=_temperature_builder('imu_link', lambda t: t / 256.0),
                compensates=True, unknown_cov=True),
    'px4_dds': dict(imu='/fmu/out/sensor_gyro', imu_cls=QuaternionStamped,
                    imu_msg=_sensor_gyro_builder, qos=BEST_EFFORT_TRANSIENT, frame='base_link',
                    temp='/fmu/out/sensor_gyro', temp_cls=None, compensates=True,
                    unknown_cov=True,
                    mimic=dict(imu_type='geometry_msgs/msg/QuaternionStamped',
                               angular_velocity_field='quaternion',
                               stamp_field='header.stamp',
                               temperature_type='geometry_msgs/msg/QuaternionStamped',
                               temperature_field='quaternion.w',
                               temperature_stamp_field='header.stamp')),
    'ouster': dict(imu='/ouster/imu', imu_cls=Imu, imu_msg=_imu_builder('os_imu', 6e-4),
                   qos=qos_profile_sensor_data, frame='os_imu', temp='/ouster/imu_temperature',
                   temp_cls=Temperature, temp_msg=_temperature_builder('os_imu'),
                   compensates=True),
    'livox': dict(imu='/livox/imu', imu_cls=Imu, imu_msg=_imu_builder('livox_frame', 0.0),
                  qos=RELIABLE_10, frame='livox_frame', temp='/livox/imu_temperature',
                  temp_cls=Temperature, temp_msg=_temperature_builder('livox_frame'),
                  compensates=True, unknown_cov=True),
}


def recipe(name: str) -> ET.Element:
    return ET.parse(RECIPES / f'{name}.launch.xml').getroot()


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
    # It cites what it was checked against (repository, files, commit or version), and the
    # drivers page shows how to start it.
    text = (RECIPES / f'{name}.launch.xml').read_text()
    cited = re.search(r'Checked against ([\w-]+/[\w.-]+)', text)
    assert cited and re.search(r'\b[0-9a-f]{7}\b', text), name
    assert f'recipes/{name}.launch.xml' in (ROOT / 'doc' / 'drivers.md').read_text()
    assert set(DRIVERS) == {p.name.split('.')[0] for p in RECIPES.glob('*.launch.xml')}


@pytest.mark.parametrize('name', sorted(DRIVERS))
def test_recipe_fields_hold_in_the_drivers_types(name):
    """Each recipe's type and field parameters are valid for the driver's own definitions."""
    from gyro_tdc.data.driver_bags import field_table
    from gyro_tdc.nodes.compensator_inputs import message_class
    fields_of = field_table(driver_typestore())
    p = {s.name: s.default for s in PARAMS}
    p.update(node_settings(recipe(name), model_file=MODEL)['params'])
    for which in ('imu_type', 'temperature_type'):
        if p[which] not in DRIVER_MSGS:        # installed here: the class loads
            message_class(p[which], which)
    if p['imu_type'] != 'sensor_msgs/msg/Imu':
        check_vector(p['imu_type'], p['angular_velocity_field'], fields_of, 'x')
        stamp_kind(p['imu_type'], p['stamp_field'], fields_of, 'x')
    field = p['temperature_field'] or {'sensor_msgs/msg/Temperature': 'temperature',
                                       'std_msgs/msg/Float32': 'data'}[p['temperature_type']]
    check_number(p['temperature_type'], field, fields_of, 'x')
    if p['temperature_stamp_field']:
        stamp_kind(p['temperature_type'], p['temperature_stamp_field'], fields_of, 'x')


@pytest.mark.parametrize('name', sorted(DRIVERS))
def test_recipe_compensates_what_the_driver_publishes(ros_context, name):
    driver = DRIVERS[name]
    s = node_settings(recipe(name), model_file=MODEL, namespace='robot1')
    params = {**s['params'], **driver.get('mimic', {})}
    args = ['--ros-args'] + [x for a, b in s['remaps'].items() for x in ('-r', f'{a}:={b}')]
    executor = make_executor('single', ros_context)
    node = CompensatorNode(context=ros_context, namespace=s['namespace'], cli_args=args,
                           parameter_overrides=[Parameter(k, value=v)
                                                for k, v in params.items()])
    io = rclpy.create_node('mimic_' + name, context=ros_context)
    out: list[Imu] = []
    output = node.resolve_topic_name('imu/data_compensated')
    assert output == '/robot1/imu/data_compensated'
    io.create_subscription(Imu, output, out.append, OUT_QOS)
    imu_pub = io.create_publisher(driver['imu_cls'], driver['imu'], driver['qos'])
    temp_pub = (io.create_publisher(driver['temp_cls'], driver['temp'], driver['qos'])
                if driver['temp'] and driver['temp_cls'] else None)
    temp_c = driver.get('temp_c', 31.0)
    w = (0.01, -0.02, 0.03)
    try:
        for n in (node, io):
            executor.add_node(n)
        spin_until(executor, lambda: imu_pub.get_subscription_count() > 0
                   and (temp_pub is None or temp_pub.get_subscription_count() > 0)
                   and matched_writers(node, imu_pub.topic_name) > 0
                   and (temp_pub is None or matched_writers(node, temp_pub.topic_name) > 0)
                   and matched_readers(node, output) > 0
                   and matched_writers(io, output) > 0, 10.0, what='discovery')
        t0 = 1_700_000_000 * 10 ** 9
        sent = 0
        for k in range(6):
            ns = t0 + k * 10_000_000
            stamped = driver.get('temp_cls') is not Float32
            if temp_pub is not None and (stamped or k):   # a Float takes the latest IMU stamp
                before = node.core.temps.received
                temp_pub.publish(driver['temp_msg'](ns, temp_c))
                spin_until(executor, lambda: node.core.temps.received > before, 10.0,
                           what='temperature in')
            imu_pub.publish(driver['imu_msg'](ns, w))
            sent += 1
            spin_until(executor, lambda: len(out) >= sent, 10.0, what=f'output {sent}')
        executor.spin_once(timeout_sec=0.05)
        assert len(out) == sent == 6          # one compensated output per input
        assert all(m.header.frame_id == driver['frame'] for m in out)
        last = out[-1]
        flags = node.core.stream.flags
        got = (last.angular_velocity.x, last.angular_velocity.y, last.angular_velocity.z)
        if driver['temp']:
            # The reading as the driver encodes it, decoded (quirk) to what the model takes.
            assert node.core.temps.latest[0] == pytest.approx(temp_c, abs=1e-6)
        if driver['compensates']:
            assert not flags & PASSTHROUGH, flags
            # The same samples through the pure core, in FLU: the node read every field
            # (FRD turned back, quirk undone, stamps) as the Imu + Temperature path would.
            ref = CompensatorCore(node.core.policy, node.core.model)
            for k in range(6):
                ns = t0 + k * 10_000_000
                if driver.get('temp_cls') is not Float32:
                    ref.add_temperature(stamp_s(ns), temp_c)
                elif k:
                    ref.add_temperature(stamp_s(ns - 10_000_000), temp_c)
                want = ref.process(stamp_s(ns), *w)[:3]
            assert got == pytest.approx(want, abs=1e-12, rel=0)
            assert got != pytest.approx(w, abs=1e-6)
        else:                   # no thermometer, or corrected upstream: passed through
            assert flags & PASSTHROUGH
            assert got == w
        cov = last.angular_velocity_covariance
        if driver.get('unknown_cov'):   # REP 145 unknown stays unknown, and is marked
            assert not any(cov)
            assert diagonal_marked(cov) is driver['compensates']
        else:
            assert diagonal_marked(cov) is driver['compensates']
    finally:
        executor.shutdown()
        io.destroy_node()
        node.destroy_node()
