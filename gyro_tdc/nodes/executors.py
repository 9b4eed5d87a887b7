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
Executors for the nodes: which one, how to spin it, and the Jazzy ``main()`` loop.

rclpy's executor, not the arithmetic, bounds a Python node's per-message cost: measured with
``bench/bench_compensator.py``, the EventsExecutor (``events``) moves ~2.9x the messages of a
SingleThreadedExecutor (``single``) in one process and needs ~1.5x less CPU per message across
processes; its ``spin()`` is broken in the Jazzy wheels, so :func:`spin` loops on
``spin_once``.
"""

from __future__ import annotations

import gc
import sys
from typing import Any, Callable

from gyro_tdc.errors import GyroTdcError, one_line
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

__all__ = ['STARTUP_ERRORS', 'make_executor', 'run_node', 'spin']

#: Errors of a node's configuration at start-up, reported in one line by :func:`run_node`:
#: rclpy's parameter errors (wrong type, out of range, ...) and gyro_tdc's own
#: (:class:`~gyro_tdc.errors.ConfigError`: not one of the choices, a topic loop...).
STARTUP_ERRORS = (GyroTdcError, ParameterException)


def make_executor(kind: str, context: Any = None) -> Any:
    """
    Return the executor named by an ``executor`` parameter.

    Parameters
    ----------
    kind : str
        ``'events'`` (rclpy.experimental.EventsExecutor) or ``'single'``.
    context : rclpy.context.Context, optional
        Context of the executor.

    Returns
    -------
    rclpy.executors.Executor
        The executor.

    """
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def spin(executor: Any, context: Any = None) -> None:
    """
    Run ``executor`` until its context shuts down.

    The loop calls ``spin_once``: in the rclpy 7.1.6 Jazzy wheels
    ``EventsExecutor.spin()`` dispatches nothing at all (neither timers nor
    subscriptions) while its ``spin_once`` works and is the fast path.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        The executor, nodes added.
    context : rclpy.context.Context, optional
        Its context (default: the global one).

    """
    while rclpy.ok(context=context):
        executor.spin_once(timeout_sec=0.5)


def run_node(make_node: Callable[[], Node], args: list[str] | None = None, *,
             executor: str | Callable[[Any], str] = 'single',
             freeze_heap: bool = False, name: str = 'node') -> int:
    """
    Run one node until shutdown: the ``main()`` of ros2/demos, shared by the nodes.

    Initialise rclpy, build the node inside ``try``, spin it, treat Ctrl-C and an external
    shutdown as a normal end, then shut the executor down, destroy the node and shut rclpy
    down. A node that cannot start because of its configuration (a parameter of the wrong
    type, out of range or not one of its choices, inconsistent topic names: every
    :data:`STARTUP_ERRORS`) prints one line, ``NAME: error: ...``, on stderr and the exit
    status is 2, with no traceback.

    Parameters
    ----------
    make_node : callable returning rclpy.node.Node
        Builds the node (after ``rclpy.init``).
    args : list of str, optional
        Command-line arguments for ``rclpy.init``.
    executor : str or callable
        Executor kind for :func:`make_executor`, or a function of the node returning it.
    freeze_heap : bool
        Move the objects alive after start-up out of the cyclic garbage collector's reach
        (``gc.freeze()``), so that its full passes do not stall callbacks.
    name : str
        Executable name for the error line.

    Returns
    -------
    int
        Exit status: 0, or 2 when the node could not start.

    """
    rclpy.init(args=args)
    node = None
    ex = None
    try:
        try:
            node = make_node()
        except STARTUP_ERRORS as exc:
            print(f'{name}: error: {one_line(exc)}', file=sys.stderr)
            return 2
        ex = make_executor(executor(node) if callable(executor) else executor)
        ex.add_node(node)
        if freeze_heap:
            gc.freeze()
        spin(ex)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if ex is not None:
            ex.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
