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

Subscribes ``imu/data_raw`` (sensor-data QoS with a deep queue) and ``imu/temperature``;
publishes ``imu/data_compensated`` with the header and every field copied unchanged
except ``angular_velocity`` (corrected by the model) and ``angular_velocity_covariance``
(widened by the model's residual variance and by the policies); ``/diagnostics`` at 1 Hz.
``model_file`` can be changed at run time (parameter set) or re-read (``~/reload``,
std_srvs/Trigger); an invalid file is refused with its reason and the old model stays.

Every decision lives in :mod:`gyro_tdc.compensation_logic`; this module converts. With
``raw_cdr`` (default) the Imu is taken as serialized bytes and patched in place by
:mod:`gyro_tdc.nodes.imu_cdr`, which saves most of a Python relay's per-message cost.
``main()`` spins rclpy's EventsExecutor (``executor: events``): measured with
``bench/bench_compensator.py`` it moves ~2.9x the messages of a SingleThreadedExecutor in one
process and needs ~1.5x less CPU per message across processes; its ``spin()`` is broken in the
Jazzy wheels, so :func:`spin` loops on ``spin_once``.
"""

from __future__ import annotations

from dataclasses import dataclass
import gc
import math
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_tdc.compensation_logic import (
    CompensatorCore, describe_flags, NO_MODEL, NO_TEMPERATURE, NON_FINITE, OUT_OF_RANGE,
    PASSTHROUGH, Policy, STALE)
from gyro_tdc.errors import ModelFileError
from gyro_tdc.model import CompensationModel
from gyro_tdc.modelfile import load_model
from gyro_tdc.nodes._params import declare, ParamSpec
from gyro_tdc.nodes.imu_cdr import ImuView, locate
from gyro_tdc.resources import model_path
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger

PARAMS = (
    ParamSpec('model_file', '', 'Model YAML file, or the name of a model in config/models; '
              'settable at run time (hot reload). Empty: pass the raw rate through.',
              read_only=False),
    ParamSpec('out_of_range', 'clamp', 'Outside the model temperature range: evaluate at the '
              'nearest valid temperature (clamp) or extrapolate.',
              choices=('clamp', 'extrapolate')),
    ParamSpec('temperature_timeout', 5.0, 'Temperature older than this (IMU stamp minus '
              'thermometer stamp) is stale [s].', 0.001, 86400.0),
    ParamSpec('stale_policy', 'hold', 'With a stale temperature: keep compensating with the '
              'last value (hold) or pass the raw rate through (passthrough).',
              choices=('hold', 'passthrough')),
    ParamSpec('stale_variance', 1.0e-6, 'Added to the angular_velocity_covariance diagonal '
              'while compensating with a stale temperature [(rad/s)^2].', 0.0, 1.0e3),
    ParamSpec('out_of_range_variance', 1.0e-6, 'Added to the covariance diagonal outside the '
              "model's temperature range [(rad/s)^2].", 0.0, 1.0e3),
    ParamSpec('passthrough_variance', 1.0e-4, 'Added to the covariance diagonal when the raw '
              'rate is passed through uncompensated [(rad/s)^2].', 0.0, 1.0e3),
    ParamSpec('reanchor_on_start', False, 'Shift the model offset so the compensated rate '
              'averages zero once the IMU has been still for still_window.'),
    ParamSpec('still_window', 10.0, 'Stillness window for re-anchoring [s].', 0.1, 3600.0),
    ParamSpec('still_gyro_std', 0.02, 'Largest per-axis standard deviation of the raw rate '
              'over a still window [rad/s].', 0.0, 10.0),
    ParamSpec('still_max_rate', 0.02, 'Largest per-axis mean compensated rate over a still '
              'window, i.e. the largest shift allowed [rad/s].', 0.0, 10.0),
    ParamSpec('still_accel_std', 0.1, 'Largest per-axis standard deviation of the '
              'acceleration over a still window, when the IMU has one [m/s^2].', 0.0, 100.0),
    ParamSpec('queue_depth', 2000, 'Queue depth of the imu/data_raw and imu/temperature '
              'subscriptions and of the publisher (keep last) [messages].', 1, 1000000),
    ParamSpec('raw_cdr', True, 'Take imu/data_raw as serialized CDR and patch the bytes '
              'instead of deserialising each message (same output, a fraction of the cost; '
              'other encodings fall back to deserialising).'),
    ParamSpec('executor', 'events', 'Executor main() spins the node with: rclpy.experimental '
              'EventsExecutor (events, fastest) or SingleThreadedExecutor (single).',
              choices=('events', 'single')),
)


@dataclass(frozen=True)
class CompensatorParams:
    """The compensator's parameters (see ``PARAMS`` for meanings and units)."""

    model_file: str
    out_of_range: str
    temperature_timeout: float
    stale_policy: str
    stale_variance: float
    out_of_range_variance: float
    passthrough_variance: float
    reanchor_on_start: bool
    still_window: float
    still_gyro_std: float
    still_max_rate: float
    still_accel_std: float
    queue_depth: int
    raw_cdr: bool
    executor: str

    def policy(self) -> Policy:
        """Return the pure-logic policy these parameters describe."""
        return Policy(
            out_of_range=self.out_of_range, temperature_timeout=self.temperature_timeout,
            stale_policy=self.stale_policy, stale_variance=self.stale_variance,
            out_of_range_variance=self.out_of_range_variance,
            passthrough_variance=self.passthrough_variance,
            reanchor_on_start=self.reanchor_on_start, still_window=self.still_window,
            still_gyro_std=self.still_gyro_std, still_max_rate=self.still_max_rate,
            still_accel_std=self.still_accel_std)


def read_model(name_or_file: str) -> CompensationModel:
    """
    Resolve and load a model file.

    Parameters
    ----------
    name_or_file : str
        A path or the name of a model shipped in ``config/models``.

    Returns
    -------
    CompensationModel
        The validated model.

    Raises
    ------
    ModelFileError
        The file is missing, malformed or inconsistent (one-line reason).

    """
    return load_model(model_path(name_or_file))


class CompensatorNode(Node):
    """
    Remove the temperature drift of a gyro, one output message per input message.

    Parameters
    ----------
    **kwargs
        Forwarded to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).

    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'compensator_node'), **kwargs)
        self.params = CompensatorParams(**declare(self, PARAMS))
        p = self.params
        self.core = CompensatorCore(p.policy())
        self.model_file = ''
        self.last_reload = 'none'
        self._pending: dict[str, CompensationModel] = {}
        if p.model_file:
            try:
                self._install(p.model_file, read_model(p.model_file))
            except ModelFileError as exc:
                self.last_reload = f'failed: {exc}'
                self.get_logger().error(f'cannot load model_file {p.model_file!r}: {exc}; '
                                        'passing the raw rate through')
        else:
            self.get_logger().warning('no model_file: passing the raw rate through')

        self._pub = self.create_publisher(Imu, 'imu/data_compensated', QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
            reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
        imu_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                             reliability=ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.VOLATILE)
        # As deep as the IMU queue: a simulated run streamed faster than real time sends
        # one temperature per IMU sample, and a lost temperature makes the next ones stale.
        temp_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                              reliability=qos_profile_sensor_data.reliability,
                              durability=qos_profile_sensor_data.durability)
        if p.raw_cdr:
            self.create_subscription(Imu, 'imu/data_raw', self._on_imu_raw, imu_qos, raw=True)
        else:
            self.create_subscription(Imu, 'imu/data_raw', self._on_imu, imu_qos)
        self.create_subscription(Temperature, 'imu/temperature', self._on_temperature, temp_qos)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_service(Trigger, '~/reload', self._on_reload)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self._temps_rejected_seen = 0
        self._errors = 0
        self._errors_seen = 0
        self._last_error = ''
        self._flags_seen = dict(self.core.flag_counts)
        self._reported_anchor = None
        self.create_timer(1.0, self._on_diagnostics)

    # -- the hot path -----------------------------------------------------------------

    def _on_imu(self, msg: Imu) -> None:
        st = msg.header.stamp
        w = msg.angular_velocity
        a = None
        if self.core.policy.reanchor_on_start and self.core.anchor is None:
            la = msg.linear_acceleration
            if msg.linear_acceleration_covariance[0] != -1.0:
                a = (la.x, la.y, la.z)
        try:
            wx, wy, wz, var, flags = self.core.process(
                st.sec + st.nanosec * 1e-9, w.x, w.y, w.z, a)
        except Exception as exc:  # the callback edge: never lose the message
            self._on_error(exc)
            v = self.params.passthrough_variance
            wx, wy, wz, var = w.x, w.y, w.z, (v, v, v)
        w.x, w.y, w.z = wx, wy, wz
        cov = msg.angular_velocity_covariance
        if cov[0] != -1.0:
            cov[0] += var[0]
            cov[4] += var[1]
            cov[8] += var[2]
        self._pub.publish(msg)

    def _on_imu_raw(self, data: bytes) -> None:
        found = locate(data)
        if found is None:  # not little-endian plain CDR: the slow, general way
            self._on_imu(deserialize_message(data, Imu))
            return
        sec, nanosec, base = found
        view = ImuView(data, base)
        wx, wy, wz = view.angular_velocity()
        a = None
        if self.core.policy.reanchor_on_start and self.core.anchor is None:
            a = view.linear_acceleration()
        try:
            wx, wy, wz, var, flags = self.core.process(sec + nanosec * 1e-9, wx, wy, wz, a)
        except Exception as exc:  # the callback edge: never lose the message
            self._on_error(exc)
            v = self.params.passthrough_variance
            var = (v, v, v)
        self._pub.publish(view.patched(wx, wy, wz, var))

    def _on_error(self, exc: Exception) -> None:
        """Count an unexpected compensation failure; the raw sample goes out flagged."""
        self.core.counts['out'] += 1
        self._errors += 1
        self._last_error = f'{type(exc).__name__}: {exc}'
        self.get_logger().error(f'compensation failed, raw rate passed through: '
                                f'{self._last_error}', throttle_duration_sec=1.0)

    def _on_temperature(self, msg: Temperature) -> None:
        st = msg.header.stamp
        self.core.add_temperature(st.sec + st.nanosec * 1e-9, msg.temperature)

    # -- model loading ----------------------------------------------------------------

    def _install(self, name: str, model: CompensationModel) -> None:
        """Swap the model in (one assignment inside the core) and log it."""
        self.core.set_model(model)
        self.model_file = name
        self.last_reload = f'loaded {model.model_id}'
        lo, hi = model.temp_range_c
        self.get_logger().info(
            f'model {model.model_id} from {name!r}: {model.kind}, features '
            f'{",".join(model.features)}, valid {lo:.1f}..{hi:.1f} degC')

    def load(self, name: str) -> tuple[bool, str]:
        """
        Load ``name`` and install it; on failure keep the current model.

        Parameters
        ----------
        name : str
            Model file path or shipped model name ('' to pass through).

        Returns
        -------
        tuple of (bool, str)
            Success and a one-line message.

        """
        if not name:
            self.core.set_model(None)
            self.model_file = ''
            self.last_reload = 'no model'
            return True, 'no model: passing the raw rate through'
        try:
            model = read_model(name)
        except ModelFileError as exc:
            self.last_reload = f'rejected: {exc}'
            self.get_logger().error(f'model {name!r} rejected, keeping '
                                    f'{self._model_id() or "no model"}: {exc}')
            return False, str(exc)
        self._install(name, model)
        return True, f'loaded model {model.model_id} from {name}'

    def _model_id(self) -> str:
        return self.core.model.model_id if self.core.model is not None else ''

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a new ``model_file`` by loading it; refuse it with the reason."""
        for param in params:
            if param.name == 'model_file':
                name = param.value
                if not isinstance(name, str):
                    return SetParametersResult(successful=False,
                                               reason='model_file must be a string')
                if name:
                    try:
                        self._pending[name] = read_model(name)
                    except ModelFileError as exc:
                        self.last_reload = f'rejected: {exc}'
                        self.get_logger().error(f'model_file {name!r} rejected: {exc}')
                        return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        """Install the model validated by :meth:`_on_set_parameters`."""
        for param in params:
            if param.name == 'model_file':
                name = param.value
                model = self._pending.pop(name, None)
                if model is not None:
                    self._install(name, model)
                elif not name:
                    self.load('')
        self._pending.clear()

    def _on_reload(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        name = self.get_parameter('model_file').value
        response.success, response.message = self.load(name)
        return response

    # -- diagnostics ------------------------------------------------------------------

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the compensator's DiagnosticStatus (and log what changed)."""
        core = self.core
        model = core.model
        counts = core.flag_counts
        new = {bit: counts[bit] - self._flags_seen.get(bit, 0) for bit in counts}
        self._flags_seen = dict(counts)
        rejected = core.temps.rejected - self._temps_rejected_seen
        self._temps_rejected_seen = core.temps.rejected
        st = DiagnosticStatus()
        st.name = f'{self.get_name()}: gyro compensation'
        st.hardware_id = (model.sensor_id or model.frame_id) if model is not None else ''
        age = core.temperature_age()
        problems = []
        level = DiagnosticStatus.OK
        if model is None:
            level = DiagnosticStatus.ERROR
            problems.append(f'no model loaded ({self.last_reload})')
        for bit in (NO_TEMPERATURE, STALE, OUT_OF_RANGE, NON_FINITE):
            if new[bit]:
                level = max(level, DiagnosticStatus.WARN)
                problems.append(f'{describe_flags(bit)} ({new[bit]} samples)')
        if rejected:
            level = max(level, DiagnosticStatus.WARN)
            problems.append(f'non-finite temperature ({rejected} samples rejected)')
        errors = self._errors - self._errors_seen
        self._errors_seen = self._errors
        if errors:
            level = DiagnosticStatus.ERROR
            problems.append(f'compensation failed on {errors} samples, passed through: '
                            f'{self._last_error}')
        if problems:
            st.message = '; '.join(problems)
        elif core.counts['in'] == 0:
            st.message = 'waiting for imu/data_raw'
        else:
            st.message = 'compensating'
        if new[PASSTHROUGH]:
            st.message += f'; {new[PASSTHROUGH]} samples passed through uncompensated'
        st.level = level
        anchor = core.anchor
        values: dict[str, Any] = {
            'compensation active': (model is not None and core.counts['compensated'] > 0
                                    and not core.last_flags & PASSTHROUGH),
            'why not': describe_flags(core.last_flags & ~OUT_OF_RANGE & ~STALE)
            if core.last_flags & PASSTHROUGH else '',
            'model id': self._model_id(), 'model file': self.model_file,
            'model features': ','.join(model.features) if model is not None else '',
            'model kind': model.kind if model is not None else '',
            'model range degC': '{:.2f}..{:.2f}'.format(*model.temp_range_c)
            if model is not None else '',
            'last reload': self.last_reload,
            'temperature degC': f'{core.last_temp:.3f}' if core.last_temp is not None else '',
            'temperature age s': f'{age:.3f}' if age is not None else '',
            'temperature stale': bool(core.last_flags & STALE),
            'in range': not core.last_flags & OUT_OF_RANGE,
            'messages in': core.counts['in'], 'messages out': core.counts['out'],
            'compensated': core.counts['compensated'],
            'passed through': counts[PASSTHROUGH],
            'no temperature yet': counts[NO_TEMPERATURE], 'stale': counts[STALE],
            'out of range': counts[OUT_OF_RANGE], 'non-finite': counts[NON_FINITE],
            'no model': counts[NO_MODEL], 'temperatures rejected': core.temps.rejected,
            'errors': self._errors, 'last error': self._last_error,
            'reanchor': ('off' if not core.policy.reanchor_on_start else
                         'waiting for stillness' if anchor is None else
                         f'done at t={anchor.t:.3f} s'),
        }
        if anchor is not None:
            values['reanchor shift dps'] = ','.join(f'{math.degrees(v):.5f}'
                                                    for v in anchor.delta)
            if anchor is not self._reported_anchor:
                self._reported_anchor = anchor
                self.get_logger().info(
                    f're-anchored after {anchor.samples} still samples at '
                    f'{anchor.temp_c:.2f} degC: offset shift {values["reanchor shift dps"]} '
                    'deg/s')
        st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        return st

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)


def make_executor(kind: str, context: Any = None) -> Any:
    """
    Return the executor named by the ``executor`` parameter.

    Parameters
    ----------
    kind : str
        ``'events'`` (rclpy.experimental.EventsExecutor) or ``'single'``.
    context : rclpy.context.Context, optional
        Context of the executor.

    Returns
    -------
    rclpy.executors.Executor
        The executor.

    """
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def spin(executor: Any, context: Any = None) -> None:
    """
    Run ``executor`` until its context shuts down.

    The loop calls ``spin_once``: in the rclpy 7.1.6 Jazzy wheels
    ``EventsExecutor.spin()`` dispatches nothing at all (neither timers nor
    subscriptions) while its ``spin_once`` works and is the fast path.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        The executor, nodes added.
    context : rclpy.context.Context, optional
        Its context (default: the global one).

    """
    while rclpy.ok(context=context):
        executor.spin_once(timeout_sec=0.5)


def main(args: list[str] | None = None) -> None:
    """Run the compensator node until shutdown (``ros2 run gyro_tdc compensator_node``)."""
    rclpy.init(args=args)
    node = None
    executor = None
    try:
        node = CompensatorNode()
        executor = make_executor(node.params.executor)
        executor.add_node(node)
        # Keep the ~30k start-up objects (numpy, the model...) out of the cyclic collector's
        # full passes, which otherwise stall the callback for ~10 ms now and then (p99).
        gc.freeze()
        spin(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
