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
Shared pytest set-up: DDS isolation, rclpy contexts, ``serial`` tests, a ``ci`` hypothesis profile.

At import time, before any test imports ``rclpy``: discovery stays on loopback and each pytest
process claims a ``ROS_DOMAIN_ID`` in 1..101 (``ros_domain``: a lock in /tmp held while it lives;
no run takes an id another live one holds unless told to). A plain run keeps the id it is given
(``make test`` sets one), else the first free one from its pid. xdist worker ``gwN`` of a run on
id ``base`` takes ``(base - 1 + 20 (N + 1)) % 101 + 1`` (never ``base``), else the next free id
along that stride. A test marked ``serial`` runs with no other worker's test beside it.
"""

import os
from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent / 'support'))

from hypothesis import settings  # noqa: E402
import pytest  # noqa: E402
import ros_domain  # noqa: E402
from serial_gate import SerialGate  # noqa: E402

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
_WORKER = os.environ.get('PYTEST_XDIST_WORKER')
if _WORKER:
    # The run's id, inherited from the controller, which ran this file first.
    _BASE = int(os.environ.get('ROS_DOMAIN_ID') or os.getppid() % ros_domain.DOMAINS + 1)
    _DOMAIN, _CLAIMED = ros_domain.worker_domain(_BASE, _WORKER)
else:
    _DOMAIN, _CLAIMED = ros_domain.run_domain(os.environ.get('ROS_DOMAIN_ID'), os.getpid())
    os.environ['GYRO_TDC_TEST_RUN'] = str(os.getpid())   # names the run's serial gate
os.environ['ROS_DOMAIN_ID'] = str(_DOMAIN)
_GATE = SerialGate(os.environ.get('GYRO_TDC_TEST_RUN') or str(os.getppid()))

settings.register_profile('ci', derandomize=True, database=None, deadline=None)
settings.load_profile('ci')


def pytest_configure(config):
    """Register the ``copyright`` (no ament_copyright wheel provides it) and ``serial`` markers."""
    config.addinivalue_line('markers', 'copyright: marks tests checking for copyright headers')
    config.addinivalue_line('markers', 'serial: runs alone, no test on another xdist worker '
                            'beside it (its result depends on the load: losses, rates)')


def pytest_unconfigure(config):
    """Remove this run's serial gate files (the xdist controller or a plain run)."""
    if not _WORKER:
        _GATE.remove()


def _serial(item):
    return item is not None and item.get_closest_marker('serial') is not None


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    """
    On an xdist worker, run a ``serial`` test (set-up to tear-down) alone (``serial_gate``).

    The outermost wrapper: the wait at the gate comes before pytest-timeout's timer starts.
    """
    if not _WORKER:
        return (yield)
    _GATE.enter(_serial(item))
    try:
        return (yield)
    finally:
        _GATE.leave(_serial(nextitem))


def pytest_report_header(config):
    """Show the DDS isolation settings of this run in pytest's header."""
    line = (f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")
    if not _CLAIMED:
        line += ' (this id is in use by another pytest run on this machine)'
    if getattr(config.option, 'numprocesses', None):
        line += '; each xdist worker takes its own id (listed at the end)'
    return line


def pytest_sessionfinish(session):
    """On an xdist worker, hand the worker's ``ROS_DOMAIN_ID`` to the controller."""
    if _WORKER and hasattr(session.config, 'workeroutput'):
        session.config.workeroutput['ros_domain_id'] = (_DOMAIN, _CLAIMED)


_WORKER_DOMAINS = {}


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """Record the ``ROS_DOMAIN_ID`` a finished xdist worker used."""
    got = getattr(node, 'workeroutput', {}).get('ros_domain_id')
    if got:
        _WORKER_DOMAINS[node.gateway.id] = got


def pytest_terminal_summary(terminalreporter):
    """List the ``ROS_DOMAIN_ID`` of each xdist worker."""
    if _WORKER_DOMAINS:
        terminalreporter.write_line('ROS_DOMAIN_ID per xdist worker: ' + ', '.join(
            f'{w}={d}' + ('' if claimed else ' (shared)')
            for w, (d, claimed) in sorted(_WORKER_DOMAINS.items())))


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
