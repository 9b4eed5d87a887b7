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
Shared pytest set-up: DDS isolation for this run and a fresh rclpy context per test.

The environment is set at import time, before any test module can import ``rclpy``:
discovery stays on loopback and, unless the caller chose one, this run gets its own
``ROS_DOMAIN_ID`` (1..101, from the process id) so parallel runs do not talk to each other.
``rclpy`` itself is imported only inside the ``ros_context`` fixture, so pure tests never load
it. Use ``rosutil.spin_until`` to wait on a condition with a deadline. The tests mirror the
packages (``test/<package>/test_<module>.py``); shared helpers live in ``test/support/``, which
is put on ``sys.path`` here, and system suites (lint, packaging, hostile input, docs) in
``test/system/``.
"""

import os
from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent / 'support'))

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
if not os.environ.get('ROS_DOMAIN_ID'):
    os.environ['ROS_DOMAIN_ID'] = str(os.getpid() % 101 + 1)

import pytest  # noqa: E402


def pytest_configure(config):
    """Register the ``copyright`` marker (no ament_copyright wheel provides it)."""
    config.addinivalue_line('markers', 'copyright: marks tests checking for copyright headers')


def pytest_report_header(config):
    """Show the DDS isolation settings of this run in pytest's header."""
    return (f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")


@pytest.fixture
def ros_context():
    """
    Yield a fresh, initialised ``rclpy.context.Context`` and shut it down afterwards.

    Pass it on as ``context=`` to nodes and executors, e.g.
    ``SingleThreadedExecutor(context=ros_context)``.
    """
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@pytest.fixture
def rig_factory(ros_context):
    """
    Yield a maker of compensator rigs (:class:`compensator_rig.Rig`), called with parameters.

    Every rig made is closed after the test; ``compensator_rig`` (which imports ``rclpy``) is
    imported only when a test asks for this fixture.
    """
    from compensator_rig import Rig

    rigs = []

    def make(**params):
        rig = Rig(ros_context, **params)
        rigs.append(rig)
        return rig

    yield make
    for rig in rigs:
        rig.close()


@pytest.fixture(scope='module')
def setup_kwargs():
    """Run setup.py with ``setuptools.setup`` replaced, and return the keyword arguments."""
    import runpy
    from pathlib import Path

    import setuptools

    root = Path(__file__).resolve().parent.parent
    captured = {}
    original, cwd = setuptools.setup, os.getcwd()
    setuptools.setup = captured.update
    try:
        os.chdir(root)
        runpy.run_path(str(root / 'setup.py'), run_name='__main__')
    finally:
        os.chdir(cwd)
        setuptools.setup = original
    return captured
