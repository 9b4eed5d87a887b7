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
The compensator's decisions, free of rclpy: what to do with each gyro sample.

:class:`CompensatorCore` holds the model, the thermometer's recent samples and the
policies, and turns one raw sample into one output sample, the variance to add to
its covariance and flags (:mod:`gyro_tdc.health`) saying what happened.
``gyro_tdc.nodes.compensator_node`` only converts messages to floats and back, so every rule
here is tested without ROS (the stillness test is :mod:`gyro_tdc.stillness`, the judgement
shown on /diagnostics :mod:`gyro_tdc.health`):

* the temperature used for a sample stamped ``t`` is the latest thermometer sample
  stamped at or before ``t`` (zero-order hold by stamp, so the interleaving of the two
  topics in the executor does not matter);
* older than ``temperature_timeout`` it is stale: ``hold`` keeps compensating with it and
  widens the covariance, ``passthrough`` sends the raw rate;
* before the first temperature, without a model, or with a NaN/Inf in the sample, the raw
  rate passes through unchanged;
* outside the model's temperature range the model continues along its tangent (``linear``,
  :mod:`gyro_tdc.out_of_range`), clamps or extrapolates, and the covariance is widened (with
  ``linear`` the more, the farther);
* start-up re-anchoring: once the gyro is still, the compensated rate is averaged until its
  mean is known to ``reanchor_tolerance`` (:mod:`gyro_tdc.stillness`), and the model's
  offset is shifted so that it averages zero;
* a model with an accelerometer part (``model.accel``) also corrects the specific force of
  each sample that carries one, with the same temperature, the same policies and the same
  variances (read in (m/s^2)^2) added to the accelerometer residual variance; the result is
  left in :attr:`CompensatorCore.accel_out` and :attr:`CompensatorCore.accel_var`.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import replace
import math
from typing import Iterable, NamedTuple, Sequence

from gyro_tdc.effects import STATIC_EFFECTS
from gyro_tdc.health import (FLAG_NAMES, NO_ACCEL_DATA, NO_MODEL, NO_TEMPERATURE, NON_FINITE,
                             OUT_OF_RANGE, PASSTHROUGH, STALE)
from gyro_tdc.model import CompensationModel, StreamingCompensator
from gyro_tdc.out_of_range import (DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C,
                                   OUT_OF_RANGE_POLICIES, variance_growth)
from gyro_tdc.paramspec import ParamSpec, spec_dataclass
from gyro_tdc.stillness import (Anchor, STILL_WINDOW_MAX_S, STILL_WINDOW_S, StillnessDetector,
                                Vec3)
import numpy as np

__all__ = ['CompensatorCore', 'PARAMS', 'Policy', 'PreparedModel', 'Priming', 'Replay',
           'STATIC_EFFECTS', 'TEMPERATURE_TYPES', 'TemperatureHold', 'prepare',
           'widen_covariance']

# STATIC_EFFECTS (from the effect library): a model made of these has a drift that changes
# only when the temperature does, so the compensator evaluates it once per thermometer sample.


#: Message types the compensator's ``imu/temperature`` input accepts (``temperature_type``).
TEMPERATURE_TYPES = ('sensor_msgs/msg/Temperature', 'std_msgs/msg/Float32',
                     'std_msgs/msg/Float64')

#: The compensator's parameters (the node declares them; ``policy`` rows build :class:`Policy`).
PARAMS = (
    ParamSpec('model_file', '', 'Model YAML file, or the name of a model in config/models; '
              'settable at run time (hot reload). Empty: pass the raw rate through.',
              read_only=False),
    ParamSpec('out_of_range', DEFAULT_OUT_OF_RANGE, 'Outside the model temperature range: '
              'continue the correction along its tangent at the range end for up to '
              'max_extrapolation_c, then hold it (linear); evaluate at the nearest valid '
              'temperature (clamp); or evaluate the model there (extrapolate).',
              choices=OUT_OF_RANGE_POLICIES, policy=True),
    ParamSpec('max_extrapolation_c', MAX_EXTRAPOLATION_C, 'How far beyond the model '
              'temperature range the linear policy follows the tangent before it holds '
              '[degC].', 0.0, 1000.0, policy=True),
    ParamSpec('temperature_timeout', 5.0, 'Temperature older than this (IMU stamp minus '
              'thermometer stamp) is stale [s].', 0.001, 86400.0, policy=True),
    ParamSpec('stale_policy', 'hold', 'With a stale temperature: keep compensating with the '
              'last value (hold) or pass the raw rate through (passthrough).',
              choices=('hold', 'passthrough'), policy=True),
    ParamSpec('stale_variance', 1.0e-6, 'Added to the angular_velocity_covariance diagonal '
              'while compensating with a stale temperature [(rad/s)^2].', 0.0, 1.0e3,
              policy=True),
    ParamSpec('out_of_range_variance', 1.0e-6, 'Added to the covariance diagonal outside the '
              "model's temperature range; with linear, times 1 + (d / 5 degC)^2 at a distance "
              'd from the range [(rad/s)^2].', 0.0, 1.0e3, policy=True),
    ParamSpec('passthrough_variance', 1.0e-4, 'Added to the covariance diagonal when the raw '
              'rate is passed through uncompensated [(rad/s)^2].', 0.0, 1.0e3, policy=True),
    ParamSpec('reanchor_on_start', False, 'Shift the model offset so the compensated rate '
              'averages zero once the IMU is still and the mean is known to '
              'reanchor_tolerance.', policy=True),
    ParamSpec('reanchor_tolerance', 0.0, 'Largest standard error of the re-anchoring shift '
              "per axis; 0: auto, 0.1 x the model's residual standard deviation, at least "
              '1e-5 rad/s [rad/s].', 0.0, 10.0, policy=True),
    ParamSpec('still_window', STILL_WINDOW_S, 'Stillness window: the shortest averaging for '
              're-anchoring [s].', 0.1, 3600.0, policy=True),
    ParamSpec('still_window_max', STILL_WINDOW_MAX_S, 'Longest averaging for re-anchoring '
              '(the shift is taken then even when its standard error is above the '
              'tolerance) [s].', 0.1, 86400.0, policy=True),
    ParamSpec('still_gyro_std', 0.0, 'Largest per-axis standard deviation of the raw rate '
              'over a still window; 0: auto, 4 x the quietest window so far [rad/s].', 0.0,
              10.0, policy=True),
    ParamSpec('still_max_rate', 0.02, 'Largest per-axis mean compensated rate over a still '
              'window, i.e. the largest shift allowed [rad/s].', 0.0, 10.0, policy=True),
    ParamSpec('still_accel_std', 0.0, 'Largest per-axis standard deviation of the '
              'acceleration over a still window, when the IMU has one; 0: auto, 4 x the '
              'quietest window so far [m/s^2].', 0.0, 100.0, policy=True),
    ParamSpec('queue_depth', 2000, 'Queue depth of the imu/data_raw (best_effort) and '
              'imu/temperature subscriptions and of the publisher (keep last) [messages].', 1,
              1000000),
    ParamSpec('input_reliability', 'best_effort', 'QoS of the imu/data_raw subscription: '
              'best_effort (REP 2003 sensor data, keep last queue_depth: the freshest samples '
              'when behind; DDS does not report what this queue overwrites) or reliable (keep '
              "all: a keep-last publisher's drops are reported, and a reliable keep-all "
              'publisher is held back by flow control instead of losing messages).',
              choices=('best_effort', 'reliable')),
    ParamSpec('load_wait', 0.1, 'Longest time a model_file set or ~/reload waits for the new '
              'file to be read and checked before answering: the IMU path pauses at most this '
              'long; a slower file is installed when ready, its outcome on /diagnostics and in '
              'the log [s].', 0.0, 10.0),
    ParamSpec('raw_cdr', True, 'Take imu/data_raw as serialized CDR and patch the bytes '
              'instead of deserialising each message (same output, a fraction of the cost; '
              'other encodings fall back to deserialising).'),
    ParamSpec('executor', 'events', 'Executor main() spins the node with: rclpy.experimental '
              'EventsExecutor (events, fastest) or SingleThreadedExecutor (single).',
              choices=('events', 'single')),
    ParamSpec('temperature_type', TEMPERATURE_TYPES[0], 'Message type of imu/temperature: '
              'sensor_msgs/msg/Temperature (stamped), or std_msgs/msg/Float32 or Float64 (degC, '
              'no stamp: each reading takes the stamp of the latest IMU message received; '
              'readings before the first IMU message are ignored).', choices=TEMPERATURE_TYPES),
    ParamSpec('sensor_id', '', "This IMU's id: when set and the model's sensor.sensor_id "
              'differs, the node warns in the log and on /diagnostics (WARN) for as long as '
              'that model is in use (a model trained on another sensor, or the shipped '
              'simulated one). Empty: no check.'),
    ParamSpec('learn', False, 'Learn the bias vs temperature from still time while '
              'compensating (gyro_tdc.learning): still-stretch means in 1 degC bins, refit off '
              'the message path, swapped in when it predicts the recent still time better; '
              'model_file is the prior, none: starts from the first still stretch.'),
    ParamSpec('learn_file', '', 'Learned model and point table (JSON), written atomically '
              'every learn_save_period of message-stamp time, on ~/learn_save and at '
              'shutdown, and resumed from at start. Empty: nothing is kept across restarts.'),
    ParamSpec('learn_save_period', 180.0, 'Message-stamp time between saves of learn_file '
              '[s].', 1.0, 86400.0),
)

#: One field per ``policy`` row of :data:`PARAMS` (same name, default and meaning), checked on
#: construction (a choice, or a finite number of the sign the row's range gives).
Policy = spec_dataclass(
    'Policy', [s for s in PARAMS if s.policy], 'What the compensator does when it cannot '
    'simply compensate (the ``policy`` rows of ``PARAMS``).', module=__name__, check=True)


class TemperatureHold:
    """
    Zero-order hold of the thermometer by stamp.

    Parameters
    ----------
    capacity : int
        Thermometer samples kept (enough to cover reordering between the two topics).

    """

    def __init__(self, capacity: int = 256) -> None:
        self._t: list[float] = []
        self._c: list[float] = []
        self._capacity = int(capacity)
        self.received = 0
        self.rejected = 0

    def __len__(self) -> int:
        """Return the number of samples held."""
        return len(self._t)

    def add(self, t: float, temp_c: float) -> bool:
        """
        Add one thermometer sample.

        Parameters
        ----------
        t : float, s
            Stamp.
        temp_c : float, degC
            Reading.

        Returns
        -------
        bool
            False when the sample is NaN/Inf and was rejected.

        """
        self.received += 1
        if not (math.isfinite(t) and math.isfinite(temp_c)):
            self.rejected += 1
            return False
        if not self._t or t > self._t[-1]:
            self._t.append(t)
            self._c.append(temp_c)
        else:
            i = bisect.bisect_right(self._t, t)
            if i and self._t[i - 1] == t:
                self._c[i - 1] = temp_c
            else:
                self._t.insert(i, t)
                self._c.insert(i, temp_c)
        if len(self._t) > self._capacity:
            del self._t[:len(self._t) - self._capacity]
            del self._c[:len(self._c) - self._capacity]
        return True

    def at(self, t: float) -> tuple[float, float] | None:
        """
        Return ``(temp_c, stamp)`` of the latest sample stamped at or before ``t``.

        Returns
        -------
        tuple of float or None
            None when every sample held is later than ``t`` (or none was received).

        """
        ts = self._t
        if ts and ts[-1] <= t:
            return self._c[-1], ts[-1]
        i = bisect.bisect_right(ts, t)
        return (self._c[i - 1], ts[i - 1]) if i else None

    @property
    def latest(self) -> tuple[float, float] | None:
        """Return ``(temp_c, stamp)`` of the newest sample, or None."""
        return (self._c[-1], self._t[-1]) if self._t else None


def widen_covariance(cov: Sequence[float], add: Sequence[float]) -> list[float]:
    """
    Return a 3x3 row-major covariance with ``add`` added to its diagonal.

    Parameters
    ----------
    cov : sequence of 9 float
        Input covariance (REP 145: all zeros means unknown).
    add : sequence of 3 float, (rad/s)^2
        Variance to add per axis.

    Returns
    -------
    list of 9 float
        The widened covariance; an input with ``cov[0] == -1`` (no data) is returned as is.

    """
    out = list(cov)
    if out[0] == -1.0:
        return out
    out[0] += add[0]
    out[4] += add[1]
    out[8] += add[2]
    return out


class Priming(NamedTuple):
    """
    A copy of what a new model's feature filters are replayed over.

    ``first`` is the stamp and temperature of the first compensated sample, ``history`` the
    thermometer samples recorded (at most one per second), ``last_t`` and ``last_temp`` the
    last IMU stamp and the temperature used for it (None before any).
    """

    first: tuple[float, float] | None = None
    history: tuple[tuple[float, float], ...] = ()
    last_t: float | None = None
    last_temp: float | None = None


class Replay(NamedTuple):
    """Where a replay stopped: filters advanced to ``t_prev``, history read up to ``t_seen``."""

    t_prev: float
    temp_prev: float
    t_seen: float


class PreparedModel(NamedTuple):
    """A model ready to install: its streaming compensator primed over a :class:`Priming`."""

    model: CompensationModel
    model_id: str
    comp: StreamingCompensator
    var: dict[int, Vec3]
    scale: np.ndarray
    static: bool
    priming: Priming
    replay: Replay | None


def _advance(comp: StreamingCompensator, t: float, temp: float) -> None:
    """Advance ``comp``'s filters (and its accelerometer part's) to ``t``."""
    comp.drift(t, temp)
    if comp.accel is not None:
        comp.accel.drift(t, temp)


def _replay(comp: StreamingCompensator, history: Iterable[tuple[float, float]], until: float,
            state: Replay) -> Replay:
    """Advance ``comp`` over thermometer samples later than ``state.t_seen`` up to ``until``."""
    t_prev, temp_prev, t_seen = state
    for t_k, temp_k in history:
        if t_k <= t_seen:
            continue
        if t_k > until:
            break
        if t_k > t_prev:
            _advance(comp, t_k, temp_prev)
            t_prev = t_k
        temp_prev = temp_k
        t_seen = t_k
    return Replay(t_prev, temp_prev, t_seen)


def _replay_from_first(comp: StreamingCompensator, first: tuple[float, float],
                       history: Iterable[tuple[float, float]], until: float) -> Replay:
    """Start ``comp`` at the first compensated sample and replay the history up to ``until``."""
    _advance(comp, *first)
    return _replay(comp, history, until, Replay(first[0], first[1], -math.inf))


def prepare(model: CompensationModel, policy: Policy, priming: Priming) -> PreparedModel:
    """
    Make ``model`` ready to install, off the compensating thread.

    Builds its streaming compensator, replays the feature filters over ``priming`` (the
    first compensated sample, then the thermometer samples at most one per second, up to the
    last IMU stamp of the copy), so a model with ``warmup`` or ``lag`` features carries on
    rather than restarting, and works out its variance table and content id. Touches nothing
    shared: safe in a worker thread while the core keeps compensating.
    :meth:`CompensatorCore.install` finishes the replay and swaps it in.

    Parameters
    ----------
    model : CompensationModel
        The model.
    policy : Policy
        The policies (``out_of_range`` and the variances).
    priming : Priming
        From :meth:`CompensatorCore.priming`.

    Returns
    -------
    PreparedModel
        The model, its primed compensator and its tables.

    """
    comp = StreamingCompensator(model, out_of_range=policy.out_of_range,
                                max_extrapolation_c=policy.max_extrapolation_c)
    replay = None
    if priming.first is not None and priming.last_t is not None:
        replay = _replay_from_first(comp, priming.first, priming.history, priming.last_t)
    resid = tuple(float(v) for v in np.asarray(model.residual_var, dtype=np.float64))
    p = policy
    var = {
        0: resid,
        STALE: tuple(v + p.stale_variance for v in resid),
        OUT_OF_RANGE: tuple(v + p.out_of_range_variance for v in resid),
        STALE | OUT_OF_RANGE: tuple(v + p.stale_variance + p.out_of_range_variance
                                    for v in resid),
    }
    return PreparedModel(model, model.model_id, comp, var,
                         np.asarray(model.scale, dtype=np.float64),
                         set(model.features) <= STATIC_EFFECTS, priming, replay)


class CompensatorCore:
    """
    One raw sample in, one output sample out: the compensator without ROS.

    Parameters
    ----------
    policy : Policy
        The policies and thresholds.
    model : CompensationModel, optional
        The model; without one every sample passes through, flagged.

    """

    #: Temperature history kept to prime a reloaded model (one sample per second at most).
    HISTORY_SPACING_S = 1.0
    HISTORY_LENGTH = 7200

    def __init__(self, policy: Policy, model: CompensationModel | None = None) -> None:
        self.policy = policy
        self.temps = TemperatureHold()
        self.counts = {'in': 0, 'out': 0, 'compensated': 0}
        self.flag_counts = {bit: 0 for bit in FLAG_NAMES}
        self.anchor: Anchor | None = None
        self.last_t: float | None = None
        self.last_temp: float | None = None
        self.last_flags = 0
        self.errors = 0
        self.last_error = ''
        self._first: tuple[float, float] | None = None
        self._history: deque[tuple[float, float]] = deque(maxlen=self.HISTORY_LENGTH)
        self._detector = StillnessDetector(policy.still_window, policy.still_gyro_std,
                                           policy.still_max_rate, policy.still_accel_std,
                                           window_max=policy.still_window_max,
                                           tolerance=policy.reanchor_tolerance)
        self.last_distance_c = 0.0
        #: The model has an accelerometer part: :meth:`process` then sets ``accel_out`` (the
        #: corrected specific force, None: leave it as it is) and ``accel_var`` (to add to the
        #: linear_acceleration_covariance diagonal, None: leave it) for every sample.
        self.accel_on = False
        self.accel_out: Vec3 | None = None
        self.accel_var: Vec3 | None = None
        #: Flags of the last sample's accelerometer (``PASSTHROUGH`` with why;
        #: ``NO_ACCEL_DATA``: the sample had none); -1 before any.
        self.accel_flags = -1
        self.accel_counts = {'compensated': 0, 'passed through': 0, 'missing': 0}
        self._acomp: StreamingCompensator | None = None
        self._acache: dict[float, tuple] = {}
        self.model: CompensationModel | None = None
        self.model_id = ''
        self._comp: StreamingCompensator | None = None
        self._learner = None
        self._lt = self._lw = self._la = None
        if model is not None:
            self.set_model(model)

    @property
    def learner(self):
        """Return the attached :class:`gyro_tdc.learning.Learner`, or None."""
        return self._learner

    @learner.setter
    def learner(self, learner) -> None:
        """Attach a learner: it sees every raw sample and thermometer reading (appends)."""
        self._learner = learner
        self._lt = self._lw = self._la = None
        if learner is not None:
            self._lt, self._lw, self._la = (learner.bt.append, learner.bw.append,
                                            learner.ba.extend)
            self._nan3 = (math.nan,) * 3
            self._lperiod = 1.0 / learner.config.max_rate_hz
            self._lnext = -math.inf

    # -- model ------------------------------------------------------------------------

    def priming(self) -> Priming:
        """Return a copy of what a new model's filters are replayed over (see :func:`prepare`)."""
        return Priming(self._first, tuple(self._history), self.last_t, self.last_temp)

    def set_model(self, model: CompensationModel | None) -> None:
        """
        Prepare and install ``model`` in one step (:func:`prepare`, then :meth:`install`).

        Parameters
        ----------
        model : CompensationModel or None
            The new model, or None to pass every sample through.

        """
        if model is None:
            self.model, self._comp = None, None
            self._accel_tables(None, None)
            return
        self.install(prepare(model, self.policy, self.priming()))

    def install(self, prepared: PreparedModel) -> None:
        """
        Swap in a model made ready by :func:`prepare` (call it on the thread that compensates).

        The replay :func:`prepare` did over a :meth:`priming` copy is carried on over the
        thermometer samples recorded since, up to the last IMU stamp, so the result is that of
        a replay done here; only that short tail costs time on this thread. Re-anchoring:
        when the new model has the same ``model_id`` as the current one (a reload of the same
        file), the start-up shift is kept (or the stillness window carries on); any other
        model clears it, and with ``reanchor_on_start`` the next still window measures it
        again.

        Parameters
        ----------
        prepared : PreparedModel
            The model and its primed streaming state.

        """
        model, comp = prepared.model, prepared.comp
        if self._first is not None and self.last_t is not None:
            state = prepared.replay
            if (state is None or prepared.priming.first != self._first
                    or prepared.priming.last_t is None or self.last_t < prepared.priming.last_t):
                # The stream moved in a way the copy did not see: replay it all here.
                comp = StreamingCompensator(model, out_of_range=self.policy.out_of_range,
                                            max_extrapolation_c=self.policy.max_extrapolation_c)
                state = _replay_from_first(comp, self._first, self._history, self.last_t)
            else:
                tail = []
                for entry in reversed(self._history):
                    if entry[0] <= state.t_seen:
                        break
                    tail.append(entry)
                state = _replay(comp, reversed(tail), self.last_t, state)
            if self.last_t > state.t_prev:
                _advance(comp, self.last_t,
                         state.temp_prev if self.last_temp is None else self.last_temp)
        same = self.model is not None and prepared.model_id == self.model_id
        if same and self.anchor is not None:
            comp.shift_offset(np.asarray(self.anchor.delta, dtype=np.float64))
        elif not same:
            self.anchor = None
            self._detector.reset(residual_var=model.residual_var)
        self._var, self._scale, self._static = prepared.var, prepared.scale, prepared.static
        self._cache: dict[float, tuple] = {}
        self._accel_tables(model, comp)
        self.model_id = prepared.model_id
        self.model, self._comp = model, comp

    # -- inputs -----------------------------------------------------------------------

    def add_temperature(self, t: float, temp_c: float) -> bool:
        """
        Record one thermometer sample.

        Returns
        -------
        bool
            False when the sample is NaN/Inf and was rejected.

        """
        if not self.temps.add(t, temp_c):
            return False
        if self.learner is not None:
            self.learner.add_temperature(t, temp_c)
        if not self._history or t >= self._history[-1][0] + self.HISTORY_SPACING_S:
            self._history.append((t, temp_c))
        if self._comp is not None and self._static and temp_c not in self._cache:
            self._refresh(t, temp_c)
        return True

    def process(self, t: float, wx: float, wy: float, wz: float,
                accel: Sequence[float] | None = None
                ) -> tuple[float, float, float, tuple[float, float, float], int]:
        """
        Compensate one sample, or say why not.

        Parameters
        ----------
        t : float, s
            IMU stamp.
        wx, wy, wz : float, rad/s
            Raw angular velocity.
        accel : sequence of 3 float, m/s^2, optional
            Acceleration when the IMU has one: the stillness test's input, and corrected by
            the model's accelerometer part (result in ``accel_out``/``accel_var``).

        Returns
        -------
        wx, wy, wz : float, rad/s
            The output rate (the raw rate when passed through).
        variance : tuple of 3 float, (rad/s)^2
            To add to the covariance diagonal.
        flags : int
            Bit set of ``STALE``, ``OUT_OF_RANGE``, ``NON_FINITE``, ``NO_TEMPERATURE``,
            ``NO_MODEL``, ``PASSTHROUGH``.

        """
        self.counts['in'] += 1
        if self._lt is not None and t >= self._lnext:  # learning, at most max_rate_hz
            self._lnext = t + self._lperiod
            self._lt(t)
            lw = self._lw
            lw(wx)
            lw(wy)
            lw(wz)
            self._la(self._nan3 if accel is None else accel)
        comp = self._comp
        if comp is None:
            return self._pass(t, wx, wy, wz, NO_MODEL)
        if not (math.isfinite(wx) and math.isfinite(wy) and math.isfinite(wz)
                and math.isfinite(t)):
            return self._pass(t, wx, wy, wz, NON_FINITE, accel)
        held = self.temps.at(t)
        if held is None:
            return self._pass(t, wx, wy, wz, NO_TEMPERATURE, accel)
        temp, t_temp = held
        flags = 0
        if t - t_temp > self.policy.temperature_timeout:
            if self.policy.stale_policy == 'passthrough':
                return self._pass(t, wx, wy, wz, STALE, accel)
            flags = STALE
        if self._first is None:
            self._first = (t, temp)
        if self._static:
            # Static features: the drift only changes when the temperature does.
            entry = self._cache.get(temp) or self._refresh(t, temp)
            bx, by, bz, dx, dy, dz, in_range, dist, more = entry
            ox, oy, oz = (wx - bx) / dx, (wy - by) / dy, (wz - bz) / dz
            if not in_range:
                flags |= OUT_OF_RANGE
        else:
            out = comp.step(t, temp, (wx, wy, wz))
            dist = comp.range_distance_c
            more = 0.0
            if not comp.in_range:
                flags |= OUT_OF_RANGE
                more = variance_growth(self.policy.out_of_range_variance, dist,
                                       self.policy.out_of_range)
            ox, oy, oz = out.tolist()
        if self.accel_on:
            self._accel(t, temp, accel, flags & STALE)
        self.last_t, self.last_temp, self.last_flags = t, temp, flags
        self.last_distance_c = dist
        counts = self.counts
        counts['out'] += 1
        counts['compensated'] += 1
        if flags:
            for bit in (STALE, OUT_OF_RANGE):
                if flags & bit:
                    self.flag_counts[bit] += 1
        elif self.policy.reanchor_on_start and self.anchor is None:
            self._still(t, (wx, wy, wz), (ox, oy, oz), accel, temp)
        if more:           # linear: the added variance grows with the distance
            var = self._var[flags]
            return ox, oy, oz, (var[0] + more, var[1] + more, var[2] + more), flags
        return ox, oy, oz, self._var[flags], flags

    def _refresh(self, t: float, temp: float) -> tuple:
        """
        Evaluate the drift of a static model at one temperature and keep it.

        ``StreamingCompensator.step`` computes ``(omega - b) / (1 + dT s)`` elementwise in
        float64; the same operations on the kept ``b`` and ``1 + dT s`` give the same bits.
        The thermometer callback calls this as each reading arrives, so the IMU callback only
        looks the result up.

        Returns
        -------
        tuple
            ``(bx, by, bz, 1 + dT sx, 1 + dT sy, 1 + dT sz, in_range, distance_c,
            variance growth)``.

        """
        comp = self._comp
        b = comp.drift(t, temp).tolist()
        den = (1.0 + comp.dt_c * self._scale).tolist()
        dist = comp.range_distance_c
        entry = (*b, *den, comp.in_range, dist,
                 variance_growth(self.policy.out_of_range_variance, dist,
                                 self.policy.out_of_range) if dist else 0.0)
        if len(self._cache) >= 64:
            self._cache.clear()
            self._acache.clear()
        self._cache[temp] = entry
        if self._astatic:
            self._arefresh(t, temp)
        return entry

    # -- the accelerometer part -------------------------------------------------------

    def _accel_tables(self, model: CompensationModel | None,
                      comp: StreamingCompensator | None) -> None:
        """Set up (or clear) the accelerometer part's variance table and cache."""
        part = None if model is None or comp is None else model.accel
        self._acache = {}
        self.accel_out = self.accel_var = None
        if part is None:
            self._acomp, self.accel_on, self._astatic = None, False, False
            return
        p = self.policy
        resid = tuple(float(v) for v in np.asarray(part.residual_var, dtype=np.float64))
        self._avar = {
            0: resid,
            STALE: tuple(v + p.stale_variance for v in resid),
            OUT_OF_RANGE: tuple(v + p.out_of_range_variance for v in resid),
            STALE | OUT_OF_RANGE: tuple(v + p.stale_variance + p.out_of_range_variance
                                        for v in resid),
        }
        self._acomp = comp.accel
        # Cached per temperature only when the gyro's drift is (both static).
        self._astatic = self._static and set(part.features) <= STATIC_EFFECTS
        self.accel_on = True

    def _arefresh(self, t: float, temp: float) -> tuple:
        """Evaluate a static accelerometer part at one temperature and keep it."""
        acomp = self._acomp
        b = acomp.drift(t, temp).tolist()
        dist = acomp.range_distance_c
        entry = (*b, acomp.in_range,
                 variance_growth(self.policy.out_of_range_variance, dist,
                                 self.policy.out_of_range) if dist else 0.0)
        self._acache[temp] = entry
        return entry

    def _accel(self, t: float, temp: float, accel: Sequence[float] | None, flags: int) -> None:
        """Correct one sample's specific force (``flags``: ``STALE`` or 0)."""
        counts = self.accel_counts
        if accel is None:
            self.accel_out = self.accel_var = None
            self.accel_flags = NO_ACCEL_DATA
            counts['missing'] += 1
            return
        ax, ay, az = accel
        if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)):
            self._accel_pass(accel, NON_FINITE)
            return
        if self._astatic:
            bx, by, bz, in_range, more = (self._acache.get(temp)
                                          or self._arefresh(t, temp))
            self.accel_out = (ax - bx, ay - by, az - bz)
        else:
            acomp = self._acomp        # no scale term: step() is a - b (saves numpy ops)
            bx, by, bz = acomp.drift(t, temp).tolist()
            self.accel_out = (ax - bx, ay - by, az - bz)
            in_range = acomp.in_range
            more = 0.0 if in_range else variance_growth(
                self.policy.out_of_range_variance, acomp.range_distance_c,
                self.policy.out_of_range)
        if not in_range:
            flags |= OUT_OF_RANGE
        var = self._avar[flags]
        self.accel_var = (var[0] + more, var[1] + more, var[2] + more) if more else var
        self.accel_flags = flags
        counts['compensated'] += 1

    def _accel_pass(self, accel: Sequence[float] | None, why: int) -> None:
        """Leave one sample's specific force as it is, widened by ``passthrough_variance``."""
        if accel is None:
            self.accel_out = self.accel_var = None
            self.accel_flags = NO_ACCEL_DATA
            self.accel_counts['missing'] += 1
            return
        var = self.policy.passthrough_variance
        self.accel_out, self.accel_var = None, (var, var, var)
        self.accel_flags = why | PASSTHROUGH
        self.accel_counts['passed through'] += 1

    def _pass(self, t: float, wx: float, wy: float, wz: float, why: int,
              accel: Sequence[float] | None = None
              ) -> tuple[float, float, float, tuple[float, float, float], int]:
        flags = why | PASSTHROUGH
        if self.accel_on:
            self._accel_pass(accel, why)
        self.flag_counts[why] += 1
        self.flag_counts[PASSTHROUGH] += 1
        self.counts['out'] += 1
        self.last_flags = flags
        if math.isfinite(t):
            self.last_t = t
        var = self.policy.passthrough_variance
        return wx, wy, wz, (var, var, var), flags

    def fail(self, exc: Exception) -> Vec3:
        """Count a sample whose compensation raised ``exc`` (sent raw); return its variance."""
        self.counts['out'] += 1
        self.errors += 1
        self.last_error = f'{type(exc).__name__}: {exc}'
        var = self.policy.passthrough_variance
        return var, var, var

    def _still(self, t: float, raw: Vec3, out: Vec3, accel: Sequence[float] | None,
               temp: float) -> None:
        found = self._detector.update(t, raw, out, accel, temp)
        if found is None:
            return
        # The compensated rate is divided by 1 + s dT: the drift shift is the mean times it.
        den = (np.asarray(self._cache[temp][3:6]) if self._static
               else 1.0 + self._comp.dt_c * self._scale)
        delta = np.asarray(found.delta) * den
        self._comp.shift_offset(delta)
        self._cache.clear()
        self._acache.clear()
        self.anchor = replace(found, delta=tuple(float(v) for v in delta),
                              se=tuple(float(v) for v in np.asarray(found.se) * np.abs(den)))

    @property
    def still_windows_rejected(self) -> int:
        """Return how many windows were judged not still while waiting to re-anchor."""
        return self._detector.windows_rejected

    @property
    def thermal_progress(self) -> float | None:
        """Return the time since the first sample in the model's state tau (None: no lag)."""
        return None if self._comp is None else self._comp.thermal_progress

    def temperature_age(self) -> float | None:
        """Return the last IMU stamp minus the newest thermometer stamp, s (None if unknown)."""
        latest = self.temps.latest
        if latest is None or self.last_t is None:
            return None
        return self.last_t - latest[1]
