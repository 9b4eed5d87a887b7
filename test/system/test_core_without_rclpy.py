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
Pure core, thin shell: every module outside ``gyro_tdc.nodes`` imports without ROS.

A child interpreter installs a meta-path finder that makes ``rclpy``, the message packages
and ``rosidl*`` unimportable, then imports every module that ``pkgutil`` finds under
``gyro_tdc`` except ``gyro_tdc.nodes`` and reports the result as JSON.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]

BLOCKER = r"""
import importlib.abc
import sys

BLOCKED = ('rclpy', 'sensor_msgs', 'std_msgs', 'geometry_msgs', 'diagnostic_msgs',
           'std_srvs', 'builtin_interfaces', 'rcl_interfaces', 'rosgraph_msgs',
           'action_msgs', 'lifecycle_msgs', 'launch', 'launch_ros')


def blocked(name):
    top = name.partition('.')[0]
    return top in BLOCKED or top.startswith('rosidl')


class BlockRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if blocked(name):
            raise ImportError(f'{name} is blocked: core modules must not import ROS',
                              name=name)
        return None


for name in [m for m in sys.modules if blocked(m)]:
    del sys.modules[name]
sys.meta_path.insert(0, BlockRos())
"""

SWEEP = r"""
import importlib
import json
import pkgutil
import traceback

ROOT = sys.argv[1]
sys.path.insert(0, ROOT)

import gyro_tdc  # noqa: E402

errors = {}


def record(name):
    errors[name] = traceback.format_exc(limit=-3)


def skipped(name):
    return name == 'gyro_tdc.nodes' or name.startswith('gyro_tdc.nodes.')


names = ['gyro_tdc']
for info in pkgutil.iter_modules(gyro_tdc.__path__, 'gyro_tdc.'):
    if skipped(info.name):
        continue
    names.append(info.name)
    if info.ispkg:
        try:
            package = importlib.import_module(info.name)
        except Exception:
            record(info.name)
            continue
        for sub in pkgutil.walk_packages(package.__path__, info.name + '.', onerror=record):
            names.append(sub.name)

imported = []
for name in names:
    if name in errors:
        continue
    try:
        importlib.import_module(name)
    except Exception:
        record(name)
    else:
        imported.append(name)

leaked = sorted(m for m in sys.modules if blocked(m))
print(json.dumps({'file': gyro_tdc.__file__, 'imported': imported, 'errors': errors,
                  'leaked': leaked}))
"""

CHILD = BLOCKER + SWEEP


def run_child() -> dict:
    """Run the import sweep in a fresh interpreter and return its JSON report."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([sys.executable, '-c', CHILD, str(ROOT)], cwd=str(ROOT), env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f'import sweep crashed:\n{proc.stdout}\n{proc.stderr}'
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_blocker_blocks_rclpy():
    code = BLOCKER + (
        'for name in ("rclpy", "sensor_msgs.msg", "rosidl_runtime_py"):\n'
        '    try:\n'
        '        __import__(name)\n'
        '    except ImportError:\n'
        '        print("blocked", name)\n')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.split('\n')[:3] == [
        'blocked rclpy', 'blocked sensor_msgs.msg', 'blocked rosidl_runtime_py'], (
        proc.stdout + proc.stderr)


def test_every_core_module_imports_without_rclpy():
    report = run_child()
    assert Path(report['file']).resolve().parent == ROOT / 'gyro_tdc', report['file']
    assert not report['errors'], 'modules that fail to import without ROS:\n' + '\n'.join(
        f'--- {name}\n{text}' for name, text in sorted(report['errors'].items()))
    assert not report['leaked'], f'ROS modules imported anyway: {report["leaked"]}'
    for expected in ('gyro_tdc', 'gyro_tdc.errors', 'gyro_tdc.data.runs',
                     'gyro_tdc.base.resources', 'gyro_tdc.cli', 'gyro_tdc.__main__'):
        assert expected in report['imported']
    assert not any(name.startswith('gyro_tdc.nodes') for name in report['imported'])
