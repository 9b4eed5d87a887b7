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
The nodes' command lines, as child processes: --help, and configuration errors in one line.

``--help``/``-h`` prints the parameter table and exits 0 before ``rclpy.init`` (a node that
started would never exit: the timeout would fail the test). A bad parameter, an unknown
back-end or scenario prints one line naming the parameter and what is allowed, exit 2, no
traceback, nothing retried.
"""

from __future__ import annotations

import os
import subprocess
import sys

from gyro_tdc.base.paramspec import help_requested
from gyro_tdc.base.resources import scenario_names
from gyro_tdc.nodes import compensator_node, driver_node
from gyro_tdc.runtime import TEMPERATURE_TYPES
import pytest

NODES = {'driver_node': driver_node, 'compensator_node': compensator_node}


def run(module: str, *args: str) -> subprocess.CompletedProcess:
    """Run ``python -m gyro_tdc.nodes.MODULE ARGS`` in the test's ROS environment."""
    return subprocess.run([sys.executable, '-m', f'gyro_tdc.nodes.{module}', *args],
                          env=dict(os.environ), capture_output=True, text=True, timeout=60)


def one_error_line(proc: subprocess.CompletedProcess, prog: str) -> str:
    """Check a refused start: exit 2, one line on stderr, no traceback; return the line."""
    assert proc.returncode == 2, proc.stderr
    assert 'Traceback' not in proc.stderr + proc.stdout
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f'{prog}: error: ')
    return lines[0]


@pytest.mark.parametrize('flag', ['--help', '-h'])
@pytest.mark.parametrize('prog', sorted(NODES))
def test_help_prints_every_parameter_and_exits_0(prog, flag):
    proc = run(prog, flag)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ''
    out = proc.stdout
    assert out.startswith(f'usage: {prog} [-h] [--ros-args')
    assert max(len(line) for line in out.splitlines()) <= 79
    entries = {}         # name: the entry's facts (first lines, to its description)
    for line in out.split('parameters (', 1)[1].splitlines()[1:]:
        if line.startswith('  ') and not line.startswith('   '):
            name, _, facts = line.strip().partition(': ')
            entries[name] = facts
        elif line.startswith('    ') and not line.startswith('      '):
            entries[name] += ' ' + line.strip()
    assert list(entries) == [spec.name for spec in NODES[prog].PARAMS]
    for spec in NODES[prog].PARAMS:
        row = entries[spec.name]
        assert type(spec.default).__name__ in row
        if isinstance(spec.default, float):     # typed as -p NAME:= takes it
            assert f'default {spec.default!r}' in row
        if spec.unit:
            assert f'; {spec.unit}' in row, row
        for choice in spec.choices:
            assert choice in row


def test_help_after_ros_arguments_is_still_help():
    proc = run('compensator_node', '--ros-args', '-p', 'executor:=single', '--', '--help')
    assert proc.returncode == 0 and 'temperature_type: str' in proc.stdout


def test_help_is_looked_for_outside_the_ros_arguments_only():
    assert help_requested(['driver_node', '--help'])
    assert help_requested(['driver_node', '--ros-args', '-p', 'seed:=1', '--', '-h'])
    assert not help_requested(['driver_node'])
    assert not help_requested(['--help'])                       # the program name
    assert not help_requested(['driver_node', '--ros-args', '-p', 'frame_id:=-h'])
    assert not help_requested(['driver_node', '--ros-args', '--help'])


def test_unknown_backend_names_the_choices():
    line = one_error_line(run('driver_node', '--ros-args', '-p', 'backend:=foo'),
                          'driver_node')
    assert '`backend`' in line and "'foo'" in line and 'sim' in line and 'iio' in line


def test_retry_max_below_retry_initial_is_refused_in_one_line():
    line = one_error_line(run('driver_node', '--ros-args', '-p', 'retry_initial:=2.0', '-p',
                              'retry_max:=1.0'), 'driver_node')
    assert '`retry_max`' in line and '`retry_initial`' in line and '1.0' in line


def test_run_index_beyond_the_scenario_is_refused_by_name():
    line = one_error_line(run('driver_node', '--ros-args', '-p', 'run_index:=10000'),
                          'driver_node')
    assert "scenario 'l3gd20_paper': " in line and '`run_index`' in line
    assert 'Scenario(' not in line and len(line) < 200


def test_unknown_scenario_names_the_shipped_ones_and_is_not_retried():
    proc = run('driver_node', '--ros-args', '-p', 'scenario:=nope')
    line = one_error_line(proc, 'driver_node')
    assert "'nope'" in line
    for name in scenario_names():
        assert name in line
    assert 'device error' not in proc.stderr + proc.stdout and 'retry' not in line


def test_simulated_run_too_large_is_refused_before_simulating():
    line = one_error_line(run('driver_node', '--ros-args', '-p', 'sim_rate_hz:=100000.0'),
                          'driver_node')
    assert 'sim_rate_hz' in line and 'GB' in line


@pytest.mark.parametrize('prog, arg, needles', [
    ('driver_node', 'seed:=abc', ('seed',)),
    ('driver_node', 'time_scale:=-1.0', ('time_scale',)),
    ('compensator_node', 'temperature_type:=Float32', ('temperature_type', *TEMPERATURE_TYPES)),
    ('compensator_node', 'out_of_range:=wrap', ('out_of_range', 'linear', 'clamp')),
    ('compensator_node', 'queue_depth:=0', ('queue_depth',)),
])
def test_bad_parameter_is_one_line(prog, arg, needles):
    line = one_error_line(run(prog, '--ros-args', '-p', arg), prog)
    for needle in needles:
        assert needle in line
