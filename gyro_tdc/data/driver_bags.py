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
Bags recorded from drivers as they publish: any IMU and thermometer type, read by field.

:class:`DriverInputs` holds the compensator's input choices (``--imu-type``,
``--angular-velocity-field``, ``--stamp-field``, ``--input-frame``, ``--temperature-type``,
``--temperature-field``, ``--temperature-stamp-field``, ``--temperature-quirk``);
:func:`normalize_bag` decodes such a bag with rosbags' typestore (the bag's own message
definitions) and writes the same samples as ``sensor_msgs/Imu`` + ``sensor_msgs/Temperature``,
which :func:`~gyro_tdc.data.read_bag` reads as any other bag. The live node reads the same
fields the same way (:mod:`gyro_tdc.data.field_paths`), so a model is trained on what it is fed.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from gyro_tdc.base import INPUT_FRAMES
from gyro_tdc.data.bag.codec import IMU_TYPE
from gyro_tdc.data.bag.metadata import Unfit
from gyro_tdc.data.bag.reader import READ_ERRORS, topic_messages
from gyro_tdc.data.bag.storage_mcap import cut_off
from gyro_tdc.data.bag.writer import write_bag
from gyro_tdc.data.field_paths import (normalize_type, rate_fields, stamp_seconds,
                                       temperature_fields, unquirk)
from gyro_tdc.errors import ConfigError, DatasetError, one_line
import numpy as np
from rosbags.interfaces import Nodetype

__all__ = ['DriverInputs', 'field_table', 'normalize_bag']


@dataclass(frozen=True)
class DriverInputs:
    """
    How a driver's bag holds the gyro and the thermometer (defaults: Imu + Temperature).

    Parameters
    ----------
    imu_type, angular_velocity_field, stamp_field, input_frame : str
        The IMU topic's type, the dotted path to its x/y/z rate (rad/s; '' the message
        itself), to its stamp (a Time or an integer in microseconds), and its axes
        (``flu`` or ``frd``).
    temperature_type : str
        The thermometer topic's type ('' as the bag says: Temperature, Float32, Float64).
    temperature_field, temperature_stamp_field, temperature_quirk : str
        Dotted path to the degC number ('' the type's usual one), to its stamp ('' its
        ``header.stamp``, else the latest IMU stamp), and the driver's encoding to undo.

    Raises
    ------
    ConfigError
        An unknown ``input_frame`` or ``temperature_quirk``, or a malformed type name.

    """

    imu_type: str = IMU_TYPE
    angular_velocity_field: str = 'angular_velocity'
    stamp_field: str = 'header.stamp'
    input_frame: str = 'flu'
    temperature_type: str = ''
    temperature_field: str = ''
    temperature_stamp_field: str = ''
    temperature_quirk: str = ''

    def __post_init__(self) -> None:
        """Check the choices and spell the type names ``pkg/msg/Type``."""
        if self.input_frame not in INPUT_FRAMES:
            raise ConfigError(f'input_frame: expected one of {", ".join(INPUT_FRAMES)}, got '
                              f'{self.input_frame!r}.')
        unquirk(self.temperature_quirk)      # raises on an unknown one
        object.__setattr__(self, 'imu_type', normalize_type(self.imu_type))
        if self.temperature_type:
            object.__setattr__(self, 'temperature_type', normalize_type(self.temperature_type))

    @property
    def plain(self) -> bool:
        """Return whether the bag is read as it is (every choice at its default)."""
        return self == DriverInputs()


def field_table(typestore: Any) -> Any:
    """Return ``fields_of(type name)`` over a rosbags typestore (None: not a message)."""
    def fields_of(name: str) -> Mapping[str, str] | None:
        full = name if '/msg/' in name else name.replace('/', '/msg/', 1)
        if full not in typestore.fielddefs:
            return None
        return {fname: desc[0] if kind == Nodetype.BASE else desc if kind == Nodetype.NAME
                else 'array' for fname, (kind, desc) in typestore.fielddefs[full][1]}
    return fields_of


def _option(name: str) -> str:
    """Return the command-line option of a :class:`DriverInputs` field (``--stamp-field``)."""
    return '--' + name.replace('_', '-')


def _connection(every: Sequence[Any], topic: str, want: str | None, option: str) -> Any:
    if not (conns := [c for c in every if c.topic == topic]):
        raise DatasetError(f'bag has no topic {topic!r} (topics: '
                           f'{", ".join(sorted({c.topic for c in every}))}).')
    got = conns[0].msgtype
    if want is not None and got != want:
        raise DatasetError(f'{option}: topic {topic!r} holds {got}, not {want}.')
    return conns[0]


def normalize_bag(path: str | Path, inputs: DriverInputs, *, imu_topic: str,
                  temperature_topic: str, out: str | Path,
                  warn: Callable[[str], Any] = lambda _line: None) -> Path:
    """
    Write a bag's gyro and thermometer, read by field, as a plain Imu + Temperature bag.

    Parameters
    ----------
    path : str or Path
        The rosbag2 bag recorded from the driver.
    inputs : DriverInputs
        How its topics hold the rate and the temperature.
    imu_topic, temperature_topic : str
        The topics to read; the new bag has them under the same names.
    out : str or Path
        The bag directory to create.
    warn : callable
        Takes each warning of the read (an mcap file cut off: the bytes lost).

    Returns
    -------
    Path
        ``out``: rates in FLU, header stamps from the chosen stamp fields (a header-less
        reading takes the stamp of the latest IMU message logged before it; readings before
        the first one are dropped), temperatures with the quirk undone.

    Raises
    ------
    ConfigError
        A field path is missing or of the wrong kind (the message names the option).
    DatasetError
        The bag cannot be read, lacks a topic or holds another type than declared.

    """
    path = Path(path)
    try:
        with topic_messages(path, (imu_topic, temperature_topic), warn) as (
                store, conns, messages):
            fields_of = field_table(store)
            imu_conn = _connection(conns, imu_topic, inputs.imu_type, '--imu-type')
            temp_conn = _connection(conns, temperature_topic, inputs.temperature_type or None,
                                    '--temperature-type')
            imu_name = imu_conn.msgtype
            rate, stamp, kind = rate_fields(imu_name, inputs, fields_of, _option)
            value, tstamp = temperature_fields(temp_conn.msgtype, inputs, fields_of, _option)
            # Flat float64 arrays: a fifth of the memory of lists of Python floats.
            imu_t, gyro, accel, temp_t, temp_c = (array('d') for _ in range(5))
            frame_id, gyro_cov, accel_cov = 'imu_link', None, (-1.0, 0.0, 0.0)
            for conn, _, raw in messages(imu_conn, temp_conn):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                if conn is imu_conn:
                    if not imu_t and hasattr(msg, 'header'):
                        frame_id = msg.header.frame_id
                    if not imu_t and imu_name == IMU_TYPE:
                        gyro_cov = tuple(msg.angular_velocity_covariance[[0, 4, 8]])
                        accel_cov = tuple(msg.linear_acceleration_covariance[[0, 4, 8]])
                    imu_t.append(stamp_seconds(kind, stamp(msg)))
                    gyro.extend(rate(msg))
                    if imu_name == IMU_TYPE:
                        a = msg.linear_acceleration
                        accel.extend((a.x, a.y, a.z))
                elif tstamp is not None or imu_t:    # else no IMU stamp to give it yet
                    temp_t.append(tstamp(msg) if tstamp else imu_t[-1])
                    temp_c.append(value(msg))
    except (*READ_ERRORS, Unfit) as exc:   # rosbags' errors and what its parsers let through
        cut = cut_off(sorted(path.glob('*.mcap')) if path.is_dir() else [path])
        raise DatasetError(f'cannot read bag {str(path)!r}: {one_line(exc)}{cut}') from None
    if not imu_t:
        raise DatasetError(f'bag {str(path)!r} has no message on {imu_topic!r}.')
    temp_t, temp_c = np.frombuffer(temp_t), np.frombuffer(temp_c)
    order = np.argsort(temp_t, kind='stable')
    write_bag(out, imu_t=np.frombuffer(imu_t), gyro=np.frombuffer(gyro).reshape(-1, 3),
              accel=np.frombuffer(accel).reshape(-1, 3) if accel else np.zeros((len(imu_t), 3)),
              temp_t=temp_t[order], temp_c=temp_c[order],
              frame_id=frame_id, imu_topic=imu_topic, temperature_topic=temperature_topic,
              gyro_cov=gyro_cov, accel_cov=accel_cov)
    return Path(out)
