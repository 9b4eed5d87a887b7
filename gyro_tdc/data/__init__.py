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
Data in.

Rosbag2 bags and flight-controller logs (PX4 ULog, ArduPilot DataFlash; how to read them one
:class:`BagOptions`), the serialized Imu and its compensation mark, thermal runs as arrays,
their coverage, and real-data converters. See ``doc/internals/data.md``.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'bag.codec': ['IMU_TYPE', 'REFERENCE_TYPE', 'TEMPERATURE_TYPE'],
    'bag.motion': ['encode_twists', 'read_motion', 'TWIST_TYPE'],
    'bag.reader': ['read_bag'],
    'bag.writer': ['write_bag'],
    'coverage': ['Coverage', 'coverage', 'RATE_THRESHOLD_C_PER_MIN', 'temperature_rate'],
    'dataflash': ['read_dataflash'],
    'dataset': ['expand_bags', 'find_bags', 'iter_runs', 'load_runs'],
    'driver_bags': ['DriverInputs', 'normalize_bag'],
    'field_paths': ['check_number', 'check_vector', 'frd_to_flu', 'normalize_type',
                    'rate_fields', 'reader', 'stamp_kind', 'stamp_seconds', 'temperature_fields',
                    'temperature_path', 'unquirk'],
    'flightlog': ['detect_format', 'FlightLog', 'imu_of', 'is_flight_log'],
    'imu_cdr': ['ImuView', 'locate'],
    'mark': ['diagonal_marked'],
    'options': ['BagOptions', 'DEFAULT_IMU_TOPIC', 'DEFAULT_REFERENCE_TOPIC',
                'DEFAULT_TEMPERATURE_TOPIC', 'LOG_FORMATS', 'MAX_LOSS_FRACTION',
                'TEMPERATURE_SOURCES'],
    'sessions': ['find_breaks', 'GAP_PERIODS', 'Session', 'session_gap', 'SESSION_GAP_S',
                 'SESSION_MODES', 'SessionSplit', 'split_sessions'],
    'realdata': ['default_pan_csv', 'PanCubesat', 'read_pan_cubesat_csv'],
    'runs': ['Run'],
    'ulog': ['read_ulog'],
})
