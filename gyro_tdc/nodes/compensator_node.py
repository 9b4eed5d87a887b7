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

from diagnostic_msgs.msg import DiagnosticArray
from gyro_tdc.base import spec_dataclass
from gyro_tdc.data import ImuView, locate
from gyro_tdc.errors import ConfigError
from gyro_tdc.model import CompensationModel
from gyro_tdc.nodes._params import declare, print_help
from gyro_tdc.nodes.compensator_diagnostics import (Diagnostics, DIAGNOSTICS_PERIOD_S,
                                                    TEMPERATURE_MESSAGES)
from gyro_tdc.nodes.compensator_inputs import input_reader
from gyro_tdc.nodes.compensator_learning import LEARN_STEP_S, Learning
from gyro_tdc.nodes.compensator_loading import LOAD_POLL_S, ModelLoading, read_model
from gyro_tdc.nodes.compensator_motion import MOTION_MESSAGES, MotionInput
from gyro_tdc.nodes.executors import run_node
from gyro_tdc.runtime import (CompensatorCore, InputStatus, PARAMS, PASSTHROUGH, Policy,
                              sensor_mismatch, upstream_note)
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu
from std_srvs.srv import Trigger

__all__ = ['CompensatorNode', 'CompensatorParams', 'PARAMS', 'TEMPERATURE_MESSAGES', 'main',
           'read_model']

#: The compensator's parameters, read at start-up; the writable rows are replaced when set.
CompensatorParams = spec_dataclass(
    'CompensatorParams', PARAMS, "The compensator's parameters (rows of ``PARAMS``).",
    module=__name__, methods={'policy': lambda self: Policy(
        **{s.name: getattr(self, s.name) for s in PARAMS if s.policy})})

#: The rows a running node takes from a parameter set: the policies (a new Policy swapped in
#: between two messages) and the others read where they are used; ``model_file`` is loading's.
POLICY_NAMES = frozenset(s.name for s in PARAMS if s.policy)
LIVE_NAMES = frozenset(s.name for s in PARAMS if not s.read_only and not s.policy) - {
    'model_file'}


def qos_overrides() -> QoSOverridingOptions:
    """Return the options of one entity's qos_overrides parameters: history, depth, reliability."""
    return QoSOverridingOptions.with_default_policies()


def imu_qos(p: Any) -> QoSProfile:
    """Return the imu/data_raw subscription's QoS (the default of its qos_overrides)."""
    if p.input_reliability == 'reliable':
        # Keep all: nothing is overwritten here. A keep-all publisher is held back by
        # flow control; a keep-last one drops its oldest unacknowledged samples, which
        # the next accepted sample reveals as a sequence gap the message-lost event counts.
        # Bounded by the RMW's limits (Fast DDS: 5000).
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=p.queue_depth,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    # REP 2003 sensor data, deep: the freshest queue_depth samples when behind. DDS
    # does not report the oldest ones this queue overwrites (only transport gaps).
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


class CompensatorNode(Node):
    """
    Remove the temperature drift of a gyro, one output message per input message.

    The node wires the topics, timers, services and parameter callbacks to its parts:
    ``loading`` (:class:`~gyro_tdc.nodes.compensator_loading.ModelLoading`), ``learning``
    (:class:`~gyro_tdc.nodes.compensator_learning.Learning`, None unless ``learn``),
    ``motion`` (:class:`~gyro_tdc.nodes.compensator_motion.MotionInput`) and ``diagnostics``
    (:class:`~gyro_tdc.nodes.compensator_diagnostics.Diagnostics`). Every IMU input, raw CDR,
    deserialised or read by field, goes through one step on the serialized message.

    Parameters
    ----------
    loader : callable, optional
        Reads a model file: ``loader(name) -> CompensationModel`` (default
        :func:`read_model`); tests inject a slow one.
    **kwargs
        Forwarded to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).

    Raises
    ------
    ConfigError
        A parameter is invalid, or ``imu/data_raw`` and ``imu/data_compensated`` resolve to
        the same topic.

    """

    #: Set by :meth:`destroy_node`: a timer event that still comes then does nothing.
    stopping = False

    def __init__(self, *, loader: Callable[[str], CompensationModel] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'compensator_node'), **kwargs)
        self.params = p = CompensatorParams(**declare(self, PARAMS))
        self.reader = input_reader(p)     # the input types and fields, checked
        try:
            policy = p.policy()
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        in_topic = self.resolve_topic_name('imu/data_raw')
        out_topic = self.resolve_topic_name('imu/data_compensated')
        if in_topic == out_topic:
            raise ConfigError(f'imu/data_raw and imu/data_compensated both resolve to '
                              f'{out_topic}: the compensator would compensate its own output '
                              'in a loop; remap one of them')
        self.core = CompensatorCore(policy)
        self.inputs = InputStatus(p.input_reliability)
        self.temperatures_ignored = 0  # readings without a stamp before the first IMU message
        self._last_imu: bytes | None = None    # the latest input, for its frame_id
        self.learning: Learning | None = None
        self.loading = ModelLoading(
            self.core, lambda: self.params, self.get_logger(), loader,
            model_file=lambda: self.get_parameter('model_file').value,
            set_model_file=lambda name: self.set_parameters([Parameter('model_file',
                                                                       value=name)]),
            on_model=self._new_prior)
        self.loading.load_at_start()
        self.motion = MotionInput(self.core, p.motion_topic)
        self.diagnostics = Diagnostics(
            self, self.core, self.inputs, lambda: self.params, in_topic,
            loading=self.loading, motion=self.motion, frame_id=self._frame_id,
            temperatures_ignored=lambda: self.temperatures_ignored)
        self._record = self.diagnostics.backlog.record    # the IMU step's one call per sample
        self._say_upstream(policy)                        # said once at start-up
        self._wire(p)
        if p.learn:
            self.learning = Learning(self.core, p, policy, self.get_logger(), self._learned)
            self.diagnostics.learning = self.learning
            self.create_service(Trigger, '~/learn_save', self.learning.on_save)
            self.create_service(Trigger, '~/learn_reset', self.learning.on_reset)
            # The steady clock: with use_sim_time and no /clock (or a paused bag) learning
            # goes on; what it learns follows the message stamps anyway.
            self.create_timer(LEARN_STEP_S, self.learning.on_timer,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _wire(self, p: Any) -> None:
        """Create the publishers, subscriptions, timers, services and parameter callbacks."""
        self._pub = self.create_publisher(Imu, 'imu/data_compensated', QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
            reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE),
            qos_overriding_options=qos_overrides())
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        events = SubscriptionEventCallbacks(message_lost=self._on_message_lost)
        # The profiles are the defaults of the qos_overrides.<resolved topic>.* parameters
        # (read-only: QoS is fixed when an entity is created), which may override them.
        reader = self.reader
        if not reader.fast:     # another type: turned into an Imu, then the one step
            imu_sub = self.create_subscription(
                reader.imu_cls, 'imu/data_raw', self._on_imu_other, imu_qos(p),
                event_callbacks=events, qos_overriding_options=qos_overrides())
        else:
            imu_sub = self.create_subscription(
                Imu, 'imu/data_raw', self._on_imu_raw if p.raw_cdr else self._on_imu,
                imu_qos(p), raw=p.raw_cdr, event_callbacks=events,
                qos_overriding_options=qos_overrides())
        self.inputs.reliability = imu_sub.qos_profile.reliability.name.lower()
        # As deep as the IMU queue: a simulated run streamed faster than real time sends
        # one temperature per IMU sample, and a lost temperature makes the next ones stale.
        self.create_subscription(
            reader.temperature_cls, 'imu/temperature', self._on_temperature, QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                reliability=qos_profile_sensor_data.reliability,
                durability=qos_profile_sensor_data.durability),
            qos_overriding_options=qos_overrides())
        if p.motion_topic:
            self.create_subscription(
                MOTION_MESSAGES[p.motion_type], p.motion_topic, self.motion.on_motion,
                MotionInput.qos(p.input_reliability, p.queue_depth),
                qos_overriding_options=qos_overrides())
        self.create_service(Trigger, '~/reload', self.loading.on_reload)
        # rclpy calls the callbacks added last first: the policy check runs before
        # model_file's (which reads the file), the policy swap after the model install.
        self.add_post_set_parameters_callback(self._on_policy_set)
        self.add_on_set_parameters_callback(self.loading.on_set)
        self.add_post_set_parameters_callback(self.loading.on_parameters_set)
        self.add_on_set_parameters_callback(self._on_set_policy)
        # The steady clock: with use_sim_time and no /clock (or a paused bag) the reports and
        # the model poll go on; every decision on the data follows the message stamps anyway.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_diagnostics, clock=steady)
        self.create_timer(LOAD_POLL_S, self.loading.on_poll, clock=steady)

    def destroy_node(self) -> None:
        """
        Stop the timers, save what was learned (the stretch in progress too), then go away.

        In that order: an executor may still hold a timer event of this node (the
        EventsExecutor dispatches it even after ``remove_node``); a cancelled timer's, like
        any report once ``stopping`` is set, does nothing, and the learner's worker has
        finished before the final save.
        """
        self.stopping = True
        for timer in list(self.timers):
            timer.cancel()
        if self.learning is not None:
            self.learning.stop()
        super().destroy_node()

    def diagnostic_status(self) -> Any:
        """Return the compensator's DiagnosticStatus now (and log what changed)."""
        return self.diagnostics.status()

    def _on_diagnostics(self) -> None:
        if self.stopping:
            return
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostics.status()]
        self._diag_pub.publish(arr)

    def _frame_id(self) -> str:
        """Return ``header.frame_id`` of the latest imu/data_raw message ('' before one)."""
        last = self._last_imu
        return '' if last is None else deserialize_message(last, Imu).header.frame_id

    def _new_prior(self, model: CompensationModel | None) -> None:
        """Make a model loaded from ``model_file`` (or none) the learner's prior."""
        if self.learning is not None:
            self.learning.new_prior(model)

    def _learned(self) -> None:
        """Name the model in use after the learner installed one."""
        self.loading.model_file = 'learned'

    def _say_upstream(self, policy: Policy) -> None:
        """Log what upstream_correction does with the input (a warning when it passes it)."""
        note = upstream_note(policy)
        if note:
            log = self.get_logger()
            (log.warning if self.core.upstream_pass else log.info)(note)

    # -- run-time parameter changes ----------------------------------------------------

    def _on_set_policy(self, params: list[Parameter]) -> SetParametersResult:
        """Check a set of policy parameters (ROS checked types and ranges): refuse with why."""
        changes = {q.name: q.value for q in params if q.name in POLICY_NAMES}
        if changes:
            try:
                replace(self.core.policy, **changes)
            except (TypeError, ValueError) as exc:   # Policy's own check: choices, signs
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_policy_set(self, params: list[Parameter]) -> None:
        """Swap the new policy in on the executor's thread: it applies from the next message."""
        changes = {q.name: q.value for q in params if q.name in POLICY_NAMES}
        live = {q.name: q.value for q in params if q.name in LIVE_NAMES}
        if not changes and not live:
            return
        self.params = replace(self.params, **changes, **live)
        old = self.core.policy
        policy = replace(old, **changes)
        said = [f'{k} {getattr(old, k)!r} -> {v!r}' for k, v in changes.items()
                if getattr(old, k) != v]
        if said:
            self.core.set_policy(policy)
            if self.learning is not None:
                self.learning.set_timeout(policy.temperature_timeout)
            self.get_logger().info('policy changed, from the next message: ' + ', '.join(said))
            if (old.upstream_correction, old.upstream_policy) != (
                    policy.upstream_correction, policy.upstream_policy):
                self._say_upstream(policy)
        if 'sensor_id' in live and self.core.model is not None:
            mismatch = sensor_mismatch(self.core.model, self.params.sensor_id)
            if mismatch:
                self.get_logger().warning(mismatch)

    # -- the hot path -----------------------------------------------------------------

    def _compensate(self, data: bytes, start: float | None = None) -> None:
        """
        Compensate one serialized Imu and publish it: the one step of every IMU input.

        The rates and the covariance diagonals are patched in a copy of the bytes
        (:meth:`gyro_tdc.data.imu_cdr.ImuView.patched`, the REP 145 rule), every other byte as
        it came; bytes that are not little-endian plain CDR are deserialised and serialized
        again first. ``start``: the callback's start on the steady clock, for the backlog.
        """
        if start is None:
            start = perf_counter()
        found = locate(data)
        if found is None:  # not little-endian plain CDR: the slow, general way
            try:
                data = serialize_message(deserialize_message(data, Imu))
            except Exception as exc:  # the callback edge: any participant can send bytes
                self._on_malformed(exc, len(data))
                return
            found = locate(data)
        sec, nanosec, base = found
        self._last_imu = data
        view = ImuView(data, base)
        if view.marked():
            self.inputs.already_compensated += 1
        wx, wy, wz = view.angular_velocity()
        core = self.core
        a = view.linear_acceleration() if core.needs_accel else None
        t = sec + nanosec * 1e-9
        try:
            wx, wy, wz, var, flags, aout, avar = core.process(t, wx, wy, wz, a)
        except Exception as exc:  # the callback edge: never lose the message
            var, flags = self._on_error(exc), PASSTHROUGH
            aout, avar = None, (var if a is not None and core.accel_on else None)
        self._pub.publish(view.patched(wx, wy, wz, var, not flags & PASSTHROUGH, aout, avar,
                                       core.policy.base_variance))
        self._record((t, start, perf_counter()))    # the backlog: stamp, start, end

    #: The ``raw_cdr`` subscription's callback: the bytes as they came.
    _on_imu_raw = _compensate

    def _on_imu(self, msg: Imu, start: float | None = None) -> None:
        """Compensate a deserialised Imu: serialized again, then the one step."""
        if start is None:
            start = perf_counter()
        self._compensate(serialize_message(msg), start)

    def _on_imu_other(self, msg: Any) -> None:
        """Turn an ``imu_type`` message into an Imu (FLU, stamped) and compensate that."""
        start = perf_counter()
        try:
            imu = self.reader.to_imu(msg)
        except Exception as exc:  # the callback edge: a field out of range, a bad stamp
            self.inputs.malformed += 1
            self.get_logger().warning(
                f'imu/data_raw message not readable as {self.params.imu_type} (dropped, '
                f'{self.inputs.malformed} in total): {type(exc).__name__}: {exc}',
                throttle_duration_sec=5.0)
            return
        self._compensate(serialize_message(imu), start)

    def _on_malformed(self, exc: Exception, size: int) -> None:
        """Count a message that is not an Imu (nothing to republish); the stream goes on."""
        self.inputs.malformed += 1
        self.get_logger().warning(
            f'malformed imu/data_raw message dropped ({size} bytes, {self.inputs.malformed} '
            f'in total): {type(exc).__name__}: {exc}', throttle_duration_sec=5.0)

    def _on_error(self, exc: Exception) -> tuple[float, float, float]:
        """Count an unexpected compensation failure; the raw sample goes out flagged."""
        var = self.core.fail(exc)
        self.get_logger().error(f'compensation failed, raw rate passed through: '
                                f'{self.core.last_error}', throttle_duration_sec=1.0)
        return var

    def _on_temperature(self, msg: Any) -> None:
        """
        Take a reading at its own stamp, or at the latest IMU stamp when it has none.

        Field, stamp and quirk come from the node's ``reader`` (``input_reader``); a reading
        without a stamp before the first IMU message is ignored (``temperatures_ignored``).
        """
        stamp = self.reader.temperature_stamp
        if stamp is None:
            t = self.core.last_t
            if t is None:  # before the first IMU message there is no stamp to give it
                self.temperatures_ignored += 1
                return
        else:
            t = stamp(msg)
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
    # gc.freeze(): keep the ~30k start-up objects (numpy, the model...) out of the cyclic
    # collector's full passes, which otherwise stall the callback for ~10 ms now and then (p99).
    return run_node(CompensatorNode, args, executor=lambda node: node.params.executor,
                    freeze_heap=True, name='compensator_node')


if __name__ == '__main__':
    sys.exit(main())
