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
The compensator under test plus a feeding and listening node (real rclpy; tests import it).

The ``rig_factory`` fixture (conftest.py) makes rigs of this class and closes them.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
import numpy as np
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosutil import matched_readers, matched_writers, spin_until
from sensor_msgs.msg import Imu, Temperature

__all__ = ['BACKLOG_WARNING', 'learning_caught_up', 'ok_but_backlog', 'problems', 'rates',
           'record_statuses', 'RELIABLE', 'reported', 'Rig', 'stamp_s', 'to_ns']

RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000,
                      reliability=ReliabilityPolicy.RELIABLE)


def learning_caught_up(node: CompensatorNode):
    """Return a test of whether ``node``'s learner has stepped over everything it received."""
    return lambda: node.learning.wait(0.0) and node.learning.learner.caught_up()


def to_ns(t: float) -> int:
    return int(round(t * 1e9))


def stamp_s(ns: int) -> float:
    """Seconds exactly as the node computes them from a builtin_interfaces/Time."""
    return ns // 10 ** 9 + (ns % 10 ** 9) * 1e-9


def rates(msgs):
    """Return the angular velocities of Imu messages, shape (N, 3)."""
    return np.array([(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)
                     for m in msgs])


#: How the node's own backlog report starts: a node starved of CPU (a loaded machine) is
#: rightly said to fall behind, whatever else a test is about.
BACKLOG_WARNING = 'falling behind: '
#: The messages of a status without a problem.
NO_PROBLEM = ('compensating', 'waiting for imu/data_raw')


def problems(status: DiagnosticStatus) -> list[str]:
    """Return the problems a compensator status names, but a falling-behind report."""
    return [p for p in status.message.split('; ')
            if p not in NO_PROBLEM and not p.startswith(BACKLOG_WARNING)]


def ok_but_backlog(status: DiagnosticStatus) -> bool:
    """Return whether ``status`` is OK, or WARN for nothing but falling behind."""
    return not problems(status) and (status.level == DiagnosticStatus.OK or (
        status.level == DiagnosticStatus.WARN and BACKLOG_WARNING in status.message))


def record_statuses(node) -> list[DiagnosticStatus]:
    """
    Keep every status ``node`` judges from now on, in order: its 1 Hz timer's and the test's.

    Each report says what is new since the one before; under load the timer's may fall
    anywhere in a feed, so a test sums or orders them rather than expect one report.
    """
    statuses: list[DiagnosticStatus] = []
    judge = node.diagnostic_status

    def recorded() -> DiagnosticStatus:
        status = judge()
        statuses.append(status)
        return status
    node.diagnostic_status = recorded
    return statuses


def reported(statuses, problem: str) -> int:
    """Return the samples counted by ``problem (N samples)`` over ``statuses``, summed."""
    head = f'{problem} ('
    return sum(int(p[len(head):].split()[0]) for s in statuses for p in problems(s)
               if p.startswith(head))


class Rig:
    """The compensator under test plus a test node that feeds it and listens."""

    def __init__(self, context, executor_kind='single', node_kwargs=None, **params):
        self.executor = make_executor(executor_kind, context)
        self.node = CompensatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()], **(node_kwargs or {}))
        self.io = rclpy.create_node('feeder', context=context)
        self.imu_pub = self.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.temp_pub = self.io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
        self.out: list[Imu] = []
        self.diag: list[DiagnosticStatus] = []
        self.io.create_subscription(Imu, 'imu/data_compensated', self.out.append, RELIABLE)
        self.io.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10)
        self.executor.add_node(self.node)
        self.executor.add_node(self.io)
        # Matched on both sides, each way: what is published before is lost.
        spin_until(self.executor, lambda: self.imu_pub.get_subscription_count() > 0
                   and self.temp_pub.get_subscription_count() > 0
                   and matched_writers(self.node, 'imu/data_raw') > 0
                   and matched_writers(self.node, 'imu/temperature') > 0
                   and matched_readers(self.node, 'imu/data_compensated') > 0
                   and matched_writers(self.io, 'imu/data_compensated') > 0
                   and matched_readers(self.node, '/diagnostics') > 0
                   and matched_writers(self.io, '/diagnostics') > 0, 20.0,
                   what='discovery')

    def _on_diag(self, msg):
        self.diag.extend(s for s in msg.status if 'gyro compensation' in s.name)

    def spin_until(self, predicate, timeout_s=10.0, what=None):
        spin_until(self.executor, predicate, timeout_s, what=what)

    def temperature(self, ns: int, value: float) -> None:
        msg = Temperature()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(ns), 10 ** 9)
        msg.header.frame_id = 'imu_link'
        msg.temperature = value
        msg.variance = 0.01
        self.temp_pub.publish(msg)

    def imu(self, ns: int, w, k: int = 0, *, accel=None, accel_cov=None) -> Imu:
        """
        Publish one Imu of rate ``w`` and return it.

        ``accel``: the specific force (default gravity on z, x stepping with ``k``);
        ``accel_cov``: its nine covariance entries (default 1e-3 on x, the rest zero).
        """
        msg = Imu()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(ns), 10 ** 9)
        msg.header.frame_id = 'imu_link'
        msg.orientation.w = 1.0
        msg.orientation_covariance[0] = -1.0
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = map(float, w)
        msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
        msg.angular_velocity_covariance[8] = 2e-6
        msg.angular_velocity_covariance[1] = 1e-9
        a = msg.linear_acceleration
        a.x, a.y, a.z = (1e-3 * (k % 7), 0.0, 9.81) if accel is None else map(float, accel)
        msg.linear_acceleration_covariance[:] = (
            (1e-3,) + (0.0,) * 8 if accel_cov is None else accel_cov)
        self.imu_pub.publish(msg)
        return msg

    def feed(self, imu_ns, omega, temp_ns=(), temp_c=(), chunk=250) -> list[Imu]:
        """Publish temperatures and IMU samples in stamp order; wait for every output."""
        sent = []
        j = 0
        start = len(self.out)
        temps_before = self.node.core.temps.received
        for lo in range(0, len(imu_ns), chunk):
            hi = min(lo + chunk, len(imu_ns))
            while j < len(temp_ns) and temp_ns[j] <= imu_ns[hi - 1]:
                self.temperature(temp_ns[j], temp_c[j])
                j += 1
            self.spin_until(lambda: self.node.core.temps.received >= temps_before + j,
                            what='temperatures in')
            for k in range(lo, hi):
                sent.append(self.imu(imu_ns[k], omega[k], k))
            self.spin_until(lambda: len(self.out) >= start + hi, what=f'{hi} outputs')
        return sent

    def close(self):
        self.executor.shutdown()
        self.io.destroy_node()
        self.node.destroy_node()
