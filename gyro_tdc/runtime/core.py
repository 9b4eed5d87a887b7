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
rules it follows are in doc/internals/runtime.md.
"""

from __future__ import annotations

from array import array
from collections import deque
from dataclasses import dataclass, field, replace
import math
from operator import attrgetter
from typing import Any, Callable, Sequence

from gyro_tdc.base import (MAX_ACCEL_DRIFT_MPS2, MAX_DRIFT_RAD_S, MAX_RATE_RAD_S, MAX_TEMP_LEAD_S,
                           RESTART_BACK_S, SESSION_GAP_S)
from gyro_tdc.model import (CompensationModel, gated_shift, STATIC_EFFECTS,
                            StreamingCompensator, variance_growth)
from gyro_tdc.runtime.flags import (FLAG_NAMES, IMPLAUSIBLE_INPUT, IMPLAUSIBLE_OUTPUT,
                                    NO_ACCEL_DATA, NO_MODEL, NO_TEMPERATURE, NON_FINITE,
                                    OUT_OF_RANGE, PASSTHROUGH, STALE, UPSTREAM)
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.priming import (advance, prepare, PREPARED_BY, prepared_for, PreparedModel,
                                      Priming, replay, replay_from_first)
from gyro_tdc.runtime.reanchor import Anchor, StillnessDetector, Vec3
from gyro_tdc.runtime.temperature_hold import TemperatureHold
from gyro_tdc.signal import SessionRule
import numpy as np

__all__ = ['AccelEntry', 'AccelSlot', 'CompensatorCore', 'correction_is_safe', 'DriftEntry',
           'LearningGate', 'ModelSlot', 'Output', 'Reanchoring', 'StreamState', 'Tally',
           'timeless']

#: What :meth:`CompensatorCore.process` returns, a plain tuple (a NamedTuple costs more per
#: sample than the rest of the static path): ``(wx, wy, wz, variance, flags, accel,
#: accel_variance)``. ``accel`` is the corrected specific force, m/s^2 (None: leave the
#: message's as it is), ``accel_variance`` what to add to the linear_acceleration_covariance
#: diagonal, (m/s^2)^2 (None: leave it).
Output = tuple[float, float, float, Vec3, int, Vec3 | None, Vec3 | None]

#: The plausibility bounds of the message path (gyro_tdc.base.limits), as module constants.
_MAX_RATE = MAX_RATE_RAD_S
_MAX_DRIFT = MAX_DRIFT_RAD_S
_MAX_ACCEL_DRIFT = MAX_ACCEL_DRIFT_MPS2
#: Floats per sample handed to the learner: stamp, rate (3), specific force (3; NaN: none).
BLOCK_FIELDS = 7


@dataclass(frozen=True, slots=True)
class DriftEntry:
    """
    A static model's drift at one temperature, as the message path uses it.

    The output rate is ``(w - b) / d`` per axis, the operations ``StreamingCompensator.step``
    does, so the same bits.
    """

    bx: float
    by: float
    bz: float
    #: ``1 + dT * scale`` per axis.
    dx: float
    dy: float
    dz: float
    #: ``OUT_OF_RANGE`` outside the model's temperature range, else 0.
    oor: int
    distance_c: float
    #: Variance to add, fresh and stale temperature.
    var: Vec3
    var_stale: Vec3
    #: Every input the input check lets through (finite, within ``MAX_RATE_RAD_S``) is
    #: corrected by at most half ``MAX_DRIFT_RAD_S``: the per-sample output check can be skipped.
    safe: bool = False


def correction_is_safe(b: Vec3, d: Vec3) -> bool:
    """
    Say whether ``(w - b) / d`` moves every ``|w| <= MAX_RATE_RAD_S`` by under half the limit.

    The correction is ``w (1/d - 1) - b/d``, at most ``MAX_RATE |1/d - 1| + |b/d|`` in size;
    the half is a margin far above the rounding of either side. NaN or Inf gives False.
    """
    for bi, di in zip(b, d):
        if not di or not _MAX_RATE * abs(1.0 / di - 1.0) + abs(bi / di) <= 0.5 * _MAX_DRIFT:
            return False            # NaN fails the compare
    return True


def timeless(model: CompensationModel) -> bool:
    """
    Return whether ``model``'s output depends on the current temperature alone.

    No time terms (warm-up, rates of change, ...: only ``STATIC_EFFECTS``) and no lagged
    thermal state, in the gyro part and the accelerometer part: such a model has no filter
    to replay, so installing it reads no thermometer history.
    """
    for part in (model, getattr(model, 'accel', None)):
        if part is None:
            continue
        thermal = part.thermal
        if not set(part.features) <= STATIC_EFFECTS or (
                thermal is not None and thermal.kind != 'none'):
            return False
    return True


@dataclass(frozen=True, slots=True)
class AccelEntry:
    """A static accelerometer part's drift at one temperature: ``a - b``, and its flag."""

    bx: float
    by: float
    bz: float
    oor: int
    #: Variance growth outside the range (``linear``: with the distance), (m/s^2)^2.
    growth: float


@dataclass(slots=True)
class AccelSlot:
    """The installed model's accelerometer part: its compensator, variance table and cache."""

    comp: StreamingCompensator
    var: dict[int, Vec3]
    #: Cached per temperature (only when the gyro's drift is static too).
    static: bool
    cache: dict[float, AccelEntry] = field(default_factory=dict)


@dataclass(slots=True)
class ModelSlot:
    """The model in use, its streaming compensator, variance table and per-temperature cache."""

    model: CompensationModel | None = None
    model_id: str = ''
    comp: StreamingCompensator | None = None
    var: dict[int, Vec3] = field(default_factory=dict)
    scale: np.ndarray | None = None
    #: Made of ``STATIC_EFFECTS``: its drift changes only when the temperature does.
    static: bool = False
    cache: dict[float, DriftEntry] = field(default_factory=dict)
    accel: AccelSlot | None = None
    #: The attached learner's model (:meth:`CompensatorCore.schedule`).
    learned: bool = False


@dataclass(slots=True)
class Tally:
    """
    What the core counted (what /diagnostics shows).

    ``counts``: ``in``, ``out`` and ``compensated`` samples; ``flags``: samples per flag bit;
    ``accel``: accelerometer samples ``compensated``, ``passed through`` and ``missing``.
    Every sample goes out once, compensated, passed through or raw after an error, so ``out``
    is not counted per sample: :attr:`CompensatorCore.counts` works it out when read.
    """

    counts: dict[str, int] = field(default_factory=lambda: {
        'in': 0, 'out': 0, 'compensated': 0})
    flags: dict[int, int] = field(default_factory=lambda: dict.fromkeys(FLAG_NAMES, 0))
    accel: dict[str, int] = field(default_factory=lambda: {
        'compensated': 0, 'passed through': 0, 'missing': 0})
    errors: int = 0
    last_error: str = ''
    motion_reports: int = 0


@dataclass(slots=True)
class StreamState:
    """
    Where the streams are: what a new model's filters are replayed over, and the last sample.

    ``first`` is the stamp and temperature of the first compensated sample, ``history`` the
    thermometer at most one sample a second, ``t``, ``temp``, ``flags`` and ``distance_c``
    the last IMU stamp, its temperature, flags and distance from the model's range;
    ``accel_flags`` the last accelerometer flags (-1 before any), ``moving`` the latest
    outside motion report (None before any).
    """

    history: deque[tuple[float, float]]
    first: tuple[float, float] | None = None
    t: float | None = None
    temp: float | None = None
    flags: int = 0
    distance_c: float = 0.0
    accel_flags: int = -1
    moving: bool | None = None


@dataclass(slots=True)
class Reanchoring:
    """
    The re-anchoring: the stillness detector, the shift it found (or None), the session.

    ``session`` counts the IMU's power cycles seen (from 1), ``session_t`` the first stamp of
    the current one, ``session_k`` the ``in`` count at it and ``session_why`` what started it
    (``'gap of X s'``, ``'restart (stamps back by X s)'``; ``''`` for the first);
    ``pauses`` and ``paused_s`` the steps over ``SESSION_GAP_S`` that were no break, and their
    sum (left out of the session's sample period). ``learned``: a learned model carrying this
    session's offset is installed (taken from its own still time), so re-anchoring is done
    for the session without a shift; ``waiting`` that it still waits for a still window
    (:meth:`CompensatorCore._update_needs`).
    """

    detector: StillnessDetector
    anchor: Anchor | None = None
    session: int = 1
    session_t: float | None = None
    session_k: int = 0
    session_why: str = ''
    pauses: int = 0
    paused_s: float = 0.0
    learned: bool = False
    waiting: bool = False
    #: The shared session-break rule (:class:`gyro_tdc.signal.SessionRule`): the stream's
    #: rhythm over sessions.
    rule: SessionRule = field(default_factory=SessionRule)


@dataclass(slots=True)
class LearningGate:
    """
    The attached learner and the message path's one compare for all learning work.

    ``extend`` is the learner's buffer's extend (one call a hand-off), ``block`` the samples
    since the last hand-off (:data:`BLOCK_FIELDS` floats each), ``next`` the stamp of the
    next hand-off (every ``period`` s: the block's mean, :meth:`CompensatorCore._learning`);
    ``queue`` the learned models waiting for their effective stamp, ``[stamp,
    PreparedModel]`` oldest first, ``due`` the first one's stamp; ``gate`` the stamp from
    which :meth:`CompensatorCore.process` calls :meth:`CompensatorCore._learning` (-inf with
    a learner: every sample joins the block); ``installs`` the learned models installed.
    """

    learner: Any = None
    extend: Callable[[tuple], None] | None = None
    block: array = field(default_factory=lambda: array('d'))
    block_extend: Callable[[tuple], None] | None = None
    period: float = math.inf
    next: float = math.inf
    queue: deque[tuple[float, PreparedModel]] = field(default_factory=deque)
    due: float = math.inf
    gate: float = math.inf
    installs: int = 0
    #: Samples in the last hand-off within a run of samples (not cut by a pause).
    block_n: int = 1


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
        self.reanchoring = Reanchoring(StillnessDetector(
            policy.still_window, policy.still_gyro_std, policy.still_max_rate,
            policy.still_accel_std, window_max=policy.still_window_max,
            tolerance=policy.reanchor_tolerance))
        self.learning = LearningGate()
        #: The gyro is declared thermally corrected upstream and is to pass through (never
        #: corrected twice): :meth:`process`'s one check for it.
        self.upstream_pass = bool(policy.upstream_correction) and (
            policy.upstream_policy == 'passthrough')
        #: :meth:`process` uses the sample's specific force: the model has an accelerometer
        #: part, or re-anchoring waits for a still window (the node reads it per message).
        self.needs_accel = False
        self._update_needs()
        if model is not None:
            self.set_model(model)

    model = property(attrgetter('slot.model'), doc='The model in use (None: passing through).')
    model_id = property(attrgetter('slot.model_id'), doc="The model's content id.")
    anchor = property(attrgetter('reanchoring.anchor'),
                      doc="The current session's re-anchoring shift, or None.")
    flag_counts = property(attrgetter('tally.flags'), doc='Samples per flag bit.')
    accel_counts = property(attrgetter('tally.accel'),
                            doc='Accelerometer samples compensated, passed through, missing.')
    errors = property(attrgetter('tally.errors'), doc='Samples whose compensation raised.')
    last_error = property(attrgetter('tally.last_error'), doc='The last of those errors.')
    motion_reports = property(attrgetter('tally.motion_reports'),
                              doc='Outside motion reports received.')
    last_t = property(attrgetter('stream.t'), doc='The last IMU stamp, s (None before any).')
    last_temp = property(attrgetter('stream.temp'),
                         doc='The temperature used for the last compensated sample, degC.')
    last_flags = property(attrgetter('stream.flags'), doc="The last sample's flags.")
    last_distance_c = property(attrgetter('stream.distance_c'),
                               doc="The last sample's distance from the model's range, degC.")
    accel_flags = property(attrgetter('stream.accel_flags'), doc=(
        "The last sample's accelerometer flags (``PASSTHROUGH`` with why; ``NO_ACCEL_DATA``: "
        'the sample had none); -1 before any.'))
    moving = property(attrgetter('stream.moving'),
                      doc='The latest outside motion report: None before any, else motion.')
    learned_installs = property(attrgetter('learning.installs'), doc=(
        'Learned models installed (on time or late: the learner counts the late ones).'))

    @property
    def counts(self) -> dict[str, int]:
        """Return the samples ``in``, ``out`` and ``compensated`` (the core's own dict)."""
        tally = self.tally
        counts = tally.counts
        counts['out'] = counts['compensated'] + tally.flags[PASSTHROUGH] + tally.errors
        return counts

    @property
    def session_note(self) -> str:
        """Return ``''`` in the first session, else which session it is and what started it."""
        a = self.reanchoring
        if a.session <= 1:
            return ''
        return f' (session {a.session} from t={a.session_t:.3f} s, after a {a.session_why})'

    @property
    def accel_on(self) -> bool:
        """Return whether the model has an accelerometer part (:meth:`process` corrects it)."""
        return self.slot.accel is not None

    def _update_needs(self) -> None:
        a = self.reanchoring
        a.waiting = bool(self.policy.reanchor_on_start and a.anchor is None and not a.learned)
        self.needs_accel = self.slot.accel is not None or a.waiting

    # -- learning ---------------------------------------------------------------------

    @property
    def learner(self):
        """Return the attached :class:`gyro_tdc.learn.learner.Learner`, or None."""
        return self.learning.learner

    @learner.setter
    def learner(self, learner) -> None:
        """Attach a learner: it sees every raw sample and thermometer reading (appends)."""
        gate = self.learning
        gate.learner = learner
        gate.extend = None
        gate.next = math.inf
        del gate.block[:]
        gate.block_extend = gate.block.extend
        if learner is not None:
            gate.extend = learner.buf.extend
            gate.period = 1.0 / learner.config.max_rate_hz
            gate.next = -math.inf
        gate.gate = self._gate()

    def learn_step(self) -> list:
        """
        Step the learner (off the message path: a timer) and schedule the models it swapped in.

        Each accepted candidate is made ready here (:func:`prepare`) and installed by
        :meth:`process` at the first message stamped at or after its effective stamp
        (:meth:`gyro_tdc.learn.learner.Learner.take_swaps`); later than that, at once (the
        learner counts it in ``late_swaps``).

        Returns
        -------
        list of (float or None, CompensationModel)
            The models scheduled (or installed) with their effective stamps, oldest first.

        """
        learner = self.learning.learner
        if learner is None:
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
        gate = self.learning
        last_t = self.stream.t
        if due is None or (last_t is not None and due <= last_t):
            gate.queue.clear()
            gate.due = math.inf
            gate.gate = self._gate()
            gate.installs += 1
            self.install(prepared, learned=True)
            return
        gate.queue.append((due, prepared))
        gate.due = gate.queue[0][0]
        gate.gate = self._gate()

    def cancel_scheduled(self) -> None:
        """Drop the learned models waiting for their stamp (a model_file or a reset came)."""
        gate = self.learning
        gate.queue.clear()
        gate.due = math.inf
        gate.gate = self._gate()

    def _gate(self) -> float:
        """Return the stamp from which :meth:`process` calls :meth:`_learning`."""
        gate = self.learning
        return -math.inf if gate.extend is not None else gate.due

    def _learning(self, t: float, wx: float, wy: float, wz: float,
                  accel: Sequence[float] | None) -> None:
        """
        Install a learned model that is due; add the sample to the learner's block.

        The learner is handed the mean of the samples since the last hand-off (stamp, rate,
        specific force) at most every ``period`` s of stamps (``max_rate_hz``), by stamp, so
        a replay at any speed hands the same means: at 1-2 kHz a mean of 10-20 samples (a
        tenth to a twentieth of the noise variance of one), slower streams sample by sample.
        A block is closed at a pause in the stamps longer than 1.5 periods (a burst ends, a
        gap), so no mean spans one. The per-sample work is one ``extend`` of the block.
        """
        gate = self.learning
        if t >= gate.due:
            queue = gate.queue
            prepared = None
            while queue and queue[0][0] <= t:
                prepared = queue.popleft()[1]
            gate.due = queue[0][0] if queue else math.inf
            gate.gate = self._gate()
            gate.installs += 1
            self.install(prepared, learned=True)
            if gate.extend is None:           # no learner: nothing to hand
                return
        if accel is None:                     # Learner.observe's layout
            sample = (t, wx, wy, wz, math.nan, math.nan, math.nan)
        else:
            ax, ay, az = accel
            sample = (t, wx, wy, wz, ax, ay, az)
        if t < gate.next:                     # no hand-off due yet, by stamp
            gate.block_extend(sample)
            return
        gate.next = t + 0.999 * gate.period
        block = gate.block
        last = self.stream.t
        if block and last is not None and t - last > 1.5 * gate.period:
            # A pause: the block before it goes alone; this sample starts the next.
            self._hand_off(block, gate.extend)
            gate.block_extend(sample)
        else:
            gate.block_extend(sample)
            gate.block_n = self._hand_off(block, gate.extend)

    @staticmethod
    def _hand_off(block: array, extend: Callable) -> int:
        """
        Hand the learner the mean of ``block``'s samples (NaN where one had none); empty it.

        Returns the number of samples it held.
        """
        n = len(block) // BLOCK_FIELDS
        if n == 1:
            extend(block)
        elif n:
            extend(tuple(sum(block[i::BLOCK_FIELDS]) / n for i in range(BLOCK_FIELDS)))
        del block[:]
        return n

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

        Parameters
        ----------
        model : CompensationModel or None
            The new model, or None to pass every sample through (``model_id`` keeps naming
            the last model installed).

        """
        if model is None:
            self.slot = ModelSlot(model_id=self.slot.model_id)
            self._update_needs()
            return
        self.install(prepare(model, self.policy, self.priming(model)))

    def install(self, prepared: PreparedModel, learned: bool = False) -> None:
        """
        Swap in a model made ready by :func:`prepare` (call it on the thread that compensates).

        The replay :func:`prepare` did over a :meth:`priming` copy is carried on over the
        thermometer samples recorded since, up to the last IMU stamp; a model with the same
        ``model_id`` as the current one keeps the start-up shift, any other clears it.

        A ``learned`` model (the attached learner's, :meth:`schedule`) carries an offset of
        its own: one taken from this session's still time (its ``created['offset_until']``
        at or after the session's first stamp) replaces the shift and ends the session's
        re-anchoring; one of an older session's (a new power cycle the learner has not seen
        still yet) after a learned model keeps the shift, or the re-anchoring under way (the
        shift is this session's offset against the older one, which both models share).

        Parameters
        ----------
        prepared : PreparedModel
            The model and its primed streaming state.
        learned : bool
            The model is the attached learner's.

        """
        if not prepared_for(prepared, self.policy):   # read before a policy change
            prepared = prepare(prepared.model, self.policy, prepared.priming)
        model, comp = prepared.model, prepared.comp
        stream = self.stream
        if timeless(model):               # no filter: nothing to replay
            if stream.t is not None and stream.temp is not None:
                advance(comp, stream.t, stream.temp)
        elif stream.first is not None and stream.t is not None:
            state = prepared.replay
            if (state is None or prepared.priming.first != stream.first
                    or prepared.priming.last_t is None or stream.t < prepared.priming.last_t):
                # The stream moved in a way the copy did not see: replay it all here.
                comp = StreamingCompensator(model, out_of_range=self.policy.out_of_range,
                                            max_extrapolation_c=self.policy.max_extrapolation_c)
                state = replay_from_first(comp, stream.first, stream.history, stream.t)
            else:
                tail = []
                for entry in reversed(stream.history):
                    if entry[0] <= state.t_seen:
                        break
                    tail.append(entry)
                state = replay(comp, reversed(tail), stream.t, state)
            if stream.t > state.t_prev:
                advance(comp, stream.t, state.temp_prev if stream.temp is None else stream.temp)
        old = self.slot
        anchoring = self.reanchoring
        same = old.model is not None and prepared.model_id == old.model_id
        learned = learned and self.learning.learner is not None
        older = learned and old.learned   # a learned model after a learned one
        if learned and self._session_offset(model):
            anchoring.anchor = None       # this session's offset: no shift, no re-anchoring
            anchoring.learned = True
        elif (same or older) and anchoring.anchor is not None:
            comp.shift_offset(np.asarray(anchoring.anchor.delta, dtype=np.float64))
        elif not same and not older:
            anchoring.anchor = None
            anchoring.learned = False
            anchoring.detector.reset(residual_var=self._reanchor_var(model) if learned
                                     else model.residual_var)
        self.slot = ModelSlot(model, prepared.model_id, comp, prepared.var, prepared.scale,
                              prepared.static, {}, self._accel_slot(model, comp, prepared.static),
                              learned)
        self._update_needs()

    def _session_offset(self, model: CompensationModel) -> bool:
        """Return whether a learned ``model``'s offset was taken in the current session."""
        until = model.created.get('offset_until')
        start = self.reanchoring.session_t
        return until is not None and start is not None and until >= start

    def set_policy(self, policy: Policy) -> None:
        """
        Swap in new policies between two messages (call it on the thread that compensates).

        :meth:`process` reads ``policy`` once per message; what was built from the old one is
        rebuilt here: the model in use is prepared again when a field of ``PREPARED_BY``
        changed (replayed over the stream so far; the same model keeps its start-up shift),
        and so are the learned models waiting for their stamp; while no start-up shift has
        been taken, the stillness detector is made anew when a re-anchoring threshold
        changed (its windows start over; the motion report in force carries over).

        Parameters
        ----------
        policy : Policy
            The new policies, checked (a :class:`Policy` checks itself when built).

        """
        old, self.policy = self.policy, policy
        self.upstream_pass = bool(policy.upstream_correction) and (
            policy.upstream_policy == 'passthrough')
        still = ('still_window', 'still_gyro_std', 'still_max_rate', 'still_accel_std',
                 'still_window_max', 'reanchor_tolerance')
        anchoring = self.reanchoring
        if anchoring.anchor is None and any(getattr(old, f) != getattr(policy, f)
                                            for f in still):
            detector = StillnessDetector(
                policy.still_window, policy.still_gyro_std, policy.still_max_rate,
                policy.still_accel_std, window_max=policy.still_window_max,
                tolerance=policy.reanchor_tolerance)
            detector.reset(residual_var=self._reanchor_var(self.slot.model))
            if self.stream.moving and self.stream.t is not None:
                detector.observe_motion(self.stream.t, True)
            anchoring.detector = detector
        if any(getattr(old, f) != getattr(policy, f) for f in PREPARED_BY):
            gate = self.learning
            gate.queue = deque((due, prepare(p.model, policy, p.priming))
                               for due, p in gate.queue)
            if self.slot.model is not None:
                self.install(prepare(self.slot.model, policy, self.priming(self.slot.model)),
                             learned=self.slot.learned)
        self._update_needs()

    def _accel_slot(self, model: CompensationModel, comp: StreamingCompensator,
                    static: bool) -> AccelSlot | None:
        """Return the accelerometer part's slot (None: the model has none)."""
        part = model.accel
        if part is None:
            return None
        p = self.policy
        resid = tuple(float(v) for v in np.asarray(part.residual_var, dtype=np.float64))
        var = {
            0: resid,
            STALE: tuple(v + p.stale_variance for v in resid),
            OUT_OF_RANGE: tuple(v + p.out_of_range_variance for v in resid),
            STALE | OUT_OF_RANGE: tuple(v + p.stale_variance + p.out_of_range_variance
                                        for v in resid),
        }
        return AccelSlot(comp.accel, var, static and set(part.features) <= STATIC_EFFECTS)

    # -- inputs -----------------------------------------------------------------------

    def add_temperature(self, t: float, temp_c: float) -> bool:
        """
        Record one thermometer sample.

        A reading that is not finite, outside the plausible range, jumping faster than the
        slew bound (:mod:`gyro_tdc.base.plausible`) or stamped further ahead of the last IMU
        stamp than ``temperature_timeout`` or ``MAX_TEMP_LEAD_S``, whichever is longer, is
        counted and dropped: it reaches neither the hold, nor a filter, nor the thermometer
        history, nor the learner.

        Returns
        -------
        bool
            False when the sample was rejected.

        """
        last_t = self.stream.t
        if not self.temps.add(t, temp_c, math.inf if last_t is None else last_t + max(
                self.policy.temperature_timeout, MAX_TEMP_LEAD_S)):
            return False
        learner = self.learning.learner
        if learner is not None:
            learner.add_temperature(t, temp_c)
        history = self.stream.history
        if not history or t >= history[-1][0] + self.HISTORY_SPACING_S:
            history.append((t, temp_c))
        slot = self.slot
        if slot.comp is not None and slot.static and temp_c not in slot.cache:
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

        While a report says motion, no sample is still, for re-anchoring and the learner
        alike. Only changes are passed on (a report holds until the next one).
        """
        self.tally.motion_reports += 1
        stream = self.stream
        if moving == stream.moving:
            return
        stream.moving = moving
        self.reanchoring.detector.observe_motion(t, moving)
        learner = self.learning.learner
        if learner is not None:
            learner.observe_motion(t, moving)

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
        tally = self.tally
        tally.counts['in'] += 1
        stream = self.stream
        last = stream.t
        if last is None:                # the first session starts
            self.reanchoring.session_t, self.reanchoring.session_k = t, tally.counts['in']
        else:
            d = t - last                # NaN fails the compares
            if d > SESSION_GAP_S or d < -RESTART_BACK_S:
                self._session_break(t, d)
        if t >= self.learning.gate:    # learning: a sample to hand over, or a model due
            self._learning(t, wx, wy, wz, accel)
        if self.upstream_pass:         # the flight controller corrected it: never twice
            return self._pass(t, wx, wy, wz, UPSTREAM, accel)
        slot = self.slot
        comp = slot.comp
        if comp is None:
            return self._pass(t, wx, wy, wz, NO_MODEL)
        m = _MAX_RATE                   # NaN fails the compares
        if not (abs(wx) <= m and abs(wy) <= m and abs(wz) <= m and math.isfinite(t)):
            finite = (math.isfinite(wx) and math.isfinite(wy) and math.isfinite(wz)
                      and math.isfinite(t))
            return self._pass(t, wx, wy, wz, IMPLAUSIBLE_INPUT if finite else NON_FINITE, accel)
        held = self.temps.at(t)
        if held is None:
            return self._pass(t, wx, wy, wz, NO_TEMPERATURE, accel)
        temp, t_temp = held
        policy = self.policy
        flags = 0
        if t - t_temp > policy.temperature_timeout:
            if policy.stale_policy == 'passthrough':
                return self._pass(t, wx, wy, wz, STALE, accel)
            flags = STALE
        if stream.first is None:
            stream.first = (t, temp)
        if slot.static:
            # Static features: the drift, and the variance to add, only change when the
            # temperature does.
            e = slot.cache.get(temp) or self._refresh(t, temp)
            ox, oy, oz = (wx - e.bx) / e.dx, (wy - e.by) / e.dy, (wz - e.bz) / e.dz
            # The output check (the entry's variances were checked when it was made): finite
            # and corrected by a plausible drift on every axis (NaN fails the compares). A
            # safe entry (the usual case) cannot fail it for an input that passed its check.
            m = _MAX_DRIFT
            if not (e.safe or (abs(ox - wx) <= m and abs(oy - wy) <= m and abs(oz - wz) <= m)):
                return self._pass(t, wx, wy, wz, IMPLAUSIBLE_OUTPUT, accel)
            var = e.var_stale if flags else e.var
            flags |= e.oor
            dist = e.distance_c
        else:
            out = comp.step(t, temp, (wx, wy, wz))
            dist = comp.range_distance_c
            if comp.in_range:
                var = slot.var[flags]
            else:
                flags |= OUT_OF_RANGE
                more = variance_growth(policy.out_of_range_variance, dist,
                                       policy.out_of_range)
                var = slot.var[flags]
                if more:       # linear: the added variance grows with the distance
                    var = (var[0] + more, var[1] + more, var[2] + more)
            ox, oy, oz = out.tolist()
            m = _MAX_DRIFT
            if not (abs(ox - wx) <= m and abs(oy - wy) <= m and abs(oz - wz) <= m
                    and math.isfinite(var[0] + var[1] + var[2])):     # the output check
                return self._pass(t, wx, wy, wz, IMPLAUSIBLE_OUTPUT, accel)
        if slot.accel is None:
            aout = avar = None
        else:
            aout, avar = self._accel(slot.accel, t, temp, accel, flags & STALE)
        stream.t = t
        stream.temp = temp
        stream.flags = flags
        stream.distance_c = dist
        tally.counts['compensated'] += 1
        if flags:
            fc = tally.flags
            if flags & STALE:
                fc[STALE] += 1
            if flags & OUT_OF_RANGE:
                fc[OUT_OF_RANGE] += 1
                # With a learner, a new power cycle is re-anchored out of range too: the
                # shift holds only until the learner gives the cycle its own offset.
                if (flags == OUT_OF_RANGE and self.reanchoring.waiting
                        and self.learning.extend is not None):
                    self._still(t, (wx, wy, wz), (ox, oy, oz), accel, temp)
        elif policy.reanchor_on_start and self.reanchoring.waiting:
            self._still(t, (wx, wy, wz), (ox, oy, oz), accel, temp)
        return ox, oy, oz, var, flags, aout, avar

    def _refresh(self, t: float, temp: float) -> DriftEntry:
        """
        Evaluate the drift of a static model at one temperature and keep it.

        The thermometer callback calls this as each reading arrives, so the IMU callback only
        looks the result up.
        """
        slot = self.slot
        comp = slot.comp
        bx, by, bz = comp.drift(t, temp).tolist()
        dx, dy, dz = (1.0 + comp.dt_c * slot.scale).tolist()
        dist = comp.range_distance_c
        more = (variance_growth(self.policy.out_of_range_variance, dist,
                                self.policy.out_of_range) if dist else 0.0)
        oor = 0 if comp.in_range else OUT_OF_RANGE
        var, var_stale = slot.var[oor], slot.var[oor | STALE]
        if more:           # linear: the added variance grows with the distance
            var = (var[0] + more, var[1] + more, var[2] + more)
            var_stale = (var_stale[0] + more, var_stale[1] + more, var_stale[2] + more)
        if not math.isfinite(var[0] + var[1] + var[2] + var_stale[0] + var_stale[1]
                             + var_stale[2]):
            bx = math.nan              # process's output check refuses the entry
        entry = DriftEntry(bx, by, bz, dx, dy, dz, oor, dist, var, var_stale,
                           correction_is_safe((bx, by, bz), (dx, dy, dz)))
        acc = slot.accel
        if len(slot.cache) >= 64:
            slot.cache.clear()
            if acc is not None:
                acc.cache.clear()
        slot.cache[temp] = entry
        if acc is not None and acc.static:
            self._arefresh(acc, t, temp)
        return entry

    # -- the accelerometer part -------------------------------------------------------

    def _arefresh(self, acc: AccelSlot, t: float, temp: float) -> AccelEntry:
        """Evaluate a static accelerometer part at one temperature and keep it."""
        acomp = acc.comp
        bx, by, bz = acomp.drift(t, temp).tolist()
        dist = acomp.range_distance_c
        entry = AccelEntry(bx, by, bz, 0 if acomp.in_range else OUT_OF_RANGE,
                           variance_growth(self.policy.out_of_range_variance, dist,
                                           self.policy.out_of_range) if dist else 0.0)
        acc.cache[temp] = entry
        return entry

    def _accel(self, acc: AccelSlot, t: float, temp: float, accel: Sequence[float] | None,
               flags: int) -> tuple[Vec3 | None, Vec3 | None]:
        """Correct one sample's specific force (``flags``: ``STALE`` or 0); return it, var."""
        if accel is None:
            self.stream.accel_flags = NO_ACCEL_DATA
            self.tally.accel['missing'] += 1
            return None, None
        ax, ay, az = accel
        if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)):
            return self._accel_pass(accel, NON_FINITE)
        if acc.static:
            e = acc.cache.get(temp) or self._arefresh(acc, t, temp)
            out = (ax - e.bx, ay - e.by, az - e.bz)
            flags |= e.oor
            more = e.growth
        else:
            acomp = acc.comp           # no scale term: step() is a - b (saves numpy ops)
            bx, by, bz = acomp.drift(t, temp).tolist()
            out = (ax - bx, ay - by, az - bz)
            if acomp.in_range:
                more = 0.0
            else:
                flags |= OUT_OF_RANGE
                more = variance_growth(self.policy.out_of_range_variance,
                                       acomp.range_distance_c, self.policy.out_of_range)
        var = acc.var[flags]
        var = (var[0] + more, var[1] + more, var[2] + more) if more else var
        if not (abs(out[0] - ax) <= _MAX_ACCEL_DRIFT and abs(out[1] - ay) <= _MAX_ACCEL_DRIFT
                and abs(out[2] - az) <= _MAX_ACCEL_DRIFT
                and math.isfinite(var[0] + var[1] + var[2])):
            return self._accel_pass(accel, IMPLAUSIBLE_OUTPUT)
        self.stream.accel_flags = flags
        self.tally.accel['compensated'] += 1
        return out, var

    def _accel_pass(self, accel: Sequence[float] | None, why: int
                    ) -> tuple[None, Vec3 | None]:
        """Leave one sample's specific force as it is, widened by ``passthrough_variance``."""
        if accel is None:
            self.stream.accel_flags = NO_ACCEL_DATA
            self.tally.accel['missing'] += 1
            return None, None
        var = self.policy.passthrough_variance
        self.stream.accel_flags = why | PASSTHROUGH
        self.tally.accel['passed through'] += 1
        return None, (var, var, var)

    def _pass(self, t: float, wx: float, wy: float, wz: float, why: int,
              accel: Sequence[float] | None = None) -> Output:
        flags = why | PASSTHROUGH
        aout = avar = None
        if self.slot.accel is not None:
            aout, avar = self._accel_pass(accel, why)
        tally = self.tally
        tally.flags[why] += 1
        tally.flags[PASSTHROUGH] += 1
        stream = self.stream
        stream.flags = flags
        if math.isfinite(t):
            stream.t = t
        var = self.policy.passthrough_variance
        return wx, wy, wz, (var, var, var), flags, aout, avar

    def fail(self, exc: Exception) -> Vec3:
        """Count a sample whose compensation raised ``exc`` (sent raw); return its variance."""
        tally = self.tally
        tally.errors += 1
        tally.last_error = f'{type(exc).__name__}: {exc}'
        var = self.policy.passthrough_variance
        return var, var, var

    def _still(self, t: float, raw: Vec3, out: Vec3, accel: Sequence[float] | None,
               temp: float) -> None:
        anchoring = self.reanchoring
        found = anchoring.detector.update(t, raw, out, accel, temp)
        if found is None:
            return
        # The compensated rate is divided by 1 + s dT: the drift shift is the mean times it.
        slot = self.slot
        if slot.static:
            e = slot.cache[temp]
            den = np.asarray((e.dx, e.dy, e.dz))
        else:
            den = 1.0 + slot.comp.dt_c * slot.scale
        # The axes the model's held-out record does not re-anchor (gyro_tdc.model.no_harm).
        delta = gated_shift(slot.model, np.asarray(found.delta) * den)
        slot.comp.shift_offset(delta)
        slot.cache.clear()
        if slot.accel is not None:
            slot.accel.cache.clear()
        anchoring.anchor = replace(found, delta=tuple(float(v) for v in delta),
                                   se=tuple(float(v) for v in np.asarray(found.se) * np.abs(den)))
        self._update_needs()

    def _session_break(self, t: float, d: float) -> None:
        """
        Start a new session at stamp ``t`` when the step ``d`` from the last one is a break.

        A break is what cuts a dataset's sessions, the shared rule
        (:class:`gyro_tdc.signal.SessionRule`, shown the steps over ``SESSION_GAP_S``): a
        pause longer than ``SESSION_GAP_S``, than ``SESSION_GAP_PERIODS`` sample periods (the
        session's mean step, its pauses over ``SESSION_GAP_S`` left out) and, once the stream
        pauses regularly, than three times its median pause; or stamps
        stepping back by more than ``RESTART_BACK_S`` (the device's clock restarted). The
        IMU was power-cycled, with a new turn-on offset: with ``reanchor_on_start`` the old
        shift is dropped and the re-anchoring starts over (a still window, then a new shift).
        A power cycle restarts the model's time terms too, whatever the policy: the thermal
        state starts again, settled, at the next temperature, the warm-up and the other
        feature filters at the next sample (:meth:`StreamingCompensator.reset`); the
        thermometer history a new model is replayed over starts at the break.
        """
        a = self.reanchoring
        k = self.tally.counts['in']
        period = 0.0
        if d > 0:
            steps = k - a.session_k - 1 - a.pauses
            period = ((self.stream.t - a.session_t - a.paused_s) / steps
                      if steps > 0 and a.session_t is not None else 0.0)
        why = a.rule.judge(d, period)
        if not why:
            a.pauses += 1
            a.paused_s += d
            return
        a.session += 1
        a.session_t, a.session_k, a.session_why = t, k, why
        a.pauses, a.paused_s = 0, 0.0
        a.learned = False
        slot = self.slot
        stream = self.stream
        stream.first = None               # set again at the session's first compensated sample
        stream.history.clear()            # the new session's: from the reading held at t
        if d < 0:
            # The clock restarted: readings stamped beyond what the new session may send
            # (its first stamp plus the stale timeout) are the old session's; held, they
            # would be its ``latest`` (a negative temperature age) and could be looked up.
            self.temps.drop_after(t + self.policy.temperature_timeout)
        held = self.temps.at(t)
        if held is not None and t - held[1] <= self.policy.temperature_timeout and (
                d < 0 or held[1] > stream.t):
            stream.history.append((held[1], held[0]))
        if slot.comp is not None:
            slot.comp.reset()             # warm-up and thermal state from the power-on
        if not self.policy.reanchor_on_start:
            return
        if a.anchor is not None and slot.comp is not None:
            slot.comp.shift_offset(-np.asarray(a.anchor.delta, dtype=np.float64))
            slot.cache.clear()
            if slot.accel is not None:
                slot.accel.cache.clear()
        a.anchor = None
        a.detector.reset(residual_var=self._reanchor_var(slot.model))
        if self.learning.extend is not None:
            # The break is a pause the detector was not shown (a learned model held this
            # session's offset, nothing was given to it): a window may end early, within a
            # burst (runtime.reanchor).
            a.detector.paused = True
        self._update_needs()

    def _reanchor_var(self, model: CompensationModel | None):
        """
        Return the residual variance re-anchoring on ``model`` is reset with, (rad/s)^2.

        The model's (None without one); for a learned model with a learner attached, at
        least the raw rate's noise variance per sample: the learner's noise floor of the
        means it is handed (``created['gyro_floor']``) times the samples of the last one
        handed within a run. A learned model's residual variance is that of its points'
        means (of whole windows), far below one sample's scatter: as the still threshold's
        prior and the tolerance's scale it would refuse every window or never be met.
        """
        if model is None:
            return None
        var = np.asarray(model.residual_var, dtype=np.float64)
        floor = model.created.get('gyro_floor') if self.learning.extend is not None else None
        if floor is None:
            return var
        floor = np.asarray(floor, dtype=np.float64)
        if floor.shape != (3,) or not np.isfinite(floor).all():
            return var
        return np.maximum(var, floor ** 2 * max(1, self.learning.block_n))

    @property
    def still_windows_rejected(self) -> int:
        """Return how many windows were judged not still while waiting to re-anchor."""
        return self.reanchoring.detector.windows_rejected

    @property
    def thermal_progress(self) -> float | None:
        """Return the time since the first sample in the model's state tau (None: no lag)."""
        comp = self.slot.comp
        return None if comp is None else comp.thermal_progress

    def temperature_age(self) -> float | None:
        """Return the last IMU stamp minus the newest thermometer stamp, s (None if unknown)."""
        latest = self.temps.latest
        if latest is None or self.stream.t is None:
            return None
        return self.stream.t - latest[1]
