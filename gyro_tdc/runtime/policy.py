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
The compensator's parameter table and the :class:`Policy` it builds (pure, no rclpy).

:data:`PARAMS` is the one table of ``compensator_node``'s parameters; its ``policy`` rows are
the fields of :class:`Policy` (doc/internals/runtime.md), settable at run time (the node
swaps a new Policy in between two messages); a read-only row says why a change needs a
restart.
"""

from __future__ import annotations

from gyro_tdc.base import INPUT_FRAMES, ParamSpec, spec_dataclass, TEMPERATURE_QUIRKS
from gyro_tdc.model import DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C, OUT_OF_RANGE_POLICIES
from gyro_tdc.runtime.blockstats import STILL_WINDOW_MAX_S
from gyro_tdc.signal import MOTION_EPS, STILL_WINDOW_S

__all__ = ['MOTION_TYPES', 'PARAMS', 'Policy', 'TEMPERATURE_TYPES', 'UPSTREAM_CORRECTIONS',
           'UPSTREAM_POLICIES']


#: The usual thermometer types (``temperature_type`` takes any installed message type; these
#: three have a default ``temperature_field``).
TEMPERATURE_TYPES = ('sensor_msgs/msg/Temperature', 'std_msgs/msg/Float32', 'std_msgs/msg/Float64')

#: Message types of the compensator's ``motion_topic`` (``motion_type``): geometry_msgs/Twist,
#: geometry_msgs/TwistStamped, nav_msgs/Odometry.
MOTION_TYPES = ('twist', 'twist_stamped', 'odometry')

#: Upstream corrections the compensator can be told about (``upstream_correction``; '' none):
#: thermal ones (px4 TC_G_ENABLE, ardupilot INS_TCALn, other), PX4's EKF gyro bias taken off
#: the MAVLink HIGHRES_IMU rate (px4_ekf), and a gyro bias a driver removes at start
#: (bias_at_start: Xsens, UM7 zero_gyros, Phidgets); and what it does then (``upstream_policy``).
UPSTREAM_CORRECTIONS = ('', 'px4', 'ardupilot', 'other', 'px4_ekf', 'bias_at_start')
UPSTREAM_POLICIES = ('passthrough', 'compensate')


def _policy(*args, **kwargs) -> ParamSpec:
    """Return a ``policy`` row: a field of :class:`Policy`, settable at run time."""
    return ParamSpec(*args, policy=True, read_only=False, **kwargs)


#: The compensator's parameters (the node declares them; ``policy`` rows build :class:`Policy`).
PARAMS = (
    ParamSpec('model_file', '', 'Model YAML file, or the name of a model in config/models; '
              'settable at run time (hot reload). Empty: pass the raw rate through.',
              read_only=False),
    _policy('out_of_range', DEFAULT_OUT_OF_RANGE, 'Outside the model temperature range: continue '
            'the correction along its tangent at the range end for up to max_extrapolation_c, '
            'then hold it (linear); evaluate at the nearest valid temperature (clamp); or '
            'evaluate the model there (extrapolate).', choices=OUT_OF_RANGE_POLICIES),
    _policy('max_extrapolation_c', MAX_EXTRAPOLATION_C, 'How far beyond the model temperature '
            'range the linear policy follows the tangent before it holds [degC].', 0.0, 1000.0),
    _policy('temperature_timeout', 5.0, 'Temperature older than this (IMU stamp minus thermometer '
            'stamp) is stale [s].', 0.001, 86400.0),
    _policy('stale_policy', 'hold', 'With a stale temperature: keep compensating with the last '
            'value (hold) or pass the raw rate through (passthrough).',
            choices=('hold', 'passthrough')),
    _policy('stale_variance', 1.0e-6, 'Added to the angular_velocity_covariance diagonal while '
            'compensating with a stale temperature [(rad/s)^2].', 0.0, 1.0e3),
    _policy('out_of_range_variance', 1.0e-6, 'Added to the covariance diagonal outside the '
            "model's temperature range; with linear, times 1 + (d / 5 degC)^2 at a distance d "
            'from the range [(rad/s)^2].', 0.0, 1.0e3),
    _policy('passthrough_variance', 1.0e-4, 'Added to the covariance diagonal when the raw rate '
            'is passed through uncompensated [(rad/s)^2].', 0.0, 1.0e3),
    _policy('base_variance', 0.0, 'Base variance for an input whose angular_velocity_covariance '
            'is all zero (REP 145: unknown). 0: unknown stays unknown (all zero out, no '
            "compensation mark); > 0: the output diagonal is this plus the model's variance, "
            'marked. A -1 in element 0 (no data) stays as it came [(rad/s)^2].', 0.0, 1.0e3),
    _policy('reanchor_on_start', True, 'Shift the model offset so the compensated rate averages '
            'zero once the IMU is still and the mean is known to reanchor_tolerance (meanwhile by '
            'the mean so far on the axes where it is beyond 3 standard errors): the turn-on '
            'offset of this power cycle, which no model trained on other power cycles knows; with '
            'the default still_window, still_window_max and reanchor_tolerance, on an axis only '
            "beyond the gate its training found (the model's reanchor min_shift_dps; none: any "
            'shift). false: keep the model offset (the mean of its training sessions).'),
    _policy('reanchor_tolerance', 0.0, 'Largest standard error of the re-anchoring shift per '
            "axis; 0: auto, 0.1 x the model's residual standard deviation, at least 1e-5 rad/s "
            '[rad/s].', 0.0, 10.0),
    _policy('still_window', STILL_WINDOW_S, 'Stillness window: the shortest averaging for '
            're-anchoring [s].', 0.1, 3600.0),
    _policy('still_window_max', STILL_WINDOW_MAX_S, 'Longest averaging for re-anchoring (the '
            'shift is taken then even when its standard error is above the tolerance) [s].', 0.1,
            86400.0),
    _policy('still_gyro_std', 0.0, 'Largest per-axis standard deviation of the raw rate over a '
            'still window; 0: auto, 4 x the quietest window so far [rad/s].', 0.0, 10.0),
    _policy('still_max_rate', 0.02, 'Largest per-axis mean compensated rate over a still window, '
            'i.e. the largest shift allowed [rad/s].', 0.0, 10.0),
    _policy('still_accel_std', 0.0, 'Largest per-axis standard deviation of the acceleration over '
            'a still window, when the IMU has one; 0: auto, 4 x the quietest window so far '
            '[m/s^2].', 0.0, 100.0),
    ParamSpec('queue_depth', 2000, 'Depth of the imu/data_raw, imu/temperature and motion_topic '
              'subscriptions and of the imu/data_compensated publisher: the default of their '
              'qos_overrides.<topic>.<subscription|publisher>.depth parameters, which set one '
              "entity alone. Read at start: a subscription's QoS is fixed when it is created "
              '[messages].', 1, 1000000),
    ParamSpec('input_reliability', 'best_effort', 'QoS of the imu/data_raw subscription: '
              'best_effort (REP 2003 sensor data, keep last queue_depth: the freshest samples '
              'when behind; DDS does not report what this queue overwrites) or reliable (keep '
              "all: a keep-last publisher's drops are reported, and a reliable keep-all "
              'publisher is held back by flow control instead of losing messages). The default '
              'of qos_overrides.<imu topic>.subscription.reliability and .history, which '
              "override it. Read at start: a subscription's QoS is fixed when it is created.",
              choices=('best_effort', 'reliable')),
    ParamSpec('load_wait', 0.1, 'Longest time a model_file set or ~/reload waits for the new '
              'file to be read and checked before answering: the IMU path pauses at most this '
              'long; a slower file is installed when ready, its outcome on /diagnostics and in '
              'the log [s].', 0.0, 10.0, read_only=False),
    ParamSpec('raw_cdr', True, 'Take imu/data_raw as serialized CDR and patch the bytes instead '
              'of deserialising each message (same output, a fraction of the cost; other '
              'encodings fall back to deserialising). Read at start: the subscription is created '
              'raw or typed.'),
    ParamSpec('executor', 'events', 'Executor main() spins the node with: rclpy.experimental '
              'EventsExecutor (events, fastest) or SingleThreadedExecutor (single). Read at '
              'start: main() builds the executor before spinning.', choices=('events', 'single')),
    ParamSpec('temperature_type', TEMPERATURE_TYPES[0], 'Message type of imu/temperature: any '
              'installed pkg/msg/Type, e.g. sensor_msgs/msg/Temperature (stamped), '
              "std_msgs/msg/Float32 or Float64, or a driver's own type with temperature_field. "
              "Read at start: a subscription's type is fixed when it is created."),
    ParamSpec('temperature_field', '', 'Dotted path to the temperature (a number, degC) in a '
              'temperature_type message, e.g. mean_temp (MicroStrain). Empty: temperature for '
              'sensor_msgs/msg/Temperature, data for std_msgs Float32/Float64. Read at start.'),
    ParamSpec('temperature_stamp_field', '', 'Dotted path to the stamp of a temperature_type '
              "message: a builtin_interfaces/Time (e.g. header.header.stamp, MicroStrain's "
              'nested header) or an integer in microseconds. Empty: header.stamp where the type '
              'has a header, else each reading takes the stamp of the latest IMU message '
              'received (readings before the first IMU message are ignored). Read at start.'),
    ParamSpec('temperature_quirk', '', "Undo a driver's temperature encoding: "
              'bno055_unsigned_byte (flynneva/bno055 reads the register unsigned: below 0 degC '
              "it publishes 256 + T) or sbg_legacy_div256 (sbg_ros2_driver's legacy IMU log "
              'publishes T / 256). Empty: none. Read at start.', choices=TEMPERATURE_QUIRKS),
    ParamSpec('imu_type', 'sensor_msgs/msg/Imu', 'Message type of imu/data_raw: '
              'sensor_msgs/msg/Imu (compensated in place, the fast path), or any installed '
              'pkg/msg/Type holding an x/y/z rate in rad/s, e.g. '
              'geometry_msgs/msg/Vector3Stamped (Xsens /imu/angular_velocity) or '
              'px4_msgs/msg/SensorGyro; the output is a sensor_msgs/Imu either way. Read at '
              'start.'),
    ParamSpec('angular_velocity_field', 'angular_velocity', 'Dotted path to the x/y/z rate '
              '(rad/s) in an imu_type message, e.g. vector for geometry_msgs/msg/Vector3Stamped; '
              "empty: the message itself (px4_msgs SensorGyro's x, y, z). Read at start."),
    ParamSpec('stamp_field', 'header.stamp', 'Dotted path to the stamp of an imu_type message: a '
              "builtin_interfaces/Time, or an integer in microseconds (px4_msgs' timestamp). "
              'Read at start.'),
    ParamSpec('input_frame', INPUT_FRAMES[0], 'Axes of the imu_type rate: flu (REP 103) or frd '
              '(PX4: forward, right, down), turned to FLU (y and z negated). A '
              'sensor_msgs/msg/Imu input is FLU (REP 145). Read at start.', choices=INPUT_FRAMES),
    ParamSpec('frame_id', 'imu_link', 'header.frame_id of the output when the imu_type has no '
              'header (px4_msgs SensorGyro); an input header is copied unchanged. Read at start.'),
    ParamSpec('sensor_id', '', "This IMU's id: when set and the model's sensor.sensor_id "
              'differs, the node warns in the log and on /diagnostics (WARN) for as long as that '
              'model is in use (a model trained on another sensor, or the shipped simulated '
              'one). Empty: no check.', read_only=False),
    ParamSpec('expected_rate_hz', 0.0, 'Expected imu/data_raw rate for the liveness check on '
              '/diagnostics (as diagnostic_updater FrequencyStatus, 10 % tolerance: WARN when '
              'slower or faster, ERROR when none came over its window); 0: learnt from the '
              'arrivals of the first 5 s, then only slowing is judged. Read at start: the check '
              'is built then [Hz].', 0.0, 1.0e6),
    _policy('upstream_correction', '', 'A correction known to be active upstream of imu/data_raw: '
            'px4 (TC_G_ENABLE=1), ardupilot (INS_TCALn_ENABLE=1), other (a factory thermal '
            'calibration), px4_ekf (the EKF gyro bias estimate taken off MAVLink HIGHRES_IMU, '
            'even with TC_G_ENABLE=0) or bias_at_start (the driver removes a gyro bias at start: '
            'Xsens, UM7 zero_gyros, Phidgets; with upstream_policy compensate, re-anchoring takes '
            'it out). Set: the node warns in the log and on /diagnostics (WARN) and, with '
            'upstream_policy passthrough, passes the rate through instead of correcting it twice. '
            'Empty: none known.', choices=UPSTREAM_CORRECTIONS),
    _policy('upstream_policy', 'passthrough', 'With upstream_correction set: pass the raw rate '
            'through, flagged and without the compensation mark (passthrough), or compensate '
            'anyway, for a model trained on the already corrected rate (compensate; no WARN).',
            choices=UPSTREAM_POLICIES),
    ParamSpec('learn', False, 'Learn the bias vs temperature from still time while compensating '
              '(gyro_tdc.learn.learner): still-stretch means in 1 degC bins, refit off the '
              'message path, swapped in when it predicts the recent still time better; '
              'model_file is the prior, none: starts from the first still stretch. Read at '
              'start: the learner, its services and timer are made at start.'),
    ParamSpec('learn_file', '', 'Learned model and point table (JSON), written atomically every '
              'learn_save_period of message-stamp time, on ~/learn_save and at shutdown, and '
              'resumed from at start. Empty: nothing is kept across restarts. Read at start: the '
              'file is opened and resumed from then.'),
    ParamSpec('learn_save_period', 180.0, 'Message-stamp time between saves of learn_file; read '
              "at start, into the learner's settings [s].", 1.0, 86400.0),
    ParamSpec('learn_swap_delay', 5.0, 'A learned model takes effect at the first message '
              'stamped this long after the sample that let it be computed, so the output does '
              'not depend on when the learner ran (the 0.1 s learn timer: a replay up to about '
              'learn_swap_delay / 0.1 s times faster than real time gives the same output; '
              'beyond, it is installed at the next message and counted as a late swap on '
              "/diagnostics); read at start, into the learner's settings [s].", 0.0, 86400.0),
    ParamSpec('motion_topic', '', 'Outside motion reports (e.g. cmd_vel or odom; QoS as '
              'input_reliability): from a report that says motion until the next report, samples '
              'are not still, for re-anchoring and the learner alike (a slow turn at a constant '
              'rate looks still to the gyro). Before the first report nothing is vetoed. Empty: '
              'no motion input. Read at start: the subscription is made then.'),
    ParamSpec('motion_type', MOTION_TYPES[0], 'Message type of motion_topic: twist '
              '(geometry_msgs/Twist such as cmd_vel; no stamp: each report takes the stamp of '
              'the latest IMU message received), twist_stamped (geometry_msgs/TwistStamped) or '
              'odometry (nav_msgs/Odometry, its twist); a zero header stamp counts as none. Read '
              "at start: a subscription's type is fixed when it is created.",
              choices=MOTION_TYPES),
    _policy('motion_threshold', MOTION_EPS, 'A motion report whose linear or angular velocity has '
            'a component above this in magnitude (or a NaN) reports motion [m/s, rad/s].', 0.0,
            1000.0),
)

#: One field per ``policy`` row of :data:`PARAMS` (same name, default and meaning), checked on
#: construction (a choice, or a finite number of the sign the row's range gives).
Policy = spec_dataclass(
    'Policy', [s for s in PARAMS if s.policy], 'What the compensator does when it cannot '
    'simply compensate (the ``policy`` rows of ``PARAMS``).', module=__name__, check=True)
