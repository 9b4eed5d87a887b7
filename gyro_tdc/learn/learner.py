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
import math
from pathlib import Path
from typing import Any, Sequence

from gyro_tdc.base import RESTART_BACK_S
from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.codec import decode_state, encode_state, FORMAT, RECENT_ROWS
from gyro_tdc.learn.fit import (compare, correction_features, fit_points, grow_features,
                                learned_model, model_of, offset_until, on_prior,
                                power_up_offset, recent_offset, same_thermal, stream_state)
from gyro_tdc.learn.gate import learned_gate
from gyro_tdc.learn.records import (Entry, held_out_line, keep_power_up, LearnConfig,
                                    OpenStretch, pool, RecentStretch, relabel_power_ups,
                                    remember)
from gyro_tdc.learn.store import LearnFile
from gyro_tdc.model import CompensationModel, ThermalState
from gyro_tdc.runtime import BLOCK_FIELDS, NO_ACCEL, power_up, POWER_UP_KEY
from gyro_tdc.signal import (break_why, hold_readings, long_enough, SessionTracker, StillWindows,
                             Window)
import numpy as np
from numpy.typing import NDArray

__all__ = ['BIN_ENTRIES', 'CHECK_STRETCHES', 'FORMAT', 'Learner', 'LearnConfig', 'learned_model']

#: Entries a bin keeps (its newest).
BIN_ENTRIES = 8
#: Recent stretches the prediction check and the offset look at ...
CHECK_STRETCHES = 3
#: ... and their windows kept, newest first (a day of 10 s windows, what learn_file keeps).
CHECK_ROWS = RECENT_ROWS


class Learner:
    """
    Online learner of the bias vs temperature from still time (module docstring).

    ``config``: its settings; ``prior``: the current model at start (from ``model_file``).
    """

    def __init__(self, config: LearnConfig | None = None,
                 prior: CompensationModel | None = None) -> None:
        self.config = config or LearnConfig()
        self.prior = prior
        #: The thermal front end of the model temperature (the prior's; None: thermometer).
        self.thermal: ThermalState | None = None if prior is None else prior.thermal
        #: The thermal state after the last sample: (stamp, one value per node), or None.
        self.thermal_state: tuple[float, list[float]] | None = None
        #: One flat float array (no object per sample), the core's hand-off layout
        #: (:data:`~gyro_tdc.runtime.handoff.BLOCK_FIELDS` floats a sample: the stamp, the raw
        #: rate and the acceleration, NaN: none).
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
        self.bins: dict[int, list[Entry]] = {}
        self.still.reset()
        self.still_s, self.stretches, self.windows, self.swaps = 0.0, 0, 0, 0
        self.recent: list[RecentStretch] = []     # newest last
        self.fit: dict | None = None          # the learned model in use
        self.model: CompensationModel | None = self.prior
        #: Stamps (s) of the last model update, the last sample and the last save, or None.
        self.last_update_t = self.last_t = self.last_save_t = None
        self.check: dict | None = None
        self._stretch = OpenStretch()
        #: The entry group being filled: a stretch, or an ``entry_s`` part of a long one.
        self.segment, self.segment_t0 = 0, None
        #: The session, from 0, and the stream's median period (the shared rule).
        self.sessions = SessionTracker(self.config.session_gap_s)
        #: A new session whose first stretch is not learned yet (:meth:`_early_offset`).
        self._fresh = False
        #: Each power cycle's first still windows (``records.keep_power_up``), being pooled.
        self.power_ups: list[list] = []
        self._up_open = True
        #: Accepted candidates not handed over yet: (effective stamp or None: at once, model).
        self._swaps: list[tuple[float | None, CompensationModel]] = []
        self._trigger: float | None = None    # stamp of the sample that let a refit run

    @property
    def session(self) -> int:
        """Return the power cycle the stream is in, from 0."""
        return self.sessions.session

    @property
    def motion(self) -> list[tuple[float, bool]]:
        """Return the motion reports (stamp, moving), from the one held at the window on."""
        return self.still.motion.reports

    def state(self) -> dict[str, Any]:
        """Return the persistent state as plain types (what :meth:`save` writes)."""
        return encode_state(self)

    def load_state(self, state: dict[str, Any]) -> None:
        """
        Resume from :meth:`state` (a restart: nothing saved is lost).

        LearnFileError when it is not a state this learner wrote: every field is checked
        first (the fit's model as a model file's), so nothing changes then.
        """
        values, saved = decode_state(state, bin_c=self.config.bin_c, bin_entries=BIN_ENTRIES,
                                     stretches=CHECK_STRETCHES)
        values.pop('prior')               # the model a correction was learned over
        self.reset()
        still = self.still
        still.gyro_floor, still.accel_floor = values.pop('gyro_floor'), values.pop('accel_floor')
        still.t_first, still.motion.reports = values.pop('t_first'), values.pop('motion')
        self.sessions.session = values.pop('session')
        for name, value in values.items():
            setattr(self, name, value)
        self._up_open = not (self.power_ups and self.power_ups[-1][0] == self.session)
        if not same_thermal(saved, self.thermal):
            # Binned at another model temperature than the prior's: the set_prior rule.
            self._forget_points()
            return
        mid = None if self.fit is None else self.fit.get('prior')
        if mid is not None and (self.prior is None or self.prior.model_id != mid):
            # A correction to another prior is not applied to this one: refitted on the points.
            self.fit, self.check = None, None
        if self.fit is not None:
            self.model = model_of(self.fit, self.thermal, self.prior)
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
        self.bins, self.recent = {}, []
        self.fit, self.model, self._swaps, self.check = None, self.prior, [], None
        self._stretch, self.power_ups = OpenStretch(), []
        self.still.drop_window()
        self.thermal_state = None

    def save(self, path: str | Path) -> None:
        """Write the state (model and point table) to ``path`` atomically (JSON)."""
        LearnFile(path).write(self.state())
        self.saved()

    def load(self, path: str | Path) -> bool:
        """Resume from ``path`` when it exists; return whether it did (LearnFileError: bad)."""
        return LearnFile(path).resume(self.load_state)

    # -- the message path -------------------------------------------------------------

    def observe(self, t: float, wx: float, wy: float, wz: float,
                accel: Sequence[float] | None = None) -> None:
        """Record one raw IMU sample (the only per-message work: one ``extend``)."""
        ax, ay, az = NO_ACCEL if accel is None else accel
        self.buf.extend((t, wx, wy, wz, ax, ay, az))

    def add_temperature(self, t: float, temp_c: float) -> None:
        """Record one thermometer reading."""
        self.temps.append((t, temp_c))

    def observe_motion(self, t: float, moving: bool) -> None:
        """Record a motion report at ``t`` (s), held until the next, for windows not judged yet."""
        self.still.observe_motion(t, moving)

    def take_model(self) -> CompensationModel | None:
        """Return the newest model swapped in since the last call (once), else None."""
        swaps = self.take_swaps()
        return swaps[-1][1] if swaps else None

    def take_swaps(self, t_seen: float | None = None
                   ) -> list[tuple[float | None, CompensationModel]]:
        """
        Return the models swapped in since the last call (once), oldest first.

        Each with the stamp it takes effect from, ``swap_delay_s`` after the sample that let
        it be computed (None: at once, resumed from a file), so the output does not depend on
        when :meth:`step` ran. One stamped at or before ``t_seen`` (s, the newest stamp the
        message path compensated) comes late and is counted in ``late_swaps``.
        """
        swaps, self._swaps = self._swaps, []
        if t_seen is not None:
            self.late_swaps += sum(1 for due, _ in swaps if due is not None and due <= t_seen)
        return swaps

    def caught_up(self) -> bool:
        """Return whether :meth:`step` has nothing to judge until the next sample arrives."""
        return not self.buf or self._waiting()

    def _waiting(self) -> bool:
        """Return whether the window in progress goes on (no sample beyond it, no restart)."""
        wend, t = self.still.window_end, self.buf[-BLOCK_FIELDS]
        return (wend is not None and t < wend
                and (self.last_t is None or t >= self.last_t - RESTART_BACK_S))

    def tick_save_clock(self) -> bool:
        """
        Return whether ``save_period_s`` of stamp time passed since the last save.

        Not a pure query: the first call with a stamp starts the save clock there.
        """
        if self.last_t is None:
            return False
        if self.last_save_t is None:
            self.last_save_t = self.last_t
            return False
        # Stamps that stepped back (the IMU's clock restarted) make a save due.
        return not -RESTART_BACK_S <= self.last_t - self.last_save_t < self.config.save_period_s

    def saved(self) -> None:
        """Note that the state was saved now (by stamp)."""
        self.last_save_t = self.last_t

    # -- off the message path ----------------------------------------------------------

    def step(self, force: bool = False) -> bool:
        """
        Process the samples gathered since the last call; return whether a model swapped in.

        Until a sample beyond the window in progress has arrived, nothing is done (unless
        ``force``): the samples are converted once per window; each finished stretch refits.
        """
        buf = self.buf
        if not buf or (not force and self._waiting()):
            return False                  # the window in progress has not ended: wait
        # The core holds this array's extend method: empty it in place (call this on the
        # thread that compensates, as the node's timer does).
        m = len(buf) // BLOCK_FIELDS * BLOCK_FIELDS
        x = np.array(buf[:m], dtype=np.float64).reshape(-1, BLOCK_FIELDS)
        del buf[:m]
        ok = np.isfinite(x[:, 0])
        t, w = x[ok, 0], x[ok, 1:4]
        # Missing or not three values: the gyro alone.
        acc = x[ok, 4:7] if np.isfinite(x[:, 4:7]).all() else None
        if not t.size:
            return False
        temp, self.temps = hold_readings(self.temps, t, self.config.temperature_timeout)
        # A gap longer than the session rule's (before the batch or inside it) starts a new
        # session.
        dt = np.diff(t, prepend=t[0] if self.last_t is None else self.last_t)
        self.sessions.median_period(dt)
        back = set(np.flatnonzero(dt < -RESTART_BACK_S).tolist())   # the device restarted
        pauses = sorted(set(np.flatnonzero(dt > self.sessions.pause_s()).tolist()) | back)
        swapped = False
        for lo, hi in zip([0] + pauses, pauses + [t.size]):
            if hi > lo:
                d = float(dt[lo])
                why = break_why(d) if lo in back else (self._pause(d) if lo in pauses else '')
                swapped = self._batch(t[lo:hi], w[lo:hi], None if acc is None else acc[lo:hi],
                                      temp[lo:hi], why, d) or swapped
        return swapped

    def _pause(self, gap: float) -> str:
        """
        Judge a pause of the stream (s) by the session rule; return why it is a break or ''.

        Sessions whose gap the rule no longer cuts at (it learned the stream's rhythm since)
        are merged into their predecessor, their points and recent windows relabelled.
        """
        period = self.sessions.median or 0.0
        why = self.sessions.judge(gap, period)
        if relabel := self.sessions.merges(period):
            self.power_ups = relabel_power_ups(self.power_ups, relabel)
            for e in (e for v in self.bins.values() for e in v):
                e.session = relabel.get(e.session, e.session)
            self.recent = [r._replace(session=relabel.get(r.session, r.session))
                           for r in self.recent]
        return why

    def _batch(self, t, w, acc, temp, why: str, gap: float) -> bool:
        """
        Process samples of one session: the still test judges the windows they end.

        ``why`` (not ``''``): they start a new session, after a stamp step of ``gap`` s.
        """
        swapped = False
        if why:
            # A new session (power-up): its own turn-on offset, learned apart; what it
            # closes was computable at its first sample.
            n, t0 = len(self._swaps), float(t[0])
            swapped = self.flush(t0)
            # None not handed over carries the new session's offset (a power-up's intercept);
            # after the clock restarted (stamps back) one due by the old clock is due now.
            for k, (due, m) in enumerate(self._swaps):
                self._swaps[k] = (min(due, t0) if gap < 0 and k < n and due is not None
                                  else due, power_up(m))
            self.sessions.start(t0, why, gap=gap)
            self._power_up(t0)
            # Its first still windows are pooled and give its offset.
            self._up_open = self._fresh = True
            self.still.restart()          # the window grid starts again
            self.thermal_state = None     # after a power-off: steady state at the next reading
        temp, self.thermal_state = stream_state(self.thermal, self.thermal_state, t, temp)
        self.last_t = float(t[-1])
        return self._windows(self.still.extend(t, w, acc, temp), None) or swapped

    def _power_up(self, t0: float) -> None:
        """At a new power cycle swap in the fit with a power-up's intercept (unknown offset)."""
        if self.fit is None:
            return
        fit = dict(self.fit, coef=[power_up_offset(self.fit, self.power_ups, self.prior)]
                   + self.fit['coef'][1:])
        try:
            model = model_of(fit, self.thermal, self.prior)
        except ModelFileError as exc:     # checked as a model file: never installed
            self.refused, self.refused_why = self.refused + 1, str(exc)
            return
        model.created.update({'offset_until': None, POWER_UP_KEY: model.intercept.tolist(),
                              'gyro_floor': list(map(float, self.still.gyro_floor))})
        self._swaps.append((t0 + self.config.swap_delay_s, model))   # computable at t0
        self.fit, self.model = fit, model

    def flush(self, t_trigger: float | None = None) -> bool:
        """
        Judge the window in progress and end the stretch (at shutdown, or a new session).

        A candidate computed here counts from ``t_trigger`` (s; default the last sample's).
        """
        swapped = self.step(force=True)
        trigger = self.last_t if t_trigger is None else t_trigger
        if (last := self.still.flush()) is not None:
            swapped = self._windows([last], trigger) or swapped
        self._trigger = trigger
        return self._close() or swapped

    def _windows(self, windows: list[Window], t_next: float | None) -> bool:
        """
        Take judged windows in order; close and learn the stretches they end.

        A window is known finished at its ``t_next`` (else the argument's): by data.
        """
        swapped = False
        for win in windows:
            self.windows += 1
            self._trigger = win.t_next if win.t_next is not None else t_next
            if win.why == 'samples':
                continue                  # a sliver (a burst cut by the grid): no evidence
            if win.why or not math.isfinite(win.temp_c):
                swapped = self._close(win.thresholds) or swapped
                self._up_open &= not (self.power_ups and self.power_ups[-1][0] == self.session)
                continue
            self._stretch.add(win.light())
            if self._up_open:
                self._up_open = keep_power_up(self.power_ups, self.session, win)
            swapped = self._commit() or (self._fresh and self._early_offset(win.t1)) or swapped
        return swapped

    def _close(self, thresholds: tuple | None = None) -> bool:
        """
        End the stretch: keep it when long enough, learn what is not learned yet.

        Its windows that ``thresholds`` (default: those in force) refuse are dropped with
        everything before them (unless part of it was learned already).
        """
        st, self._stretch = self._stretch, OpenStretch()
        if not st.rows:
            return False
        if not st.learned:
            st.keep_from(self.still.last_refused(st.rows, thresholds)[0] + 1)
            if not st.rows or not self._begin(st):
                return False
        return self._learn(st.rows)

    def _begin(self, st: OpenStretch) -> bool:
        """
        Return whether a stretch not learned yet is learned (the trainers' rule).

        One that is counts from now on; its entries form a new group.
        """
        if not long_enough(st.n, st.span(), st.mean_se, self.config.window_s,
                           self.config.min_still_s):
            return False
        self.stretches += 1
        self.segment = max(self.segment + 1, self.stretches)
        self.segment_t0 = st.rows[0].t0
        return True

    def _commit(self) -> bool:
        """Learn a long stretch's windows so far (every ``commit_s``) while it goes on."""
        st = self._stretch
        if not st.learned:
            if not self._begin(st):
                return False
            st.learned = True
        elif st.rows[-1].t1 - st.rows[0].t0 < self.config.commit_s:
            return False
        rows, st.rows = st.rows, []
        return self._learn(rows)

    def _learn(self, new: list[Window]) -> bool:
        """Bin a stretch's new windows (one or more; merged per bin and group), refit, offer."""
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
            m, temp, bias = pool([(r.n, r.temp_c, r.gyro_mean) for r in rs])
            lst = self.bins.setdefault(b, [])
            if lst and lst[-1].group == sid:       # the same group: one entry per bin
                o = lst.pop()
                m, temp, bias = pool([(o.samples, o.temp_c, o.bias), (m, temp, bias)])
            lst.append(Entry(float(rs[-1].t1), float(m), temp, bias, sid, self.session))
            del lst[:-BIN_ENTRIES]
        remember(self.recent, RecentStretch(self.stretches, self.session, [
            [r.n, r.temp_c, *r.gyro_mean, r.t1] for r in new]), CHECK_STRETCHES, CHECK_ROWS)
        # Refit; the candidate swaps in when it predicts this session's recent still time better.
        self._fresh = False
        t_now = new[-1].t1
        fit = self._fit_table(self.entries(), len(self.bins), t_now, self._floor())
        rows = [r for s in self.recent if s.session == self.session for r in s.rows]
        return self._offer(fit, np.asarray(rows, dtype=np.float64).reshape(-1, 6), t_now)

    # -- the fit ----------------------------------------------------------------------

    def entries(self) -> NDArray[np.float64]:
        """Return the point table: rows ``(t_end, samples, temp, bx, by, bz, session)``."""
        return np.asarray([[e.t_end, e.samples, e.temp_c, *e.bias, e.session]
                           for v in self.bins.values() for e in v], np.float64).reshape(-1, 7)

    def _fit_table(self, e: NDArray[np.float64], bins: int, t_now: float, floor: float) -> dict:
        """
        Fit a point table of ``bins`` bins: its own model, or a correction to the prior.

        Where the growth rule allows fewer terms than the prior's curve has, the prior's
        shape is kept and its residuals fitted (:func:`gyro_tdc.learn.fit.correction_features`):
        the record names the prior (``prior``, its ``model_id``).
        """
        feats = grow_features(e[:, 2], bins)
        if (corr := correction_features(self.prior, feats)) is None:
            return fit_points(e, feats, t_now, self.config.half_life_s, floor)
        e = on_prior(self.prior, e, columns=(2, 3))
        return dict(fit_points(e, corr, t_now, self.config.half_life_s, floor),
                    prior=self.prior.model_id)

    def _floor(self) -> float:
        """Return the largest finite gyro noise floor of the axes, rad/s (0: none yet)."""
        floor = self.still.gyro_floor
        return float(np.nanmax(np.where(np.isfinite(floor), floor, 0.0)))

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
        if not rows.shape[0]:           # no still window of this session to judge it by
            return False
        floor = self._floor()
        since = t_now - self.config.offset_s if since is None else since
        # A correction: its offset from the windows' residuals on the prior.
        seen = rows if fit.get('prior') is None else on_prior(self.prior, rows)
        try:
            cand = model_of(fit, self.thermal, self.prior)
            offset = recent_offset(fit, seen, since) if self.config.offset_s > 0 else None
            # Whose offset it carries: the newest still time it was taken from (the core keeps
            # re-anchoring a new power cycle until a model carries that cycle's offset).
            until = offset_until(rows, since, offset is not None, self.entries(), self.session)
            up = power_up_offset(fit, self.power_ups, self.prior)
            if offset is not None or until is None:   # the newest still time's, or a power-up's
                fit['coef'][0] = up if offset is None else offset
                cand = model_of(fit, self.thermal, self.prior)
            # The intercept the core gives the next power cycle until its offset is known.
            twin = cand if offset is None and until is None else model_of(
                dict(fit, coef=[up] + fit['coef'][1:]), self.thermal, self.prior)
        except ModelFileError as exc:     # checked as a model file: never installed
            self.refused, self.refused_why = self.refused + 1, str(exc)
            return False
        anchor = since if self.config.offset_s > 0 or since == -math.inf else None
        # gyro_floor: the noise of the samples it is handed (the core's re-anchoring prior at a
        # new one).
        cand.created.update({'offset_until': until, POWER_UP_KEY: twin.intercept.tolist(),
                             'gyro_floor': [float(v) for v in self.still.gyro_floor]})
        new, old, swap = compare(cand, self.model, rows, self.thermal, anchor, floor)
        self.check = {'t': t_now, 'candidate_mse': new, 'current_mse': old, 'swapped': swap}
        if not swap:
            return False
        # The start-up shift the node takes on it: the trainer's rule on the points (learn.gate).
        fit['reanchor'] = learned_gate(cand, self.entries(), lambda sub: self._fit_table(
            sub, np.unique(sub[:, 2] // self.config.bin_c).size, t_now, floor),
            self.thermal, self.prior)
        cand = cand.replace(metrics={**cand.metrics, 'reanchor': fit['reanchor']})
        trigger = t_now if self._trigger is None else max(self._trigger, t_now)
        self._swaps.append((trigger + self.config.swap_delay_s, cand))
        self.fit, self.model, self.last_update_t = fit, cand, t_now
        self.swaps += 1
        return True

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
            'learn held out': held_out_line(self.fit),
            'learn session': str(self.session), 'learn late swaps': str(self.late_swaps),
            'learn candidates refused': (f'{self.refused} (last: {self.refused_why})'
                                         if self.refused else '0'),
        }

    def summary(self) -> dict[str, Any]:
        """Return what /diagnostics shows: points, range, still time, last update, check."""
        chk, e = self.check, self.entries()
        return {
            'points': int(e.shape[0]), 'bins': len(self.bins),
            'covered_c': (float(e[:, 2].min()), float(e[:, 2].max())) if e.shape[0] else None,
            'still_s': self.still_s,
            'stretches': self.stretches, 'last_update_t': self.last_update_t,
            'features': None if self.fit is None else (
                (['prior'] if self.fit.get('prior') else []) + (self.fit['features'] or ['bias'])),
            'held_out': None if self.fit is None else self.fit.get('held_out'),
            'swaps': self.swaps, 'check': None if chk is None else (
                f"candidate {math.sqrt(chk['candidate_mse']):.3g} rad/s vs current "
                + ('none' if chk['current_mse'] is None
                   else f"{math.sqrt(chk['current_mse']):.3g} rad/s")
                + (' -> swapped' if chk['swapped'] else ' -> kept')),
        }
