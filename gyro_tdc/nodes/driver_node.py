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
The gyro driver node: a simulated scenario or a Linux IIO device -> Imu and Temperature.

Publishes ``imu/data_raw`` (sensor_msgs/Imu, REP 145), ``imu/temperature``
(sensor_msgs/Temperature, degC), for the simulator ``rate_table/reference``
(geometry_msgs/Vector3Stamped, rad/s) whenever the table changes rate, and
``/diagnostics`` at 1 Hz. A device that disappears or returns garbage is reported
on ``/diagnostics`` and the log, retried with exponential backoff, and nothing is
published from it until it reads cleanly again.

Stamps: the IIO back-end stamps each sample with the node clock when it is read.
The simulator's stamps are its simulated times shifted onto the node clock at the
first sample (``stamp = start + (t_sim - t_sim0)``): at ``time_scale`` 1 they follow
the wall clock; faster, they run ahead of it so that every time constant in the
data (filters, dT/dt) stays in simulated seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
import time
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped
from gyro_tdc.errors import DeviceError
from gyro_tdc.nodes._params import declare, ParamSpec
from gyro_tdc.sources.base import Backoff, check_sample, ImuSample, ImuSource, SourceExhausted
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, Temperature

PARAMS = (
    ParamSpec('backend', 'sim', 'Where samples come from: the simulator or a Linux IIO device.',
              choices=('sim', 'iio')),
    ParamSpec('frame_id', 'imu_link', 'frame_id of every published message (REP 145).'),
    ParamSpec('angular_velocity_variance', 1.0e-6,
              'Diagonal of angular_velocity_covariance [(rad/s)^2].', 0.0, 1.0e3),
    ParamSpec('linear_acceleration_variance', 1.0e-3,
              'Diagonal of linear_acceleration_covariance when the device has an '
              'accelerometer [(m/s^2)^2].', 0.0, 1.0e6),
    ParamSpec('temperature_variance', 0.01, 'variance of imu/temperature [degC^2].',
              0.0, 1.0e4),
    ParamSpec('qos_depth', 100, 'Publisher history depth (reliable, keep last) [messages].',
              1, 100000),
    ParamSpec('scenario', 'l3gd20_paper', 'sim: scenario name in config/scenarios or a YAML '
              'file path.'),
    ParamSpec('seed', 0, 'sim: random seed.', 0, 2 ** 31 - 1),
    ParamSpec('run_index', 0, 'sim: which run of a multi-run scenario.', 0, 10000),
    ParamSpec('sim_rate_hz', 0.0, "sim: IMU rate overriding the scenario's; 0 keeps it [Hz].",
              0.0, 100000.0),
    ParamSpec('time_scale', 1.0, 'sim: simulated seconds per wall-clock second; 0 streams '
              'as fast as the node can publish [1].', 0.0, 1.0e6),
    ParamSpec('tick_hz', 100.0, 'sim: how often the node publishes the samples that are due '
              '[Hz].', 1.0, 10000.0),
    ParamSpec('max_batch', 2000, 'sim: most samples published per tick [samples].', 1, 1000000),
    ParamSpec('rate_hz', 200.0, 'iio: polling rate [Hz].', 0.1, 10000.0),
    ParamSpec('device_dir', '', 'iio: device sysfs directory (e.g. /sys/bus/iio/devices/'
              'iio:device0); empty to find it by device_name.'),
    ParamSpec('device_name', 'l3gd20', 'iio: device name to look for under iio_root when '
              'device_dir is empty.'),
    ParamSpec('iio_root', '/sys/bus/iio/devices', 'iio: where IIO devices are listed.'),
    ParamSpec('temp_every', 1, 'iio: read the thermometer every N gyro samples [samples].',
              1, 100000),
    ParamSpec('retry_initial', 0.5, 'First retry delay after a device error [s].', 0.001, 60.0),
    ParamSpec('retry_max', 10.0, 'Longest retry delay after repeated device errors [s].',
              0.001, 3600.0),
)


@dataclass(frozen=True)
class DriverParams:
    """The driver's parameters, read once at start-up (see ``PARAMS`` for meanings/units)."""

    backend: str
    frame_id: str
    angular_velocity_variance: float
    linear_acceleration_variance: float
    temperature_variance: float
    qos_depth: int
    scenario: str
    seed: int
    run_index: int
    sim_rate_hz: float
    time_scale: float
    tick_hz: float
    max_batch: int
    rate_hz: float
    device_dir: str
    device_name: str
    iio_root: str
    temp_every: int
    retry_initial: float
    retry_max: float


def stamp_from_ns(ns: int) -> Time:
    """Return a builtin_interfaces/Time from integer nanoseconds."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def open_source(p: DriverParams, clock_s: Any) -> ImuSource:
    """
    Open the back-end named by the parameters.

    Parameters
    ----------
    p : DriverParams
        Parameters.
    clock_s : callable returning float, s
        Clock stamping IIO samples.

    Returns
    -------
    ImuSource
        The opened source.

    Raises
    ------
    DeviceError
        The device cannot be opened.

    """
    if p.backend == 'iio':
        from gyro_tdc.sources.iio import find_iio_device, IioSource
        device = p.device_dir or find_iio_device(p.device_name, root=p.iio_root)
        return IioSource(device, temp_every=p.temp_every, clock=clock_s)
    from gyro_tdc.sources.sim import SimSource
    return SimSource(p.scenario, seed=p.seed, run_index=p.run_index,
                     rate_hz=p.sim_rate_hz or None)


class DriverNode(Node):
    """
    Publish a gyro's samples as sensor_msgs/Imu and sensor_msgs/Temperature.

    Parameters
    ----------
    source : ImuSource, optional
        Use this back-end instead of opening the one the parameters name (tests).
    **kwargs
        Forwarded to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).

    """

    def __init__(self, *, source: ImuSource | None = None, **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'driver_node'), **kwargs)
        self.params = DriverParams(**declare(self, PARAMS))
        p = self.params
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.qos_depth,
                         reliability=ReliabilityPolicy.RELIABLE)
        self._imu_pub = self.create_publisher(Imu, 'imu/data_raw', qos)
        self._temp_pub = self.create_publisher(Temperature, 'imu/temperature', qos)
        self._ref_pub = (self.create_publisher(Vector3Stamped, 'rate_table/reference', qos)
                         if p.backend == 'sim' else None)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)

        self._injected = source
        self._source: ImuSource | None = None
        self._backoff = Backoff(p.retry_initial, p.retry_max)
        self._retry_at = 0.0
        self._state = 'starting'
        self._last_error = ''
        self._errors = 0
        self._published = 0
        self._temps = 0
        self._device = ''
        self._finished = False
        self._sim_origin: tuple[int, float] | None = None  # (node ns, sim s) at first sample
        self._wall_origin = 0.0
        self._diag_count = 0

        # The message templates: constant fields filled once.
        self._imu = Imu()
        self._imu.header.frame_id = p.frame_id
        self._imu.orientation_covariance[0] = -1.0
        for i in (0, 4, 8):
            self._imu.angular_velocity_covariance[i] = p.angular_velocity_variance
        self._temp = Temperature()
        self._temp.header.frame_id = p.frame_id
        self._temp.variance = p.temperature_variance

        self._try_open()
        period = 1.0 / (p.tick_hz if p.backend == 'sim' else p.rate_hz)
        self._timer = self.create_timer(period, self._on_tick)
        self._diag_timer = self.create_timer(1.0, self._on_diagnostics)
        self.get_logger().info(
            f'{p.backend} back-end, {self._device or "no device yet"}, publishing '
            f'imu/data_raw and imu/temperature in frame {p.frame_id!r}')

    # -- source management ------------------------------------------------------------

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _try_open(self) -> None:
        """Open (or reopen) the source; on failure schedule the next attempt."""
        try:
            src = self._injected if self._injected is not None else open_source(
                self.params, lambda: self._now_ns() * 1e-9)
        except DeviceError as exc:
            self._fail(exc)
            return
        self._source = src
        self._device = getattr(src, 'name', type(src).__name__)
        self._state = 'running'
        has_accel = bool(getattr(src, 'has_accel', True))
        cov = self._imu.linear_acceleration_covariance
        for i in range(9):
            cov[i] = 0.0
        if has_accel:
            for i in (0, 4, 8):
                cov[i] = self.params.linear_acceleration_variance
        else:
            cov[0] = -1.0  # REP 145: no acceleration data
        self.get_logger().info(f'opened {self._device}')

    def _fail(self, exc: DeviceError) -> None:
        """Record a device error, drop the source and schedule a retry with backoff."""
        self._errors += 1
        self._last_error = str(exc)
        if self._source is not None and self._source is not self._injected:
            try:
                self._source.close()
            except DeviceError:
                pass
        self._source = None
        delay = self._backoff.next_delay()
        self._retry_at = time.monotonic() + delay
        self._state = 'error'
        self.get_logger().warning(f'device error: {exc} (retry in {delay:.2f} s)')

    # -- publishing -------------------------------------------------------------------

    def _publish(self, sample: ImuSample, stamp_ns: int, temp_ns: int) -> None:
        """Fill the message templates from one checked sample and publish them."""
        msg = self._imu
        msg.header.stamp = stamp_from_ns(stamp_ns)
        w = sample.omega
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
        if sample.accel is not None:
            a = sample.accel
            msg.linear_acceleration.x, msg.linear_acceleration.y = a[0], a[1]
            msg.linear_acceleration.z = a[2]
        if sample.temp_c is not None:
            self._temp.header.stamp = stamp_from_ns(temp_ns)
            self._temp.temperature = sample.temp_c
            self._temp_pub.publish(self._temp)
            self._temps += 1
        self._imu_pub.publish(msg)
        self._published += 1

    def _on_tick(self) -> None:
        """Publish what is due (sim) or poll once (iio); errors go to diagnostics."""
        if self._finished:
            return
        if self._source is None:
            if time.monotonic() >= self._retry_at:
                self._try_open()
            if self._source is None:
                return
        try:
            if self.params.backend == 'sim':
                self._tick_sim()
            else:
                self._tick_iio()
        except SourceExhausted as exc:
            self._finished = True
            self._state = 'finished'
            self._last_error = ''
            self._timer.cancel()
            self.get_logger().info(f'{exc}; {self._published} samples published')
        except DeviceError as exc:
            self._fail(exc)

    def _tick_iio(self) -> None:
        sample = check_sample(self._source.read())
        stamp = int(round(sample.t * 1e9))
        self._publish(sample, stamp, stamp)
        if self._backoff.failures:
            self._backoff.reset()
            self.get_logger().info(f'{self._device} reads again')

    def _tick_sim(self) -> None:
        src = self._source
        p = self.params
        now = time.monotonic()
        if self._sim_origin is None:
            first = src.peek_t()
            if first is None:
                raise SourceExhausted(f'scenario {p.scenario!r} has no samples')
            self._sim_origin = (self._now_ns(), first)
            self._wall_origin = now
        origin_ns, sim0 = self._sim_origin
        limit = (float('inf') if p.time_scale == 0.0
                 else sim0 + (now - self._wall_origin) * p.time_scale)
        for _ in range(p.max_batch):
            t_next = src.peek_t()
            if t_next is None:
                src.read()  # raises SourceExhausted
            if t_next > limit:
                break
            sample = check_sample(src.read())
            stamp = origin_ns + int(round((sample.t - sim0) * 1e9))
            temp_t = sample.temp_t if sample.temp_t is not None else sample.t
            if sample.ref is not None and self._ref_pub is not None:
                ref = Vector3Stamped()
                ref.header.frame_id = p.frame_id
                ref.header.stamp = stamp_from_ns(stamp)
                ref.vector.x, ref.vector.y, ref.vector.z = sample.ref
                self._ref_pub.publish(ref)
            self._publish(sample, stamp, origin_ns + int(round((temp_t - sim0) * 1e9)))

    # -- diagnostics ------------------------------------------------------------------

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the driver's current DiagnosticStatus."""
        p = self.params
        st = DiagnosticStatus()
        st.name = f'{self.get_name()}: gyro driver'
        st.hardware_id = self._device or (p.scenario if p.backend == 'sim' else
                                          p.device_dir or p.device_name)
        if self._state == 'error':
            st.level = DiagnosticStatus.ERROR
            retry = max(self._retry_at - time.monotonic(), 0.0)
            st.message = f'device error, retry in {retry:.1f} s: {self._last_error}'
        elif self._state == 'finished':
            st.level = DiagnosticStatus.OK
            st.message = 'scenario finished'
        else:
            st.level = DiagnosticStatus.OK
            st.message = 'publishing'
        values = {
            'backend': p.backend, 'device': self._device, 'state': self._state,
            'imu messages': self._published, 'temperature messages': self._temps,
            'errors': self._errors, 'last error': self._last_error,
        }
        if p.backend == 'sim':
            values['time_scale'] = p.time_scale
        st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        return st

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)

    def destroy_node(self) -> None:
        """Close the source, then destroy the node."""
        if self._source is not None and self._source is not self._injected:
            try:
                self._source.close()
            except DeviceError:
                pass
        self._source = None
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the driver node until shutdown (``ros2 run gyro_tdc driver_node``)."""
    rclpy.init(args=args)
    node = None
    try:
        node = DriverNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
