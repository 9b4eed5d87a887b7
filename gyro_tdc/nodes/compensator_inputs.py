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

``imu_type`` and ``temperature_type`` name any installed ``pkg/msg/Type``; the class is
loaded with :mod:`importlib` as ``rosidl_runtime_py.utilities.get_message`` does (that
package has no PyPI wheel). The field paths (:mod:`gyro_tdc.data.fields`) are checked
against the class's field table at start, so a bad value stops the node with one line
naming the parameter. A ``sensor_msgs/msg/Imu`` input keeps the node's in-place fast path;
any other type is turned into a ``sensor_msgs/Imu`` here. See ``doc/drivers.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import importlib
from typing import Any, Callable, Mapping

from gyro_tdc.data import (check_number, check_vector, DEFAULT_TEMPERATURE_FIELDS,
                           frd_to_flu, normalize_type, reader, stamp_kind, stamp_seconds,
                           unquirk)
from gyro_tdc.errors import ConfigError
from gyro_tdc.runtime import TEMPERATURE_TYPES
from sensor_msgs.msg import Imu

__all__ = ['IMU_TYPE', 'InputReader', 'input_reader', 'message_class']

#: The IMU type of the fast path: compensated in place (raw CDR or typed).
IMU_TYPE = 'sensor_msgs/msg/Imu'
#: The range of ``builtin_interfaces/Time.sec`` (int32): a stamp outside is refused.
_INT32_MIN, _INT32_MAX = -2 ** 31, 2 ** 31 - 1


def message_class(name: str, param: str, hint: str = '') -> type:
    """
    Return the message class of ``pkg/msg/Type`` (or ``pkg/Type``), imported at run time.

    Parameters
    ----------
    name : str
        The type's name.
    param : str
        The parameter that names it (first word of an error).
    hint : str
        Examples added to an error (e.g. the usual types).

    Returns
    -------
    type
        The message class.

    Raises
    ------
    ConfigError
        When the name is malformed, the package is not installed or holds no such message;
        the message names ``param``.

    """
    hint = f' (e.g. {hint})' if hint else ''
    try:
        full = normalize_type(name)
    except ConfigError as exc:
        raise ConfigError(f'{param}: {exc}{hint}') from None
    pkg, _, cls_name = full.split('/')
    try:
        module = importlib.import_module(f'{pkg}.msg')
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
    if '/' not in type_name or '<' in type_name or '[' in type_name:
        return None
    try:
        cls = message_class(type_name, 'type')
    except ConfigError:
        return None
    return dict(cls.get_fields_and_field_types())


@dataclass(frozen=True)
class InputReader:
    """
    How the node reads its two inputs: classes, and converters for non-Imu types.

    Parameters
    ----------
    imu_cls, temperature_cls : type
        The subscriptions' message classes.
    fast : bool
        The IMU input is a ``sensor_msgs/Imu`` (the in-place path).
    to_imu : callable or None
        ``to_imu(msg) -> Imu`` for any other IMU type: rate turned to FLU, stamp, header.
    temperature : callable
        ``temperature(msg) -> float`` (degC, the quirk undone).
    temperature_stamp : callable or None
        ``temperature_stamp(msg) -> float`` (s); None: the latest IMU stamp is taken.

    """

    imu_cls: type
    temperature_cls: type
    fast: bool
    to_imu: Callable[[Any], Imu] | None
    temperature: Callable[[Any], float]
    temperature_stamp: Callable[[Any], float] | None


def _imu_converter(cls: type, type_name: str, p: Any) -> Callable[[Any], Imu]:
    """Return ``to_imu(msg)`` for an imu_type other than sensor_msgs/Imu."""
    check_vector(type_name, p.angular_velocity_field, _fields, 'angular_velocity_field')
    kind = stamp_kind(type_name, p.stamp_field, _fields, 'stamp_field')
    rate = reader(p.angular_velocity_field)
    stamp = reader(p.stamp_field)
    fields = _fields(type_name) or {}
    has_header = fields.get('header') == 'std_msgs/Header'
    frame_id = p.frame_id
    frd = p.input_frame == 'frd'
    # One Imu, refilled per message: publish() serializes it at once, and the node touches
    # only the rate and the covariance diagonal, reset here (a new Imu costs more than the
    # rest of the conversion).
    out = Imu()
    out.orientation_covariance[0] = -1.0          # REP 145: no orientation
    out.linear_acceleration_covariance[0] = -1.0  # nor acceleration; rate: unknown (0)
    cov = out.angular_velocity_covariance

    def to_imu(msg: Any) -> Imu:
        w = rate(msg)
        x, y, z = float(w.x), float(w.y), float(w.z)
        if frd:
            x, y, z = frd_to_flu(x, y, z)
        av = out.angular_velocity
        av.x, av.y, av.z = x, y, z
        s = stamp(msg)
        if kind == 'time':
            sec, nanosec = s.sec, s.nanosec
        else:
            sec, micros = divmod(int(s), 1_000_000)
            nanosec = micros * 1000
        if not (_INT32_MIN <= sec <= _INT32_MAX and 0 <= nanosec < 1_000_000_000):
            raise ValueError(f'stamp {sec} s {nanosec} ns is not a builtin_interfaces/Time')
        h = out.header
        h.stamp.sec, h.stamp.nanosec = sec, nanosec
        h.frame_id = msg.header.frame_id if has_header else frame_id
        cov[0] = cov[4] = cov[8] = 0.0
        return out

    return to_imu


def input_reader(p: Any) -> InputReader:
    """
    Build the node's :class:`InputReader` from its parameters, checking every choice.

    Parameters
    ----------
    p : CompensatorParams
        The parameters read at start (``imu_type``, ``angular_velocity_field``,
        ``stamp_field``, ``input_frame``, ``frame_id``, ``temperature_type``,
        ``temperature_field``, ``temperature_stamp_field``, ``temperature_quirk``).

    Returns
    -------
    InputReader
        The classes and converters.

    Raises
    ------
    ConfigError
        One line naming the parameter: an unknown type, a missing field, a field that is not
        a number (temperature), an x/y/z vector (rate) or a stamp.

    """
    imu_cls = message_class(p.imu_type, 'imu_type',
                            f'{IMU_TYPE}, geometry_msgs/msg/Vector3Stamped')
    imu_name = normalize_type(p.imu_type)
    fast = imu_name == IMU_TYPE
    if fast:
        if (p.angular_velocity_field, p.stamp_field) != ('angular_velocity', 'header.stamp'):
            raise ConfigError('angular_velocity_field, stamp_field: a sensor_msgs/msg/Imu '
                              'input is read at angular_velocity and header.stamp, got '
                              f'{p.angular_velocity_field!r} and {p.stamp_field!r}.')
        if p.input_frame != 'flu':
            raise ConfigError('input_frame: a sensor_msgs/msg/Imu input is FLU (REP 145), '
                              f'got {p.input_frame!r}; frd is for other imu_type messages.')
        to_imu = None
    else:
        to_imu = _imu_converter(imu_cls, imu_name, p)
    temp_cls = message_class(p.temperature_type, 'temperature_type',
                             ', '.join(TEMPERATURE_TYPES))
    temp_name = normalize_type(p.temperature_type)
    path = p.temperature_field or DEFAULT_TEMPERATURE_FIELDS.get(temp_name, '')
    if not path:
        raise ConfigError(f'temperature_field: {temp_name} has no default temperature field; '
                          'set the dotted path to its degC number (e.g. mean_temp).')
    check_number(temp_name, path, _fields, 'temperature_field')
    get = reader(path)
    fix = unquirk(p.temperature_quirk)
    if fix is None:
        def temperature(msg: Any) -> float:
            return float(get(msg))
    else:
        def temperature(msg: Any) -> float:
            return fix(float(get(msg)))
    stamp_path = p.temperature_stamp_field
    if not stamp_path and (_fields(temp_name) or {}).get('header') == 'std_msgs/Header':
        stamp_path = 'header.stamp'
    temp_stamp: Callable[[Any], float] | None = None
    if stamp_path:
        kind = stamp_kind(temp_name, stamp_path, _fields, 'temperature_stamp_field')
        get_stamp = reader(stamp_path)

        def temp_stamp(msg: Any) -> float:  # noqa: F811 (None above: no stamp)
            return stamp_seconds(kind, get_stamp(msg))
    return InputReader(imu_cls, temp_cls, fast, to_imu, temperature, temp_stamp)
