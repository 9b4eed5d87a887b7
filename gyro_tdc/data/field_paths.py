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
Driver messages read by field: dotted paths, their checks, stamps, FRD axes, quirks (pure).

A driver publishes its gyro and thermometer in its own message types; the compensator and
the bag reader name the fields to read with a dotted path (``vector``, ``header.stamp``).
The checks walk a type's field table (``fields_of``: rclpy's
``get_fields_and_field_types()`` or a rosbags typestore's) so that a bad path is refused
once, at start, naming the parameter. See ``doc/drivers.md``.
"""

from __future__ import annotations

from operator import attrgetter
import re
from typing import Any, Callable, Mapping

from gyro_tdc.base import TEMPERATURE_QUIRKS
from gyro_tdc.errors import ConfigError

__all__ = ['check_number', 'check_vector', 'DEFAULT_TEMPERATURE_FIELDS', 'FieldsOf',
           'frd_to_flu', 'normalize_type', 'rate_fields', 'reader', 'split_path', 'stamp_kind',
           'stamp_seconds', 'temperature_fields', 'temperature_path', 'unquirk']

#: The usual number field of the common thermometer types (``temperature_field`` empty).
DEFAULT_TEMPERATURE_FIELDS = {'sensor_msgs/msg/Temperature': 'temperature',
                              'std_msgs/msg/Float32': 'data', 'std_msgs/msg/Float64': 'data'}

_FLOATS = frozenset({'float', 'double', 'float32', 'float64', 'long double'})
_INTEGERS = frozenset({'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64',
                       'uint64', 'octet', 'byte', 'char'})
_NUMBERS = _FLOATS | _INTEGERS
_TIME = 'builtin_interfaces/Time'
_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*\Z')

#: A type's field table: field name -> type name (None: not a message type).
FieldsOf = Callable[[str], 'Mapping[str, str] | None']


def normalize_type(name: str) -> str:
    """
    Return a message type name as ``pkg/msg/Type`` (``pkg/Type`` is accepted too).

    Raises
    ------
    ConfigError
        When ``name`` is not ``pkg/msg/Type`` or ``pkg/Type``.

    """
    parts = name.split('/')
    if len(parts) == 2:
        parts.insert(1, 'msg')
    if len(parts) != 3 or parts[1] != 'msg' or not all(_NAME.match(p) for p in parts):
        raise ConfigError(f'Expected a message type pkg/msg/Type, got {name!r}.')
    return '/'.join(parts)


def split_path(path: str, param: str) -> tuple[str, ...]:
    """
    Return the field names of a dotted path ('' is the message itself).

    Raises
    ------
    ConfigError
        When a part is not a field name; the message names ``param``.

    """
    parts = tuple(path.split('.')) if path else ()
    if not all(_NAME.match(part) for part in parts):
        raise ConfigError(f'{param}: expected a dotted path of field names (e.g. '
                          f'header.stamp), got {path!r}.')
    return parts


def _walk(type_name: str, path: str, fields_of: FieldsOf, param: str) -> str:
    """Return the type name at ``path`` in ``type_name``, or raise ConfigError naming it."""
    here = type_name
    for name in split_path(path, param):
        if (fields := fields_of(here)) is None:
            raise ConfigError(f'{param}: {here} in {type_name} is not a message, it has no '
                              f'field {name!r} (path {path!r}).')
        if name not in fields:
            raise ConfigError(f'{param}: {here} has no field {name!r} (path {path!r} in '
                              f'{type_name}; its fields: {", ".join(fields)}).')
        here = fields[name]
    return here


def check_number(type_name: str, path: str, fields_of: FieldsOf, param: str) -> None:
    """
    Check that ``path`` in ``type_name`` is a number (float or integer).

    Raises
    ------
    ConfigError
        When the path is missing or leads to something else; the message names ``param``.

    """
    if (leaf := _walk(type_name, path, fields_of, param)) not in _NUMBERS:
        raise ConfigError(f'{param}: {path!r} in {type_name} is {leaf}, not a number.')


def temperature_path(type_name: str, given: str, fields_of: FieldsOf, param: str) -> str:
    """
    Return the dotted path to the degC number of ``type_name``: ``given``, else its default.

    Raises
    ------
    ConfigError
        When the type has no default (and none is given) or the path is not a number; the
        message names ``param``.

    """
    if not (path := given or DEFAULT_TEMPERATURE_FIELDS.get(type_name, '')):
        raise ConfigError(f'{param}: {type_name} has no default temperature field; give the '
                          'dotted path to its degC number (e.g. mean_temp).')
    check_number(type_name, path, fields_of, param)
    return path


def check_vector(type_name: str, path: str, fields_of: FieldsOf, param: str) -> None:
    """
    Check that ``path`` in ``type_name`` holds numeric ``x``, ``y`` and ``z`` fields.

    Raises
    ------
    ConfigError
        When it does not; the message names ``param``.

    """
    leaf = _walk(type_name, path, fields_of, param)
    if (fields := fields_of(leaf)) is None or not all(fields.get(k) in _NUMBERS for k in 'xyz'):
        raise ConfigError(f'{param}: {repr(path) if path else "the message itself"} in '
                          f'{type_name} is {leaf}, not an x/y/z vector of numbers.')


def stamp_kind(type_name: str, path: str, fields_of: FieldsOf, param: str) -> str:
    """
    Return how ``path`` in ``type_name`` stamps a message: ``'time'`` or ``'micros'``.

    ``'time'`` is a ``builtin_interfaces/Time``; ``'micros'`` an integer count of
    microseconds (``px4_msgs``' ``timestamp``).

    Raises
    ------
    ConfigError
        When the path is missing or neither; the message names ``param``.

    """
    leaf = _walk(type_name, path, fields_of, param)
    if leaf.replace('/msg/', '/') == _TIME:        # rclpy spells it pkg/Type
        return 'time'
    if leaf in _INTEGERS:
        return 'micros'
    raise ConfigError(f'{param}: {path!r} in {type_name} is {leaf}, neither a '
                      'builtin_interfaces/Time nor an integer in microseconds.')


def reader(path: str) -> Callable[[Any], Any]:
    """Return a function reading a dotted path from a message ('' the message itself)."""
    return attrgetter(path) if path else (lambda msg: msg)


def stamp_seconds(kind: str, value: Any) -> float:
    """Return a stamp read at a ``stamp_kind`` path in seconds."""
    return value.sec + value.nanosec * 1e-9 if kind == 'time' else value * 1e-6


def frd_to_flu(x: float, y: float, z: float) -> tuple[float, float, float]:
    """Return a vector of FRD axes (x forward, y right, z down) in FLU axes (REP 103)."""
    return x, -y, -z


def unquirk(kind: str) -> Callable[[float], float] | None:
    """
    Return the function that undoes a driver's temperature encoding (None for '').

    ``bno055_unsigned_byte``: a reading of 128 or more is ``256 + T`` with T below 0 (the
    chip reads -40..85 degC), so 256 is taken off; ``sbg_legacy_div256``: the reading is
    T / 256. Raises ConfigError for a ``kind`` not in :data:`TEMPERATURE_QUIRKS`.
    """
    quirks = {'': None, 'bno055_unsigned_byte': lambda t: t - 256.0 if t >= 128.0 else t,
              'sbg_legacy_div256': lambda t: t * 256.0}
    if kind in quirks:
        return quirks[kind]
    raise ConfigError(f'Expected temperature_quirk to be one of '
                      f'{", ".join(map(repr, TEMPERATURE_QUIRKS))}, got {kind!r}.')


def rate_fields(type_name: str, choices: Any, fields_of: FieldsOf,
                option: Callable[[str], str] = str
                ) -> tuple[Callable[[Any], tuple[float, float, float]], Callable[[Any], Any], str]:
    """
    Check an IMU type's rate and stamp paths; return (FLU rate, stamp, :func:`stamp_kind`).

    ``choices`` holds ``angular_velocity_field``, ``stamp_field`` and ``input_frame`` (a
    :class:`~gyro_tdc.data.driver_bags.DriverInputs`, or the compensator's parameters);
    ``option(name)`` is how a ConfigError names one (the parameter, the command-line option).
    The rate reader returns x, y, z as floats in FLU axes, the stamp reader the raw stamp.
    """
    check_vector(type_name, choices.angular_velocity_field, fields_of,
                 option('angular_velocity_field'))
    kind = stamp_kind(type_name, choices.stamp_field, fields_of, option('stamp_field'))
    get, frd = reader(choices.angular_velocity_field), choices.input_frame == 'frd'

    def rate(msg: Any) -> tuple[float, float, float]:
        w = get(msg)
        x, y, z = float(w.x), float(w.y), float(w.z)
        return frd_to_flu(x, y, z) if frd else (x, y, z)
    return rate, reader(choices.stamp_field), kind


def temperature_fields(type_name: str, choices: Any, fields_of: FieldsOf,
                       option: Callable[[str], str] = str
                       ) -> tuple[Callable[[Any], float], Callable[[Any], float] | None]:
    """
    Check a thermometer type's paths; return (degC of a message, its stamp in s, or None).

    ``choices`` holds ``temperature_field`` ('' the type's default), ``temperature_stamp_field``
    ('' its ``header.stamp`` where it has one, else None is returned: the caller stamps a
    reading with the latest IMU stamp) and ``temperature_quirk`` (undone); ``option`` as in
    :func:`rate_fields`.
    """
    path = temperature_path(type_name, choices.temperature_field, fields_of,
                            option('temperature_field'))
    get, fix = reader(path), unquirk(choices.temperature_quirk) or float
    header = str((fields_of(type_name) or {}).get('header')).replace('/msg/', '/')
    stamp_path = choices.temperature_stamp_field or (
        'header.stamp' if header == 'std_msgs/Header' else '')   # rclpy spells it pkg/Type
    if not stamp_path:
        return lambda msg: fix(float(get(msg))), None
    kind = stamp_kind(type_name, stamp_path, fields_of, option('temperature_stamp_field'))
    get_stamp = reader(stamp_path)
    return lambda msg: fix(float(get(msg))), lambda msg: stamp_seconds(kind, get_stamp(msg))
