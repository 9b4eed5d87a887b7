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
A compensator process restarted beside a live driver process, watched by a probe.

What a user does: ``driver_node`` (sim back-end) and ``compensator_node`` run as two
processes, namespaced and remapped, each from a parameter file; the compensator is stopped
with SIGINT and started again while the driver keeps publishing. The probe (this process,
its own context, executor and thread) drains the driver's input and the compensator's output
continuously and records each stamp. :func:`judge` turns a run's records into what a user
sees: did the stream come back, how soon, and was every input of a running compensator
answered exactly once. Used by test_restart_across_processes and
bench/bench_restart_processes.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import threading
import time
from typing import Optional

__all__ = ['COMPENSATOR', 'DRIVER', 'judge', 'MODES', 'NAMESPACE', 'Probe', 'RATE_HZ',
           'Restarter', 'Run', 'stop', 'Verdict', 'write_params']

NAMESPACE = '/rover'
RAW = 'gyro/raw'          # the driver's imu/data_raw remapped to it, the compensator's too
OUT = 'gyro/compensated'  # the compensator's imu/data_compensated
TEMP = 'gyro/temperature'
RATE_HZ = 200.0           # the driver's steady rate (sim_rate_hz at time_scale 1) [Hz]
DRIVER = 'gyro_tdc.nodes.driver_node'
COMPENSATOR = 'gyro_tdc.nodes.compensator_node'
#: The compensator's input_reliability per mode: the default (best effort) and reliable.
MODES = ('best_effort', 'reliable')


def write_params(directory: Path, mode: str, seed: int = 0) -> tuple[Path, Path]:
    """Write the driver's and the compensator's parameter files (``mode``: input QoS)."""
    driver = directory / 'driver.yaml'
    driver.write_text(
        '/**:\n  ros__parameters:\n    backend: sim\n    scenario: demo_fast\n'
        f'    seed: {seed}\n    sim_rate_hz: {RATE_HZ}\n    time_scale: 1.0\n'
        '    tick_hz: 100.0\n    qos_depth: 100\n')
    comp = directory / f'compensator_{mode}.yaml'
    comp.write_text(
        '/**:\n  ros__parameters:\n    model_file: l3gd20_modified\n'
        f'    input_reliability: {mode}\n    expected_rate_hz: {RATE_HZ}\n')
    return driver, comp


def _remaps(topics: dict[str, str]) -> list[str]:
    out = ['-r', f'__ns:={NAMESPACE}']
    for a, b in topics.items():
        out += ['-r', f'{a}:={b}']
    return out


def driver_command(params: Path) -> list[str]:
    """Return ``python -m gyro_tdc.nodes.driver_node`` under NAMESPACE, remapped, ``params``."""
    return [sys.executable, '-m', DRIVER, '--ros-args', '--params-file', str(params),
            *_remaps({'imu/data_raw': RAW, 'imu/temperature': TEMP})]


def compensator_command(params: Path) -> list[str]:
    """Return the compensator's command as a user runs it beside that driver: its topics."""
    return [sys.executable, '-m', COMPENSATOR, '--ros-args', '--params-file', str(params),
            *_remaps({'__node': 'gyro_compensator', 'imu/data_raw': RAW,
                      'imu/temperature': TEMP, 'imu/data_compensated': OUT})]


class Probe:
    """
    Drain the driver's input and the compensator's output in a thread of its own.

    ``inputs``: every input stamp [ns]; ``outputs``: (arrival on the monotonic clock,
    stamp ns, every rate and covariance finite) per output. Both readers are reliable and
    deep; the thread spins until :meth:`close`.
    """

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu

        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('restart_probe', namespace=NAMESPACE,
                                      context=self.context)
        self.lock = threading.Lock()
        self.inputs: set[int] = set()
        self.outputs: list[tuple[float, int, bool]] = []
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(Imu, RAW, self._on_input, qos)
        self.node.create_subscription(Imu, OUT, self._on_output, qos)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name='probe', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def _on_input(self, msg) -> None:
        s = msg.header.stamp
        with self.lock:
            self.inputs.add(s.sec * 10 ** 9 + s.nanosec)

    def _on_output(self, msg) -> None:
        now = time.monotonic()
        s = msg.header.stamp
        w = msg.angular_velocity
        finite = all(math.isfinite(v) for v in (w.x, w.y, w.z, *msg.angular_velocity_covariance))
        with self.lock:
            self.outputs.append((now, s.sec * 10 ** 9 + s.nanosec, finite))

    def input_stamps(self) -> frozenset[int]:
        """Return the input stamps seen so far (a copy: the probe thread goes on adding)."""
        with self.lock:
            return frozenset(self.inputs)

    def reliability_of(self, node_name: str) -> str:
        """Return the reliability of ``node_name``'s input subscription, as the graph lists it."""
        infos = self.node.get_subscriptions_info_by_topic(f'{NAMESPACE}/{RAW}')
        return ','.join(i.qos_profile.reliability.name.lower() for i in infos
                        if i.node_name == node_name)

    def counts(self) -> tuple[int, int]:
        """Return how many inputs and outputs have come so far."""
        with self.lock:
            return len(self.inputs), len(self.outputs)

    def wait(self, predicate, timeout_s: float, what: str) -> None:
        """Wait (the probe thread spins) until ``predicate()``; AssertionError at the deadline."""
        deadline = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > deadline:
                raise AssertionError(f'{what} not within {timeout_s:g} s (inputs, outputs: '
                                     f'{self.counts()})')
            time.sleep(0.01)

    def close(self) -> None:
        """Stop the thread, destroy the node and shut the context down."""
        import rclpy
        self._stop.set()
        self._thread.join(5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@dataclass
class Run:
    """One life of a compensator process and what the probe saw of it."""

    started: float                     # Popen, monotonic [s]
    started_wall: float = math.nan     # Popen, wall clock (the nodes' log stamps) [s]
    stopped: float = math.nan          # SIGINT sent, monotonic [s]
    code: Optional[int] = None         # exit code (None: killed after the stop timeout)
    stderr: str = ''
    first_output_s: float = math.nan   # from Popen to the first output [s]; nan: none
    outputs: list = field(default_factory=list)   # (arrival, stamp ns, finite)
    input_qos: str = ''                # its input's reliability as the graph lists it

    @property
    def loaded_s(self) -> float:
        """Return the time from Popen to the node's model-loaded log line [s]; nan: none."""
        found = _LOADED.search(self.stderr)
        return float(found.group(1)) - self.started_wall if found else math.nan


#: The compensator's log line once its model is loaded (before its topics are created).
_LOADED = re.compile(r'\[INFO\] \[(\d+\.\d+)\] \[[^]]*\]: model \w+ from ')


def _start(cmd: list[str], log: Path) -> subprocess.Popen:
    with open(log.with_suffix('.out'), 'wb') as out, open(log.with_suffix('.err'), 'wb') as err:
        return subprocess.Popen(cmd, env=dict(os.environ), stdout=out, stderr=err)


def stop(child: subprocess.Popen, timeout_s: float = 15.0) -> Optional[int]:
    """SIGINT, as Ctrl-C; return the exit code, None when it had to be killed."""
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
    try:
        return child.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()
        return None


class Restarter:
    """
    The driver process, and a compensator process started and stopped one life at a time.

    ``directory`` holds the parameter files and each process's stdout and stderr.
    """

    def __init__(self, probe: Probe, directory: Path, mode: str, seed: int = 0) -> None:
        self.probe, self.directory, self.mode = probe, directory, mode
        self.driver_params, self.comp_params = write_params(directory, mode, seed)
        self.driver: Optional[subprocess.Popen] = None
        self.runs: list[Run] = []

    def start_driver(self, timeout_s: float = 30.0) -> None:
        """Start the driver and wait for its stream at the probe."""
        self.driver = _start(driver_command(self.driver_params), self.directory / 'driver')
        n0 = self.probe.counts()[0]
        self.probe.wait(lambda: self.probe.counts()[0] > n0 + int(RATE_HZ), timeout_s,
                        'the driver streaming')

    def life(self, run_s: float, first_timeout_s: float) -> Run:
        """
        Start a compensator, wait for its first output, let it run ``run_s``, SIGINT it.

        A compensator whose output does not come within ``first_timeout_s`` is stopped all
        the same (its run's ``first_output_s`` stays nan).
        """
        k = len(self.runs)
        log = self.directory / f'comp_{self.mode}_{k}'
        n0 = self.probe.counts()[1]
        run = Run(started=time.monotonic(), started_wall=time.time())
        child = _start(compensator_command(self.comp_params), log)
        try:
            self.probe.wait(lambda: self.probe.counts()[1] > n0, first_timeout_s,
                            'the first output')
            with self.probe.lock:
                run.first_output_s = self.probe.outputs[n0][0] - run.started
            # The graph may list the input a little after the output came.
            self.probe.wait(lambda: self.probe.reliability_of('gyro_compensator'),
                            first_timeout_s, 'the input in the graph')
            run.input_qos = self.probe.reliability_of('gyro_compensator')
            time.sleep(run_s)
        except AssertionError:
            pass
        finally:
            run.stopped = time.monotonic()
            run.code = stop(child)
        with self.probe.lock:
            run.outputs = self.probe.outputs[n0:]
        run.stderr = log.with_suffix('.err').read_text(errors='replace')
        self.runs.append(run)
        return run

    def close(self) -> Optional[int]:
        """Stop the driver with SIGINT; return its exit code."""
        return None if self.driver is None else stop(self.driver)


@dataclass
class Verdict:
    """What one compensator life gave a user."""

    resumed: bool          # an output came
    first_output_s: float  # [s] from the start of the process
    loaded_s: float        # [s] from the start of the process to its model loaded
    answered: int          # inputs between its first and last output that were answered
    lost: int              # inputs between its first and last output never answered
    unmatched: int         # outputs whose stamp no input carries
    duplicated: int        # outputs of a stamp already answered
    nonfinite: int         # outputs with a non-finite rate or covariance
    clean: bool            # exit code 0 after SIGINT, no traceback on stderr


def judge(run: Run, inputs: frozenset[int]) -> Verdict:
    """Judge one life against every input the probe saw (one output per input while running)."""
    stamps = [s for _, s, _ in run.outputs]
    unique = set(stamps)
    if unique:
        lo, hi = min(unique), max(unique)
        window = {s for s in inputs if lo <= s <= hi}
    else:
        window = set()
    return Verdict(
        resumed=bool(stamps), first_output_s=run.first_output_s, loaded_s=run.loaded_s,
        answered=len(window & unique), lost=len(window - unique),
        unmatched=len(unique - inputs), duplicated=len(stamps) - len(unique),
        nonfinite=sum(not ok for _, _, ok in run.outputs),
        clean=run.code == 0 and 'Traceback' not in run.stderr)
