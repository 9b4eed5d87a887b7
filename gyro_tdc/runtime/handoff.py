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
The learning hand-off: the message path's samples to the learner, its models back (pure).

:class:`LearningGate` hands the attached learner the mean of the samples since the last
hand-off and keeps the learned models waiting for their effective stamp.
"""

from __future__ import annotations

from array import array
from collections import deque
from dataclasses import dataclass, field
import math
from typing import Any, Callable, Sequence

from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime.priming import PreparedModel
import numpy as np

__all__ = ['BLOCK_FIELDS', 'hand_off', 'LearningGate', 'NO_ACCEL', 'power_up', 'POWER_UP_KEY']

#: Floats per sample handed to the learner: stamp, rate (3), specific force (3; NaN: none) ...
BLOCK_FIELDS = 7
#: ... the force of a sample without one.
NO_ACCEL = (math.nan, math.nan, math.nan)
#: A learned model's ``created`` key: the intercept (rad/s, 3 floats) its learner gives a new
#: power cycle whose offset is not known yet.
POWER_UP_KEY = 'power_up_intercept'


def power_up(model: CompensationModel) -> CompensationModel:
    """Return ``model`` for a new power cycle: its :data:`POWER_UP_KEY` intercept, no offset."""
    up = model.created.get(POWER_UP_KEY, model.intercept)
    return model.replace(intercept=np.asarray(up, dtype=np.float64).reshape(3),
                         created={**model.created, 'offset_until': None})


def hand_off(block: array, extend: Callable) -> int:
    """
    Hand the learner the mean of ``block``'s samples (NaN where one had none); empty it.

    Returns the number of samples it held.
    """
    if (n := len(block) // BLOCK_FIELDS) == 1:
        extend(block)
    elif n:
        extend(tuple(sum(block[i::BLOCK_FIELDS]) / n for i in range(BLOCK_FIELDS)))
    del block[:]
    return n


@dataclass(slots=True)
class LearningGate:
    """
    The attached learner and the message path's one compare for all learning work.

    ``extend`` is the learner's buffer's extend (one call a hand-off), ``block`` the samples
    since the last hand-off (:data:`BLOCK_FIELDS` floats each), ``next`` the stamp of the
    next hand-off (every ``period`` s: the block's mean, :meth:`add`); ``queue`` the learned
    models waiting for their effective stamp, ``[stamp, PreparedModel]`` oldest first,
    ``due`` the first one's stamp; ``gate`` the stamp from which the message path calls in
    (-inf with a learner: every sample joins the block); ``installs`` the learned models
    installed.
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

    def attach(self, learner: Any) -> None:
        """Attach ``learner`` (None: detach): it is handed the samples from now on."""
        self.learner, self.extend, self.next = learner, None, math.inf
        del self.block[:]
        self.block_extend = self.block.extend
        if learner is not None:
            self.extend, self.next = learner.buf.extend, -math.inf
            self.period = 1.0 / learner.config.max_rate_hz
        self.reopen()

    def reopen(self) -> None:
        """Set the stamp from which the message path calls :meth:`add` or :meth:`take_due`."""
        self.due = self.queue[0][0] if self.queue else math.inf
        self.gate = -math.inf if self.extend is not None else self.due

    def enqueue(self, due: float, prepared: PreparedModel) -> None:
        """Keep a learned model until the first sample stamped at or after ``due`` (s)."""
        self.queue.append((due, prepared))
        self.reopen()

    def cancel(self) -> None:
        """Drop the learned models waiting for their stamp."""
        self.queue.clear()
        self.reopen()

    def restart_clock(self) -> PreparedModel | None:
        """
        Close the old clock's hand-off and queue: the stamps stepped back (the IMU restarted).

        The block is handed over alone and the next sample is handed over at once (a hand-off
        stamp of the old clock would hold every sample back until the new stamps pass it);
        the newest learned model waiting for an old-clock stamp is returned, due now (None:
        none was waiting).
        """
        if self.extend is not None:
            hand_off(self.block, self.extend)
            self.next = -math.inf
        prepared = self.queue[-1][1] if self.queue else None
        self.cancel()
        return prepared

    def take_due(self, t: float) -> PreparedModel:
        """Return the newest learned model due at stamp ``t`` (s); drop the older ones."""
        prepared = None
        while self.queue and self.queue[0][0] <= t:
            prepared = self.queue.popleft()[1]
        self.reopen()
        self.installs += 1
        return prepared

    def add(self, t: float, wx: float, wy: float, wz: float, accel: Sequence[float] | None,
            last: float | None) -> None:
        """
        Add one sample (stamp ``t``, the last one's ``last``) to the learner's block.

        The learner is handed the mean of the samples since the last hand-off (stamp, rate,
        specific force) at most every ``period`` s of stamps (``max_rate_hz``), by stamp, so
        a replay at any speed hands the same means: at 1-2 kHz a mean of 10-20 samples (a
        tenth to a twentieth of the noise variance of one), slower streams sample by sample.
        A block is closed at a pause in the stamps longer than 1.5 periods (a burst ends, a
        gap), so no mean spans one. The per-sample work is one ``extend`` of the block.
        """
        sample = (t, wx, wy, wz, *(NO_ACCEL if accel is None else accel))
        if t >= self.next:                    # a hand-off due, by stamp
            self.next = t + 0.999 * self.period
            if self.block and last is not None and t - last > 1.5 * self.period:
                # A pause: the block before it goes alone; this sample starts the next.
                hand_off(self.block, self.extend)
            else:
                self.block_extend(sample)
                self.block_n = hand_off(self.block, self.extend)
                return
        self.block_extend(sample)
