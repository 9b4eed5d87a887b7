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
The compensator's ``/diagnostics`` status and its graph guard against chained compensators.

:class:`Diagnostics` is a part of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`:
it keeps ``backlog`` (:mod:`~gyro_tdc.nodes.compensator_backlog`, whose ``record`` the IMU
callback calls), the input rates and what the last report said, and builds the status from
the core and the node's other parts; the node publishes it.

Statuses are named ``<fully qualified node name>: gyro compensation``, diagnostic_updater's
``<node name>: <task>`` with its ``use_fqn`` form, so two compensators in two namespaces
differ; the liveness of the inputs (:mod:`gyro_tdc.runtime.liveness`) is judged on the
monotonic clock, never on ROS time.
"""

from __future__ import annotations

import time
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from gyro_tdc.nodes.compensator_backlog import Backlog
from gyro_tdc.nodes.compensator_loading import ModelLoading
from gyro_tdc.nodes.compensator_motion import MotionInput
from gyro_tdc.runtime import (CompensatorCore, frame_mismatch, health, HealthMark, InputRate,
                              InputStatus)
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from sensor_msgs.msg import Temperature
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
    """
    Judge the compensator's health for /diagnostics and say what changed in the log.

    Parameters
    ----------
    graph : rclpy.node.Node
        The node: its name, logger and ROS graph queries.
    core : CompensatorCore
        The core judged.
    inputs : InputStatus
        The input counters the IMU callback keeps.
    params : callable
        ``params() -> CompensatorParams``, the current parameters.
    in_topic : str
        ``imu/data_raw`` resolved (whose publishers are checked).
    loading, motion : ModelLoading, MotionInput
        The node's parts whose state the status shows.
    frame_id : callable
        ``frame_id() -> str``: the latest input's ``header.frame_id`` ('' before one).
    temperatures_ignored : callable
        ``temperatures_ignored() -> int``: readings dropped before the first IMU message.

    """

    def __init__(self, graph: Node, core: CompensatorCore, inputs: InputStatus,
                 params: Callable[[], Any], in_topic: str, *, loading: ModelLoading,
                 motion: MotionInput, frame_id: Callable[[], str],
                 temperatures_ignored: Callable[[], int]) -> None:
        self.graph, self.core, self.inputs, self.params = graph, core, inputs, params
        self.in_topic, self.loading, self.motion = in_topic, loading, motion
        self.frame_id, self.temperatures_ignored = frame_id, temperatures_ignored
        self.log = graph.get_logger()
        #: The node's learning part, set when ``learn`` is on.
        self.learning = None
        self._seen = HealthMark()
        self._reported_anchor = None
        self._frame_warned: tuple[str, str] | None = None
        self.live_clock = time.monotonic          # wall time for liveness (tests replace it)
        p = params()
        self.backlog = Backlog(p.expected_rate_hz)
        start = self.live_clock()
        self._rates = {'imu': InputRate('imu/data_raw', start, p.expected_rate_hz),
                       'temperature': InputRate('imu/temperature', start, None)}
        if p.motion_topic:
            self._rates['motion'] = InputRate(p.motion_topic, start, None)

    def upstream_compensators(self) -> tuple[str, ...]:
        """
        Return the other nodes publishing ``imu/data_raw`` that look like gyro_tdc compensators.

        A node is taken for one when it offers ``~/reload`` (std_srvs/srv/Trigger) and
        subscribes a temperature topic (any ``temperature_type``) besides publishing Imu on
        our input: the graph shows a compensator's interface whatever its name or remaps.
        """
        me = self.graph.get_fully_qualified_name()
        found = set()
        try:
            publishers = self.graph.get_publishers_info_by_topic(self.in_topic)
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
                services = self.graph.get_service_names_and_types_by_node(*who)
                subs = self.graph.get_subscriber_names_and_types_by_node(*who)
            except _rclpy.RCLError:  # it left between the queries (NodeNameNonExistentError)
                continue
            if any(n == f'{fqn}/reload' and 'std_srvs/srv/Trigger' in t for n, t in services) \
                    and any(TEMPERATURE_MESSAGES.keys() & set(t) for _, t in subs):
                found.add(fqn)
        return tuple(sorted(found))

    def status(self) -> DiagnosticStatus:
        """Return the compensator's DiagnosticStatus (and log a new re-anchoring)."""
        upstream = self.upstream_compensators()
        if upstream and upstream != self.inputs.upstream:
            self.log.warning(
                f'imu/data_raw ({self.in_topic}) is published by gyro_tdc compensator '
                f'{", ".join(upstream)}: chained compensators remove the drift twice')
        self.inputs.upstream = upstream
        frame = self.frame_id()
        h = health(self.core, self._seen, model_file=self.loading.model_file,
                   sensor_id=self.params().sensor_id, frame_id=frame,
                   last_reload=self.loading.last_reload, inputs=self.inputs)
        self._warn_frame(frame)
        if h.mark.already_compensated > self._seen.already_compensated:
            self.log.warning(
                f'{h.mark.already_compensated - self._seen.already_compensated} imu/data_raw '
                'samples were already compensated by gyro_tdc: the model is applied twice',
                throttle_duration_sec=10.0)
        self._seen = h.mark
        anchor = self.core.anchor
        if anchor is not None and anchor is not self._reported_anchor:
            self._reported_anchor = anchor
            self.log.info(
                f're-anchored after {anchor.samples} still samples over '
                f'{anchor.duration_s:.1f} s at {anchor.temp_c:.2f} degC: offset shift '
                f'{h.values["reanchor shift dps"]} deg/s, standard error '
                f'{h.values["reanchor se dps"]} deg/s ({h.values["reanchor stopped on"]})')
        values = dict(h.values)
        values.update(self.motion.values())
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
        if self.learning is not None:
            values.update(self.learning.values())
            for problem in self.learning.problems():  # learn_file refused, a save failed
                level = max(level, DiagnosticStatus.WARN[0])
                message = f'{message}; {problem}'
        return DiagnosticStatus(
            level=bytes((level,)), name=f'{self.graph.get_fully_qualified_name()}: {TASK}',
            message=message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def liveness(self) -> dict:
        """Judge each input's arrivals now (monotonic clock): role -> RateReport."""
        now = self.live_clock()
        core = self.core
        counts = {'imu': core.counts['in'],
                  'temperature': core.temps.received + self.temperatures_ignored(),
                  'motion': core.motion_reports + self.motion.ignored}
        return {role: rate.run(now, counts[role]) for role, rate in self._rates.items()}

    def _warn_frame(self, frame: str) -> None:
        """Log a frame mismatch once per model and data frame (/diagnostics warns throughout)."""
        model = self.core.model
        why = frame_mismatch(model, frame)
        if why and self._frame_warned != (model.model_id, frame):
            self._frame_warned = (model.model_id, frame)
            self.log.warning(why)
