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
The compensator's inputs as drivers publish them: message classes by name, fields by path.

``imu_type`` and ``temperature_type`` name any installed ``pkg/msg/Type``, loaded with
:mod:`importlib` as ``rosidl_runtime_py.utilities.get_message`` does (no PyPI wheel); the
field paths (:mod:`gyro_tdc.data.field_paths`) are checked at start, so a bad value stops
the node with one line naming the parameter. A non-Imu IMU type is turned into a
``sensor_msgs/Imu`` here (``doc/drivers.md``). :class:`MotionInput` reads ``motion_topic``.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import importlib
from typing import Any, Callable, Mapping

from geometry_msgs.msg import Twist, TwistStamped
from gyro_tdc.data import normalize_type, rate_fields, temperature_fields
from gyro_tdc.errors import ConfigError
from gyro_tdc.runtime import CompensatorCore, TEMPERATURE_TYPES
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

__all__ = ['IMU_TYPE', 'InputReader', 'input_reader', 'message_class', 'MOTION_MESSAGES',
           'MotionInput']

IMU_TYPE = 'sensor_msgs/msg/Imu'  # (gyro_tdc.data's would load rosbags)
MOTION_MESSAGES = {'twist': Twist, 'twist_stamped': TwistStamped, 'odometry': Odometry}
_INT32_MIN, _INT32_MAX = -2 ** 31, 2 ** 31 - 1


def message_class(name: str, param: str, hint: str = '') -> type:
    """
    Return the message class of ``pkg/msg/Type`` (or ``pkg/Type``), imported at run time.

    A malformed name, a package not installed or without that message is a ConfigError
    naming ``param`` (``hint``: examples added to it).
    """
    hint = f' (e.g. {hint})' if hint else ''
    try:
        pkg, _, cls_name = normalize_type(name).split('/')
        module = importlib.import_module(f'{pkg}.msg')
    except ConfigError as exc:
        raise ConfigError(f'{param}: {exc}{hint}') from None
    except ImportError:
        raise ConfigError(f'{param}: no installed message package {pkg!r} (for {name!r}; '
                          f'source its workspace or install it){hint}') from None
    cls = getattr(module, cls_name, None)
    if cls is None or not callable(getattr(cls, 'get_fields_and_field_types', None)):
        raise ConfigError(f'{param}: {pkg} has no message {cls_name!r} (for {name!r}){hint}.')
    return cls


@functools.lru_cache(maxsize=256)
def _fields(type_name: str) -> Mapping[str, str] | None:
    """Return the field table of a message type name as rclpy spells it, None if not one."""
    try:
        return dict(message_class(type_name, 'type').get_fields_and_field_types())
    except ConfigError:
        return None


@dataclass(frozen=True)
class InputReader:
    """
    How the node reads its two inputs: the subscriptions' classes and the converters.

    ``to_imu(msg) -> Imu`` (FLU, stamped) converts an IMU input that is not a
    ``sensor_msgs/Imu`` (None for one); ``temperature(msg)`` is degC (quirk undone),
    ``temperature_stamp(msg)`` s (None: the latest IMU stamp is taken).
    """

    imu_cls: type
    temperature_cls: type
    to_imu: Callable[[Any], Imu] | None
    temperature: Callable[[Any], float]
    temperature_stamp: Callable[[Any], float] | None


def _imu_converter(type_name: str, p: Any) -> Callable[[Any], Imu]:
    """Return ``to_imu(msg)`` for an imu_type other than sensor_msgs/Imu."""
    rate, stamp, kind = rate_fields(type_name, p, _fields)
    has_header = (_fields(type_name) or {}).get('header') == 'std_msgs/Header'
    frame_id = p.frame_id
    # One Imu, refilled per message: publish() serializes it at once (a new Imu costs more
    # than the rest of the conversion). REP 145: no orientation, no acceleration.
    out = Imu()
    out.orientation_covariance[0] = out.linear_acceleration_covariance[0] = -1.0
    cov, av, h = out.angular_velocity_covariance, out.angular_velocity, out.header

    def to_imu(msg: Any) -> Imu:
        av.x, av.y, av.z = rate(msg)
        s = stamp(msg)    # a builtin_interfaces/Time, or microseconds
        sec, nanosec = (s.sec, s.nanosec) if kind == 'time' else divmod(int(s) * 1000, 10 ** 9)
        if not (_INT32_MIN <= sec <= _INT32_MAX and 0 <= nanosec < 1_000_000_000):
            raise ValueError(f'stamp {sec} s {nanosec} ns is not a builtin_interfaces/Time')
        h.stamp.sec, h.stamp.nanosec = sec, nanosec
        h.frame_id = msg.header.frame_id if has_header else frame_id
        cov[0] = cov[4] = cov[8] = 0.0
        return out

    return to_imu


def input_reader(p: Any) -> InputReader:
    """
    Build the node's :class:`InputReader` from its parameters, checking every choice.

    A ConfigError names the parameter: an unknown type, a missing field, a field that is not
    a number (temperature), an x/y/z vector (rate) or a stamp.
    """
    imu_cls = message_class(p.imu_type, 'imu_type',
                            f'{IMU_TYPE}, geometry_msgs/msg/Vector3Stamped')
    fast = (imu_name := normalize_type(p.imu_type)) == IMU_TYPE
    if fast and (p.angular_velocity_field, p.stamp_field) != ('angular_velocity',
                                                              'header.stamp'):
        raise ConfigError('angular_velocity_field, stamp_field: a sensor_msgs/msg/Imu '
                          'input is read at angular_velocity and header.stamp, got '
                          f'{p.angular_velocity_field!r} and {p.stamp_field!r}.')
    if fast and p.input_frame != 'flu':
        raise ConfigError('input_frame: a sensor_msgs/msg/Imu input is FLU (REP 145), '
                          f'got {p.input_frame!r}; frd is for other imu_type messages.')
    to_imu = None if fast else _imu_converter(imu_name, p)
    temp_cls = message_class(p.temperature_type, 'temperature_type',
                             ', '.join(TEMPERATURE_TYPES))
    # No temperature stamp path: the latest IMU stamp is taken.
    temperature, temp_stamp = temperature_fields(normalize_type(p.temperature_type), p, _fields)
    return InputReader(imu_cls, temp_cls, to_imu, temperature, temp_stamp)


class MotionInput:
    """
    Take outside motion reports (``motion_topic``) and pass them to the core by stamp.

    While one says motion no sample is still. ``topic`` '' means none: no /diagnostics pairs.
    """

    def __init__(self, core: CompensatorCore, topic: str) -> None:
        self.core, self.topic = core, topic
        #: Reports without a stamp before the first IMU message (nothing to stamp them with).
        self.ignored = 0

    def on_motion(self, msg: Any) -> None:
        """Hand one Twist, TwistStamped or Odometry to the core at its stamp (or the latest)."""
        twist, st = (msg, None) if isinstance(msg, Twist) else (
            msg.twist.twist if isinstance(msg, Odometry) else msg.twist, msg.header.stamp)
        t = st.sec + st.nanosec * 1e-9 if st is not None and (st.sec or st.nanosec) else (
            self.core.last_t)                # no stamp: the latest IMU stamp received
        if t is None:
            self.ignored += 1
            return
        lin, ang = twist.linear, twist.angular
        self.core.motion(t, (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))

    def values(self) -> dict[str, str]:
        """Return the motion input's /diagnostics key/value pairs (none without a topic)."""
        if not self.topic:
            return {}
        state = {None: 'no report yet', True: 'moving', False: 'not moving'}[self.core.moving]
        return {'motion': state, 'motion reports': str(self.core.motion_reports),
                'motion reports ignored': str(self.ignored)}
