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

:class:`CompensatorCore` turns one raw sample into one output sample, the variance to add to
its covariance, flags (:mod:`gyro_tdc.runtime.flags`) and the corrected specific force; the
rules it follows are in doc/internals/runtime.md. Its parts own their state: the held
thermometer (:class:`gyro_tdc.signal.TemperatureHold`), the sessions
(:class:`gyro_tdc.signal.SessionTracker`), the model and its drift
(:mod:`~gyro_tdc.runtime.drift`), the re-anchoring and the counters
(:mod:`~gyro_tdc.runtime.state`), the learning hand-off (:mod:`~gyro_tdc.runtime.handoff`).
"""

from __future__ import annotations

from collections import deque
import math
from operator import attrgetter
from typing import Sequence

from gyro_tdc.base import (MAX_DRIFT_RAD_S as _MAX_DRIFT, MAX_RATE_RAD_S as _MAX_RATE,
                           MAX_TEMP_LEAD_S, RESTART_BACK_S)
from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime.blockstats import Vec3
from gyro_tdc.runtime.drift import accel_slot, growth, ModelSlot, timeless, widen
from gyro_tdc.runtime.flags import (IMPLAUSIBLE_INPUT, IMPLAUSIBLE_OUTPUT, NO_ACCEL_DATA,
                                    NO_MODEL, NO_TEMPERATURE, NON_FINITE, OUT_OF_RANGE,
                                    PASSTHROUGH, STALE, UPSTREAM)
from gyro_tdc.runtime.handoff import LearningGate, power_up, POWER_UP_KEY
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.priming import (catch_up, prepare, PREPARED_BY, prepared_for, PreparedModel,
                                      Priming)
from gyro_tdc.runtime.state import detector_for, reanchor_var, Reanchoring, StreamState, Tally
from gyro_tdc.signal import TemperatureHold
import numpy as np

__all__ = ['CompensatorCore', 'Output']

#: What :meth:`CompensatorCore.process` returns, a plain tuple (a NamedTuple costs more per
#: sample than the rest of the static path): ``(wx, wy, wz, variance, flags, accel,
#: accel_variance)``. ``accel`` is the corrected specific force, m/s^2 (None: leave the
#: message's as it is), ``accel_variance`` what to add to the linear_acceleration_covariance
#: diagonal, (m/s^2)^2 (None: leave it).
Output = tuple[float, float, float, Vec3, int, Vec3 | None, Vec3 | None]
_INF = math.inf


class CompensatorCore:
    """
    One raw sample in, one output sample out: the compensator without ROS.

    Its state is in a few named groups: ``temps`` (the held thermometer), ``stream`` (where the
    streams are), ``slot`` (the model), ``tally`` (counters), ``reanchoring`` and
    ``learning``; the properties below read them.

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
        self.stream = StreamState(deque(maxlen=self.HISTORY_LENGTH))
        self.slot = ModelSlot()
        self.tally = Tally()
        self.reanchoring = Reanchoring(detector_for(policy))
        self.learning = LearningGate()
        #: Steps over this (s) are shown to the session rule: every step while the stream's
        #: median period is learnt, then its ``pause_s()`` (the learner's too).
        self._pause_s = 0.0
        self._update_needs()
        if model is not None:
            self.set_model(model)

    model = property(attrgetter('slot.model'), doc='The model in use (None: passing through).')
    model_id = property(attrgetter('slot.model_id'), doc="The model's content id.")
    anchor = property(attrgetter('reanchoring.anchor'), doc="This session's shift, or None.")
    flag_counts = property(attrgetter('tally.flags'), doc='Samples per flag bit.')
    last_error = property(attrgetter('tally.last_error'), doc='The last of those errors.')
    motion_reports = property(attrgetter('tally.motion_reports'), doc='Motion reports taken.')
    last_t = property(attrgetter('stream.t'), doc='The last IMU stamp, s (None before any).')
    last_flags = property(attrgetter('stream.flags'), doc="The last sample's flags.")
    accel_flags = property(attrgetter('stream.accel_flags'),
                           doc="The last sample's accelerometer flags (-1 before any).")
    moving = property(attrgetter('stream.moving'), doc='The latest motion report (None: none).')
    learned_installs = property(attrgetter('learning.installs'), doc='Learned models installed.')
    still_windows_rejected = property(attrgetter('reanchoring.detector.windows_rejected'),
                                      doc='Windows judged not still while waiting to re-anchor.')

    @property
    def counts(self) -> dict[str, int]:
        """Return the samples ``in``, ``out`` and ``compensated`` (the core's own dict)."""
        tally, counts = self.tally, self.tally.counts
        counts['out'] = counts['compensated'] + tally.flags[PASSTHROUGH] + tally.errors
        return counts

    @property
    def accel_on(self) -> bool:
        """Return whether the model has an accelerometer part (:meth:`process` corrects it)."""
        return self.slot.accel is not None

    def _update_needs(self) -> None:
        """
        Work out :meth:`process`'s one-compare checks from the policy, model and anchor.

        ``upstream_pass``: the gyro is declared thermally corrected upstream and passes
        through (never corrected twice); ``needs_accel``: the model has an accelerometer part
        or re-anchoring waits for a still window (the node reads the force per message);
        ``pass_var``: the variance a sample passed through raw adds, per axis.
        """
        a, policy = self.reanchoring, self.policy
        a.waiting = bool(policy.reanchor_on_start and not a.settled and not a.learned)
        self.needs_accel = self.slot.accel is not None or a.waiting
        self.upstream_pass = bool(policy.upstream_correction) and (
            policy.upstream_policy == 'passthrough')
        self.pass_var = (policy.passthrough_variance,) * 3

    # -- learning ---------------------------------------------------------------------

    #: The attached :class:`gyro_tdc.learn.learner.Learner`, or None; setting one attaches it:
    #: it sees every raw sample and thermometer reading (appends).
    learner = property(attrgetter('learning.learner'), lambda self, v: self.learning.attach(v))

    def learn_step(self) -> list:
        """
        Step the learner (off the message path: a timer) and :meth:`schedule` its new models.

        Returns the models scheduled (or installed), ``(effective stamp or None, model)``,
        oldest first (:meth:`gyro_tdc.learn.learner.Learner.take_swaps`).
        """
        if (learner := self.learning.learner) is None:
            return []
        learner.step()
        swaps = learner.take_swaps(self.stream.t)
        for due, model in swaps:
            self.schedule(model, due)
        return swaps

    def schedule(self, model: CompensationModel, due: float | None) -> None:
        """
        Install a learned ``model`` at the first message stamped at or after ``due`` (s).

        Made ready now (:func:`prepare`; call it on the thread that compensates); installed
        at once when ``due`` is None or the message path has already passed it (late).
        """
        prepared = prepare(model, self.policy, self.priming(model))
        gate, last_t = self.learning, self.stream.t
        if due is not None and (last_t is None or due > last_t):
            return gate.enqueue(due, prepared)
        gate.cancel()
        gate.installs += 1
        self.install(prepared, learned=True)

    # -- model ------------------------------------------------------------------------

    def priming(self, model: CompensationModel | None = None) -> Priming:
        """
        Return a copy of what a new model's filters are replayed over (see :func:`prepare`).

        For a :func:`timeless` ``model`` the copy has no thermometer history: it has no
        filter to replay (its install costs what a model evaluation does, not a replay of
        up to ``HISTORY_LENGTH`` readings).
        """
        stream = self.stream
        history = () if model is not None and timeless(model) else tuple(stream.history)
        return Priming(stream.first, history, stream.t, stream.temp)

    def set_model(self, model: CompensationModel | None) -> None:
        """
        Prepare and install ``model`` in one step (:func:`prepare`, then :meth:`install`).

        None passes every sample through (``model_id`` keeps naming the last model installed).
        """
        if model is not None:
            return self.install(prepare(model, self.policy, self.priming(model)))
        self.slot = ModelSlot(model_id=self.slot.model_id)
        self._update_needs()

    def install(self, prepared: PreparedModel, learned: bool = False, *,
                older_clock: bool = False) -> None:
        """
        Swap in a model made ready by :func:`prepare` (call it on the thread that compensates).

        Its replay is carried on to the last IMU stamp (:func:`catch_up`); the re-anchoring
        shift is kept or dropped by :meth:`Reanchoring.on_install`.

        Parameters
        ----------
        prepared : PreparedModel
            The model and its primed streaming state.
        learned : bool
            The model is the attached learner's.
        older_clock : bool
            Learned before the stamps stepped back: never of this session's offset.

        """
        if not prepared_for(prepared, self.policy):   # read before a policy change
            prepared = prepare(prepared.model, self.policy, prepared.priming)
        model, stream, old = prepared.model, self.stream, self.slot
        comp = catch_up(prepared, Priming(stream.first, stream.history, stream.t, stream.temp),
                        self.policy)
        learned = learned and self.learning.learner is not None
        self.reanchoring.on_install(
            comp, model, old.model is not None and prepared.model_id == old.model_id, learned,
            learned and old.learned,
            reanchor_var(model, self.learning) if learned else model.residual_var,
            older_clock=older_clock)
        self.slot = ModelSlot(model, prepared.model_id, comp, prepared.var, prepared.scale,
                              prepared.static, {},
                              accel_slot(model, comp, prepared.static, self.policy), learned,
                              model.offset_only)
        self._update_needs()

    def set_policy(self, policy: Policy) -> None:
        """
        Swap in new policies between two messages (call it on the thread that compensates).

        What was built from the old ``policy`` is rebuilt: the model in use is prepared again
        when a field of ``PREPARED_BY`` changed (the same model keeps its start-up shift), the
        learned models waiting at their install (:meth:`install`: :func:`prepared_for`); the
        stillness detector by :meth:`Reanchoring.rethreshold`.
        """
        old, self.policy = self.policy, policy
        slot = self.slot
        self.reanchoring.rethreshold(old, policy, reanchor_var(slot.model, self.learning),
                                     self.stream.t if self.stream.moving else None)
        if slot.model is not None and any(getattr(old, f) != getattr(policy, f)
                                          for f in PREPARED_BY):
            self.install(prepare(slot.model, policy, self.priming(slot.model)),
                         learned=slot.learned)
        self._update_needs()

    # -- inputs -----------------------------------------------------------------------

    def add_temperature(self, t: float, temp_c: float) -> bool:
        """
        Record one thermometer sample; return False when it was rejected.

        A reading that is not finite, outside the plausible range, jumping faster than the
        slew bound (:mod:`gyro_tdc.base.plausible`) or stamped further ahead of the last IMU
        stamp than ``temperature_timeout`` or ``MAX_TEMP_LEAD_S``, whichever is longer, is
        counted and dropped: it reaches neither the hold, nor a filter, nor the history, nor
        the learner.
        """
        last_t = self.stream.t
        if not self.temps.add(t, temp_c, math.inf if last_t is None else last_t + max(
                self.policy.temperature_timeout, MAX_TEMP_LEAD_S)):
            return False
        if (learner := self.learning.learner) is not None:
            learner.add_temperature(t, temp_c)
        history = self.stream.history
        if not history or t >= history[-1][0] + self.HISTORY_SPACING_S:
            history.append((t, temp_c))
        slot = self.slot
        if slot.comp is not None and slot.static and temp_c not in slot.cache:
            slot.refresh(t, temp_c, self.policy)
        return True

    def motion(self, t: float, components: Sequence[float]) -> bool:
        """
        Record an outside motion report (``cmd_vel``, odometry); return whether it says motion.

        ``t`` is its stamp (s; the latest IMU stamp for a bare Twist), ``components`` its
        linear and angular velocity (m/s, rad/s): motion when any is above
        ``motion_threshold`` in magnitude or not finite. From ``t`` until the next report, no
        sample is still while a report says motion, for re-anchoring and the learner alike.
        """
        eps = self.policy.motion_threshold
        moving = not all(math.isfinite(v) and abs(v) <= eps for v in components)
        self.tally.motion_reports += 1
        if moving != self.stream.moving:     # only changes are passed on
            self.stream.moving = moving
            self.reanchoring.detector.observe_motion(t, moving)
            if self.learning.learner is not None:
                self.learning.learner.observe_motion(t, moving)
        return moving

    def process(self, t: float, wx: float, wy: float, wz: float,
                accel: Sequence[float] | None = None) -> Output:
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
            the model's accelerometer part.

        Returns
        -------
        wx, wy, wz : float, rad/s
            The output rate (the raw rate when passed through).
        variance : tuple of 3 float, (rad/s)^2
            To add to the covariance diagonal.
        flags : int
            Bit set of ``STALE``, ``OUT_OF_RANGE``, ``NON_FINITE``, ``NO_TEMPERATURE``,
            ``NO_MODEL``, ``UPSTREAM``, ``IMPLAUSIBLE_INPUT`` (a rate beyond
            ``MAX_RATE_RAD_S``), ``IMPLAUSIBLE_OUTPUT`` (an output not finite or corrected by
            more than ``MAX_DRIFT_RAD_S``), ``PASSTHROUGH``.
        accel : tuple of 3 float or None, m/s^2
            The corrected specific force (None: leave the message's as it is).
        accel_variance : tuple of 3 float or None, (m/s^2)^2
            To add to the linear_acceleration_covariance diagonal (None: leave it).

        """
        tally, stream = self.tally, self.stream
        tally.counts['in'] += 1
        if not -_INF < t < _INF:        # no time: in no session, not learnt from (NaN too)
            return self._pass(t, wx, wy, wz, NON_FINITE, accel)
        if (last := stream.t) is None:  # the first session starts
            self.reanchoring.sessions.begin(t, tally.counts['in'])
        elif (d := t - last) > self._pause_s or d < -RESTART_BACK_S:
            self._session_break(t, d)
        gate = self.learning
        if t >= gate.gate:             # learning: a model due, or a sample to hand over
            if t >= gate.due:
                self.install(gate.take_due(t), learned=True)
            if gate.extend is not None:
                gate.add(t, wx, wy, wz, accel, last)
        if self.upstream_pass:         # the flight controller corrected it: never twice
            return self._pass(t, wx, wy, wz, UPSTREAM, accel)
        slot = self.slot
        if slot.comp is None:
            return self._pass(t, wx, wy, wz, NO_MODEL)
        m = _MAX_RATE                   # NaN fails the compares
        if not (abs(wx) <= m and abs(wy) <= m and abs(wz) <= m):
            finite = all(map(math.isfinite, (wx, wy, wz)))
            return self._pass(t, wx, wy, wz, IMPLAUSIBLE_INPUT if finite else NON_FINITE, accel)
        if (held := self.temps.at(t)) is None:
            return self._pass(t, wx, wy, wz, NO_TEMPERATURE, accel)
        temp, t_temp = held
        policy, flags = self.policy, 0
        if t - t_temp > policy.temperature_timeout:
            if policy.stale_policy == 'passthrough':
                return self._pass(t, wx, wy, wz, STALE, accel)
            flags = STALE
        if stream.first is None:
            stream.first = (t, temp)
        if slot.static:
            # Static features: the drift and the variance change only with the temperature.
            # The output check (finite, a plausible drift per axis; NaN fails the compares)
            # cannot fail for a safe entry and an input that passed its check.
            e = slot.cache.get(temp) or slot.refresh(t, temp, policy)
            ox, oy, oz = (wx - e.bx) / e.dx, (wy - e.by) / e.dy, (wz - e.bz) / e.dz
            m = _MAX_DRIFT
            if not (e.safe or (abs(ox - wx) <= m and abs(oy - wy) <= m and abs(oz - wz) <= m)):
                return self._pass(t, wx, wy, wz, IMPLAUSIBLE_OUTPUT, accel)
            var = e.var_stale if flags else e.var
            flags |= e.oor
            dist = e.distance_c
        else:
            if (out := self._timed(t, temp, wx, wy, wz, flags)) is None:
                return self._pass(t, wx, wy, wz, IMPLAUSIBLE_OUTPUT, accel)
            ox, oy, oz, var, flags, dist = out
        aout = avar = None
        if slot.accel is not None:
            aout, avar, aflags = (None, None, 0) if accel is None else slot.accel.correct(
                t, temp, accel, flags & STALE, policy)
            aout, avar = self._accel_pass(accel, aflags, aout, avar)
        stream.t, stream.temp, stream.flags, stream.distance_c = t, temp, flags, dist
        tally.counts['compensated'] += 1
        if flags:
            self._flagged(t, (wx, wy, wz), (ox, oy, oz), accel, temp, flags)
        elif policy.reanchor_on_start and self.reanchoring.waiting:
            self._still(t, (wx, wy, wz), (ox, oy, oz), accel, temp)
        return ox, oy, oz, var, flags, aout, avar

    def _timed(self, t: float, temp: float, wx: float, wy: float, wz: float, flags: int
               ) -> tuple[float, float, float, Vec3, int, float] | None:
        """
        Compensate one sample with a model of time terms (its filters step every sample).

        Returns the output rate, the variance to add, the flags and the distance from the
        range; None when the output check refuses it (not finite, an implausible drift).
        """
        slot, comp = self.slot, self.slot.comp
        ox, oy, oz = comp.step(t, temp, (wx, wy, wz)).tolist()
        dist = comp.range_distance_c
        if comp.in_range:
            var = slot.var[flags]
        else:
            flags |= OUT_OF_RANGE
            var = widen(slot.var[flags], growth(dist, self.policy))
        m = _MAX_DRIFT
        if not (abs(ox - wx) <= m and abs(oy - wy) <= m and abs(oz - wz) <= m
                and math.isfinite(var[0] + var[1] + var[2])):     # the output check
            return None
        return ox, oy, oz, var, flags, dist

    def _flagged(self, t: float, raw: Vec3, out: Vec3, accel: Sequence[float] | None,
                 temp: float, flags: int) -> None:
        """Count a compensated sample's flags; re-anchor out of range where it is safe."""
        for bit in (STALE, OUT_OF_RANGE):
            if flags & bit:
                self.tally.flags[bit] += 1
        # Out of range a shift would take in the curve's extrapolation error, except: with a
        # learner (the shift holds only until it gives the cycle its own offset), and for a
        # model of the offset only (no curve to extrapolate: its range is no limit).
        if (flags == OUT_OF_RANGE and self.reanchoring.waiting
                and (self.learning.extend is not None or self.slot.flat)):
            self._still(t, raw, out, accel, temp)

    def _accel_pass(self, accel: Sequence[float] | None, why: int, out: Vec3 | None = None,
                    var: Vec3 | None = None) -> tuple[Vec3 | None, Vec3 | None]:
        """
        Record one specific force's outcome and return it with the variance to add.

        None: the sample had none; ``out`` None: it passes through (``why``), widened by
        ``passthrough_variance``; else ``out`` was corrected, with flags ``why``.
        """
        flags, outcome, result = (
            (NO_ACCEL_DATA, 'missing', (None, None)) if accel is None else
            (why, 'compensated', (out, var)) if out is not None else
            (why | PASSTHROUGH, 'passed through', (None, self.pass_var)))
        self.stream.accel_flags = flags
        self.tally.accel[outcome] += 1
        return result

    def _pass(self, t: float, wx: float, wy: float, wz: float, why: int,
              accel: Sequence[float] | None = None) -> Output:
        aout, avar = (None, None) if self.slot.accel is None else self._accel_pass(accel, why)
        counts = self.tally.flags
        counts[why] += 1
        counts[PASSTHROUGH] += 1
        self.stream.flags = flags = why | PASSTHROUGH
        if math.isfinite(t):
            self.stream.t = t
        return wx, wy, wz, self.pass_var, flags, aout, avar

    def fail(self, exc: Exception) -> Vec3:
        """Count a sample whose compensation raised ``exc`` (sent raw); return its variance."""
        self.tally.errors += 1
        self.tally.last_error = f'{type(exc).__name__}: {exc}'
        return self.pass_var

    def _still(self, t: float, raw: Vec3, out: Vec3, accel: Sequence[float] | None,
               temp: float) -> None:
        a = self.reanchoring
        if a.anchor is not None:          # a provisional shift: the detector averages without it
            s = a.shown
            out = (out[0] + s[0], out[1] + s[1], out[2] + s[2])
        if (found := a.detector.update(t, raw, out, accel, temp)) is not None:
            a.take(found, self.slot, temp)
            self._update_needs()
        elif a.detector.provisional is not a.seen:
            a.seen = a.detector.provisional
            a.take(a.seen, self.slot, temp)

    def _session_break(self, t: float, d: float) -> None:
        """
        Start a new session at stamp ``t`` when the step ``d`` from the last one is a break.

        A break is the shared rule's (:class:`gyro_tdc.signal.SessionTracker`, shown the steps
        over its ``pause_s()`` as the learner shows it, from which it learns the stream's
        rhythm, and steps back by ``RESTART_BACK_S``): the IMU was power-cycled. Its
        streams start over (:meth:`StreamState.restart`), so do the model's time terms
        (:meth:`StreamingCompensator.reset`) and, with ``reanchor_on_start``, the
        re-anchoring (the old shift dropped).
        """
        a, k = self.reanchoring, self.tally.counts['in']
        sessions = a.sessions
        if sessions.median is None:     # the period is being learnt: the steps over the gap
            if sessions.median_period(np.array([d])) is not None:
                self._pause_s = sessions.pause_s()
            if not (d > sessions.gap_s or d < -RESTART_BACK_S):
                return
        if not (why := sessions.judge(d, sessions.period(self.stream.t, k) if d > 0 else 0.0)):
            return
        sessions.start(t, why, k)
        # The stamps stepped back: the learner's hand-off and queue ran on the old clock.
        waiting = self.learning.restart_clock() if d < 0 else None
        a.learned = False
        self.stream.restart(t, d, self.temps, self.policy.temperature_timeout)
        slot = self.slot
        if slot.comp is not None:
            slot.comp.reset()             # warm-up and thermal state from the power-on
        if self.policy.reanchor_on_start:
            gate = self.learning
            a.restart(slot, reanchor_var(slot.model, gate), gate.extend is not None)
            self._update_needs()
        # The new power cycle starts on the newest learned model (``waiting`` on the old clock,
        # else the one installed; none: the one in force) with the intercept its learner gave
        # a power cycle whose offset is not known yet (power_up): not the last cycle's offset.
        model = waiting.model if waiting is not None else slot.model if slot.learned else None
        if model is not None and POWER_UP_KEY in model.created:
            waiting = prepare(up := power_up(model), self.policy, self.priming(up))
        if waiting is not None:
            self.learning.installs += 1
            self.install(waiting, learned=True, older_clock=True)

    def temperature_age(self) -> float | None:
        """Return the last IMU stamp minus the newest thermometer stamp, s (None if unknown)."""
        latest, t = self.temps.latest, self.stream.t
        return None if latest is None or t is None else t - latest[1]
