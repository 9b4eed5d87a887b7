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
The shipped parameter files apply wherever the node runs; QoS through ``qos_overrides.``.

Each test starts ``compensator_node`` as a child process under ``/mavros`` with another node
name, as a launch include or a driver recipe starts it, and reads it back from a test node:
parameters through the parameter service, QoS from the graph.
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import PARAMS
import pytest
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import ReliabilityPolicy
from rosutil import interrupt, node_process, request_until_answered, spin_until
import yaml

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config'
NODE = 'gyro_tdc.nodes.compensator_node'
WHERE = ('-r', '__ns:=/mavros', '-r', '__node:=gyro_comp')


def shipped(name: str) -> dict:
    """Return the ``ros__parameters`` of a shipped parameter file, checked to be keyed ``/**``."""
    doc = yaml.safe_load((CONFIG / name).read_text())
    assert list(doc) == ['/**']
    return doc


def write(tmp_path: Path, doc: dict) -> str:
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def read_back(ros_context, names: list[str], node_name: str = '/mavros/gyro_comp') -> dict:
    """Read parameters of a node (default /mavros/gyro_comp) through its parameter service."""
    import rclpy
    node = rclpy.create_node('param_reader', context=ros_context)
    executor = make_executor('single', ros_context)
    executor.add_node(node)
    try:
        client = AsyncParameterClient(node, node_name)
        # Another process: 60 s, as every wait for one (a child starved under load answered
        # none of six requests in 30 s).
        spin_until(executor, lambda: client.services_are_ready(), 60.0,
                   what=f'parameter services of {node_name}')
        answer = request_until_answered(executor, lambda: client.get_parameters(names),
                                        60.0, what=f'get_parameters of {node_name}')
        values = [parameter_value_to_python(v) for v in answer.values]
        return dict(zip(names, values))
    finally:
        executor.shutdown()
        node.destroy_node()


def test_shipped_file_applies_under_a_namespace_and_a_new_name(ros_context, tmp_path):
    doc = shipped('compensator.yaml')
    doc['/**']['ros__parameters']['stale_policy'] = 'passthrough'   # not the default
    doc['/**']['ros__parameters']['temperature_timeout'] = 2.5
    names = [s.name for s in PARAMS]
    with node_process(NODE, *WHERE, '--params-file', write(tmp_path, doc)) as child:
        values = read_back(ros_context, names)
        code, log = interrupt(child)
    assert code == 0, log
    expect = dict(doc['/**']['ros__parameters'])
    assert values == expect
    assert values['stale_policy'] == 'passthrough' != next(
        s.default for s in PARAMS if s.name == 'stale_policy')


def test_the_still_logger_file_overlays_the_shipped_defaults(ros_context, tmp_path):
    """Given after compensator.yaml, still_logger.yaml turns learning on; the rest stays."""
    base = shipped('compensator.yaml')
    overlay = shipped('still_logger.yaml')['/**']['ros__parameters']
    known = {s.name: s.default for s in PARAMS}
    assert set(overlay) <= set(known) and overlay['learn'] is True
    assert known['learn'] is False                          # the node's default stays off
    names = [s.name for s in PARAMS]
    with node_process(NODE, *WHERE, '--params-file', str(CONFIG / 'compensator.yaml'),
                      '--params-file', str(CONFIG / 'still_logger.yaml')) as child:
        values = read_back(ros_context, names)
        code, log = interrupt(child)
    assert code == 0, log
    assert values == {**base['/**']['ros__parameters'], **overlay}


@pytest.mark.parametrize('name', ['driver_sim.yaml', 'driver_iio.yaml'])
def test_driver_files_are_keyed_for_any_node(name):
    doc = shipped(name)
    assert doc['/**']['ros__parameters']['backend'] in ('sim', 'iio')


def test_driver_file_applies_under_a_namespace_and_a_new_name(ros_context, tmp_path):
    from gyro_tdc.nodes.driver_node import PARAMS as DRIVER_PARAMS
    doc = shipped('driver_sim.yaml')
    params = doc['/**']['ros__parameters']
    params.update(scenario='demo_fast', seed=7)             # seed: not the default
    assert next(s.default for s in DRIVER_PARAMS if s.name == 'seed') != 7
    with node_process('gyro_tdc.nodes.driver_node', '-r', '__ns:=/mavros', '-r',
                      '__node:=imu_driver', '--params-file', write(tmp_path, doc)) as child:
        values = read_back(ros_context, list(params), '/mavros/imu_driver')
        code, log = interrupt(child)
    assert code == 0, log
    assert values == params


def test_invalid_value_in_the_file_is_reported_under_a_namespace(tmp_path):
    doc = shipped('compensator.yaml')
    doc['/**']['ros__parameters']['stale_policy'] = 'sometimes'
    done = subprocess.run([sys.executable, '-m', NODE, '--ros-args', *WHERE, '--params-file',
                           write(tmp_path, doc)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    errors = [x for x in done.stderr.splitlines() if x.strip()]
    assert len(errors) == 1 and 'Traceback' not in done.stderr + done.stdout
    assert errors[0].startswith('compensator_node: error: ')
    assert 'stale_policy' in errors[0] and 'sometimes' in errors[0]


def test_qos_overrides_make_the_input_reliable(ros_context, tmp_path):
    import rclpy
    doc = shipped('compensator.yaml')
    params = doc['/**']['ros__parameters']
    assert params['input_reliability'] == 'best_effort'            # the default stays
    params['qos_overrides'] = {'/mavros/imu/data_raw': {'subscription': {
        'reliability': 'reliable'}}}
    node = rclpy.create_node('graph_reader', context=ros_context)
    executor = make_executor('single', ros_context)
    executor.add_node(node)
    try:
        with node_process(NODE, *WHERE, '--params-file', write(tmp_path, doc)) as child:
            def endpoints(topic):
                return [i for i in node.get_subscriptions_info_by_topic(topic)
                        if i.node_name == 'gyro_comp' and i.node_namespace == '/mavros']

            spin_until(executor, lambda: endpoints('/mavros/imu/data_raw')
                       and endpoints('/mavros/imu/temperature'), 20.0,
                       what='the subscriptions of /mavros/gyro_comp')
            (imu,) = endpoints('/mavros/imu/data_raw')
            (temp,) = endpoints('/mavros/imu/temperature')
            code, log = interrupt(child)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert code == 0, log
    assert imu.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    # Not overridden: the temperature keeps its default, sensor data (best effort).
    assert temp.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
