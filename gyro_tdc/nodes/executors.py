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

rclpy's executor, not the arithmetic, bounds a Python node's per-message cost: the
EventsExecutor (``events``) moves more messages than the SingleThreadedExecutor (``single``;
figures in doc/benchmarks.md); its ``spin()`` is broken in the Jazzy wheels, so :func:`run_node`
loops on ``spin_once``. :class:`StopSignals` makes SIGINT and SIGTERM one request to stop, acted on
between callbacks, so a node stops the same clean way at any moment (doc/internals/nodes.md).
"""

from __future__ import annotations

import contextlib
import gc
import os
import re
import signal
import sys
import threading
from typing import Any, Callable, Iterator

from diagnostic_msgs.msg import DiagnosticArray
from gyro_tdc.errors import GyroTdcError, one_line
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

__all__ = ['ShellNode', 'STARTUP_ERRORS', 'STOP_POLL_S', 'StopRequested', 'StopSignals',
           'make_executor', 'quiet_abandoned', 'run_node', 'trigger']

#: Errors of a node's configuration at start-up, reported in one line by :func:`run_node`:
#: rclpy's parameter errors (wrong type, out of range, ...) and gyro_tdc's own
#: (:class:`~gyro_tdc.errors.ConfigError`: not one of the choices, a topic loop...).
STARTUP_ERRORS = (GyroTdcError, ParameterException)
#: Longest wait of one ``spin_once`` of :func:`run_node`, hence the longest delay between a
#: stop signal and the start of the teardown [s].
STOP_POLL_S = 0.1
#: The signals that stop a node: Ctrl-C, and what ``ros2 launch`` and systemd send.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class ShellNode(Node):
    """
    What both nodes share: ``/diagnostics`` from their ``diagnostic_status()``, a clean stop.

    :meth:`destroy_node` cancels the timers first: an executor may still hold a timer event
    of this node (the EventsExecutor dispatches it even after ``remove_node``); a cancelled
    timer's, like any report once ``stopping`` is set, does nothing. Then :meth:`release`
    lets the node close what it holds (a device, a learner to save).
    """

    #: Set by :meth:`destroy_node`: a timer event that still comes then does nothing.
    stopping = False

    def report_diagnostics(self, period_s: float, **timer: Any) -> None:
        """Publish ``diagnostic_status()`` on ``/diagnostics`` every ``period_s``."""
        pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)

        def publish() -> None:
            if not self.stopping:
                arr = DiagnosticArray(status=[self.diagnostic_status()])
                arr.header.stamp = self.get_clock().now().to_msg()
                pub.publish(arr)
        self.create_timer(period_s, publish, **timer)

    def release(self) -> None:
        """Close what the node holds, its timers cancelled (nothing here)."""

    def destroy_node(self) -> None:
        """Stop the timers, :meth:`release`, then destroy the node."""
        self.stopping = True
        for timer in list(self.timers):
            timer.cancel()
        self.release()
        super().destroy_node()


def trigger(act: Callable[[], tuple[bool, str]]) -> Callable[[Any, Any], Any]:
    """Return a std_srvs/Trigger service callback: each call is answered ``act()``'s pair."""

    def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = act()
        return response
    return serve


class StopRequested(BaseException):
    """
    A stop signal came while a node was being built: abandon it (caught by :func:`run_node`).

    Not a KeyboardInterrupt: CPython makes a process whose KeyboardInterrupt went through
    code run by ``PyRun_String`` (as extension modules do) exit by SIGINT at the very end,
    whatever ``main()`` returned. A BaseException: no ``except Exception`` edge swallows it.
    """


class StopSignals:
    """
    Turn SIGINT and SIGTERM into one request to stop, read between callbacks.

    rclpy's own handlers shut the context down at once, from another thread, whatever the
    process is doing: a node still being built then fails in ``create_timer`` and a callback
    running meets destroyed handles. These handlers record the request; :func:`run_node`
    ends the spin at the next callback boundary and tears the node down in order. Only
    while a node is being built (:meth:`interrupting`: nothing learned yet, nothing to save)
    does a signal raise :class:`StopRequested` at once, so that a slow start (the sim back-end
    simulates its whole run first) does not hold the stop up. A signal the kernel hands to a
    thread of rclpy's (not a Python one) only flags it, and CPython's main thread looks at
    the flags when something makes it stop (a GIL request): so while a node is being built,
    a Python thread asks for the GIL every :data:`STOP_POLL_S`. A second signal while the
    teardown runs (a save on a hung disk) ends the process at once with status 128 + the
    signal number.
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        self.abandoned = False
        self._previous: dict[int, Any] = {}
        self._interrupt = False

    def install(self) -> bool:
        """Handle the stop signals here; return False off the main thread (nothing done)."""
        if threading.current_thread() is not threading.main_thread():
            return False
        self._previous.update((s, signal.signal(s, self._handle)) for s in STOP_SIGNALS)
        return True

    def restore(self) -> None:
        """Put back the handlers found by :meth:`install`."""
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    @contextlib.contextmanager
    def interrupting(self) -> Iterator[None]:
        """Within the block a stop signal (or one already received) raises StopRequested."""
        self._interrupt = True
        done = threading.Event()
        threading.Thread(target=_nudge, args=(done,), name='stop nudge', daemon=True).start()
        try:
            if self.signum is not None:     # a stop signal has already arrived
                raise StopRequested(signal.Signals(self.signum).name)
            yield
        finally:
            self._interrupt = False
            done.set()

    def _handle(self, signum: int, frame: Any) -> None:
        if self._interrupt:
            self.signum, self.abandoned = signum, True
            raise StopRequested(signal.Signals(signum).name)
        if self.signum is not None:
            raise SystemExit(128 + signum)
        self.signum = signum


def _nudge(done: threading.Event) -> None:
    """Take the GIL every STOP_POLL_S until ``done``: the main thread runs pending handlers."""
    while not done.wait(STOP_POLL_S):
        pass


@contextlib.contextmanager
def quiet_abandoned(stop: StopSignals) -> Iterator[None]:
    """
    Within the block, silence the finalisers of objects a stop left half-built.

    :class:`StopRequested` raised mid-build can land inside any constructor, rclpy's too;
    the ``__del__`` of such an object then meets attributes its ``__init__`` never set
    (rclpy's ``RcutilsLogger``) and Python prints "Exception ignored in ..." with a
    traceback. Only AttributeErrors of finalisers after an abandoned build are dropped (and
    the garbage collected here, not at exit); every other unraisable goes to the hook found.
    """
    previous = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if not (stop.abandoned and isinstance(unraisable.exc_value, AttributeError)
                and getattr(unraisable.object, '__name__', None) == '__del__'):
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        if stop.abandoned:
            gc.collect()
        sys.unraisablehook = previous


def make_executor(kind: str, context: Any = None) -> Any:
    """Return the executor of an ``executor`` parameter: ``'events'`` or ``'single'``."""
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def run_node(make_node: Callable[[], Node], args: list[str] | None = None, *,
             executor: str | Callable[[Any], str] = 'single',
             freeze_heap: bool = False, name: str = 'node') -> int:
    """
    Run one node until shutdown: the ``main()`` of ros2/demos, shared by the nodes.

    Ctrl-C, SIGTERM and an external shutdown end normally (exit 0): the executor shuts
    down, then the node is destroyed (it saves first) and rclpy shut down; a stop during
    start-up abandons the node being built, also where an import or a constructor wrapped
    the stop in an error of its own (an extension module's "initialization failed"). A
    configuration error (every :data:`STARTUP_ERRORS`) prints ``NAME: error: ...`` on
    stderr and returns 2, no traceback; so does a command line rcl refuses (a params file it
    cannot read). ``executor`` is a kind for :func:`make_executor` or
    a function of the node returning one; ``freeze_heap`` calls ``gc.freeze()`` after
    start-up so the collector's full passes do not stall callbacks.
    """
    argv = sys.argv if args is None else args
    for flag, path in zip(argv, argv[1:]):
        if flag == '--params-file' and not os.access(path, os.R_OK):
            # Said before rcl, which would log its own line and raise.
            print(f'{name}: error: cannot read the params file {path!r} (--params-file)',
                  file=sys.stderr)
            return 2
    stop = StopSignals()
    own = stop.install()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO if own else None)
    except RuntimeError as exc:     # rcl refused the command line: a params file, a remap
        stop.restore()
        text = re.sub(r', at \S+:\d+', '', one_line(exc))     # rcl's source locations
        print(f'{name}: error: cannot start: {text}', file=sys.stderr)
        return 2
    with quiet_abandoned(stop):
        node = ex = None
        try:
            try:
                with stop.interrupting():
                    node = make_node()
            except Exception as exc:    # StopRequested is no Exception: it passes
                if stop.abandoned:      # the stop, wrapped by an import or a constructor
                    raise StopRequested(signal.Signals(stop.signum).name) from exc
                if not isinstance(exc, STARTUP_ERRORS):
                    raise
                print(f'{name}: error: {one_line(exc)}', file=sys.stderr)
                return 2
            ex = make_executor(executor(node) if callable(executor) else executor)
            ex.add_node(node)
            if freeze_heap:
                gc.freeze()
            # spin_once, not spin(): in rclpy's Jazzy wheels EventsExecutor.spin() dispatches
            # nothing while its spin_once works and is the fast path.
            while rclpy.ok() and stop.signum is None:
                ex.spin_once(timeout_sec=STOP_POLL_S)
        except (StopRequested, KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            try:
                if ex is not None:
                    ex.shutdown()
                if node is not None:
                    node.destroy_node()
                rclpy.try_shutdown()
            finally:
                stop.restore()
    return 0
