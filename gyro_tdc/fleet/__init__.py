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
Fleet calibration on Dask: one model per sensor of a manifest, fleet statistics, a summary.

Every sensor of a manifest is one Dask task (:func:`run_sensor`) that trains and evaluates
its model; :func:`fleet_statistics` flags sensors whose drift curve departs from the fleet's;
an unchanged sensor is skipped when resuming. Never imports rclpy.
The manifest, the statistics and resuming: ``doc/internals/fleet.md``.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'manifest': ['check_sensor_id', 'input_key', 'read_manifest', 'SensorSpec'],
    'results': ['FleetResult', 'format_table', 'SensorResult', 'summary_dict', 'write_summary'],
    'run': ['Engine', 'open_engine', 'run_fleet', 'run_sensor', 'SensorOutcome',
            'sigterm_as_interrupt'],
    'stats': ['DEFAULT_OUTLIER_Z', 'drift_polynomial', 'fleet_statistics', 'MIN_FLEET',
              'robust_z'],
})
