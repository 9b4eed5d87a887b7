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
its covariance and flags (:mod:`gyro_tdc.runtime.health`) saying what happened.
``gyro_tdc.nodes.compensator_node`` only converts messages to floats and back, so every rule
here is tested without ROS (the stillness test is :mod:`gyro_tdc.runtime.reanchor`, the judgement
shown on /diagnostics :mod:`gyro_tdc.runtime.health`, the parameter table and :class:`Policy`
:mod:`gyro_tdc.runtime.policy`, a model made ready off the compensating thread
:mod:`gyro_tdc.runtime.priming`):

* the temperature used for a sample stamped ``t`` is the latest thermometer sample
  stamped at or before ``t`` (zero-order hold by stamp, :mod:`gyro_tdc.runtime.temperature_hold`,
  so the interleaving of the two topics in the executor does not matter);
* older than ``temperature_timeout`` it is stale: ``hold`` keeps compensating with it and
  widens the covariance, ``passthrough`` sends the raw rate;
* before the first temperature, without a model, or with a NaN/Inf in the sample, the raw
  rate passes through unchanged;
* outside the model's temperature range the model continues along its tangent (``linear``,
  :mod:`gyro_tdc.model.out_of_range`), clamps or extrapolates, and the covariance is widened (with
  ``linear`` the more, the farther);
* start-up re-anchoring: once the gyro is still, the compensated rate is averaged until its
  mean is known to ``reanchor_tolerance`` (:mod:`gyro_tdc.runtime.reanchor`), and the model's
  offset is shifted so that it averages zero;
* a model with an accelerometer part (``model.accel``) also corrects the specific force of
  each sample that carries one, with the same temperature, the same policies and the same
  variances (read in (m/s^2)^2) added to the accelerometer residual variance; the result is
  left in :attr:`CompensatorCore.accel_out` and :attr:`CompensatorCore.accel_var`;
* with a learner attached (:mod:`gyro_tdc.learn.learner`), one stamp compare per message gates
  both handing it a sample (at most ``max_rate_hz``) and installing a learned model whose
  effective stamp has come (:meth:`CompensatorCore.learn_step` made it ready off the
  message path), so the output does not depend on when the learner was stepped.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace
import math
from typing import Sequence

from gyro_tdc.model import CompensationModel, STATIC_EFFECTS, StreamingCompensator, variance_growth
from gyro_tdc.runtime.health import (FLAG_NAMES, NO_ACCEL_DATA, NO_MODEL, NO_TEMPERATURE,
                                     NON_FINITE, OUT_OF_RANGE, PASSTHROUGH, STALE)
from gyro_tdc.runtime.policy import PARAMS, Policy, TEMPERATURE_TYPES
from gyro_tdc.runtime.priming import (advance, prepare, PreparedModel, Priming, Replay, replay,
                                      replay_from_first)
from gyro_tdc.runtime.reanchor import Anchor, StillnessDetector, Vec3
from gyro_tdc.runtime.temperature_hold import TemperatureHold, widen_covariance
import numpy as np

# PARAMS, Policy, TEMPERATURE_TYPES (gyro_tdc.runtime.policy), the priming types
# (gyro_tdc.runtime.priming), TemperatureHold and widen_covariance
# (gyro_tdc.runtime.temperature_hold) are
# re-exported: the compensator's pure API stays importable from here.
__all__ = ['CompensatorCore', 'PARAMS', 'Policy', 'PreparedModel', 'Priming', 'Replay',
           'STATIC_EFFECTS', 'TEMPERATURE_TYPES', 'TemperatureHold', 'prepare',
           'widen_covariance']

# STATIC_EFFECTS (from the effect library): a model made of these has a drift that changes
# only when the temperature does, so the compensator evaluates it once per thermometer sample.


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
        self._lx = None                 # the learner's buffer's extend (one call a sample)
        self._lnext = math.inf          # next stamp the learner takes a sample at
        #: Learned models waiting for their effective stamp: [stamp, PreparedModel], oldest
        #: first (:meth:`schedule`); ``_due`` is the first one's stamp, ``_gate`` the smaller
        #: of it and ``_lnext``: the message path's one compare for all learning work.
        self._queue: deque[tuple[float, PreparedModel]] = deque()
        self._due = math.inf
        self._gate = math.inf
        #: Learned models installed (:meth:`schedule`, on time or late: the learner counts
        #: the late ones, ``Learner.late_swaps``).
        self.learned_installs = 0
        #: The latest outside motion report: None before any, else whether it says motion.
        self.moving: bool | None = None
        self.motion_reports = 0
        if model is not None:
            self.set_model(model)

    @property
    def learner(self):
        """Return the attached :class:`gyro_tdc.learn.learner.Learner`, or None."""
        return self._learner

    @learner.setter
    def learner(self, learner) -> None:
        """Attach a learner: it sees every raw sample and thermometer reading (appends)."""
        self._learner = learner
        self._lx = None
        self._lnext = math.inf
        if learner is not None:
            self._lx = learner.buf.extend
            self._lperiod = 1.0 / learner.config.max_rate_hz
            self._lnext = -math.inf
        self._gate = min(self._lnext, self._due)

    def learn_step(self) -> list:
        """
        Step the learner (off the message path: a timer) and schedule the models it swapped in.

        Each accepted candidate is made ready here (:func:`prepare`) and installed by
        :meth:`process` at the first message stamped at or after its effective stamp
        (:meth:`gyro_tdc.learn.learner.Learner.take_swaps`), so the output does not depend on
        when this runs, provided it runs within the learner's ``swap_delay_s`` of stamps
        after the data; later, the model is installed here at once (the next message is
        the first to use it) and the learner counts it in ``late_swaps``.

        Returns
        -------
        list of (float or None, CompensationModel)
            The models scheduled (or installed) with their effective stamps, oldest first.

        """
        learner = self._learner
        if learner is None:
            return []
        learner.step()
        swaps = learner.take_swaps(self.last_t)
        for due, model in swaps:
            self.schedule(model, due)
        return swaps

    def schedule(self, model: CompensationModel, due: float | None) -> None:
        """
        Install a learned ``model`` at the first message stamped at or after ``due`` (s).

        Made ready now (:func:`prepare`; call it on the thread that compensates); installed
        at once when ``due`` is None or the message path has already passed it (late).
        """
        prepared = prepare(model, self.policy, self.priming())
        if due is None or (self.last_t is not None and due <= self.last_t):
            self._queue.clear()
            self._due = math.inf
            self._gate = min(self._lnext, self._due)
            self.learned_installs += 1
            self.install(prepared)
            return
        self._queue.append((due, prepared))
        self._due = self._queue[0][0]
        self._gate = min(self._lnext, self._due)

    def cancel_scheduled(self) -> None:
        """Drop the learned models waiting for their stamp (a model_file or a reset came)."""
        self._queue.clear()
        self._due = math.inf
        self._gate = min(self._lnext, self._due)

    def _learning(self, t: float, wx: float, wy: float, wz: float,
                  accel: Sequence[float] | None) -> None:
        """Install a learned model that is due, hand the learner a sample (``_gate`` passed)."""
        if t >= self._due:
            queue = self._queue
            prepared = None
            while queue and queue[0][0] <= t:
                prepared = queue.popleft()[1]
            self._due = queue[0][0] if queue else math.inf
            self.learned_installs += 1
            self.install(prepared)
        if t >= self._lnext:                  # at most max_rate_hz, by stamp
            self._lnext = t + self._lperiod
            if accel is None:                 # Learner.observe's layout, one extend
                self._lx((t, wx, wy, wz, math.nan, math.nan, math.nan))
            else:
                ax, ay, az = accel
                self._lx((t, wx, wy, wz, ax, ay, az))
        self._gate = min(self._lnext, self._due)

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
                state = replay_from_first(comp, self._first, self._history, self.last_t)
            else:
                tail = []
                for entry in reversed(self._history):
                    if entry[0] <= state.t_seen:
                        break
                    tail.append(entry)
                state = replay(comp, reversed(tail), self.last_t, state)
            if self.last_t > state.t_prev:
                advance(comp, self.last_t,
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

    def motion(self, t: float, components: Sequence[float]) -> bool:
        """
        Record an outside motion report (``cmd_vel``, odometry) by its velocity components.

        Parameters
        ----------
        t : float, s
            Stamp of the report (the message's, or the latest IMU stamp for a bare Twist).
        components : sequence of float, m/s and rad/s
            Linear and angular velocity: motion when any is above ``motion_threshold`` in
            magnitude or not finite.

        Returns
        -------
        bool
            Whether the report says motion.

        """
        eps = self.policy.motion_threshold
        moving = not all(math.isfinite(v) and abs(v) <= eps for v in components)
        self.observe_motion(t, moving)
        return moving

    def observe_motion(self, t: float, moving: bool) -> None:
        """
        Record that the vehicle is moving (or not) from stamp ``t`` until the next report.

        While a report says motion, no sample is still: the re-anchoring detector and the
        learner both veto the windows that overlap it. Only changes are passed on (a report
        holds until the next one, so a repeated state adds nothing).
        """
        self.motion_reports += 1
        if moving == self.moving:
            return
        self.moving = moving
        self._detector.observe_motion(t, moving)
        if self._learner is not None:
            self._learner.observe_motion(t, moving)

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
        if t >= self._gate:            # learning: a sample to hand over, or a model due
            self._learning(t, wx, wy, wz, accel)
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
            # Static features: the drift, and the variance to add, only change when the
            # temperature does.
            entry = self._cache.get(temp) or self._refresh(t, temp)
            bx, by, bz, dx, dy, dz, in_range, dist, _, var, var_stale = entry
            ox, oy, oz = (wx - bx) / dx, (wy - by) / dy, (wz - bz) / dz
            if flags:
                var = var_stale
            if not in_range:
                flags |= OUT_OF_RANGE
        else:
            out = comp.step(t, temp, (wx, wy, wz))
            dist = comp.range_distance_c
            if comp.in_range:
                var = self._var[flags]
            else:
                flags |= OUT_OF_RANGE
                more = variance_growth(self.policy.out_of_range_variance, dist,
                                       self.policy.out_of_range)
                var = self._var[flags]
                if more:       # linear: the added variance grows with the distance
                    var = (var[0] + more, var[1] + more, var[2] + more)
            ox, oy, oz = out.tolist()
        if self.accel_on:
            self._accel(t, temp, accel, flags & STALE)
        self.last_t, self.last_temp, self.last_flags = t, temp, flags
        self.last_distance_c = dist
        counts = self.counts
        counts['out'] += 1
        counts['compensated'] += 1
        if flags:
            fc = self.flag_counts
            if flags & STALE:
                fc[STALE] += 1
            if flags & OUT_OF_RANGE:
                fc[OUT_OF_RANGE] += 1
        elif self.policy.reanchor_on_start and self.anchor is None:
            self._still(t, (wx, wy, wz), (ox, oy, oz), accel, temp)
        return ox, oy, oz, var, flags

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
            variance growth, variance to add, the same when stale)``.

        """
        comp = self._comp
        b = comp.drift(t, temp).tolist()
        den = (1.0 + comp.dt_c * self._scale).tolist()
        dist = comp.range_distance_c
        more = (variance_growth(self.policy.out_of_range_variance, dist,
                                self.policy.out_of_range) if dist else 0.0)
        oor = 0 if comp.in_range else OUT_OF_RANGE
        var, var_stale = self._var[oor], self._var[oor | STALE]
        if more:           # linear: the added variance grows with the distance
            var = (var[0] + more, var[1] + more, var[2] + more)
            var_stale = (var_stale[0] + more, var_stale[1] + more, var_stale[2] + more)
        entry = (*b, *den, comp.in_range, dist, more, var, var_stale)
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
