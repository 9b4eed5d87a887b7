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
The compensator node: raw Imu in, drift-compensated Imu out, one for one, in order.

Subscribes ``imu/data_raw`` and ``imu/temperature`` (any message types, read by field:
``imu_type``, ``temperature_type``), publishes ``imu/data_compensated`` (every field copied
but the corrected rates and widened covariances) and ``/diagnostics``.
Every decision lives in :mod:`gyro_tdc.runtime`; this module converts. Topics, loading,
learning, motion and guards: ``doc/internals/nodes.md``.
"""

from __future__ import annotations

from dataclasses import replace
import sys
from time import perf_counter
from typing import Any, Callable

from gyro_tdc.base import spec_dataclass
from gyro_tdc.data import ImuView, locate
from gyro_tdc.errors import ConfigError
from gyro_tdc.model import CompensationModel
from gyro_tdc.nodes._params import declare, print_help
from gyro_tdc.nodes.compensator_diagnostics import Diagnostics, DIAGNOSTICS_PERIOD_S
from gyro_tdc.nodes.compensator_inputs import input_reader, MOTION_MESSAGES, MotionInput
from gyro_tdc.nodes.compensator_learning import LEARN_STEP_S, Learning
from gyro_tdc.nodes.compensator_loading import LOAD_POLL_S, ModelLoading, read_model
from gyro_tdc.nodes.executors import run_node, ShellNode, trigger
from gyro_tdc.runtime import (CompensatorCore, InputStatus, PARAMS, PASSTHROUGH, Policy,
                              sensor_mismatch, upstream_note)
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu
from std_srvs.srv import Trigger

__all__ = ['CompensatorNode', 'CompensatorParams', 'PARAMS', 'main', 'read_model']

CompensatorParams = spec_dataclass(
    'CompensatorParams', PARAMS, "The compensator's parameters (rows of ``PARAMS``).",
    module=__name__)

POLICY_NAMES = frozenset(s.name for s in PARAMS if s.policy)
LIVE_NAMES = frozenset(s.name for s in PARAMS if not s.read_only and not s.policy) - {
    'model_file'}


def qos(depth: int, reliable: bool, keep_all: bool = False) -> QoSProfile:
    """
    Return a volatile QoS profile: keep last ``depth`` (or all), reliable or best effort.

    imu/data_raw is keep-all when reliable: a keep-all publisher is held back by flow
    control, a keep-last one drops its oldest unacknowledged samples, which the next sample
    reveals as a sequence gap the message-lost event counts (bounded by the RMW's limits,
    Fast DDS: 5000). Best effort it is REP 2003 sensor data, deep: the freshest ``depth``
    samples when behind (DDS does not report the ones this queue overwrites).
    """
    return QoSProfile(history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
                      depth=depth, durability=DurabilityPolicy.VOLATILE,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT)


class CompensatorNode(ShellNode):
    """
    Remove the temperature drift of a gyro, one output message per input message.

    The node wires topics, timers, services and parameter callbacks to its parts
    ``loading``, ``learning`` (None unless ``learn``), ``motion`` and ``diagnostics``. Every
    IMU input, raw CDR, deserialised or read by field, goes through :meth:`_compensate`.
    ``loader(name) -> CompensationModel`` reads a model file (default :func:`read_model`;
    tests inject a slow one); ``kwargs`` go to :class:`rclpy.node.Node`. A ConfigError: a
    parameter is invalid, or the input and output resolve to the same topic.
    """

    def __init__(self, *, loader: Callable[[str], CompensationModel] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'compensator_node'), **kwargs)
        self.params = p = CompensatorParams(**declare(self, PARAMS))
        self.reader = input_reader(p)     # the input types and fields, checked
        try:
            policy = Policy(**{name: getattr(p, name) for name in POLICY_NAMES})
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.in_topic = self.resolve_topic_name('imu/data_raw')
        if (out_topic := self.resolve_topic_name('imu/data_compensated')) == self.in_topic:
            raise ConfigError(f'imu/data_raw and imu/data_compensated both resolve to '
                              f'{out_topic}: the compensator would compensate its own output '
                              'in a loop; remap one of them')
        self.core = CompensatorCore(policy)
        self.inputs = InputStatus(p.input_reliability)
        self.temperatures_ignored = 0  # readings without a stamp before the first IMU message
        self._last_imu: bytes | None = None    # the latest input, for its frame_id
        self.learning: Learning | None = None
        self.loading = ModelLoading(self, loader)
        self.loading.load_at_start()
        self.motion = MotionInput(self.core, p.motion_topic)
        self.diagnostics = Diagnostics(self)
        #: The compensator's DiagnosticStatus now (and what changed logged).
        self.diagnostic_status = self.diagnostics.status
        self._record = self.diagnostics.backlog.record    # the IMU step's one call per sample
        self._say_upstream(policy)                        # said once at start-up
        self._wire(p)

    def _wire(self, p: Any) -> None:
        """Create the publishers, subscriptions, timers, services and parameter callbacks."""
        # Every entity's qos_overrides parameters: history, depth, reliability.
        reliable, depth, opts = p.input_reliability == 'reliable', p.queue_depth, {
            'qos_overriding_options': QoSOverridingOptions.with_default_policies()}
        # The profiles are the defaults of the qos_overrides.<resolved topic>.* parameters
        # (read-only: QoS is fixed when an entity is created), which may override them.
        self._pub = self.create_publisher(Imu, 'imu/data_compensated', qos(depth, True), **opts)
        reader, imu_qos = self.reader, qos(depth, reliable, keep_all=reliable)
        events = SubscriptionEventCallbacks(message_lost=self._on_message_lost)
        raw = reader.to_imu is None and p.raw_cdr    # another type is made an Imu first
        imu_sub = self.create_subscription(
            reader.imu_cls, 'imu/data_raw', self._on_imu_raw if raw else self._on_imu, imu_qos,
            raw=raw, event_callbacks=events, **opts)
        self.inputs.reliability = imu_sub.qos_profile.reliability.name.lower()
        # As deep as the IMU queue, best effort: a simulated run streamed faster than real time
        # sends one temperature per IMU sample, and a lost one makes the next ones stale.
        self.create_subscription(reader.temperature_cls, 'imu/temperature',
                                 self._on_temperature, qos(depth, False), **opts)
        if p.motion_topic:
            self.create_subscription(MOTION_MESSAGES[p.motion_type], p.motion_topic,
                                     self.motion.on_motion, qos(depth, reliable), **opts)
        self.create_service(Trigger, '~/reload', trigger(self.loading.reload))
        # rclpy calls the callbacks added last first: the policy check runs before
        # model_file's (which reads the file), the policy swap after the model install.
        self.add_post_set_parameters_callback(self._on_policy_set)
        self.add_on_set_parameters_callback(self.loading.on_set)
        self.add_post_set_parameters_callback(self.loading.on_parameters_set)
        self.add_on_set_parameters_callback(self._on_set_policy)
        # The steady clock: with use_sim_time and no /clock (or a paused bag) the reports, the
        # model poll and learning go on; every decision follows the message stamps anyway.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.report_diagnostics(DIAGNOSTICS_PERIOD_S, clock=steady)
        self.create_timer(LOAD_POLL_S, self.loading.on_poll, clock=steady)
        if p.learn:
            self.learning = self.diagnostics.learning = Learning(self)
            self.create_service(Trigger, '~/learn_save', trigger(self.learning.save_service))
            self.create_service(Trigger, '~/learn_reset', trigger(self.learning.reset))
            self.create_timer(LEARN_STEP_S, self.learning.on_timer, clock=steady)

    def release(self) -> None:
        """Save what was learned (the stretch in progress too), the learner's worker done."""
        if self.learning is not None:
            self.learning.stop()

    def frame_id(self) -> str:
        """Return ``header.frame_id`` of the latest imu/data_raw message ('' before one)."""
        last = self._last_imu
        return '' if last is None else deserialize_message(last, Imu).header.frame_id

    def _say_upstream(self, policy: Policy) -> None:
        """Log what upstream_correction does with the input (a warning when it passes it)."""
        note, log = upstream_note(policy), self.get_logger()
        if note:
            (log.warning if self.core.upstream_pass else log.info)(note)

    # -- run-time parameter changes ----------------------------------------------------

    def _on_set_policy(self, params: list[Parameter]) -> SetParametersResult:
        """Check a set of policy parameters (ROS checked types and ranges): refuse with why."""
        try:   # Policy's own check: choices, signs
            replace(self.core.policy, **{q.name: q.value for q in params
                                         if q.name in POLICY_NAMES})
        except (TypeError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_policy_set(self, params: list[Parameter]) -> None:
        """Swap the new policy in on the executor's thread: it applies from the next message."""
        changes = {q.name: q.value for q in params if q.name in POLICY_NAMES}
        live = {q.name: q.value for q in params if q.name in LIVE_NAMES}
        if not changes and not live:
            return
        self.params = replace(self.params, **changes, **live)
        old, log = self.core.policy, self.get_logger()
        policy = replace(old, **changes)
        said = [f'{k} {getattr(old, k)!r} -> {v!r}' for k, v in changes.items()
                if getattr(old, k) != v]
        if said:
            self.core.set_policy(policy)
            if self.learning is not None:
                self.learning.set_timeout(policy.temperature_timeout)
            log.info('policy changed, from the next message: ' + ', '.join(said))
            if (old.upstream_correction, old.upstream_policy) != (
                    policy.upstream_correction, policy.upstream_policy):
                self._say_upstream(policy)
        if mismatch := 'sensor_id' in live and sensor_mismatch(self.core.model,
                                                               self.params.sensor_id):
            log.warning(mismatch)

    # -- the hot path -----------------------------------------------------------------

    def _compensate(self, data: bytes, start: float | None = None) -> None:
        """
        Compensate one serialized Imu and publish it: the one step of every IMU input.

        The rates and the covariance diagonals are patched in a copy of the bytes
        (:meth:`gyro_tdc.data.imu_cdr.ImuView.patched`, the REP 145 rule), every other byte as
        it came; bytes that are not little-endian plain CDR are deserialised and serialized
        again first. ``start``: the callback's start on the steady clock, for the backlog.
        """
        start = perf_counter() if start is None else start
        if (found := locate(data)) is None:  # not little-endian plain CDR: the slow, general way
            try:
                data = serialize_message(deserialize_message(data, Imu))
            except Exception as exc:  # the callback edge: any participant can send bytes
                return self._malformed(f'malformed imu/data_raw message dropped ({len(data)} '
                                       'bytes', exc)
            found = locate(data)
        sec, nanosec, base = found
        self._last_imu = data
        view = ImuView(data, base)
        if view.marked():
            self.inputs.already_compensated += 1
        wx, wy, wz = view.angular_velocity()
        core, t = self.core, sec + nanosec * 1e-9
        a = view.linear_acceleration() if core.needs_accel else None
        try:
            wx, wy, wz, var, flags, aout, avar = core.process(t, wx, wy, wz, a)
        except Exception as exc:  # the callback edge: never lose the message
            var, flags = core.fail(exc), PASSTHROUGH
            aout, avar = None, (var if a is not None and core.accel_on else None)
            self.get_logger().error(f'compensation failed, raw rate passed through: '
                                    f'{core.last_error}', throttle_duration_sec=1.0)
        self._pub.publish(view.patched(wx, wy, wz, var, not flags & PASSTHROUGH, aout, avar,
                                       core.policy.base_variance))
        self._record((t, start, perf_counter()))    # the backlog: stamp, start, end

    #: The ``raw_cdr`` subscription's callback: the bytes as they came.
    _on_imu_raw = _compensate

    def _on_imu(self, msg: Any) -> None:
        """Compensate a deserialised message (an ``imu_type`` one made an Imu first: FLU)."""
        start = perf_counter()
        if self.reader.to_imu is not None:
            try:
                msg = self.reader.to_imu(msg)
            except Exception as exc:  # the callback edge: a field out of range, a bad stamp
                return self._malformed('imu/data_raw message not readable as '
                                       f'{self.params.imu_type} (dropped', exc)
        self._compensate(serialize_message(msg), start)

    def _malformed(self, what: str, exc: Exception) -> None:
        """Count an input that is not an Imu (nothing to republish); the stream goes on."""
        self.inputs.malformed += 1
        self.get_logger().warning(f'{what}, {self.inputs.malformed} in total): '
                                  f'{type(exc).__name__}: {exc}', throttle_duration_sec=5.0)

    def _on_temperature(self, msg: Any) -> None:
        """
        Take a reading at its own stamp, or at the latest IMU stamp when it has none.

        A reading without a stamp before the first IMU message is ignored
        (``temperatures_ignored``).
        """
        stamp = self.reader.temperature_stamp
        # Before the first IMU message there is no stamp to give it.
        if (t := self.core.last_t if stamp is None else stamp(msg)) is None:
            self.temperatures_ignored += 1
            return
        self.core.add_temperature(t, self.reader.temperature(msg))

    def _on_message_lost(self, info: QoSMessageLostInfo) -> None:
        new = info.total_count - self.inputs.lost
        self.inputs.lost = info.total_count
        self.get_logger().warning(
            f'{new} imu/data_raw messages lost ({info.total_count} in total, reported by '
            'DDS): the compensator cannot keep up or the link drops', throttle_duration_sec=5.0)


def main(args: list[str] | None = None) -> int:
    """Run the compensator node until shutdown (``ros2 run gyro_tdc compensator_node``); --help."""
    if print_help('compensator_node', __doc__, PARAMS, args, epilog=(
            'Parameter file: share/gyro_tdc/config/compensator.yaml (--params-file; keyed /**, '
            'it applies under any namespace and node name). A value of the wrong type, out of '
            'range or not one of the choices stops the node with one line and exit status 2; '
            'set at run time, it is refused with the reason. QoS: the read-only '
            'qos_overrides.<topic>.subscription|publisher.reliability|history|depth '
            'parameters, <topic> as resolved.')):
        return 0
    # gc.freeze(): keep the start-up objects (numpy, the model...) out of the cyclic
    # collector's full passes, which otherwise stall the callback now and then (p99).
    return run_node(CompensatorNode, args, executor=lambda node: node.params.executor,
                    freeze_heap=True, name='compensator_node')


if __name__ == '__main__':
    sys.exit(main())
