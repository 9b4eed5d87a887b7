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

"""Hand-made Imu, Temperature and Vector3Stamped messages and small bags of them."""

from __future__ import annotations

from gyro_tdc.data import IMU_TYPE, REFERENCE_TYPE, TEMPERATURE_TYPE, write_bag
from gyro_tdc.data.bag import codec
import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

TS = get_typestore(Stores.ROS2_JAZZY)
STORAGES = ('sqlite3', 'mcap')
PLUGINS = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
# Frame ids of every length mod 8 (the float64 block is aligned to 8 after the string).
FRAME_IDS = ('', 'a', 'ab', 'abc', 'imu', 'imu_', 'imu_l', 'imu_li', 'imu_lin', 'imu_link',
             'imu_link0', 'base_link/imu_12', 'caf\u00e9')


def _header(sec, nsec, frame_id):
    return TS.types['std_msgs/msg/Header'](TS.types['builtin_interfaces/msg/Time'](sec, nsec),
                                           frame_id)


def _imu(rng, sec=1, nsec=2, frame_id='imu_link', gyro=None):
    vec = TS.types['geometry_msgs/msg/Vector3']
    g = rng.normal(size=3) if gyro is None else gyro
    quat = TS.types['geometry_msgs/msg/Quaternion']
    return TS.types[IMU_TYPE](
        _header(sec, nsec, frame_id), quat(*rng.normal(size=4)),
        rng.normal(size=9), vec(*g), rng.normal(size=9), vec(*rng.normal(size=3)),
        rng.normal(size=9))


def _temperature(rng, sec=1, nsec=2, frame_id='imu_link', value=None):
    return TS.types[TEMPERATURE_TYPE](_header(sec, nsec, frame_id),
                                      rng.normal() if value is None else value, rng.random())


def _vector3(rng, sec=1, nsec=2, frame_id='imu_link'):
    return TS.types[REFERENCE_TYPE](_header(sec, nsec, frame_id),
                                    TS.types['geometry_msgs/msg/Vector3'](*rng.normal(size=3)))


MAKERS = {IMU_TYPE: _imu, TEMPERATURE_TYPE: _temperature, REFERENCE_TYPE: _vector3}


def _fields(msgtype, msg):
    """Flatten every field of a message for comparisons."""
    return codec.from_msg(msgtype, msg)


def _write_raw(path, storage, topics):
    """Write {topic: (msgtype, [(log_ns, bytes), ...])} with rosbags' writer, time ordered."""
    with Writer(path, version=9, storage_plugin=PLUGINS[storage]) as writer:
        conns = {name: writer.add_connection(name, msgtype, typestore=TS)
                 for name, (msgtype, _) in topics.items()}
        items = sorted((ns, name, raw) for name, (_, msgs) in topics.items()
                       for ns, raw in msgs)
        for ns, name, raw in items:
            writer.write(conns[name], ns, raw)


def _small_bag(path, storage, *, n=300, frame_id='imu_link', seed=1, **kw):
    rng = np.random.default_rng(seed)
    data = dict(imu_t=100.0 + np.arange(n) * 0.01, gyro=rng.normal(size=(n, 3)),
                accel=rng.normal(size=(n, 3)), temp_t=100.0 + np.arange(n // 100 + 1) * 1.0,
                temp_c=20.0 + rng.normal(size=n // 100 + 1))
    data.update(kw)
    write_bag(path, storage=storage, frame_id=frame_id, **data)
    return data
