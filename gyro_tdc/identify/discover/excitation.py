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
What the data can excite, decided before any fit: spans, rates, directions, soaks.

:func:`excitation` names the candidates the runs cannot excite (with the experiment that
would) and notes what the data leave untestable; :func:`one_way` tells data that only heat
(or only cool), where ``lag`` and ``dTdt`` are aliases.
"""

from __future__ import annotations

from typing import Sequence

from gyro_tdc.identify.discover.data import BlockData
from gyro_tdc.identify.discover.results import Unidentifiable
from gyro_tdc.identify.fit import MIN_SPAN_C
from gyro_tdc.model import EFFECTS, REFERENCE_EFFECTS, STATIC_EFFECTS, TEMPERATURE_EFFECTS
import numpy as np
from numpy.typing import NDArray

__all__ = ['directions', 'excitation', 'moving_blocks', 'one_way']

#: Effects a temperature span excites (``scale`` needs rate-table steps too: its own test).
_SPAN = tuple(e for e in EFFECTS if e in TEMPERATURE_EFFECTS and e not in REFERENCE_EFFECTS)
#: Of those, the ones with time memory: excited by how the temperature changes.
_RATE = tuple(e for e in _SPAN if e not in STATIC_EFFECTS)
#: A soak (the temperature still) counts from this long, s (and three blocks).
_SOAK_S = 120.0


def moving_blocks(data: BlockData) -> NDArray[np.bool_]:
    """Return the blocks whose temperature changes at a measurable rate."""
    rate = data.rate_cpm
    max_rate = float(np.max(np.abs(rate))) if rate.size else 0.0
    return np.abs(rate) > max(0.02, 0.1 * max_rate)


def directions(data: BlockData, moving: NDArray[np.bool_]) -> tuple[bool, bool]:
    """Return whether the data heat and whether they cool at a measurable rate."""
    return (bool(np.any(moving & (data.rate_cpm > 0))),
            bool(np.any(moving & (data.rate_cpm < 0))))


def one_way(data: BlockData) -> bool:
    """Return True when the data change temperature in one direction only."""
    heating, cooling = directions(data, moving_blocks(data))
    return heating != cooling


def _soak_min_s(data: BlockData) -> float:
    """Return the shortest soak (s) that counts: 2 minutes and three blocks."""
    return max(_SOAK_S, 3.0 * data.block_s)


def _first_soaks(data: BlockData, moving: NDArray[np.bool_]) -> NDArray[np.float64]:
    """
    Return, per run, how long it soaks after power-on before the temperature first moves, s.

    Zero for a run with fewer than four blocks before its first move (one block is no soak).
    """
    out = np.zeros(data.n_runs)
    for r in range(data.n_runs):
        m = data.run == r
        tr, mv = data.t_since[m], moving[m]
        first_move = tr[np.argmax(mv)] if np.any(mv) else tr[-1]
        if np.count_nonzero(tr < first_move) >= 4:
            out[r] = first_move
    return out


def _longest_soak(data: BlockData, moving: NDArray[np.bool_]) -> float:
    """
    Return the longest soak next to a ramp, s: a stretch of still blocks in a run that moves.

    A change of rate between a ramp and a soak is what a time constant shows in (the die
    catching up, or starting to lag); a run that never moves, or never stops, has none.
    """
    best = 0.0
    for r in range(data.n_runs):
        idx = np.flatnonzero(data.run == r)
        mv = moving[idx]
        if not np.any(mv) or np.all(mv):
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[1], mv.astype(np.int8), [1]])))
        for a, b in zip(edges[::2], edges[1::2]):      # still stretches [a, b)
            best = max(best, float(data.tlast[idx[b - 1]] - data.tfirst[idx[a]]))
    return best


def excitation(data: BlockData, base: Sequence[str]) -> tuple[dict, list[str]]:
    """
    Decide which candidates this data cannot excite, before any fit.

    Returns ``{effect: Unidentifiable}`` and a list of notes about the data.
    """
    out: dict[str, Unidentifiable] = {}
    notes: list[str] = []
    span = float(data.temp.max() - data.temp.min())
    rate = data.rate_cpm
    moving = moving_blocks(data)
    heating, cooling = directions(data, moving)

    def add(eid: str, reason: str, extra: str = '') -> None:
        exp = EFFECTS[eid].excited_by
        out[eid] = Unidentifiable(eid, reason, exp[0].upper() + exp[1:] + extra + '.')

    if span < MIN_SPAN_C:
        for eid in _SPAN:
            add(eid, f'the temperature spans only {span:.2f} degC', ', of at least 10 degC')
    if not np.any(moving):
        for eid in _RATE:
            if eid not in out:
                add(eid, 'the temperature never changes at a measurable rate')
    elif heating != cooling:
        leg = 'heat' if heating else 'cool'
        r = np.abs(rate[moving])
        q1, q3 = np.percentile(r, [25, 75])
        one_rate = (q3 - q1) < 0.25 * float(np.median(r))
        soak = _longest_soak(data, moving)
        if one_rate and soak < _soak_min_s(data):
            # Scored all the same: a die settled at power-on falls behind at the start of the
            # ramp, which shows tau; a recording that starts mid-ramp shows nothing, and the
            # guard then rejects the lag (its profile is flat).
            notes.append(f'The data only {leg} and at one rate (~{np.median(r):.2f} degC/min) '
                         'with no soak before or after the ramp: a lag or dT/dt effect can '
                         'only show where the ramp starts from a die settled at power-on; '
                         'from a recording that starts mid-ramp it is not identifiable, and '
                         'hysteresis between heating and cooling cannot be tested.')
        elif one_rate:
            notes.append(f'The data only {leg} and at one rate (~{np.median(r):.2f} degC/min): '
                         'a lag or dT/dt effect rests on the changes of rate between the ramp '
                         f'and the soaks (the longest {soak:.0f} s: the approach to equilibrium '
                         'there shows a time constant); hysteresis between heating and cooling '
                         'cannot be tested.')
        else:
            notes.append(f'The data only {leg}: hysteresis between heating and cooling cannot '
                         'be tested; a dT/dt or lag effect seen here rests on the change of '
                         f'the {leg}ing rate alone.')
    if not np.any(data.scale_axes):
        if not np.any(np.abs(data.ref) > 1e-12):
            add('scale', 'the reference rate is zero on every run: a sensitivity change has '
                'nothing to scale')
        else:
            add('scale', 'the reference rate is constant on every run, so a sensitivity '
                'change is indistinguishable from dT')
    # Warm-up: some run must start with a soak (no temperature change) after power-on.
    soak_ok = bool(np.any(_first_soaks(data, moving) >= _soak_min_s(data)))
    if not soak_ok:
        add('warmup', 'no run starts with a soak after power-on: a warm-up transient cannot be '
            'told apart from the temperature response and the bias')
    for eid in base:
        out.pop(eid, None)
    return out, notes
