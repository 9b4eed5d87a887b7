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
The compensator's ``/diagnostics`` and its graph guard against chained compensators.

:class:`Diagnostics` is a mixin of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`
(see doc/internals/runtime.md); the node provides ``core``, ``inputs``, ``params``,
``model_file``, ``last_reload``, ``learner``, ``learning_values()``,
``learn_file_warning``, ``motion_values()`` and ``_in_topic``.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_tdc.runtime import health, HealthMark, upstream_note
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from sensor_msgs.msg import Temperature
from std_msgs.msg import Float32, Float64

__all__ = ['DIAGNOSTICS_PERIOD_S', 'Diagnostics', 'TEMPERATURE_MESSAGES']

#: The message class of each ``temperature_type`` (gyro_tdc.runtime.policy.TEMPERATURE_TYPES).
TEMPERATURE_MESSAGES = {'sensor_msgs/msg/Temperature': Temperature,
                        'std_msgs/msg/Float32': Float32, 'std_msgs/msg/Float64': Float64}
#: Period of the /diagnostics report [s].
DIAGNOSTICS_PERIOD_S = 1.0


def _fqn(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


class Diagnostics:
    """Report the compensator's health on /diagnostics and in the log (mixin)."""

    def _init_diagnostics(self) -> None:
        """Create the /diagnostics publisher and what the reports compare against."""
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._seen = HealthMark()
        self._reported_anchor = None
        note = upstream_note(self.core.policy)     # never twice: said once at start-up
        if note:
            log = self.get_logger()
            (log.warning if self.core.upstream_pass else log.info)(note)

    def upstream_compensators(self) -> tuple[str, ...]:
        """
        Return the other nodes publishing ``imu/data_raw`` that look like gyro_tdc compensators.

        A node is taken for one when it offers ``~/reload`` (std_srvs/srv/Trigger) and
        subscribes a temperature topic (any ``temperature_type``) besides publishing Imu on
        our input: the graph shows a compensator's interface whatever its name or remaps.
        """
        me = self.get_fully_qualified_name()
        found = set()
        try:
            publishers = self.get_publishers_info_by_topic(self._in_topic)
        except _rclpy.RCLError:  # the graph cannot say now: ask again at the next report
            return self.inputs.upstream
        for info in publishers:
            if not info.node_namespace.startswith('/'):
                continue  # a writer whose node is not discovered yet: next time
            fqn = _fqn(info.node_namespace, info.node_name)
            if fqn == me or fqn in found:
                continue
            who = (info.node_name, info.node_namespace)
            try:
                services = self.get_service_names_and_types_by_node(*who)
                subs = self.get_subscriber_names_and_types_by_node(*who)
            except _rclpy.RCLError:  # it left between the queries (NodeNameNonExistentError)
                continue
            if any(n == f'{fqn}/reload' and 'std_srvs/srv/Trigger' in t for n, t in services) \
                    and any(TEMPERATURE_MESSAGES.keys() & set(t) for _, t in subs):
                found.add(fqn)
        return tuple(sorted(found))

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the compensator's DiagnosticStatus (and log a new re-anchoring)."""
        upstream = self.upstream_compensators()
        if upstream and upstream != self.inputs.upstream:
            self.get_logger().warning(
                f'imu/data_raw ({self._in_topic}) is published by gyro_tdc compensator '
                f'{", ".join(upstream)}: chained compensators remove the drift twice')
        self.inputs.upstream = upstream
        h = health(self.core, self._seen, model_file=self.model_file,
                   sensor_id=self.params.sensor_id,
                   last_reload=self.last_reload, inputs=self.inputs)
        if h.mark.already_compensated > self._seen.already_compensated:
            self.get_logger().warning(
                f'{h.mark.already_compensated - self._seen.already_compensated} imu/data_raw '
                'samples were already compensated by gyro_tdc: the model is applied twice',
                throttle_duration_sec=10.0)
        self._seen = h.mark
        anchor = self.core.anchor
        if anchor is not None and anchor is not self._reported_anchor:
            self._reported_anchor = anchor
            self.get_logger().info(
                f're-anchored after {anchor.samples} still samples over '
                f'{anchor.duration_s:.1f} s at {anchor.temp_c:.2f} degC: offset shift '
                f'{h.values["reanchor shift dps"]} deg/s, standard error '
                f'{h.values["reanchor se dps"]} deg/s ({h.values["reanchor stopped on"]})')
        values = dict(h.values)
        values.update(self.motion_values())
        level, message = h.level, h.message
        if self.learner is not None:
            values.update(self.learning_values())
            if self.learn_file_warning:       # learn_file refused: kept, learning beside it
                level = max(level, DiagnosticStatus.WARN[0])
                message = f'{message}; learn_file refused (see learn file)'
        return DiagnosticStatus(
            level=bytes((level,)), name=f'{self.get_name()}: gyro compensation',
            message=message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)
