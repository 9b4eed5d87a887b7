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

"""The drivers' own message definitions (from their .msg files) in a rosbags typestore."""

from rosbags.typesys import get_types_from_msg, get_typestore, Stores

#: Types not installable here (no wheel), as the drivers define them: px4_msgs' SensorGyro
#: and MicroStrain's temperature statistics with their nested MIP header (cited in the
#: recipes of launch/recipes/).
DRIVER_MSGS = {
    'px4_msgs/msg/SensorGyro': """
uint64 timestamp
uint64 timestamp_sample
uint32 device_id
float32 x
float32 y
float32 z
float32 temperature
uint32 error_count
uint8[3] clip_counter
uint8 samples
uint8 ORB_QUEUE_LENGTH = 8
""",
    'microstrain_inertial_msgs/msg/MipHeader': """
std_msgs/Header header
uint8 event_source
uint64 reference_timestamp
""",
    'microstrain_inertial_msgs/msg/MipSensorTemperatureStatistics': """
microstrain_inertial_msgs/MipHeader header
float32 min_temp
float32 max_temp
float32 mean_temp
""",
}


def driver_typestore():
    """Return a Jazzy typestore with :data:`DRIVER_MSGS` registered."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in DRIVER_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store
