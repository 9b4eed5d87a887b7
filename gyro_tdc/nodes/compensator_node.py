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
from gyro_tdc.data import diagonal_marked, ImuView, locate, mark_diagonal, mark_unknown
from gyro_tdc.errors import ConfigError
from gyro_tdc.model import CompensationModel
from gyro_tdc.nodes._params import declare, print_help
from gyro_tdc.nodes.compensator_diagnostics import (Diagnostics, DIAGNOSTICS_PERIOD_S,
                                                    TEMPERATURE_MESSAGES)
from gyro_tdc.nodes.compensator_inputs import input_reader
from gyro_tdc.nodes.compensator_learning import Learning
from gyro_tdc.nodes.compensator_loading import LOAD_ERRORS, LOAD_POLL_S, ModelLoading, read_model
from gyro_tdc.nodes.compensator_motion import MotionInput
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
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu
from std_srvs.srv import Trigger

__all__ = ['CompensatorNode', 'CompensatorParams', 'LOAD_ERRORS', 'PARAMS',
           'TEMPERATURE_MESSAGES', 'main', 'read_model']

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

#: The deprecated QoS parameters, aliases of the ``qos_overrides.`` ones for one release.
DEPRECATED_QOS = ('input_reliability', 'queue_depth')


def qos_overrides() -> QoSOverridingOptions:
    """Return the options of one entity's qos_overrides parameters: history, depth, reliability."""
    return QoSOverridingOptions.with_default_policies()


class CompensatorNode(ModelLoading, Learning, MotionInput, Diagnostics, Node):
    """
    Remove the temperature drift of a gyro, one output message per input message.

    Model loading (:mod:`~gyro_tdc.nodes.compensator_loading`), learning
    (:mod:`~gyro_tdc.nodes.compensator_learning`), the motion input
    (:mod:`~gyro_tdc.nodes.compensator_motion`) and /diagnostics
    (:mod:`~gyro_tdc.nodes.compensator_diagnostics`) come from mixins; this class wires
    the topics and converts messages on the hot path.

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

    def __init__(self, *, loader: Callable[[str], CompensationModel] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'compensator_node'), **kwargs)
        self.params = CompensatorParams(**declare(self, PARAMS))
        p = self.params
        self.reader = reader = input_reader(p)     # the input types and fields, checked
        self._temperature_value = reader.temperature
        self._temperature_stamp = reader.temperature_stamp
        self._to_imu = reader.to_imu
        try:
            policy = p.policy()
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self._in_topic = self.resolve_topic_name('imu/data_raw')
        out_topic = self.resolve_topic_name('imu/data_compensated')
        if self._in_topic == out_topic:
            raise ConfigError(f'imu/data_raw and imu/data_compensated both resolve to '
                              f'{out_topic}: the compensator would compensate its own output '
                              'in a loop; remap one of them')
        self.core = CompensatorCore(policy)
        self.inputs = InputStatus(p.input_reliability)
        for name in DEPRECATED_QOS:
            if getattr(p, name) != next(s.default for s in PARAMS if s.name == name):
                self.get_logger().warning(
                    f'{name} is deprecated (kept for one release): it seeds the defaults of '
                    'the qos_overrides.<topic>.subscription|publisher.* parameters, which '
                    'override it; set those instead')
        self.temperatures_ignored = 0  # std_msgs readings before the first IMU message
        self.learner = None
        self._init_loading(loader)

        self._pub = self.create_publisher(Imu, 'imu/data_compensated', QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
            reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE),
            qos_overriding_options=qos_overrides())
        if p.input_reliability == 'reliable':
            # Keep all: nothing is overwritten here. A keep-all publisher is held back by
            # flow control; a keep-last one drops its oldest unacknowledged samples, which
            # the next accepted sample reveals as a sequence gap the message-lost event
            # counts (76-99 % of them measured). Bounded by the RMW's limits (Fast DDS: 5000).
            imu_qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=p.queue_depth,
                                 reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.VOLATILE)
        else:
            # REP 2003 sensor data, deep: the freshest queue_depth samples when behind. DDS
            # does not report the oldest ones this queue overwrites (only transport gaps).
            imu_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                                 reliability=ReliabilityPolicy.BEST_EFFORT,
                                 durability=DurabilityPolicy.VOLATILE)
        # As deep as the IMU queue: a simulated run streamed faster than real time sends
        # one temperature per IMU sample, and a lost temperature makes the next ones stale.
        temp_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                              reliability=qos_profile_sensor_data.reliability,
                              durability=qos_profile_sensor_data.durability)
        events = SubscriptionEventCallbacks(message_lost=self._on_message_lost)
        # The profiles above are the defaults of the qos_overrides.<resolved topic>.* parameters
        # (read-only: QoS is fixed when an entity is created), which may override them.
        if not reader.fast:     # another type: turned into an Imu, then the typed path
            imu_sub = self.create_subscription(
                reader.imu_cls, 'imu/data_raw', self._on_imu_other, imu_qos,
                event_callbacks=events, qos_overriding_options=qos_overrides())
        else:
            imu_sub = self.create_subscription(
                Imu, 'imu/data_raw', self._on_imu_raw if p.raw_cdr else self._on_imu,
                imu_qos, raw=p.raw_cdr, event_callbacks=events,
                qos_overriding_options=qos_overrides())
        self.inputs.reliability = imu_sub.qos_profile.reliability.name.lower()
        self.create_subscription(
            reader.temperature_cls, 'imu/temperature', self._on_temperature, temp_qos,
            qos_overriding_options=qos_overrides())
        self._init_motion()
        self._init_diagnostics()
        self.create_service(Trigger, '~/reload', self._on_reload)
        # rclpy calls the callbacks added last first: the policy check runs before
        # model_file's (which reads the file), the policy swap after the model install.
        self.add_post_set_parameters_callback(self._on_policy_set)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.add_on_set_parameters_callback(self._on_set_policy)
        # The steady clock: with use_sim_time and no /clock (or a paused bag) the reports and
        # the model poll go on; every decision on the data follows the message stamps anyway.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_diagnostics, clock=steady)
        self.create_timer(LOAD_POLL_S, self._on_load_poll, clock=steady)
        if p.learn:
            self._start_learning(policy)

    def destroy_node(self) -> None:
        """Save what was learned (the stretch in progress too) before going away."""
        self._stop_learning()
        super().destroy_node()

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
        log = self.get_logger()
        old = self.core.policy
        policy = replace(old, **changes)
        said = [f'{k} {getattr(old, k)!r} -> {v!r}' for k, v in changes.items()
                if getattr(old, k) != v]
        if said:
            self.core.set_policy(policy)
            self.set_learn_timeout(policy.temperature_timeout)
            log.info('policy changed, from the next message: ' + ', '.join(said))
            if (old.upstream_correction, old.upstream_policy) != (
                    policy.upstream_correction, policy.upstream_policy):
                note = upstream_note(policy)
                if note:
                    (log.warning if self.core.upstream_pass else log.info)(note)
        if 'sensor_id' in live and self.core.model is not None:
            mismatch = sensor_mismatch(self.core.model, self.params.sensor_id)
            if mismatch:
                log.warning(mismatch)

    # -- the hot path -----------------------------------------------------------------

    def _on_imu(self, msg: Imu, start: float | None = None) -> None:
        if start is None:                   # the callback's start on the steady clock
            start = perf_counter()
        self._last_imu = msg                # its frame_id, read by /diagnostics
        st = msg.header.stamp
        t = st.sec + st.nanosec * 1e-9
        w = msg.angular_velocity
        cov = msg.angular_velocity_covariance
        if diagonal_marked(cov):
            self.inputs.already_compensated += 1
        core = self.core
        a = None
        if core.needs_accel:
            la = msg.linear_acceleration
            if msg.linear_acceleration_covariance[0] != -1.0:
                a = (la.x, la.y, la.z)
        try:
            wx, wy, wz, var, flags, aout, avar = core.process(t, w.x, w.y, w.z, a)
        except Exception as exc:  # the callback edge: never lose the message
            var, flags = self._on_error(exc), PASSTHROUGH
            wx, wy, wz = w.x, w.y, w.z
            aout, avar = None, (var if a is not None and core.accel_on else None)
        w.x, w.y, w.z = wx, wy, wz
        # REP 145: -1 in element 0 is no data (left as it came); all zero is unknown, which
        # stays unknown (marked with negative zeros, still all == 0) unless base_variance
        # gives unknown input a base (ImuView.patched, the same rule).
        if cov[0] != -1.0:
            base = core.policy.base_variance
            if cov[0] != 0.0 or any(cov):
                base = 0.0
            elif base <= 0.0:
                base = None
            if base is not None:
                cov[0] += base + var[0]
                cov[4] += base + var[1]
                cov[8] += base + var[2]
                if not flags & PASSTHROUGH:
                    mark_diagonal(cov)
            elif not flags & PASSTHROUGH:
                mark_unknown(cov)
        if aout is not None:
            la.x, la.y, la.z = aout
        if avar is not None:
            acov = msg.linear_acceleration_covariance
            acov[0] += avar[0]
            acov[4] += avar[1]
            acov[8] += avar[2]
        self._pub.publish(msg)
        self._record((t, start, perf_counter()))    # the backlog: stamp, start, end

    def _on_imu_other(self, msg: Any) -> None:
        """Turn an ``imu_type`` message into an Imu (FLU, stamped) and compensate that."""
        start = perf_counter()
        try:
            imu = self._to_imu(msg)
        except Exception as exc:  # the callback edge: a field out of range, a bad stamp
            self.inputs.malformed += 1
            self.get_logger().warning(
                f'imu/data_raw message not readable as {self.params.imu_type} (dropped, '
                f'{self.inputs.malformed} in total): {type(exc).__name__}: {exc}',
                throttle_duration_sec=5.0)
            return
        self._on_imu(imu, start)

    def _on_imu_raw(self, data: bytes) -> None:
        start = perf_counter()
        found = locate(data)
        if found is None:  # not little-endian plain CDR: the slow, general way
            try:
                msg = deserialize_message(data, Imu)
            except Exception as exc:  # the callback edge: any participant can send bytes
                self._on_malformed(exc, len(data))
                return
            self._on_imu(msg, start)
            return
        sec, nanosec, base = found
        self._last_imu = data               # its frame_id, read by /diagnostics
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
        self._record((t, start, perf_counter()))

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
        stamp = self._temperature_stamp
        if stamp is None:
            t = self.core.last_t
            if t is None:  # before the first IMU message there is no stamp to give it
                self.temperatures_ignored += 1
                return
        else:
            t = stamp(msg)
        self.core.add_temperature(t, self._temperature_value(msg))

    #: The same handler for header-less readings (std_msgs Float32/Float64).
    _on_float_temperature = _on_temperature

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
