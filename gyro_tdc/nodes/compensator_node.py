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

Every decision lives in :mod:`gyro_tdc.compensation_logic` (the policies, the parameter
table ``PARAMS``, the health on /diagnostics); this module converts. With ``raw_cdr``
(default) the Imu is taken as serialized bytes and patched in place by
:mod:`gyro_tdc.imu_cdr`, which saves most of a Python relay's per-message cost. ``main()``
spins rclpy's EventsExecutor (``executor: events``, see :mod:`gyro_tdc.nodes.executors`).
"""

from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_tdc.compensation_logic import CompensatorCore, PARAMS, Policy
from gyro_tdc.errors import ModelFileError
from gyro_tdc.health import health, HealthMark
from gyro_tdc.imu_cdr import ImuView, locate
from gyro_tdc.model import CompensationModel
from gyro_tdc.modelfile import load_model
from gyro_tdc.nodes._params import declare
from gyro_tdc.nodes.executors import run_node
from gyro_tdc.paramspec import spec_dataclass
from gyro_tdc.resources import model_path
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger

__all__ = ['CompensatorNode', 'CompensatorParams', 'PARAMS', 'main', 'read_model']

#: The compensator's parameters, read once at start-up (``model_file`` also at run time).
CompensatorParams = spec_dataclass(
    'CompensatorParams', PARAMS, "The compensator's parameters (rows of ``PARAMS``).",
    module=__name__, methods={'policy': lambda self: Policy(
        **{s.name: getattr(self, s.name) for s in PARAMS if s.policy})})


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
        self._seen = HealthMark()
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
            var = self._on_error(exc)
            wx, wy, wz = w.x, w.y, w.z
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
            var = self._on_error(exc)
        self._pub.publish(view.patched(wx, wy, wz, var))

    def _on_error(self, exc: Exception) -> tuple[float, float, float]:
        """Count an unexpected compensation failure; the raw sample goes out flagged."""
        var = self.core.fail(exc)
        self.get_logger().error(f'compensation failed, raw rate passed through: '
                                f'{self.core.last_error}', throttle_duration_sec=1.0)
        return var

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
            model = self.core.model
            kept = (model.model_id if model is not None else '') or 'no model'
            self.get_logger().error(f'model {name!r} rejected, keeping {kept}: {exc}')
            return False, str(exc)
        self._install(name, model)
        return True, f'loaded model {model.model_id} from {name}'

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
        """Return the compensator's DiagnosticStatus (and log a new re-anchoring)."""
        h = health(self.core, self._seen, model_file=self.model_file,
                   last_reload=self.last_reload)
        self._seen = h.mark
        anchor = self.core.anchor
        if anchor is not None and anchor is not self._reported_anchor:
            self._reported_anchor = anchor
            self.get_logger().info(
                f're-anchored after {anchor.samples} still samples at {anchor.temp_c:.2f} '
                f'degC: offset shift {h.values["reanchor shift dps"]} deg/s')
        return DiagnosticStatus(
            level=bytes((h.level,)), name=f'{self.get_name()}: gyro compensation',
            message=h.message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in h.values.items()])

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)


def main(args: list[str] | None = None) -> None:
    """Run the compensator node until shutdown (``ros2 run gyro_tdc compensator_node``)."""
    # gc.freeze(): keep the ~30k start-up objects (numpy, the model...) out of the cyclic
    # collector's full passes, which otherwise stall the callback for ~10 ms now and then (p99).
    run_node(CompensatorNode, args, executor=lambda node: node.params.executor,
             freeze_heap=True)


if __name__ == '__main__':
    main()
