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
Learn in the field: the compensator's online bias-vs-temperature learner.

Pure (numpy only): the message path appends samples to one flat array; :meth:`Learner.step`
(from a timer) takes its still windows from the one streaming still test
(:class:`gyro_tdc.signal.StillWindows`), bins them by model temperature and refits. See
doc/internals/signal.md for the still test and the learner's use of it.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any, Sequence

from gyro_tdc.base import RESTART_BACK_S, SESSION_GAP_S
from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.fit import (BINS_DT2, BINS_DT3, fit_points, grow_features, learned_model,
                                MAX_DROPS, model_of, OUTLIER_K, predict_windows,
                                recent_offset, SPAN_DT2_C, SPAN_DT3_C, SPAN_DT_C, window_error)
from gyro_tdc.learn.store import (decode_state, encode_state, FORMAT, read_state, RECENT_ROWS,
                                  write_state)
from gyro_tdc.learn.temperature import hold_readings, same_thermal, stream_state
from gyro_tdc.model import CompensationModel, learned_coef, ThermalState
from gyro_tdc.signal import (BURST_FACTOR, BURST_MAX_S, BURST_PAUSES, GAP_PERIODS, MIN_STILL_S,
                             SessionRule, STILL_WINDOW_S, StillWindows, Window)
import numpy as np
from numpy.typing import NDArray

__all__ = ['BIN_ENTRIES', 'BURST_FACTOR', 'BURST_MAX_S', 'BURST_PAUSES', 'CHECK_STRETCHES',
           'FORMAT', 'GAP_PERIODS', 'Learner', 'LearnConfig', 'OUTLIER_K', 'SPAN_DT2_C',
           'SPAN_DT3_C', 'SPAN_DT_C', 'BINS_DT2', 'BINS_DT3',
           'MAX_DROPS', 'learned_model']

NAN3 = (math.nan, math.nan, math.nan)
#: Floats per sample in :attr:`Learner.buf`: stamp, rate (3), acceleration (3).
SAMPLE = 7
#: Entries a bin keeps (its newest).
BIN_ENTRIES = 8
#: Recent stretches the prediction check and the offset look at ...
CHECK_STRETCHES = 3
#: ... and their windows kept, newest first (a day of 10 s windows, what learn_file keeps).
CHECK_ROWS = RECENT_ROWS
#: A candidate is swapped in only when its prediction over the recent windows differs from
#: the current model's by this fraction of the gyro noise floor (RMS, rad/s) or more.
SWAP_CHANGE = 0.02
#: The sample period is the median of the stream's first this many intervals.
PERIOD_STEPS = 64
#: The session-break rule (GAP_PERIODS, BURST_PAUSES, BURST_FACTOR, BURST_MAX_S) is
#: gyro_tdc.signal.sessions', shared with the trainer's batch split and the compensator's core.


@dataclass(frozen=True)
class LearnConfig:
    """
    Settings of the learner.

    Parameters
    ----------
    bin_c : float, degC
        Temperature bin width.
    half_life_s : float, s
        Age (by message stamp) at which an entry weighs half.
    window_s, min_still_s : float, s
        Still test window and shortest stretch.
    temperature_timeout : float, s
        A thermometer reading older than this (by stamp) gives no temperature.
    save_period_s : float, s
        Stamp time between periodic saves.
    commit_s : float, s
        A still stretch longer than this is learned every ``commit_s`` while it goes on.
    entry_s : float, s
        A bin's entry gathers one stretch's windows over at most this long (then a new entry
        begins), so a long stop is learned as many points, each of its hours aged apart.
    offset_s : float, s
        The current session's offset is the mean over the newest ``offset_s`` of its still
        windows of the raw rate minus the fitted shape (the offset wanders: a random walk,
        bias instability); 0: the fit's intercept of the session.
    max_rate_hz : float, Hz
        The core hands the learner at most one sample per ``1 / max_rate_hz`` of stamps
        (by stamp, so a replay at any speed hands the same samples): from a faster IMU the
        mean of the samples since the last hand-off (a 1 kHz IMU is learned from means of
        10, a tenth of the noise variance of one sample), plenty for 10 s still windows.
    session_gap_s : float, s
        A gap in the IMU stamps longer than this starts a new session (a power-up: the
        gyro's turn-on offset changes; each session gets its own intercept in the fit), when
        it is also longer than :data:`GAP_PERIODS` sample periods and, in a stream that pauses
        regularly (bursts), than :data:`BURST_FACTOR` times its median pause; stamps that step
        back by over ``RESTART_BACK_S`` (a device clock restarted) start one too.
    swap_delay_s : float, s
        An accepted candidate takes effect this long (by stamp) after the sample that let it
        be computed (:meth:`Learner.take_swaps`), so its effective stamp is fixed by the
        data, not by when :meth:`Learner.step` happens to run.

    """

    bin_c: float = 1.0
    half_life_s: float = 86400.0
    window_s: float = STILL_WINDOW_S
    min_still_s: float = MIN_STILL_S
    temperature_timeout: float = 5.0
    save_period_s: float = 180.0
    commit_s: float = 300.0
    entry_s: float = 3600.0
    offset_s: float = 1800.0
    max_rate_hz: float = 100.0
    session_gap_s: float = SESSION_GAP_S
    swap_delay_s: float = 5.0


@dataclass
class _Stretch:
    """
    The current still stretch: its windows not learned yet, its first stamp and samples.

    ``rows`` are :class:`gyro_tdc.signal.Window` without samples; once part of the stretch
    is learned (``learned``), only the windows since are kept.
    """

    rows: list[Window] = field(default_factory=list)
    t0: float = math.nan
    n: int = 0
    learned: bool = False

    def add(self, win: Window) -> None:
        """Append a still window."""
        if not self.rows and not self.learned:
            self.t0 = win.t0
        self.rows.append(win)
        self.n += win.n

    def span(self) -> float:
        """Return the stretch's duration so far, s (one sample period included)."""
        if not self.rows:
            return 0.0
        d = self.rows[-1].t1 - self.t0
        return d + d / max(self.n - 1, 1)

    def keep_from(self, j: int) -> None:
        """Drop the windows before ``j`` (a stretch not learned yet)."""
        self.rows = self.rows[j:]
        self.n = sum(r.n for r in self.rows)
        self.t0 = self.rows[0].t0 if self.rows else math.nan


class Learner:
    """
    Online learner of the bias vs temperature from still time (module docstring).

    Parameters
    ----------
    config : LearnConfig
        Settings.
    prior : CompensationModel, optional
        The current model at start (from ``model_file``).

    """

    def __init__(self, config: LearnConfig | None = None,
                 prior: CompensationModel | None = None) -> None:
        self.config = config or LearnConfig()
        self.prior = prior
        #: The thermal front end of the model temperature (the prior's; None: thermometer).
        self.thermal: ThermalState | None = None if prior is None else prior.thermal
        #: The thermal state after the last sample: (stamp, one value per node), or None.
        self.thermal_state: tuple[float, list[float]] | None = None
        #: One flat float array (no object per sample), :data:`SAMPLE` floats a sample: the
        #: stamp, the raw rate and the acceleration (NaN: none).
        self.buf = array('d')
        self.temps: list[tuple[float, float]] = []
        #: The one streaming still test (windows on the grid of the first stamp; a window of
        #: three samples may be still); it keeps the motion reports.
        self.still = StillWindows(self.config.window_s, min_samples=3)
        #: Candidates handed over too late (:meth:`take_swaps`): a count of this process, not
        #: of the learned state (it depends on the step cadence, so it is not saved).
        self.late_swaps = 0
        #: Candidates refused by the model check (:func:`gyro_tdc.model.check_model`), and
        #: the last reason: a count of this process, not saved.
        self.refused, self.refused_why = 0, ''
        self.reset()

    # -- state -----------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything learned (points, floor, model); the prior is current again."""
        self.bins: dict[int, list[list]] = {}
        self.still.reset()
        self.still_s = 0.0
        self.stretches = 0
        self.windows = 0
        self.recent: list[list] = []          # [stretch, session, window rows] newest last
        self.session = 0
        self.fit: dict | None = None          # the learned model in use
        self.model: CompensationModel | None = self.prior
        self.last_update_t: float | None = None
        self.last_t: float | None = None
        self.last_save_t: float | None = None
        self.check: dict | None = None
        self.swaps = 0
        self._stretch = _Stretch()
        #: The entry group being filled: a stretch, or an ``entry_s`` part of a long one.
        self.segment = 0
        self.segment_t0: float | None = None
        #: The stream's rhythm (session rule): its median sample period, its pauses (the
        #: newest), and the sessions a gap started, ``(session, gap s)``.
        self._period: float | None = None
        self._dts: list[float] = []
        self._rule = SessionRule(self.config.session_gap_s)
        self._gap_starts: list[tuple[int, float]] = []
        #: A new session whose first stretch is not learned yet (:meth:`_early_offset`).
        self._fresh = False
        #: Accepted candidates not handed over yet: (effective stamp or None: at once, model).
        self._swaps: list[tuple[float | None, CompensationModel]] = []
        self._trigger: float | None = None    # stamp of the sample that let a refit run

    @property
    def gyro_floor(self) -> NDArray[np.float64]:
        """Return the gyro noise floor, shape (3,), rad/s (the still test's)."""
        return self.still.gyro_floor

    @gyro_floor.setter
    def gyro_floor(self, value) -> None:
        self.still.gyro_floor = np.asarray(value, dtype=np.float64)

    @property
    def accel_floor(self) -> NDArray[np.float64]:
        """Return the accelerometer noise floor, shape (3,), m/s^2."""
        return self.still.accel_floor

    @accel_floor.setter
    def accel_floor(self, value) -> None:
        self.still.accel_floor = np.asarray(value, dtype=np.float64)

    @property
    def t_first(self) -> float | None:
        """Return the first stamp of the session: the origin of the window grid, s."""
        return self.still.t_first

    @t_first.setter
    def t_first(self, value: float | None) -> None:
        self.still.t_first = value

    @property
    def motion(self) -> list[tuple[float, bool]]:
        """Return the motion reports (stamp, moving), from the one held at the window on."""
        return self.still.motion.reports

    @motion.setter
    def motion(self, value) -> None:
        self.still.motion.reports = list(value)

    def state(self) -> dict[str, Any]:
        """Return the persistent state as plain types (what :meth:`save` writes)."""
        return encode_state(self)

    def load_state(self, state: dict[str, Any]) -> None:
        """
        Resume from :meth:`state` (a restart: nothing saved is lost).

        Raises
        ------
        LearnFileError
            The state is not one this learner wrote (every field is checked first, the fit's
            model as a model file's: nothing changes then).

        """
        values, saved = decode_state(state, bin_c=self.config.bin_c, bin_entries=BIN_ENTRIES,
                                     stretches=CHECK_STRETCHES)
        self.reset()
        for name, value in values.items():
            setattr(self, name, value)
        if 'segment' not in values:       # a file without it: the next group above them all
            self.segment = max([self.stretches] + [int(e[4]) for v in self.bins.values()
                                                   for e in v]) + 1
            self.segment_t0 = None
        if not same_thermal(saved, self.thermal):
            # Binned at another model temperature than the prior's: the set_prior rule.
            self._forget_points()
            return
        if self.fit is not None:
            self.model = model_of(self.fit, self.thermal)
            self._swaps = [(None, self.model)]

    def set_prior(self, model: CompensationModel | None) -> None:
        """
        Replace the prior (a new ``model_file``; None: no model): it becomes the current model.

        Points are kept or dropped by its thermal section (module docstring); a learned model
        swaps in again only by predicting the recent still time better. :meth:`take_model`
        gives nothing for this change (the caller installs ``model``).
        """
        thermal = None if model is None else model.thermal
        same = same_thermal(thermal, self.thermal)
        self.prior, self.thermal = model, thermal
        self.fit, self.model, self._swaps = None, model, []
        if not same:
            self._forget_points()

    def _forget_points(self) -> None:
        """Drop what was binned at the old model temperature; restart the thermal state."""
        self.bins = {}
        self.recent = []
        self.fit, self.model, self._swaps, self.check = None, self.prior, [], None
        self._stretch = _Stretch()
        self.still.drop_window()
        self.thermal_state = None

    def save(self, path: str | Path) -> None:
        """Write the state (model and point table) to ``path`` atomically (JSON)."""
        write_state(path, self.state())
        self.saved()

    def load(self, path: str | Path) -> bool:
        """
        Resume from ``path`` when it exists; return whether it did.

        Raises
        ------
        LearnFileError
            The file is not a learner state (``gyro_tdc.learn.store``: read bounded, a
            symbolic link refused, every field checked).

        """
        state = read_state(path)
        if state is None:
            return False
        self.load_state(state)
        return True

    # -- the message path -------------------------------------------------------------

    def observe(self, t: float, wx: float, wy: float, wz: float,
                accel: Sequence[float] | None = None) -> None:
        """Record one raw IMU sample (the only per-message work: one ``extend``)."""
        if accel is None:
            self.buf.extend((t, wx, wy, wz, math.nan, math.nan, math.nan))
        else:
            ax, ay, az = accel
            self.buf.extend((t, wx, wy, wz, ax, ay, az))

    def add_temperature(self, t: float, temp_c: float) -> None:
        """Record one thermometer reading."""
        self.temps.append((t, temp_c))

    def observe_motion(self, t: float, moving: bool) -> None:
        """
        Record a motion report (stamp ``t``, s): it holds until the next (module docstring).

        Reports apply when :meth:`step` judges the windows they cover: one that arrives more
        than a window late no longer vetoes the windows already judged.
        """
        self.still.observe_motion(t, moving)

    def take_model(self) -> CompensationModel | None:
        """Return the newest model swapped in since the last call (once), else None."""
        swaps, self._swaps = self._swaps, []
        return swaps[-1][1] if swaps else None

    def take_swaps(self, t_seen: float | None = None
                   ) -> list[tuple[float | None, CompensationModel]]:
        """
        Return the models swapped in since the last call (once), oldest first.

        Each comes with the stamp from which it takes effect: ``swap_delay_s`` after the
        sample that let it be computed (the first sample after the window that ended or
        extended the still stretch; for a new session its first sample), or None: at once
        (resumed from a file). Installed at the first message stamped at or after it
        (:meth:`gyro_tdc.runtime.core.CompensatorCore.schedule`), the output does not
        depend on when :meth:`step` ran, as long as it ran within ``swap_delay_s`` of stamps.

        Parameters
        ----------
        t_seen : float, s, optional
            The newest stamp the message path has compensated: a model whose stamp is not
            after it comes late (the step ran too long after the data) and is counted in
            ``late_swaps``.

        """
        swaps, self._swaps = self._swaps, []
        if t_seen is not None:
            self.late_swaps += sum(1 for due, _ in swaps if due is not None and due <= t_seen)
        return swaps

    def caught_up(self) -> bool:
        """Return whether :meth:`step` has nothing to judge until the next sample arrives."""
        buf = self.buf
        return not buf or self._waiting()

    def _waiting(self) -> bool:
        """Return whether the window in progress goes on (no sample beyond it, no restart)."""
        wend = self.still.window_end
        t = self.buf[-SAMPLE]
        return (wend is not None and t < wend
                and (self.last_t is None or t >= self.last_t - RESTART_BACK_S))

    def save_due(self) -> bool:
        """Return whether ``save_period_s`` of stamp time passed since the last save."""
        if self.last_t is None:
            return False
        if self.last_save_t is None:
            self.last_save_t = self.last_t
            return False
        return self.last_t - self.last_save_t >= self.config.save_period_s

    def saved(self) -> None:
        """Note that the state was saved now (by stamp)."""
        self.last_save_t = self.last_t

    # -- off the message path ----------------------------------------------------------

    def step(self, force: bool = False) -> bool:
        """
        Process the samples gathered since the last call; refit after each finished stretch.

        Until a sample beyond the window in progress has arrived, nothing is done (unless
        ``force``): the samples are converted once per window.

        Returns
        -------
        bool
            True when a new model was swapped in (:meth:`take_model` gives it).

        """
        buf = self.buf
        if not buf or (not force and self._waiting()):
            return False                  # the window in progress has not ended: wait
        # The core holds this array's extend method: empty it in place (call this on the
        # thread that compensates, as the node's timer does).
        m = len(buf) // SAMPLE * SAMPLE
        x = np.array(buf[:m], dtype=np.float64).reshape(-1, SAMPLE)
        del buf[:m]
        t, w, acc = x[:, 0], x[:, 1:4], x[:, 4:7]
        if not np.isfinite(acc).all():
            acc = None                    # missing or not three values: the gyro alone
        ok = np.isfinite(t)
        t, w = t[ok], w[ok]
        acc = None if acc is None else acc[ok]
        if not t.size:
            return False
        temp, self.temps = hold_readings(self.temps, t, self.config.temperature_timeout)
        # A gap longer than the session rule's (before the batch or inside it) starts a new
        # session.
        dt = np.diff(t, prepend=t[0] if self.last_t is None else self.last_t)
        if self._period is None:          # the median of the first PERIOD_STEPS intervals
            self._dts.extend(dt[dt > 0.0][:PERIOD_STEPS - len(self._dts)].tolist())
            if len(self._dts) >= PERIOD_STEPS:
                self._period = float(np.median(self._dts))
        pause = (GAP_PERIODS * self._period if self._period is not None
                 else self.config.session_gap_s)
        back = set(np.flatnonzero(dt < -RESTART_BACK_S).tolist())   # the device restarted
        pauses = sorted(set(np.flatnonzero(dt > pause).tolist()) | back)
        swapped = False
        for lo, hi in zip([0] + pauses, pauses + [t.size]):
            if hi > lo:
                new = lo in back or (lo in pauses and self._pause(float(dt[lo])))
                swapped = self._batch(t[lo:hi], w[lo:hi], None if acc is None else acc[lo:hi],
                                      temp[lo:hi], new) or swapped
        return swapped

    def session_gap(self) -> float:
        """
        Return the stamp gap (s) above which the stream starts a new session now.

        The shared rule (:func:`gyro_tdc.signal.gap_limit`): the longest of
        ``session_gap_s``, :data:`GAP_PERIODS` sample periods and, once the stream has
        paused :data:`BURST_PAUSES` times for longer than GAP_PERIODS periods,
        :data:`BURST_FACTOR` times the median of those pauses (at most BURST_MAX_S).
        """
        return self._rule.limit(self._period or 0.0)

    def _pause(self, gap: float) -> bool:
        """Note a pause of the stream (s); return whether it starts a new session."""
        period = self._period or 0.0
        new = bool(self._rule.judge(gap, period))
        self._merge_sessions(self._rule.limit(period))
        if new:
            self._gap_starts = (self._gap_starts + [(self.session + 1, gap)])[-64:]
        return new

    def _merge_sessions(self, limit: float) -> None:
        """Merge into their predecessor the sessions whose gap the rule no longer cuts at."""
        merge = {s for s, gap in self._gap_starts if gap <= limit and s <= self.session}
        if not merge:
            return
        new, label = {}, 0
        for k in range(self.session + 1):
            if k and k not in merge:
                label += 1
            new[k] = label
        for v in self.bins.values():
            for e in v:
                e[5] = new.get(int(e[5]), e[5])
        for r in self.recent:
            r[1] = new.get(int(r[1]), r[1])
        self._gap_starts = [(new[s], g) for s, g in self._gap_starts if s not in merge
                            and s in new]
        self.session = new[self.session]

    def _batch(self, t, w, acc, temp, new_session: bool) -> bool:
        """Process samples of one session: the still test judges the windows they end."""
        swapped = False
        if new_session:
            # A new session (power-up): its own turn-on offset, learned apart; what it
            # closes was computable at its first sample.
            swapped = self.flush(float(t[0]))
            self.session += 1
            self._fresh = True            # its offset from its first still windows
            self.still.restart()          # the window grid starts again
            self.thermal_state = None     # after a power-off: steady state at the next reading
        temp, self.thermal_state = stream_state(self.thermal, self.thermal_state, t, temp)
        self.last_t = float(t[-1])
        windows = self.still.extend(t, w, acc, temp)
        return self._windows(windows, None) or swapped

    def flush(self, t_trigger: float | None = None) -> bool:
        """
        Judge the window in progress and end the stretch (at shutdown, or a new session).

        ``t_trigger`` (s) is the stamp a candidate computed here counts from (default: the
        last sample's).
        """
        swapped = self.step(force=True)
        trigger = self.last_t if t_trigger is None else t_trigger
        last = self.still.flush()
        if last is not None:
            swapped = self._windows([last], trigger) or swapped
        self._trigger = trigger
        return self._close() or swapped

    def _windows(self, windows: list[Window], t_next: float | None) -> bool:
        """
        Take judged windows in order; close and learn the stretches they end.

        A window is known finished at the first sample after it (data, not step timing):
        its ``t_next``, else ``t_next`` here (the trigger of what it decides).
        """
        swapped = False
        for win in windows:
            self.windows += 1
            self._trigger = win.t_next if win.t_next is not None else t_next
            if win.why == 'samples':
                continue                  # a sliver (a burst cut by the grid): no evidence
            if win.why or not math.isfinite(win.temp_c):
                swapped = self._close(win.thresholds) or swapped
                continue
            self._stretch.add(win.light())
            done = self._commit()
            if not done and self._fresh:
                done = self._early_offset(win.t1)
            swapped = done or swapped
        return swapped

    def _close(self, thresholds: tuple | None = None) -> bool:
        """
        End the stretch: keep it when long enough, learn what is not learned yet.

        Its windows that ``thresholds`` (default: those in force) refuse are dropped with
        everything before them (unless part of it was learned already).
        """
        st, self._stretch = self._stretch, _Stretch()
        if not st.rows:
            return False
        if not st.learned:
            j, _ = self.still.last_refused(st.rows, thresholds)
            if j >= 0:
                st.keep_from(j + 1)
            if not st.rows or st.span() + 1e-9 < self.config.min_still_s:
                return False
            self._new_stretch(st.rows[0].t0)
        return self._learn(st.rows)

    def _new_stretch(self, t0: float) -> None:
        """Count a stretch that is learned from now on; its entries form a new group."""
        self.stretches += 1
        self.segment = max(self.segment + 1, self.stretches)
        self.segment_t0 = t0

    def _commit(self) -> bool:
        """Learn a long stretch's windows so far (every ``commit_s``) while it goes on."""
        st = self._stretch
        if not st.learned:
            if st.span() < self.config.min_still_s:
                return False
            self._new_stretch(st.rows[0].t0)
            st.learned = True
        elif st.rows[-1].t1 - st.rows[0].t0 < self.config.commit_s:
            return False
        rows, st.rows = st.rows, []
        return self._learn(rows)

    def _learn(self, new: list) -> bool:
        """Bin new windows of the current stretch (merged per bin and group), refit, swap."""
        if not new:
            return False
        # Still time: the windows' own (a pause between two bursts is not still time).
        self.still_s += sum(r.t1 - r.t0 + (r.t1 - r.t0) / max(r.n - 1, 1) for r in new)
        if self.segment_t0 is None or new[-1].t1 - self.segment_t0 > self.config.entry_s:
            self.segment += 1             # a long stop: its next hour is a new group
            self.segment_t0 = new[0].t0
        sid = self.segment
        groups: dict[int, list] = {}
        for r in new:
            groups.setdefault(int(math.floor(r.temp_c / self.config.bin_c)), []).append(r)
        for b, rs in groups.items():
            m = sum(r.n for r in rs)
            entry = [float(rs[-1].t1), float(m), sum(r.temp_c * r.n for r in rs) / m,
                     tuple(sum(r.gyro_mean[a] * r.n for r in rs) / m for a in range(3)), sid,
                     self.session]
            lst = self.bins.setdefault(b, [])
            if lst and lst[-1][4] == sid:          # the same group: one entry per bin
                o = lst[-1]
                tot = o[1] + m
                entry = [entry[0], tot, (o[2] * o[1] + entry[2] * m) / tot,
                         tuple((o[3][a] * o[1] + entry[3][a] * m) / tot for a in range(3)),
                         sid, self.session]
                lst[-1] = entry
            else:
                lst.append(entry)
            del lst[:-BIN_ENTRIES]
        self._remember([[r.n, r.temp_c, *r.gyro_mean, r.t1] for r in new])
        return self._refit(new[-1].t1)

    def _remember(self, rows: list) -> None:
        """Keep new windows for the check and the offset: the newest stretches and rows."""
        stretch = self.stretches
        if self.recent and self.recent[-1][0] == stretch:
            self.recent[-1][2].extend(rows)
        else:
            self.recent.append([stretch, self.session, rows])
        del self.recent[:-CHECK_STRETCHES]
        total = sum(len(r[2]) for r in self.recent)
        while total > CHECK_ROWS:
            first = self.recent[0][2]
            cut = min(total - CHECK_ROWS, len(first))
            del first[:cut]
            total -= cut
            if not first:
                del self.recent[0]

    # -- the fit ----------------------------------------------------------------------

    def entries(self) -> NDArray[np.float64]:
        """Return the point table: rows ``(t_end, samples, temp, bx, by, bz, session)``."""
        rows = [[e[0], e[1], e[2], *e[3], e[5]] for v in self.bins.values() for e in v]
        return np.asarray(rows, dtype=np.float64).reshape(-1, 7)

    def covered_c(self) -> tuple[float, float] | None:
        """Return the covered temperature range (the entries' extremes), None when empty."""
        e = self.entries()
        return None if not e.shape[0] else (float(e[:, 2].min()), float(e[:, 2].max()))

    def _refit(self, t_now: float) -> bool:
        """Fit the point table; swap the candidate in when it predicts recent still time better."""
        self._fresh = False
        e = self.entries()
        fit = fit_points(e, grow_features(e[:, 2], len(self.bins)), t_now,
                         self.config.half_life_s, self._floor())
        rows = np.asarray(self._recent_rows(), dtype=np.float64).reshape(-1, 6)
        return self._offer(fit, rows, t_now)

    def _floor(self) -> float:
        """Return the largest finite gyro noise floor of the axes, rad/s (0: none yet)."""
        return float(np.nanmax(np.where(np.isfinite(self.gyro_floor), self.gyro_floor, 0.0)))

    def _early_offset(self, t_now: float) -> bool:
        """
        Give a new session's first still windows the last fit's shape and their offset, at once.

        Until the session's first stretch is learned (``min_still_s``), its turn-on offset
        would be the previous session's: each still window gives the shape of the last fit
        this session's offset (the points are learned with the stretch, as always).
        """
        if self.fit is None:
            return False
        rows = np.asarray([[r.n, r.temp_c, *r.gyro_mean, r.t1] for r in self._stretch.rows],
                          dtype=np.float64).reshape(-1, 6)
        fit = dict(self.fit, coef=[list(c) for c in self.fit['coef']])
        return self._offer(fit, rows, t_now, since=-math.inf)

    def _offer(self, fit: dict, rows: NDArray[np.float64], t_now: float,
               since: float | None = None) -> bool:
        """Give ``fit`` the offset of the newest windows; swap it in when the check says so."""
        floor = self._floor()
        if since is None:
            since = t_now - self.config.offset_s
        fit['coef'] = learned_coef(fit['coef'], self.prior)    # the prior's offset-only axes
        try:
            cand = model_of(fit, self.thermal)
            offset = recent_offset(fit, rows, since) if self.config.offset_s > 0 else None
            if offset is not None:        # the newest still time's offset, the same shape
                fit['coef'][0] = offset
                cand = model_of(fit, self.thermal)
        except ModelFileError as exc:     # checked as a model file: never installed
            self.refused, self.refused_why = self.refused + 1, str(exc)
            return False
        anchor = since if self.config.offset_s > 0 or since == -math.inf else None
        # Whose offset it carries: the newest still time it was taken from (the core keeps
        # re-anchoring a new power cycle until a model carries that cycle's offset).
        cand.created['offset_until'] = self._offset_until(rows, since, offset is not None)
        # The noise of the samples it is handed (the core's re-anchoring prior at a new one).
        cand.created['gyro_floor'] = [float(v) for v in self.gyro_floor]
        pred = predict_windows(cand, rows, self.thermal)
        new = window_error(rows, pred, anchor)
        old = change = None
        if self.model is not None:
            cur = predict_windows(self.model, rows, self.thermal)
            old = window_error(rows, cur, anchor)
            change = (float(np.sqrt(np.average(((pred - cur) ** 2).mean(axis=1),
                                               weights=rows[:, 0])))
                      if rows.shape[0] else math.inf)
        # Swapped in when better on the recent still time and different enough to matter:
        # an RMS change of SWAP_CHANGE noise floors (a long stop refits every few minutes;
        # each install replays the model's filters).
        swap = old is None or (new < old and not change < SWAP_CHANGE * floor)
        self.check = {'t': t_now, 'candidate_mse': new, 'current_mse': old, 'swapped': swap}
        if not swap:
            return False
        trigger = t_now if self._trigger is None else max(self._trigger, t_now)
        self._swaps.append((trigger + self.config.swap_delay_s, cand))
        self.fit, self.model = fit, cand
        self.last_update_t = t_now
        self.swaps += 1
        return True

    def _offset_until(self, rows: NDArray[np.float64], since: float, recent: bool
                      ) -> float | None:
        """
        Return the stamp of the newest still time a candidate's offset comes from, or None.

        The newest of ``rows`` after ``since`` when the offset is theirs (``recent``), else
        the newest entry of the current session (the fit's intercept of its newest session);
        None when the current session has none (the offset is an older session's).
        """
        if recent:
            new = rows[rows[:, 5] > since, 5]
            return float(new.max()) if new.size else None
        e = self.entries()
        mine = e[e[:, 6] == self.session, 0]
        return float(mine.max()) if mine.size else None

    def _recent_rows(self) -> list:
        """Return this session's recent windows (the check's and the offset's)."""
        return [r for s in self.recent if s[1] == self.session for r in s[2]]

    # -- reporting --------------------------------------------------------------------

    def diagnostic_values(self) -> dict[str, str]:
        """Return the learner's /diagnostics key/value pairs (strings)."""
        s = self.summary()
        cov = s['covered_c']
        return {
            'learn points': str(s['points']),
            'learn covered degC': 'none' if cov is None else f'{cov[0]:.2f} .. {cov[1]:.2f}',
            'learn still s': f'{s["still_s"]:.0f}',
            'learn features': 'none' if s['features'] is None else ', '.join(s['features']),
            'learn last update stamp s': ('never' if s['last_update_t'] is None
                                          else f'{s["last_update_t"]:.3f}'),
            'learn prediction check': s['check'] or 'none yet',
            'learn session': str(self.session),
            'learn late swaps': str(self.late_swaps),
            'learn candidates refused': (f'{self.refused} (last: {self.refused_why})'
                                         if self.refused else '0'),
        }

    def summary(self) -> dict[str, Any]:
        """Return what /diagnostics shows: points, range, still time, last update, check."""
        cov = self.covered_c()
        chk = self.check
        return {
            'points': int(self.entries().shape[0]), 'bins': len(self.bins),
            'covered_c': cov, 'still_s': self.still_s, 'stretches': self.stretches,
            'features': None if self.fit is None else (self.fit['features'] or ['bias']),
            'last_update_t': self.last_update_t, 'swaps': self.swaps,
            'check': None if chk is None else (
                f"candidate {math.sqrt(chk['candidate_mse']):.3g} rad/s vs current "
                + ('none' if chk['current_mse'] is None
                   else f"{math.sqrt(chk['current_mse']):.3g} rad/s")
                + (' -> swapped' if chk['swapped'] else ' -> kept')),
        }
