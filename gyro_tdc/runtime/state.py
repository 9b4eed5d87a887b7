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
The compensator core's state groups: its counters, where the streams are, the re-anchoring.

Each group owns its state and the step that changes it at a power cycle
(:meth:`StreamState.restart`, :meth:`Reanchoring.restart`); :func:`reanchor_var` is the
residual variance re-anchoring starts from.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field, replace

from gyro_tdc.model import CompensationModel, StreamingCompensator
from gyro_tdc.runtime.blockstats import Anchor
from gyro_tdc.runtime.drift import ModelSlot
from gyro_tdc.runtime.flags import FLAG_NAMES
from gyro_tdc.runtime.handoff import LearningGate
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.runtime.reanchor import gated_shift, PROVISIONAL, StillnessDetector
from gyro_tdc.signal import SessionTracker, TemperatureHold
import numpy as np
from numpy.typing import NDArray

__all__ = ['detector_for', 'Reanchoring', 'reanchor_var', 'STILL_FIELDS', 'StreamState', 'Tally']

#: The Policy fields the stillness detector is built from: its parameter of each.
STILL_FIELDS = {'still_window': 'window', 'still_gyro_std': 'gyro_std',
                'still_max_rate': 'max_rate', 'still_accel_std': 'accel_std',
                'still_window_max': 'window_max', 'reanchor_tolerance': 'tolerance'}


def detector_for(policy: Policy) -> StillnessDetector:
    """Return a stillness detector with ``policy``'s re-anchoring thresholds."""
    return StillnessDetector(**{arg: getattr(policy, f) for f, arg in STILL_FIELDS.items()})


@dataclass(slots=True)
class Tally:
    """
    What the core counted (what /diagnostics shows).

    ``counts``: ``in``, ``out`` and ``compensated`` samples; ``flags``: samples per flag bit;
    ``accel``: accelerometer samples ``compensated``, ``passed through`` and ``missing``.
    Every sample goes out once, compensated, passed through or raw after an error, so ``out``
    is not counted per sample: :attr:`CompensatorCore.counts` works it out when read.
    """

    counts: dict[str, int] = field(default_factory=lambda: {'in': 0, 'out': 0, 'compensated': 0})
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

    def restart(self, t: float, d: float, temps: TemperatureHold, timeout: float) -> None:
        """
        Start the streams over at a power cycle at stamp ``t`` after a step of ``d`` s.

        The thermometer history a new model is replayed over starts at the break, from the
        reading held at ``t`` (not older than ``timeout``). A clock that restarted
        (``d`` < 0) leaves readings stamped beyond what the new session may send (``t`` plus
        ``timeout``): they are the old session's and are dropped from ``temps``.
        """
        self.first = None                 # set again at the session's first compensated sample
        self.history.clear()
        if d < 0:
            temps.drop_after(t + timeout)
        held = temps.at(t)
        if held is not None and t - held[1] <= timeout and (d < 0 or held[1] > self.t):
            self.history.append((held[1], held[0]))


@dataclass(slots=True)
class Reanchoring:
    """
    The re-anchoring: the stillness detector, the shift it found (or None), the session.

    ``sessions`` keeps the IMU's power cycles (``session``, from 1, began at ``session_t``;
    shown the pauses and steps back the learner is shown). ``learned``: a learned model
    carrying this session's offset is installed (taken from its own still time), so
    re-anchoring is done for the session without a shift; ``waiting`` that it still waits
    for a still window (:meth:`CompensatorCore._update_needs`). Until the anchor, ``anchor``
    may be the still run's shift so far (reason :data:`~gyro_tdc.runtime.reanchor.PROVISIONAL`,
    the detector's ``provisional``); ``shown`` is what it moved the output by.
    """

    detector: StillnessDetector
    anchor: Anchor | None = None
    learned: bool = False
    waiting: bool = False
    #: The IMU's sessions by the shared rule (:class:`gyro_tdc.signal.SessionTracker`).
    sessions: SessionTracker = field(default_factory=lambda: SessionTracker(first=1))
    shown: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: The detector's provisional shift last taken (the core takes each new one).
    seen: Anchor | None = None

    @property
    def settled(self) -> bool:
        """Return whether this session's shift is taken (not a provisional one, not none)."""
        return self.anchor is not None and self.anchor.reason != PROVISIONAL

    def on_install(self, comp: StreamingCompensator, model: CompensationModel, same: bool,
                   learned: bool, older: bool, residual_var: NDArray[np.float64], *,
                   older_clock: bool = False) -> None:
        """
        Carry the re-anchoring over a model swap (``comp``: the new model's compensator).

        A model with the ``same`` id keeps the start-up shift, any other clears it (the
        detector reset with ``residual_var``). A ``learned`` model carries an offset of its
        own: one taken from this session's still time (``created['offset_until']`` at or after
        its first stamp) replaces the shift and ends the session's re-anchoring; one of an
        older session after a learned model (``older``) keeps the shift, or the re-anchoring
        under way (the shift is this session's offset against the older one). One learned
        before the stamps stepped back (``older_clock``) is of an older session, whatever its
        stamps.
        """
        until = None if older_clock else model.created.get('offset_until')
        start = self.sessions.t0
        own = learned and until is not None and start is not None and until >= start
        if not own and (same or older):   # the shift (or the re-anchoring under way) is kept
            if self.anchor is not None:
                comp.shift_offset(np.asarray(self.anchor.delta, dtype=np.float64))
            return
        # This session's offset (no shift, re-anchoring done), or another model: start over.
        self.anchor, self.shown, self.learned = None, (0.0, 0.0, 0.0), own
        if not own:
            self.detector.reset(residual_var=residual_var)

    def rethreshold(self, old: Policy, policy: Policy, residual_var: NDArray[np.float64] | None,
                    moving_t: float | None) -> None:
        """
        Make the detector anew when a threshold changed from ``old`` and no shift was taken.

        Its windows start over; the motion report in force (``moving_t``: the last stamp
        while a report says motion, else None) carries over.
        """
        if self.settled or all(getattr(old, f) == getattr(policy, f) for f in STILL_FIELDS):
            return
        detector = detector_for(policy)
        detector.reset(residual_var=residual_var)
        if moving_t is not None:
            detector.observe_motion(moving_t, True)
        self.detector = detector

    def take(self, found: Anchor | None, slot: ModelSlot, temp: float) -> None:
        """
        Shift ``slot``'s model offset by the shift ``found`` at ``temp`` (None: none); keep it.

        With the default averaging, an axis whose shift is within the model's gate
        (:func:`gated_shift`: no evidence of a turn-on offset, as its training measured
        anchors of that averaging) is not shifted.
        """
        # The compensated rate is divided by 1 + s dT: the drift shift is the mean times it.
        # Read before undo: a static model's divisor comes from the drift cache undo clears.
        den = None if found is None else slot.scale_at(temp)
        self.undo(slot)                   # a provisional shift is replaced
        if found is None:
            return
        delta = np.asarray(found.delta) * den
        if self.detector.default_rule:
            delta = gated_shift(slot.model, delta)
        slot.comp.shift_offset(delta)
        slot.clear()
        self.anchor = replace(found, delta=tuple(float(v) for v in delta),
                              se=tuple(float(v) for v in np.asarray(found.se) * np.abs(den)))
        self.shown = tuple(float(v) for v in delta / den)

    def undo(self, slot: ModelSlot) -> None:
        """Undo ``slot``'s shift (none: nothing to do)."""
        if self.anchor is not None and slot.comp is not None:
            slot.comp.shift_offset(-np.asarray(self.anchor.delta, dtype=np.float64))
            slot.clear()
        self.anchor, self.shown = None, (0.0, 0.0, 0.0)

    def restart(self, slot: ModelSlot, residual_var: NDArray[np.float64] | None,
                paused: bool) -> None:
        """
        Start re-anchoring over (a new power cycle): ``slot``'s shift undone, the detector reset.

        ``paused``: the break is a pause the detector was not shown (a learner is attached),
        so a window may end early, within a burst.
        """
        self.undo(slot)
        self.detector.reset(residual_var=residual_var)
        self.detector.paused |= paused


def reanchor_var(model: CompensationModel | None, gate: LearningGate):
    """
    Return the residual variance re-anchoring on ``model`` is reset with, (rad/s)^2.

    The model's (None without one); for a learned model with a learner attached to ``gate``
    (:class:`~gyro_tdc.runtime.handoff.LearningGate`), at least the raw rate's noise variance
    per sample: the learner's noise floor of the means it is handed (``created['gyro_floor']``)
    times the ``gate.block_n`` samples of the last one handed within a run. A learned model's
    residual variance is that of its points' means, far below one sample's scatter: as the
    still threshold's prior and the tolerance's scale it would refuse every window or never be
    met.
    """
    if model is None:
        return None
    var = np.asarray(model.residual_var, dtype=np.float64)
    # No learner, no floor, or not 3 finite numbers: the model's own.
    floor = np.asarray(model.created.get('gyro_floor') if gate.extend is not None else np.nan,
                       dtype=np.float64)
    if floor.shape != (3,) or not np.isfinite(floor).all():
        return var
    return np.maximum(var, floor ** 2 * max(1, gate.block_n))
