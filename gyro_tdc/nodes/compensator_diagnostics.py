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
``learning_problems()``, ``motion_values()``, ``_in_topic`` and, set by the IMU callbacks,
``_last_imu`` (the latest input: an Imu, or its serialized bytes on the ``raw_cdr`` path);
this mixin keeps ``backlog`` (:mod:`~gyro_tdc.nodes.compensator_backlog`), whose ``record``
the IMU callbacks call as ``_record``.

Statuses are named ``<fully qualified node name>: gyro compensation``, diagnostic_updater's
``<node name>: <task>`` with its ``use_fqn`` form, so two compensators in two namespaces
differ; the liveness of the inputs (:mod:`gyro_tdc.runtime.liveness`) is judged on the
monotonic clock, never on ROS time.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_tdc.nodes.compensator_backlog import Backlog
from gyro_tdc.runtime import frame_mismatch, health, HealthMark, InputRate, upstream_note
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float32, Float64

__all__ = ['DIAGNOSTICS_PERIOD_S', 'Diagnostics', 'TEMPERATURE_MESSAGES']

#: The message class of each ``temperature_type`` (gyro_tdc.runtime.policy.TEMPERATURE_TYPES).
TEMPERATURE_MESSAGES = {'sensor_msgs/msg/Temperature': Temperature,
                        'std_msgs/msg/Float32': Float32, 'std_msgs/msg/Float64': Float64}
#: Period of the /diagnostics report [s].
DIAGNOSTICS_PERIOD_S = 1.0
#: The task part of the status name (``<fully qualified node name>: <task>``).
TASK = 'gyro compensation'


def _fqn(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


class Diagnostics:
    """Report the compensator's health on /diagnostics and in the log (mixin)."""

    #: Set by the node's ``destroy_node``: the report, which queries the ROS graph through
    #: the node's handle, is then skipped (a timer event may still come after destruction).
    stopping: bool = False

    def _init_diagnostics(self) -> None:
        """Create the /diagnostics publisher and what the reports compare against."""
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._seen = HealthMark()
        self._reported_anchor = None
        self._last_imu = None
        self._frame_warned: tuple[str, str] | None = None
        self._live_clock = time.monotonic        # wall time for liveness (tests replace it)
        self.backlog = Backlog(self.params.expected_rate_hz)
        self._record = self.backlog.record        # the IMU callbacks' one call per sample
        start = self._live_clock()
        self._rates = {'imu': InputRate('imu/data_raw', start, self.params.expected_rate_hz),
                       'temperature': InputRate('imu/temperature', start, None)}
        if self.params.motion_topic:
            self._rates['motion'] = InputRate(self.params.motion_topic, start, None)
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
        frame = self.data_frame_id()
        h = health(self.core, self._seen, model_file=self.model_file,
                   sensor_id=self.params.sensor_id, frame_id=frame,
                   last_reload=self.last_reload, inputs=self.inputs)
        self._warn_frame(frame)
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
        live = self.liveness()
        backlog = self.backlog.report(time.perf_counter())
        reports = [(report.level, report.message, report.values(role))
                   for role, report in live.items()] + [backlog]
        for report_level, report_message, report_values in reports:
            values.update(report_values)
            level = max(level, report_level)
            if report_message:
                message = (report_message if message in ('compensating',
                                                         'waiting for imu/data_raw')
                           else f'{message}; {report_message}')
        if self.learner is not None:
            values.update(self.learning_values())
            for problem in self.learning_problems():  # learn_file refused, a save failed
                level = max(level, DiagnosticStatus.WARN[0])
                message = f'{message}; {problem}'
        return DiagnosticStatus(
            level=bytes((level,)), name=f'{self.get_fully_qualified_name()}: {TASK}',
            message=message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def liveness(self) -> dict:
        """Judge each input's arrivals now (monotonic clock): role -> RateReport."""
        now = self._live_clock()
        core = self.core
        counts = {'imu': core.counts['in'],
                  'temperature': core.temps.received + self.temperatures_ignored,
                  'motion': core.motion_reports + getattr(self, 'motion_ignored', 0)}
        return {role: rate.run(now, counts[role]) for role, rate in self._rates.items()}

    def data_frame_id(self) -> str:
        """Return ``header.frame_id`` of the latest imu/data_raw message ('' before one)."""
        last = self._last_imu
        if last is None:
            return ''
        if isinstance(last, (bytes, bytearray, memoryview)):     # raw_cdr: once a report
            last = deserialize_message(bytes(last), Imu)
        return last.header.frame_id

    def _warn_frame(self, frame: str) -> None:
        """Log a frame mismatch once per model and data frame (/diagnostics warns throughout)."""
        model = self.core.model
        why = frame_mismatch(model, frame)
        if why and self._frame_warned != (model.model_id, frame):
            self._frame_warned = (model.model_id, frame)
            self.get_logger().warning(why)

    def _on_diagnostics(self) -> None:
        if self.stopping:
            return
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)
