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
A model made ready to install off the compensating thread: its feature filters primed (pure).

:func:`prepare` runs in a worker, :func:`catch_up` carries it on at install (see
doc/internals/runtime.md).
"""

from __future__ import annotations

from itertools import takewhile
import math
from typing import Iterable, NamedTuple

from gyro_tdc.model import CompensationModel, STATIC_EFFECTS, StreamingCompensator
from gyro_tdc.runtime.blockstats import Vec3
from gyro_tdc.runtime.drift import timeless, variance_table
from gyro_tdc.runtime.policy import Policy
import numpy as np

__all__ = ['PREPARED_BY', 'PreparedModel', 'Priming', 'Replay', 'advance', 'catch_up',
           'prepare', 'prepared_for', 'replay', 'replay_from_first']

#: The Policy fields :func:`prepare` builds a model's compensator and variance tables from.
PREPARED_BY = ('out_of_range', 'max_extrapolation_c', 'stale_variance', 'out_of_range_variance')


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
    #: The policy it was prepared with (:data:`PREPARED_BY`: what of it went into the tables).
    policy: Policy | None = None


def advance(comp: StreamingCompensator, t: float, temp: float) -> None:
    """Advance ``comp``'s filters (and its accelerometer part's) to ``t``."""
    comp.drift(t, temp)
    if comp.accel is not None:
        comp.accel.drift(t, temp)


def replay(comp: StreamingCompensator, history: Iterable[tuple[float, float]], until: float,
           state: Replay) -> Replay:
    """Advance ``comp`` over thermometer samples later than ``state.t_seen`` up to ``until``."""
    t_prev, temp_prev, t_seen = state
    for t_k, temp_k in history:
        if t_k <= t_seen:
            continue
        if t_k > until:
            break
        if t_k > t_prev:
            advance(comp, t_k, temp_prev)
            t_prev = t_k
        temp_prev, t_seen = temp_k, t_k
    return Replay(t_prev, temp_prev, t_seen)


def replay_from_first(model: CompensationModel, policy: Policy, priming: Priming
                      ) -> tuple[StreamingCompensator, Replay | None]:
    """
    Return a new compensator of ``model``, started at ``priming.first`` and replayed on.

    It is replayed over ``priming.history`` up to ``priming.last_t``; without a first
    compensated sample (or a last stamp) nothing is replayed.
    """
    comp = StreamingCompensator(model, out_of_range=policy.out_of_range,
                                max_extrapolation_c=policy.max_extrapolation_c)
    first, history, until, _ = priming
    if first is None or until is None:
        return comp, None
    advance(comp, *first)
    return comp, replay(comp, history, until, Replay(first[0], first[1], -math.inf))


def prepare(model: CompensationModel, policy: Policy, priming: Priming) -> PreparedModel:
    """
    Make ``model`` ready to install, off the compensating thread.

    Builds its streaming compensator and replays the feature filters over ``priming`` (from
    :meth:`CompensatorCore.priming`), so a model with ``warmup`` or ``lag`` features carries
    on rather than restarting; works out its variance table and content id. Touches nothing
    shared; :meth:`CompensatorCore.install` finishes the replay and swaps it in.
    """
    comp, state = replay_from_first(model, policy, priming)
    return PreparedModel(model, model.model_id, comp, variance_table(model.residual_var, policy),
                         np.asarray(model.scale, dtype=np.float64),
                         set(model.features) <= STATIC_EFFECTS, priming, state, policy)


def prepared_for(prepared: PreparedModel, policy: Policy) -> bool:
    """Return whether ``prepared`` was made with what ``policy`` says of :data:`PREPARED_BY`."""
    made = prepared.policy
    return made is None or all(getattr(made, f) == getattr(policy, f) for f in PREPARED_BY)


def catch_up(prepared: PreparedModel, priming: Priming, policy: Policy) -> StreamingCompensator:
    """
    Carry ``prepared``'s replay on to the stream's last IMU stamp; return its compensator.

    ``priming`` is where the stream is now (the history in full). The replay :func:`prepare`
    did is carried on over the thermometer samples recorded since; when the stream moved in a
    way its copy did not see (a new session, stamps back), it is replayed from the first
    compensated sample here. A :func:`timeless` model is only advanced to the last stamp.
    """
    model, comp = prepared.model, prepared.comp
    first, history, last_t, last_temp = priming
    if timeless(model):               # no filter: nothing to replay
        if last_t is not None and last_temp is not None:
            advance(comp, last_t, last_temp)
        return comp
    if first is None or last_t is None:
        return comp
    state = prepared.replay
    if (state is None or prepared.priming.first != first
            or prepared.priming.last_t is None or last_t < prepared.priming.last_t):
        comp, state = replay_from_first(model, policy, priming)
    else:
        # The samples recorded since, from the newest back.
        tail = list(takewhile(lambda entry: entry[0] > state.t_seen, reversed(history)))
        state = replay(comp, reversed(tail), last_t, state)
    if last_t > state.t_prev:
        advance(comp, last_t, state.temp_prev if last_temp is None else last_temp)
    return comp
