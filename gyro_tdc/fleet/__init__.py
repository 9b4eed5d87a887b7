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

A manifest is a CSV file with the header ``sensor_id,train,test``; ``train`` and ``test`` hold
one or more bag paths separated by ``;`` (``test`` may be empty), relative to the manifest::

    sensor_id,train,test
    imu-0001,bags/imu-0001/run1,bags/imu-0001/run2
    imu-0002,bags/imu-0002/run1;bags/imu-0002/run3,bags/imu-0002/run2

Every sensor is one Dask task (:func:`run_sensor`): it trains a model with the options of
``train``, evaluates it on the sensor's test bags and returns the model; the client writes
``DIR/<sensor_id>.yaml`` with ``sensor.sensor_id`` set as each task finishes. A sensor that
fails (corrupt bag, missing topic, too small a span) fails alone with a one-line reason.

Fleet statistics: the static drift curve of each model (at thermal equilibrium) is fitted
with a quadratic in temperature; its slope at the fleet's reference temperature (the median
middle of the trained ranges) and its curvature, per axis, are compared with the fleet by a
robust z-score ``(v - median) / (1.4826 MAD)``; beyond ``outlier_z`` a flag such as
``drift slope on x 6.0σ from the fleet`` is raised (an end-of-line screening test; at least
:data:`MIN_FLEET` sensors).

Resuming: a sensor whose model file exists and is unchanged, and whose input key (bag file
sizes and modification times, the training options, the gyro_tdc version) is unchanged, is
skipped. The key is computed by the worker, where the bags are read; a bag's *content* is not
hashed (an hour at 1 kHz is 1.4 GB of sqlite3), so a bag rewritten with the same size and
mtime is not noticed (use ``force``). This package never imports rclpy: workers never start
ROS.
"""

from gyro_tdc.fleet.manifest import check_sensor_id, input_key, read_manifest, SensorSpec
from gyro_tdc.fleet.results import FleetResult, SensorResult
from gyro_tdc.fleet.run import Engine, open_engine, run_fleet, run_sensor, SensorOutcome
from gyro_tdc.fleet.stats import (DEFAULT_OUTLIER_Z, drift_polynomial, fleet_statistics, MIN_FLEET,
                                  robust_z)
from gyro_tdc.fleet.summary import format_table, summary_dict, write_summary

__all__ = [
    'DEFAULT_OUTLIER_Z', 'Engine', 'FleetResult', 'MIN_FLEET', 'SensorOutcome', 'SensorResult',
    'SensorSpec', 'check_sensor_id', 'drift_polynomial', 'fleet_statistics', 'format_table',
    'input_key', 'open_engine', 'read_manifest', 'robust_z', 'run_fleet', 'run_sensor',
    'summary_dict', 'write_summary',
]
