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
Live end-to-end run: driver_node (sim) -> compensator_node, watched by a monitor node.

The two nodes run as separate processes started exactly as ``ros2 run`` would start them
(``python -m gyro_tdc.nodes.<node> --ros-args --params-file ...``); the monitor subscribes to
the raw and the compensated streams in this process and reports the live bias stability of
both on the messages they have in common (matched by header stamp).
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
import os
import signal
import subprocess
import sys
import time

from gyro_tdc.base import config_dir
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import Policy
from gyro_tdc.signal import bias_stability
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from sensor_msgs.msg import Imu, Temperature

__all__ = ['LiveResult', 'MonitorNode', 'run_live']


class MonitorNode(Node):
    """Record raw and compensated Imu and the temperature, keyed by header stamp."""

    def __init__(self, **kwargs) -> None:
        super().__init__('gyro_tdc_monitor', **kwargs)
        qos = 5000      # reliable, keep last 5000
        #: Rates (x, y, z) and angular_velocity_covariance[0] by header stamp [ns]: raw and
        #: compensated.
        self.raw: dict[int, tuple[float, float, float, float]] = {}
        self.comp: dict[int, tuple[float, float, float, float]] = {}
        self.temps: list[float] = []
        for topic, into in (('imu/data_raw', self.raw), ('imu/data_compensated', self.comp)):
            self.create_subscription(Imu, topic, functools.partial(self._store, into), qos)
        self.create_subscription(Temperature, 'imu/temperature',
                                 lambda m: self.temps.append(m.temperature), qos)

    @staticmethod
    def _store(into: dict, msg: Imu) -> None:
        w, stamp = msg.angular_velocity, msg.header.stamp
        into[stamp.sec * 1_000_000_000 + stamp.nanosec] = (
            w.x, w.y, w.z, msg.angular_velocity_covariance[0])

    def passed_raw(self, stamp: int, passthrough_variance: float) -> bool:
        """Whether the compensator passed the raw rate of ``stamp`` (its variance added)."""
        return bool(self.comp[stamp][3] - self.raw[stamp][3] >= 0.5 * passthrough_variance)


@dataclass(frozen=True)
class LiveResult:
    """What the live run measured."""

    raw_received: int
    compensated_received: int
    matched: int
    bs_raw_dps2: tuple[float, float, float]
    bs_compensated_dps2: tuple[float, float, float]
    temperature_c: tuple[float, float]
    seconds: float
    # Messages stamped inside the window where the monitor heard both streams (from the
    # later first stamp to the earlier last one); outside it one subscription (the
    # compensator's input or one of the monitor's) was not yet matched by DDS discovery.
    raw_in_window: int = 0
    compensated_in_window: int = 0
    # Matched messages the compensator passed raw (no temperature yet: its thermometer
    # subscription matched after its IMU one), and how many of them came after the first
    # corrected one. The BS is of the corrected ones.
    passed_raw: int = 0
    passed_raw_after_first_corrected: int = 0

    def lines(self) -> list[str]:
        """Return a short human-readable report."""
        fmt = ', '.join
        return [
            f'live: {self.raw_received} raw and {self.compensated_received} compensated '
            f'messages in {self.seconds:.1f} s ({self.matched} matched by stamp), '
            f'temperature {self.temperature_c[0]:.2f} .. {self.temperature_c[1]:.2f} degC',
            f'live BS raw         (deg/s)^2: {fmt(f"{v:.4g}" for v in self.bs_raw_dps2)}',
            f'live BS compensated (deg/s)^2: {fmt(f"{v:.4g}" for v in self.bs_compensated_dps2)}',
        ]


def _node_cmd(module: str, params_file: str, **overrides: object) -> list[str]:
    """Return the command line ``ros2 run`` runs ``module`` with, on a shipped params file."""
    return [sys.executable, '-m', f'gyro_tdc.nodes.{module}', '--ros-args', '--params-file',
            str(config_dir() / params_file),
            *(a for k, v in overrides.items() for a in ('-p', f'{k}:={v}'))]


def run_live(model_file: str | os.PathLike, *, scenario: str = 'demo_fast', seed: int = 7,
             sim_rate_hz: float = 10.0, time_scale: float = 100.0, seconds: float = 20.0,
             reference_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> LiveResult:
    """
    Stream a simulated run through the compensator for ``seconds`` of wall time.

    Parameters
    ----------
    model_file : str or PathLike
        Model the compensator loads.
    scenario : str
        Scenario the driver streams.
    seed : int
        Simulator seed (pick one the model was not trained on).
    sim_rate_hz : float, Hz
        IMU rate of the simulated stream.
    time_scale : float
        Simulated seconds per wall-clock second.
    seconds : float, s
        How long to stream, from the driver's first message (a busy machine may take
        seconds to start it; it has 20 s before the window opens anyway).
    reference_dps : tuple of float, deg/s
        True rate of the stream (the BS reference).

    Returns
    -------
    LiveResult
        Counts and live bias stabilities.

    """
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    comp_cmd = _node_cmd('compensator_node', 'compensator.yaml', model_file=model_file)
    drv_cmd = _node_cmd('driver_node', 'driver_sim.yaml', scenario=scenario, seed=seed,
                        sim_rate_hz=float(sim_rate_hz), time_scale=float(time_scale))
    ctx = Context()
    rclpy.init(context=ctx)
    procs: list[subprocess.Popen] = []
    node = ex = None
    try:
        node = MonitorNode(context=ctx)
        ex = make_executor('single', ctx)
        ex.add_node(node)
        procs.append(subprocess.Popen(comp_cmd, env=env, stdout=subprocess.DEVNULL))
        deadline = time.monotonic() + 20.0
        while node.count_publishers('imu/data_compensated') == 0:
            if time.monotonic() > deadline or procs[0].poll() is not None:
                raise RuntimeError('compensator_node did not come up: ' + ' '.join(comp_cmd))
            ex.spin_once(timeout_sec=0.05)
        procs.append(subprocess.Popen(drv_cmd, env=env, stdout=subprocess.DEVNULL))
        deadline = time.monotonic() + 20.0          # the driver's start-up, not the window
        while not node.raw and time.monotonic() < deadline and procs[1].poll() is None:
            ex.spin_once(timeout_sec=0.05)
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            ex.spin_once(timeout_sec=0.05)
        procs[1].send_signal(signal.SIGINT)
        last, quiet = len(node.comp), time.monotonic()
        while time.monotonic() - quiet < 1.0:
            ex.spin_once(timeout_sec=0.05)
            if len(node.comp) != last:
                last, quiet = len(node.comp), time.monotonic()
        elapsed = time.monotonic() - start
        both = sorted(set(node.raw) & set(node.comp))
        pass_var = Policy().passthrough_variance
        raw_pass = [node.passed_raw(s, pass_var) for s in both]
        stamps = [s for s, p in zip(both, raw_pass) if not p]
        first = raw_pass.index(False) if False in raw_pass else len(raw_pass)
        ref = np.radians(np.asarray(reference_dps, dtype=float))

        def bs(rates: dict) -> tuple[float, float, float]:
            """Return the bias stability of the messages both streams have, (deg/s)^2."""
            w = np.array([rates[s][:3] for s in stamps]).reshape(-1, 3)
            return tuple(bias_stability(w, ref).tolist()) if stamps else (math.nan,) * 3
        temps = node.temps or [math.nan]
        lo = max(min(node.raw, default=0), min(node.comp, default=0))
        hi = min(max(node.raw, default=-1), max(node.comp, default=-1))
        return LiveResult(
            raw_in_window=sum(1 for s in node.raw if lo <= s <= hi),
            compensated_in_window=sum(1 for s in node.comp if lo <= s <= hi),
            raw_received=len(node.raw), compensated_received=len(node.comp),
            matched=len(both), bs_raw_dps2=bs(node.raw), bs_compensated_dps2=bs(node.comp),
            passed_raw=sum(raw_pass), passed_raw_after_first_corrected=sum(raw_pass[first:]),
            temperature_c=(float(min(temps)), float(max(temps))), seconds=elapsed)
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        # The monitor's readers go with it: a context shut down alone leaves them matched
        # to the next publisher of these topics in this process's domain.
        if ex is not None:
            ex.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
