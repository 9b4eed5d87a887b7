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
Still detection: the one test of whether an IMU is still, batch and streaming.

Pure (numpy only). Every part of the package that needs still data calls this module: the
trainer (``train --still-only``, :mod:`gyro_tdc.field_training`), the accelerometer part's
still windows (:func:`gyro_tdc.accel.static_data`) and the compensator's re-anchoring
(:class:`gyro_tdc.stillness.StillnessDetector`: it keeps its own window sums, for the
re-anchoring's block-means standard error, and asks :func:`noise_thresholds` and
:func:`judge_windows` for the verdict). :func:`detect_still` is the batch form;
:class:`StreamingStill` the streaming one, one sample at a time, returning each still
stretch (:class:`StillSegment`: its mean rate and temperature) as it ends, equal to the
batch form on the same samples once the noise floor is known.

**The test.** Samples are cut into windows of ``window_s`` (at least
:data:`MIN_WINDOW_SAMPLES` sample periods). A window is still when

* its raw rate's per-axis standard deviation is at most the gyro threshold, and, when the
  IMU has an accelerometer (:func:`has_accelerometer`), its acceleration's per-axis standard
  deviation is at most the accelerometer threshold: the scatter stays within what the
  sensor's own noise explains. *Auto* thresholds (the default) are :data:`NOISE_FACTOR`
  times the noise floor, the smallest window standard deviation per axis over the windows
  that may be still (the batch form: the whole run; the streaming form: so far), so the
  test scales with the sensor and the sample rate without tuning; a positive ``gyro_std``
  or ``accel_std`` is a fixed override;
* no sample of it is vetoed by a motion report (``moving``: a ``cmd_vel`` Twist or an
  Odometry stream held onto the IMU stamps by :func:`motion_veto`, or a non-zero rate-table
  reference): still only while the vehicle reports zero motion;
* with a prior (``rate``: the rate compensated by a model, minus any reference), its mean
  is at most ``max_rate`` per axis;
* and it belongs to a stretch of consecutive still windows lasting ``min_still_s`` or
  more.

**What rejects a slow constant turn.** A turn at a constant 0.5-5 deg/s has no more
scatter than rest. Without a motion topic it is rejected only by (1) the mean-rate test
when a prior is known and the turn exceeds ``max_rate`` (the compensator always has its
model), (2) the accelerometer, when the rotation has a horizontal component: gravity then
turns in the sensor frame (0.5 deg/s turns it 5 degrees in a 10 s window, hundreds of times
the accelerometer's noise), (3) the vibration that comes with driving, and (4) in the
trainer, after the fit: a still stretch whose mean rate departs from the bias-vs-temperature
curve of the others is dropped as an outlier (:mod:`gyro_tdc.field_training`). A perfectly
smooth constant turn about the vertical, with no accelerometer change, no vibration, no
prior and no motion topic, cannot be told from a bias: the ``motion`` veto exists for that.

**Where.** :mod:`gyro_tdc.still.verdict` holds the test proper (constants, noise floor,
thresholds, :func:`judge_windows`, :func:`motion_veto`), :mod:`gyro_tdc.still.batch` the
batch form (:func:`detect_still`, :class:`Stillness`), :mod:`gyro_tdc.still.stream` the
streaming one (:class:`StreamingStill`, :class:`StillSegment`); every public name is
imported from here.
"""

from gyro_tdc.still.batch import detect_still, Stillness
from gyro_tdc.still.stream import StillSegment, StreamingStill
from gyro_tdc.still.verdict import (has_accelerometer, judge_windows, MAX_RATE, MIN_STILL_S,
                                    MIN_WINDOW_SAMPLES, MOTION_EPS, motion_veto, NOISE_FACTOR,
                                    noise_floor, noise_thresholds, NOISE_WINDOWS, REASONS,
                                    STILL_WINDOW_S)

__all__ = ['MAX_RATE', 'MIN_STILL_S', 'MIN_WINDOW_SAMPLES', 'MOTION_EPS', 'NOISE_FACTOR',
           'NOISE_WINDOWS', 'REASONS', 'STILL_WINDOW_S', 'StillSegment', 'Stillness',
           'StreamingStill', 'detect_still', 'has_accelerometer', 'judge_windows',
           'motion_veto', 'noise_floor', 'noise_thresholds']
