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

"""How to read bags and flight logs: topics, reference rate, loss allowed (:class:`BagOptions`)."""

from __future__ import annotations

from dataclasses import dataclass
import math
import re

from gyro_tdc.errors import DatasetError
import numpy as np

__all__ = ['BagOptions', 'check_sessions', 'DEFAULT_IMU_TOPIC', 'DEFAULT_REFERENCE_TOPIC',
           'DEFAULT_TEMPERATURE_TOPIC', 'LOG_FORMATS', 'MAX_LOSS_FRACTION', 'SESSION_MODES',
           'TEMPERATURE_SOURCES']

DEFAULT_IMU_TOPIC = '/imu/data_raw'
DEFAULT_TEMPERATURE_TOPIC = '/imu/temperature'
DEFAULT_REFERENCE_TOPIC = '/rate_table/reference'
#: Default largest fraction of a topic's listed messages that may be unreadable in a bag.
MAX_LOSS_FRACTION = 0.01
#: ``--sessions`` values (:mod:`gyro_tdc.data.sessions`, which imports them from here).
SESSION_MODES = ('auto', 'bag', 'none')
#: ``--log-format`` values: ``auto`` tells a bag, a PX4 ULog and an ArduPilot DataFlash log apart.
LOG_FORMATS = ('auto', 'rosbag2', 'ulog', 'dataflash')
#: ``--temperature-source`` names (beside ``TOPIC.FIELD``): the IMU's own, the barometer's.
TEMPERATURE_SOURCES = ('imu', 'baro')


@dataclass(frozen=True)
class BagOptions:
    """
    Every choice about reading bags, as :func:`gyro_tdc.data.dataset.load_run` takes them.

    Raises
    ------
    DatasetError
        When ``reference`` is not three finite rates, ``log_format`` or ``sessions`` is
        unknown, ``imu_instance`` is not an integer >= 0, ``session_gap_s`` not a number
        >= 0 or ``temperature_source`` none of its forms.

    """

    #: ``sensor_msgs/msg/Imu`` topic.
    imu_topic: str = DEFAULT_IMU_TOPIC
    #: ``sensor_msgs/msg/Temperature`` topic.
    temperature_topic: str = DEFAULT_TEMPERATURE_TOPIC
    #: Constant reference rate (x, y, z), rad/s; when given, the reference topic is not read.
    reference: tuple[float, float, float] | None = None
    #: ``geometry_msgs/msg/Vector3Stamped`` topic, held (zero-order) onto the IMU stamps
    #: when present; the reference is zero when the bag has no such topic.
    reference_topic: str = DEFAULT_REFERENCE_TOPIC
    #: Largest distance from an IMU stamp to the nearest thermometer sample, s.
    max_gap_s: float = 5.0
    #: Show a progress bar while reading.
    progress: bool = False
    #: Largest fraction of a topic's messages (as listed in the bag's metadata) that may be
    #: missing after reading; 1.0 accepts any loss (it is still reported).
    max_loss: float = MAX_LOSS_FRACTION
    #: Also read the linear acceleration into ``run.accel``.
    accel: bool = False
    #: A ``cmd_vel`` (Twist), TwistStamped or Odometry topic vetoing stillness while it
    #: reports motion (``train --still-only``); empty: none.
    motion_topic: str = ''
    #: How to read each path, one of :data:`LOG_FORMATS` (``auto`` tells by the file).
    log_format: str = 'auto'
    #: The IMU of a flight-controller log to read, 0-based (``sensor_gyro`` multi-id,
    #: DataFlash ``IMU`` instance).
    imu_instance: int = 0
    #: Read flight-log data the flight controller already thermally compensated (refused
    #: otherwise).
    allow_onboard_corrected: bool = False
    #: How the runs are cut into sessions, one turn-on offset each
    #: (:func:`gyro_tdc.data.sessions.split_sessions`): ``auto`` (a bag, cut at gaps and
    #: restarts), ``bag`` or ``none``.
    sessions: str = 'auto'
    #: Stamp gap that starts a session, s; 0 for automatic
    #: (:func:`gyro_tdc.data.sessions.session_gap`).
    session_gap_s: float = 0.0
    #: The thermometer of a flight-controller log, ``'imu'`` (the IMU's own), ``'baro'``
    #: (the barometer's, a proxy) or ``'TOPIC.FIELD'`` / ``'MSG.Field'`` (another
    #: thermometer of the board, a proxy).
    temperature_source: str = 'imu'
    #: How a driver's bag holds the gyro and the thermometer, a
    #: :class:`~gyro_tdc.data.driver_bags.DriverInputs`: read by field into a plain bag
    #: first (the run keeps the bag's own path); None: Imu + Temperature as they are.
    driver: object = None

    def __post_init__(self) -> None:
        """Check the reference rate (held as a tuple of floats), log format and instance."""
        if self.reference is not None:
            object.__setattr__(self, 'reference', _reference(self.reference))
        if self.log_format not in LOG_FORMATS:
            raise DatasetError(f'Expected `log_format` to be one of {", ".join(LOG_FORMATS)}, '
                               f'got {self.log_format!r}.')
        if (isinstance(self.imu_instance, bool) or not isinstance(self.imu_instance, int)
                or self.imu_instance < 0):
            raise DatasetError('Expected `imu_instance` to be an integer >= 0, got '
                               f'{self.imu_instance!r}.')
        check_sessions(self.sessions, self.session_gap_s)
        src = self.temperature_source
        if not (isinstance(src, str) and (src in TEMPERATURE_SOURCES
                                          or re.fullmatch(r'\w+\.\w+', src))):
            raise DatasetError('Expected `temperature_source` to be imu, baro or TOPIC.FIELD '
                               f'(e.g. sensor_baro.temperature, BARO.Temp), got {src!r}.')


def check_sessions(mode: str, gap: float) -> None:
    """Raise DatasetError unless ``mode`` is one of SESSION_MODES and ``gap`` a number >= 0."""
    if mode not in SESSION_MODES:
        raise DatasetError(f'Expected `sessions` to be one of {", ".join(SESSION_MODES)}, '
                           f'got {mode!r}.')
    if (isinstance(gap, bool) or not isinstance(gap, (int, float))
            or not (math.isfinite(gap) and gap >= 0)):
        raise DatasetError(f'Expected `session_gap_s` to be a number >= 0, got {gap!r}.')


def _reference(value: object) -> tuple[float, float, float]:
    """Return a constant reference rate (x, y, z) in rad/s or raise DatasetError."""
    try:
        ref = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        ref = np.zeros(0)
    if ref.shape != (3,) or not np.all(np.isfinite(ref)):
        raise DatasetError('Expected `reference` to be three finite rates (x, y, z) in rad/s, '
                           f'got {value!r}.')
    return tuple(ref.tolist())
