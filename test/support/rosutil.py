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
import threading
import time
from typing import Any, Callable, IO, Iterator, Optional

__all__ = ['graph_report', 'Lines', 'interrupt', 'matched_readers', 'matched_writers',
           'node_process', 'request_until_answered', 'spin_until', 'spin_until_quiet']


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


def interrupt(child: subprocess.Popen, timeout_s: float = 30.0) -> tuple[int, str]:
    """Send SIGINT (Ctrl-C) to ``child``; return its exit code and everything it printed."""
    child.send_signal(signal.SIGINT)
    code = child.wait(timeout=timeout_s)
    return code, child.stdout.read()


def matched_readers(node: Any, topic: str) -> int:
    """
    Return how many readers the publishers of ``node`` on ``topic`` have matched.

    What a wait for "the other side is there" needs: the graph (``count_subscribers``) can
    list a reader before this node's writer has matched it, and a volatile writer drops
    what it publishes in between. ``topic`` is resolved as the node resolves it.
    """
    name = node.resolve_topic_name(topic)
    return sum(pub.get_subscription_count() for pub in node.publishers
               if pub.topic_name == name)


def matched_writers(node: Any, topic: str) -> int:
    """
    Return how many writers the subscriptions of ``node`` on ``topic`` have matched.

    The reader's side of a match, which can come after the writer's: a reader drops what
    reaches it from a writer it has not matched yet (best effort: for good). A wait before
    publishing needs both sides. ``topic`` is resolved as the node resolves it.
    """
    name = node.resolve_topic_name(topic)
    return sum(sub.get_publisher_count() for sub in node.subscriptions
               if sub.topic_name == name)


def graph_report(node: Any, *topics: str) -> str:
    """
    Return who publishes and subscribes each of ``topics`` in ``node``'s graph, one line.

    For a failed discovery wait: a stale participant (one that left, still listed) and a
    missing one read differently from the counts alone.
    """
    def who(infos: list) -> str:
        return ', '.join(sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in infos))

    parts = []
    for topic in topics:
        name = node.resolve_topic_name(topic)
        parts.append(f'{name}: publishers [{who(node.get_publishers_info_by_topic(name))}], '
                     f'subscribers [{who(node.get_subscriptions_info_by_topic(name))}]')
    return '; '.join(parts)


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


def request_until_answered(executor: Any, send: Callable[[], Any], timeout_s: float = 30.0,
                           *, resend_s: float = 5.0, what: str = 'the request') -> Any:
    """
    Send a service request with ``send()`` and spin until one of its futures is done.

    Across processes, a service can look ready (its request reader is matched) before its
    response writer has matched this client's reader; the first answer is then lost and its
    future never completes. So the request is sent again every ``resend_s`` seconds until
    one answer arrives or ``timeout_s`` passes. Use it only for requests that are safe to
    repeat (reading parameters, not triggering actions).

    Returns
    -------
    object
        The first completed future's result.

    Raises
    ------
    AssertionError
        If no answer arrived by the deadline.

    """
    deadline = time.monotonic() + timeout_s
    futures = []
    while True:
        futures.append(send())
        left = deadline - time.monotonic()
        try:
            spin_until(executor, lambda: any(f.done() for f in futures),
                       max(min(resend_s, left), 1e-3), what=what)
        except AssertionError:
            if time.monotonic() >= deadline:
                raise AssertionError(f'no answer to {what} within {timeout_s:g} s '
                                     f'({len(futures)} requests sent)') from None
            continue
        return next(f for f in futures if f.done()).result()


def spin_until_quiet(executor: Any, value: Callable[[], Any], quiet_s: float = 0.5,
                     timeout_s: float = 30.0) -> None:
    """
    Spin ``executor`` until ``value()`` has not changed for ``quiet_s`` seconds of spinning.

    For the end of a stream whose length the test cannot know (a burst that loses messages):
    the executor keeps working the whole time, so this waits for the work, not for a clock.

    Raises
    ------
    AssertionError
        If ``value()`` still changes at the deadline.

    """
    deadline = time.monotonic() + timeout_s
    last = value()
    quiet_since = time.monotonic()
    while time.monotonic() - quiet_since < quiet_s:
        if time.monotonic() > deadline:
            raise AssertionError(f'still changing after {timeout_s:g} s: {last!r}')
        executor.spin_once(timeout_sec=0.05)
        now = value()
        if now != last:
            last, quiet_since = now, time.monotonic()


class Lines:
    """
    Collect the lines a child process prints, in a background thread, to check them later.

    Parameters
    ----------
    stream : text file
        The child's ``stdout`` (or ``stderr``).

    """

    def __init__(self, stream: IO[str]) -> None:
        self.lines: list[str] = []
        self._new = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            with self._new:
                self.lines.append(line.rstrip('\n'))
                self._new.notify_all()

    def has(self, text: str) -> bool:
        """Return whether a line printed so far contains ``text``."""
        with self._new:
            return any(text in line for line in self.lines)

    def wait_for(self, text: str, timeout_s: float = 15.0) -> str:
        """
        Wait until a line containing ``text`` is printed; return that line.

        Raises
        ------
        AssertionError
            If no such line came within ``timeout_s`` (the output so far is in the message).

        """
        deadline = time.monotonic() + timeout_s
        with self._new:
            while True:
                for line in self.lines:
                    if text in line:
                        return line
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(f'no line with {text!r} within {timeout_s:g} s: '
                                         + '\n'.join(self.lines))
                self._new.wait(remaining)

    def join(self, timeout_s: float = 10.0) -> str:
        """Wait for the stream to close (the child exited); return everything printed."""
        self._thread.join(timeout_s)
        return '\n'.join(self.lines)
