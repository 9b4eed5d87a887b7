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

Publishes ``imu/data_raw``, ``imu/temperature``, the simulator's ``rate_table/reference``
and ``/diagnostics``, from any :class:`gyro_tdc.sources.base.ImuSource`; a failing device is
reported and retried with backoff. See ``doc/internals/nodes.md``.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import sys
import time
from typing import Any, Callable

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3, Vector3Stamped
from gyro_tdc.base import ParamSpec, spec_dataclass
from gyro_tdc.errors import ConfigError, DeviceError, GyroTdcError, one_line
from gyro_tdc.nodes._params import declare, print_help
from gyro_tdc.nodes.executors import run_node, ShellNode
from gyro_tdc.sources import Backoff, check_sample, ImuSample, ImuSource, SourceExhausted
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Header

PARAMS = (
    ParamSpec('backend', 'sim', 'Where samples come from: the simulator or a Linux IIO device.',
              choices=('sim', 'iio')),
    ParamSpec('frame_id', 'imu_link', 'frame_id of every published message (REP 145).'),
    ParamSpec('angular_velocity_variance', 1.0e-6,
              'Diagonal of angular_velocity_covariance [(rad/s)^2].', 0.0, 1.0e3),
    ParamSpec('linear_acceleration_variance', 1.0e-3,
              'Diagonal of linear_acceleration_covariance when the device has an '
              'accelerometer [(m/s^2)^2].', 0.0, 1.0e6),
    ParamSpec('temperature_variance', 0.01, 'Variance of imu/temperature [degC^2].',
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


#: The driver's parameters, read once at start-up.
DriverParams = spec_dataclass('DriverParams', PARAMS,
                              "The driver's parameters (rows of ``PARAMS``).", module=__name__)


def stamp_from_ns(ns: int) -> Time:
    """Return a builtin_interfaces/Time from integer nanoseconds."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


#: REP 145: a covariance that starts with -1 says the message carries no such data.
NO_DATA = [-1.0] + [0.0] * 8


def _diagonal(v: float) -> list[float]:
    """Return a row-major 3x3 covariance with ``v`` on its diagonal."""
    return [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, v]


def _open_sim(p: DriverParams, clock_ns: Callable[[], int]) -> ImuSource:
    """Open the simulator; a scenario it cannot load, or a run too large, is a ConfigError."""
    from gyro_tdc.base import check_sim_samples
    from gyro_tdc.sim import load_scenario
    from gyro_tdc.sources import SimSource
    try:
        scenario = load_scenario(p.scenario)
        check_sim_samples(scenario.duration_s, p.sim_rate_hz or scenario.imu_rate_hz,
                          option='sim_rate_hz' if p.sim_rate_hz else 'imu_rate_hz')
    except (GyroTdcError, ValueError) as exc:
        raise ConfigError(one_line(exc)) from None
    return SimSource(scenario, seed=p.seed, run_index=p.run_index,
                     rate_hz=p.sim_rate_hz or None, time_scale=p.time_scale,
                     max_batch=p.max_batch, clock_ns=clock_ns)


def _open_iio(p: DriverParams, clock_ns: Callable[[], int]) -> ImuSource:
    from gyro_tdc.sources import find_iio_device, IioSource
    device = p.device_dir or find_iio_device(p.device_name, root=p.iio_root)
    return IioSource(device, temp_every=p.temp_every, clock=lambda: clock_ns() * 1e-9)


@dataclass(frozen=True)
class Backend:
    """What the node knows of one back-end: the only place the ``backend`` parameter matters."""

    #: Opens the source, ``open(params, clock_ns) -> ImuSource``; ``clock_ns()`` returns the
    #: node clock in ns.
    open: Callable[[DriverParams, Callable[[], int]], ImuSource]
    #: Parameter giving how often the node asks the source for due samples [Hz].
    tick_hz: str
    #: What /diagnostics names while no source is open, ``hardware_id(params) -> str``.
    hardware_id: Callable[[DriverParams], str]
    #: Whether the node publishes ``rate_table/reference``.
    reference: bool = False
    #: Parameters reported on /diagnostics.
    diagnostics: tuple[str, ...] = ()
    #: Whether a source that cannot be opened at start-up is retried (a device may
    #: appear); False makes it a configuration error and the node does not start.
    retry: bool = True


BACKENDS = {
    # The simulator fails only on its configuration (scenario, rates): no use retrying.
    'sim': Backend(_open_sim, 'tick_hz', lambda p: p.scenario, reference=True,
                   diagnostics=('time_scale',), retry=False),
    'iio': Backend(_open_iio, 'rate_hz', lambda p: p.device_dir or p.device_name),
}


class DriverNode(ShellNode):
    """
    Publish a gyro's samples as sensor_msgs/Imu and sensor_msgs/Temperature.

    ``source``: use this back-end instead of opening the one the parameters name (tests);
    ``kwargs`` go to :class:`rclpy.node.Node`. A ConfigError: a parameter is not one of its
    choices, or a back-end that is not retried (the simulator) cannot be opened.
    """

    def __init__(self, *, source: ImuSource | None = None, **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'driver_node'), **kwargs)
        self.params = p = DriverParams(**declare(self, PARAMS))
        self._backend = BACKENDS[p.backend]
        qos = p.qos_depth      # reliable, keep last
        self._imu_pub = self.create_publisher(Imu, 'imu/data_raw', qos)
        self._temp_pub = self.create_publisher(Temperature, 'imu/temperature', qos)
        self._ref_pub = (self.create_publisher(Vector3Stamped, 'rate_table/reference', qos)
                         if self._backend.reference else None)
        self._injected, self._source = source, None
        self._retry_at, self._state, self._last_error, self._device = 0.0, 'starting', '', ''
        # Errors, messages published; implausible readings the source dropped, as last logged.
        self._errors = self._published = self._temps = self._temps_rejected = 0
        # The message templates: constant fields filled once (REP 145: no orientation).
        self._imu = Imu(header=Header(frame_id=p.frame_id), orientation_covariance=NO_DATA,
                        angular_velocity_covariance=_diagonal(p.angular_velocity_variance))
        self._temp = Temperature(header=Header(frame_id=p.frame_id),
                                 variance=p.temperature_variance)
        try:
            if p.retry_max < p.retry_initial:
                raise ConfigError(f'Expected `retry_max` >= `retry_initial` '
                                  f'({p.retry_initial!r}), got {p.retry_max!r}.')
            self._backoff = Backoff(p.retry_initial, p.retry_max)
            self._try_open(fatal=not self._backend.retry)
        except ConfigError:
            self.destroy_node()
            raise
        self._timer = self.create_timer(1.0 / getattr(p, self._backend.tick_hz), self._on_tick)
        self.report_diagnostics(1.0)
        self.get_logger().info(
            f'{p.backend} back-end, {self._device or "no device yet"}, publishing '
            f'imu/data_raw and imu/temperature in frame {p.frame_id!r}')

    def _try_open(self, *, fatal: bool = False) -> None:
        """Open (or reopen) the source; on failure schedule the next attempt, or raise."""
        try:
            src = self._injected if self._injected is not None else self._backend.open(
                self.params, lambda: self.get_clock().now().nanoseconds)
        except DeviceError as exc:
            if fatal:
                raise ConfigError(one_line(exc)) from None
            return self._fail(exc)
        self._source, self._device, self._state = src, src.name, 'running'
        var = self.params.linear_acceleration_variance
        self._imu.linear_acceleration_covariance = _diagonal(var) if src.has_accel else NO_DATA
        self.get_logger().info(f'opened {self._device}')

    def release(self) -> None:
        """Close and drop the source (an injected one is the caller's)."""
        if self._source is not None and self._source is not self._injected:
            with contextlib.suppress(DeviceError):
                self._source.close()
        self._source = None

    def _fail(self, exc: DeviceError) -> None:
        """Record a device error, drop the source and schedule a retry with backoff."""
        self._errors += 1
        self._last_error, self._state = str(exc), 'error'
        self.release()
        delay = self._backoff.next_delay()
        self._retry_at = time.monotonic() + delay
        self.get_logger().warning(f'device error: {exc} (retry in {delay:.2f} s)')

    def _publish(self, src: ImuSource, sample: ImuSample) -> None:
        """Fill the message templates from one checked sample and publish them."""
        stamp = stamp_from_ns(src.stamp_ns(sample.t))
        if sample.ref is not None and self._ref_pub is not None:
            self._ref_pub.publish(Vector3Stamped(
                header=Header(frame_id=self.params.frame_id, stamp=stamp),
                vector=Vector3(**dict(zip('xyz', sample.ref)))))
        msg = self._imu
        msg.header.stamp = stamp
        w, a = msg.angular_velocity, msg.linear_acceleration
        w.x, w.y, w.z = sample.omega
        if sample.accel is not None:
            a.x, a.y, a.z = sample.accel
        if sample.temp_c is not None:
            self._temp.header.stamp = (stamp if sample.temp_t is None
                                       else stamp_from_ns(src.stamp_ns(sample.temp_t)))
            self._temp.temperature = sample.temp_c
            self._temp_pub.publish(self._temp)
            self._temps += 1
        self._imu_pub.publish(msg)
        self._published += 1

    def _on_tick(self) -> None:
        """Publish what the source says is due; errors go to diagnostics."""
        if self._state == 'finished' or self.stopping:
            return
        if self._source is None and time.monotonic() >= self._retry_at:
            self._try_open()
        if (src := self._source) is None:
            return
        try:
            for sample in src.pending():
                self._publish(src, check_sample(sample))
            if (rejected := getattr(src, 'temperatures_rejected', 0)) != self._temps_rejected:
                self._temps_rejected = rejected
                self.get_logger().warning(
                    f'{rejected} implausible thermometer readings dropped (outside the '
                    'plausible range or jumping faster than the slew bound)',
                    throttle_duration_sec=10.0)
            if self._backoff.failures:
                self._backoff.reset()
                self.get_logger().info(f'{self._device} reads again')
        except SourceExhausted as exc:
            self._state, self._last_error = 'finished', ''
            self._timer.cancel()
            self.get_logger().info(f'{exc}; {self._published} samples published')
        except DeviceError as exc:
            self._fail(exc)

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the driver's current DiagnosticStatus."""
        p, state = self.params, self._state
        level, message = DiagnosticStatus.OK, {'finished': 'scenario finished'}.get(
            state, 'publishing')
        if state == 'error':
            level, message = DiagnosticStatus.ERROR, (
                f'device error, retry in {max(self._retry_at - time.monotonic(), 0.0):.1f} s: '
                f'{self._last_error}')
        values = {
            'backend': p.backend, 'device': self._device, 'state': state,
            'imu messages': self._published, 'temperature messages': self._temps,
            'errors': self._errors, 'last error': self._last_error,
            'temperatures rejected (implausible)': self._temps_rejected,
            **{name: getattr(p, name) for name in self._backend.diagnostics}}
        return DiagnosticStatus(
            level=level, name=f'{self.get_name()}: gyro driver', message=message,
            hardware_id=self._device or self._backend.hardware_id(p),
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


def main(args: list[str] | None = None) -> int:
    """Run the driver node until shutdown (``ros2 run gyro_tdc driver_node``), or --help."""
    if print_help('driver_node', __doc__, PARAMS, args, epilog=(
            'Parameter files: share/gyro_tdc/config/driver_sim.yaml and driver_iio.yaml '
            '(--params-file); an unknown backend or scenario, or a value of the wrong type '
            'or out of range, stops the node with one line and exit status 2.')):
        return 0
    return run_node(DriverNode, args, executor='single', name='driver_node')


if __name__ == '__main__':
    sys.exit(main())
