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
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from gyro_tdc.nodes.compensator_backlog import Backlog
from gyro_tdc.runtime import frame_mismatch, health, InputRate, TEMPERATURE_TYPES

__all__ = ['DIAGNOSTICS_PERIOD_S', 'Diagnostics']

DIAGNOSTICS_PERIOD_S = 1.0
TASK = 'gyro compensation'


class Diagnostics:
    """Judge the compensator ``node``'s health for /diagnostics and log what changed."""

    def __init__(self, node: Any) -> None:
        self.node, self.core, self.inputs = node, node.core, node.inputs
        self.log = node.get_logger()
        self._seen: dict = {}     # the counters at the last report (Health.mark)
        self._reported_anchor = self._frame_warned = None   # the anchor, (model, frame) said
        self.live_clock = time.monotonic          # wall time for liveness (tests replace it)
        p = node.params
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
        graph, found = self.node, set()
        try:
            publishers = graph.get_publishers_info_by_topic(graph.in_topic)
        except RuntimeError:  # rclpy's RCLError: the graph cannot say now, ask again later
            return self.inputs.upstream
        for info in publishers:
            fqn = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            # A writer whose node is not discovered yet (no namespace): next time.
            if not info.node_namespace.startswith('/') or fqn in found or (
                    fqn == graph.get_fully_qualified_name()):
                continue
            who = (info.node_name, info.node_namespace)
            try:
                services = graph.get_service_names_and_types_by_node(*who)
                subs = graph.get_subscriber_names_and_types_by_node(*who)
            except RuntimeError:  # RCLError: it left between the queries (NodeNameNonExistent)
                continue
            if any(n == f'{fqn}/reload' and 'std_srvs/srv/Trigger' in t for n, t in services) \
                    and any(set(TEMPERATURE_TYPES) & set(t) for _, t in subs):
                found.add(fqn)
        return tuple(sorted(found))

    def status(self) -> DiagnosticStatus:
        """Return the compensator's DiagnosticStatus (and log a new re-anchoring)."""
        node, core, log = self.node, self.core, self.log
        upstream = self.upstream_compensators()
        if upstream and upstream != self.inputs.upstream:
            log.warning(f'imu/data_raw ({node.in_topic}) is published by gyro_tdc compensator '
                        f'{", ".join(upstream)}: chained compensators remove the drift twice')
        self.inputs.upstream = upstream
        frame = node.frame_id()
        h = health(core, self._seen, model_file=node.loading.model_file,
                   sensor_id=node.params.sensor_id, frame_id=frame,
                   last_reload=node.loading.last_reload, inputs=self.inputs)
        why = frame_mismatch(core.model, frame)   # logged once per model and data frame
        if why and self._frame_warned != (core.model.model_id, frame):
            self._frame_warned = (core.model.model_id, frame)
            log.warning(why)
        if (marked := h.mark['marked'] - self._seen.get('marked', 0)) > 0:
            log.warning(f'{marked} imu/data_raw samples were already compensated by gyro_tdc: '
                        'the model is applied twice', throttle_duration_sec=10.0)
        self._seen = h.mark
        if core.reanchoring.settled and (anchor := core.anchor) is not self._reported_anchor:
            self._reported_anchor = anchor
            log.info(f're-anchored after {anchor.samples} still samples over '
                     f'{anchor.duration_s:.1f} s at {anchor.temp_c:.2f} degC: offset shift '
                     f'{h.values["reanchor shift dps"]} deg/s, standard error '
                     f'{h.values["reanchor se dps"]} deg/s ({h.values["reanchor stopped on"]})')
        values, level, message = {**h.values, **node.motion.values()}, h.level, h.message
        reports = [(r.level, r.message, r.values(role)) for role, r in self.liveness().items()]
        reports.append(self.backlog.report(time.perf_counter()))
        if node.learning is not None:
            reports.append(node.learning.report())
        for report_level, report_message, report_values in reports:
            values.update(report_values)
            level = max(level, report_level)
            if report_message:   # said instead of the OK message, else after the problems
                message = (report_message if message in ('compensating',
                                                         'waiting for imu/data_raw')
                           else f'{message}; {report_message}')
        return DiagnosticStatus(
            level=bytes((level,)), name=f'{node.get_fully_qualified_name()}: {TASK}',
            message=message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def liveness(self) -> dict:
        """Judge each input's arrivals now (monotonic clock): role -> RateReport."""
        core = self.core
        counts = {'imu': core.counts['in'],
                  'temperature': core.temps.received + self.node.temperatures_ignored,
                  'motion': core.motion_reports + self.node.motion.ignored}
        now = self.live_clock()
        return {role: rate.run(now, counts[role]) for role, rate in self._rates.items()}
