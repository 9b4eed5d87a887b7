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
Helpers for node tests with real rclpy (imported by tests as ``from rosutil import ...``).

Nothing here imports ``rclpy``; the executor comes from the test.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from typing import Any, Callable, Iterator, Optional

__all__ = ['interrupt', 'node_process', 'spin_until']


@contextlib.contextmanager
def node_process(module: str, *ros_args: str) -> Iterator[subprocess.Popen]:
    """
    Run ``python -m MODULE --ros-args ROS_ARGS...`` as a child process for the block.

    The child inherits the test's environment (its ROS_DOMAIN_ID and loopback discovery);
    stdout and stderr are captured as text. If the child is still running when the block
    exits (a failed assertion before :func:`interrupt`), it is killed and reaped.
    """
    child = subprocess.Popen([sys.executable, '-m', module, '--ros-args', *ros_args],
                             env=dict(os.environ), stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    try:
        yield child
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def interrupt(child: subprocess.Popen, timeout_s: float = 10.0) -> tuple[int, str]:
    """Send SIGINT (Ctrl-C) to ``child``; return its exit code and everything it printed."""
    child.send_signal(signal.SIGINT)
    code = child.wait(timeout=timeout_s)
    return code, child.stdout.read()


def spin_until(executor: Any, predicate: Callable[[], bool], timeout_s: float = 10.0, *,
               step_s: float = 0.05, what: Optional[str] = None) -> None:
    """
    Spin ``executor`` one callback at a time until ``predicate()`` is true.

    There is no sleep: each ``spin_once`` returns as soon as work was done, or after at most
    ``step_s`` seconds of waiting for work, and the predicate is checked after every call.
    Cross-process discovery on loopback takes up to a few seconds, so keep ``timeout_s``
    at 5 s or more when waiting for another process.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        Executor holding the nodes under test.
    predicate : callable
        Condition to wait for; called with no arguments.
    timeout_s : float, s
        Deadline, measured on the monotonic clock from the call.
    step_s : float, s
        Longest single wait inside ``executor.spin_once``.
    what : str, optional
        Description of the condition for the failure message; defaults to the predicate's name.

    Raises
    ------
    AssertionError
        If the predicate is still false at the deadline.

    """
    if timeout_s <= 0:
        raise ValueError(f'`timeout_s` must be > 0 s, got {timeout_s!r}')
    if step_s <= 0:
        raise ValueError(f'`step_s` must be > 0 s, got {step_s!r}')
    deadline = time.monotonic() + timeout_s
    while not predicate():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            label = what or getattr(predicate, '__name__', repr(predicate))
            raise AssertionError(f'condition {label!r} not met within {timeout_s:g} s')
        executor.spin_once(timeout_sec=min(step_s, remaining))
