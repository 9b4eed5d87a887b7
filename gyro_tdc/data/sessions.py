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
Sessions: one power cycle each, a bag or the part of a bag between gaps and restarts.

:func:`find_breaks` finds where a run restarts (a stamp gap far above the sample period, a
device clock that stepped back); :func:`split_sessions` cuts runs there (``--sessions``,
``--session-gap``). Every session gets its own turn-on offset; see ``doc/internals/data.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from gyro_tdc.base import SESSION_GAP_S
from gyro_tdc.data.options import check_sessions, SESSION_MODES
from gyro_tdc.data.runs import Run
from gyro_tdc.signal import (break_why, BURST_FACTOR, BURST_PAUSES, gap_breaks, GAP_PERIODS,
                             session_gap)

__all__ = ['BURST_FACTOR', 'BURST_PAUSES', 'find_breaks', 'GAP_PERIODS', 'Session',
           'session_gap', 'SESSION_GAP_S', 'SESSION_MODES', 'SessionSplit', 'split_sessions']

# SESSION_MODES (gyro_tdc.data.options): ``auto`` (a bag, cut at gaps and restarts), ``bag``
# (one per bag), ``none`` (one offset for all the data, as one power cycle). The gap rule
# (GAP_PERIODS, BURST_PAUSES, BURST_FACTOR, session_gap) is gyro_tdc.signal.sessions', shared
# with the compensator's core and the learner.


@dataclass(frozen=True)
class Session:
    """One session: a power cycle of the sensor, with its own turn-on offset."""

    #: The run's name, the bag or ``BAG@k`` for the k-th session (from 1) of a bag cut
    #: into several.
    name: str
    #: The bag it came from (``'all'`` with ``--sessions none`` and several bags).
    bag: str
    #: Its label, 0-based in order, the offset it gets in a fit.
    index: int
    #: First stamp, s.
    start_s: float
    #: Last stamp, s.
    end_s: float
    #: Samples.
    samples: int
    #: What started it, ``'bag'``, ``'gap of X s'`` or ``'restart (stamps back by X s)'``.
    why: str = 'bag'


@dataclass(frozen=True)
class SessionSplit:
    """Runs cut into sessions, with one label per run (runs with one label share an offset)."""

    #: One per session with ``mode='auto'``; the runs as given otherwise.
    runs: list
    #: The session of each run (0-based).
    labels: list
    #: One :class:`Session` per label.
    sessions: list
    #: One of :data:`SESSION_MODES`.
    mode: str = 'auto'
    #: Every gap or restart found, in words (also those not cut with ``bag`` / ``none``).
    breaks: list = field(default_factory=list)
    #: Per run of ``runs``, (run it was cut from, start, stop), its samples ``start:stop``
    #: there (to cut per-sample arrays the same way, e.g. a motion veto).
    parts: list = field(default_factory=list)

    @property
    def count(self) -> int:
        """Return the number of sessions."""
        return len(self.sessions)

    def lines(self) -> list[str]:
        """Return the report: how many sessions, and every break found (cut or not)."""
        return [f'sessions ({self.mode}): {self.count} '
                + ('(one offset for all the data)' if self.mode == 'none' else
                   '(one turn-on offset each, a shared thermal curve)')] + [
            f'  {b}' + ('' if self.mode == 'auto' else f' (not cut: --sessions {self.mode})')
            for b in self.breaks]


def find_breaks(run: Run, gap_s: float = 0.0) -> list[tuple[int, str]]:
    """
    Return where a run starts a new session: (first sample, why) in order.

    A break is a stamp gap above ``gap_s`` (0: automatic, :func:`gyro_tdc.signal.session_gap`)
    or a restart :func:`gyro_tdc.data.dataset.load_run` found (``run.info['restarts']``);
    why reads ``'gap of X s'`` or ``'restart (stamps back by X s)'``.
    """
    out: dict[int, str] = {i: break_why(d) for i, d in gap_breaks(run.t, gap_s)}
    for i, back in run.info.get('restarts', ()):
        if 0 < int(i) < len(run):
            out[int(i)] = break_why(-float(back))
    return sorted(out.items())


def split_sessions(runs: Sequence[Run], mode: str = 'auto', gap_s: float = 0.0) -> SessionSplit:
    """
    Cut runs into sessions and label them: each session gets its own turn-on offset.

    ``mode`` ``'auto'``: every bag (``runs``: one run per bag) is a session, cut at every
    break (:func:`find_breaks`); ``'bag'``: one session per bag, not cut; ``'none'``: one
    session for everything (one offset, as if the data were one power cycle). ``gap_s``:
    ``--session-gap`` (0: automatic). Returns the runs (cut with ``auto``), a label per run,
    the sessions and the breaks found; raises DatasetError for an unknown mode or a negative
    gap.
    """
    check_sessions(mode, gap_s)
    out_runs: list[Run] = []
    sessions: list[Session] = []
    labels, breaks, parts = [], [], []       # per run, found, (bag run, start, stop) per run
    for j, run in enumerate(runs):
        found = find_breaks(run, gap_s)
        breaks += [f'{run.name}: {why} at t = {run.t[i]:.1f} s' for i, why in found]
        cut = found if mode == 'auto' else []
        cuts = [0] + [i for i, _ in cut] + [len(run)]
        for k, (a, b, why) in enumerate(zip(cuts[:-1], cuts[1:], ['bag'] + [w for _, w in cut])):
            piece = run.slice(a, b, name=f'{run.name}@{k + 1}') if cut else run
            if cut:
                piece.info.pop('restarts', None)      # indices of the whole run
            out_runs.append(piece)
            labels.append(0 if mode == 'none' else len(sessions))
            parts.append((j, a, b))
            if mode != 'none':
                sessions.append(Session(piece.name, run.name, len(sessions), float(piece.t[0]),
                                        float(piece.t[-1]), len(piece), why))
    if mode == 'none' and out_runs:
        name = out_runs[0].name if len(out_runs) == 1 else 'all'
        sessions.append(Session(name, name, 0, float(out_runs[0].t[0]), float(out_runs[-1].t[-1]),
                                sum(len(r) for r in out_runs), 'bag'))
    return SessionSplit(out_runs, labels, sessions, mode, breaks, parts)
