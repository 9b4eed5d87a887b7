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
The accelerometer part of a model: its offset's change with temperature, as PX4 and ArduPilot.

A MEMS accelerometer's offset moves with the die temperature (1-5 mg per 10 degC on
consumer parts). The accelerometer part of a model (:attr:`gyro_tdc.model.
CompensationModel.accel`, model file section ``accel:``) holds that change per axis, in
m/s^2: the same effect library and the same thermal state as the gyro part (the
accelerometer sits on the same die), the same network form (``rbf`` or ``poly``), and
nothing else. It removes only the *change* relative to T0: the intercept is set so the
correction is zero at the reference point (the model temperature at T0, every dynamic term
settled), so the compensated specific force at T0 equals the raw one; the static offset and
the gravity direction belong to the ordinary accelerometer calibration.

**Static data only.** Gravity dominates the accelerometer, so its offset can be learnt only
while the IMU is still with a fixed orientation. :func:`static_data` keeps the still windows
of the one still test (:func:`gyro_tdc.still.detect_still`): the raw rate's and the
acceleration's per-axis scatter within the noise, a zero reference rate (a turning rate table
is not static) and, when a gyro model is given, its mean compensated rate at most
``max_rate`` (:func:`fit_accel` gives none: a poor gyro model would reject still data). In
a thermal chamber the whole run is still.

**Orientation.** The orientation must stay fixed: between consecutive still windows the
mean specific force is compared with the local trend; a jump beyond :data:`JUMP_SIGMAS`
times its noise and :data:`MIN_JUMP_DEG` in direction is an orientation change. It is
reported (time, angle) and the run is split there: every orientation (and every still
stretch after more than :data:`MAX_GAP_WINDOWS` windows of motion) gets its own offset, so
a change is never fitted as drift (:func:`gyro_tdc.fitting.fit_linear` with ``groups``).

**Figures.** The accelerometer bias stability (BS) is the variance around the run mean
(around each orientation's mean when there are several), in (m/s^2)^2, raw and compensated
(:func:`static_bs`); ``evaluate`` reports it for static runs (:func:`accel_scores`) beside
the gyro's BS, with a PX4-style cubic in the measured temperature as the baseline
(:data:`PX4_FEATURES`).

**Streaming.** The part is a :class:`~gyro_tdc.model.CompensationModel` in m/s^2, so
:func:`gyro_tdc.model.compensate` (batch) and :attr:`gyro_tdc.model.StreamingCompensator.
accel` (one sample at a time, equal to the batch form) apply it; its ``residual_var`` is in
(m/s^2)^2. :func:`compensate_accel` is the batch form from the whole model.
"""


from gyro_tdc.accel.part import (ACCEL_EFFECTS, accel_features, accel_scores, AccelFit,
                                 compensate_accel, discovery_runs, fit_accel, G0, MG,
                                 MIN_STATIC_FRACTION, PX4_FEATURES)
from gyro_tdc.accel.static import (has_accelerometer, JUMP_SIGMAS, MAX_GAP_WINDOWS, MAX_RATE,
                                   MIN_JUMP_DEG, MIN_SEGMENT_S, MIN_WINDOW_SAMPLES,
                                   OrientationChange, static_bs, static_data, StaticData)

__all__ = ['ACCEL_EFFECTS', 'AccelFit', 'G0', 'JUMP_SIGMAS', 'MAX_GAP_WINDOWS', 'MAX_RATE', 'MG',
           'MIN_JUMP_DEG', 'MIN_SEGMENT_S', 'MIN_STATIC_FRACTION', 'MIN_WINDOW_SAMPLES',
           'OrientationChange', 'PX4_FEATURES', 'StaticData', 'accel_features', 'accel_scores',
           'compensate_accel', 'discovery_runs', 'fit_accel', 'has_accelerometer',
           'static_bs', 'static_data']
