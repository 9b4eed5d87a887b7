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

from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.fit import (BINS_DT2, BINS_DT3, fit_points, grow_features, learned_model,
                                MAX_DROPS, model_of, OUTLIER_K, prediction_mse, SPAN_DT2_C,
                                SPAN_DT3_C, SPAN_DT_C)
from gyro_tdc.learn.store import decode_state, encode_state, FORMAT, read_state, write_state
from gyro_tdc.learn.temperature import hold_readings, same_thermal, stream_state
from gyro_tdc.model import CompensationModel, ThermalState
from gyro_tdc.signal import MIN_STILL_S, STILL_WINDOW_S, StillWindows, Window
import numpy as np
from numpy.typing import NDArray

__all__ = ['BIN_ENTRIES', 'CHECK_STRETCHES', 'FORMAT', 'Learner', 'LearnConfig',
           'OUTLIER_K', 'SPAN_DT2_C', 'SPAN_DT3_C', 'SPAN_DT_C', 'BINS_DT2', 'BINS_DT3',
           'MAX_DROPS', 'learned_model']

NAN3 = (math.nan, math.nan, math.nan)
#: Floats per sample in :attr:`Learner.buf`: stamp, rate (3), acceleration (3).
SAMPLE = 7
BIN_ENTRIES = 4
CHECK_STRETCHES = 3


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
    max_rate_hz : float, Hz
        The core hands the learner a sample only when its stamp is at least
        ``1 / max_rate_hz`` after the last one handed (by stamp, so a replay at any speed
        hands the same samples): a 1 kHz IMU is learned from every 10th sample, plenty for
        10 s still windows, and the message path stays cheap.
    session_gap_s : float, s
        A gap in the IMU stamps longer than this starts a new session (a power-up: the
        gyro's turn-on offset changes; each session gets its own intercept in the fit).
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
    max_rate_hz: float = 100.0
    session_gap_s: float = 600.0
    swap_delay_s: float = 5.0


@dataclass
class _Stretch:
    """Windows of the current still stretch (:class:`gyro_tdc.signal.Window`, no samples)."""

    rows: list[Window] = field(default_factory=list)


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
        self._done = 0
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
        self._stretch, self._done = _Stretch(), 0
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
        wend = self.still.window_end
        return not buf or (wend is not None and buf[-SAMPLE] < wend)

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
        wend = self.still.window_end
        if not buf or (not force and wend is not None and buf[-SAMPLE] < wend):
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
        # A gap over session_gap_s (before the batch or inside it) starts a new session.
        gaps = np.flatnonzero(np.diff(t, prepend=t[0] if self.last_t is None else self.last_t)
                              > self.config.session_gap_s)
        swapped = False
        for lo, hi in zip(np.r_[0, gaps], np.r_[gaps, t.size]):
            if hi > lo:
                swapped = self._batch(t[lo:hi], w[lo:hi], None if acc is None else acc[lo:hi],
                                      temp[lo:hi], lo in gaps) or swapped
        return swapped

    def _batch(self, t, w, acc, temp, new_session: bool) -> bool:
        """Process samples of one session: the still test judges the windows they end."""
        swapped = False
        if new_session:
            # A new session (power-up): its own turn-on offset, learned apart; what it
            # closes was computable at its first sample.
            swapped = self.flush(float(t[0]))
            self.session += 1
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
            if win.why or not math.isfinite(win.temp_c):
                swapped = self._close(win.thresholds) or swapped
                continue
            self._stretch.rows.append(win.light())
            swapped = self._commit() or swapped
        return swapped

    def _close(self, thresholds: tuple | None = None) -> bool:
        """
        End the stretch: keep it when long enough, learn what is not learned yet.

        Its windows that ``thresholds`` (default: those in force) refuse are dropped with
        everything before them (unless part of it was learned already).
        """
        rows, self._stretch = self._stretch.rows, _Stretch()
        done, self._done = self._done, 0
        if not rows:
            return False
        if not done:
            j, _ = self.still.last_refused(rows, thresholds)
            if j >= 0:
                rows = rows[j + 1:]
            if not rows or self._span(rows) + 1e-9 < self.config.min_still_s:
                return False
            self.stretches += 1
        return self._learn(rows[done:], rows)

    @staticmethod
    def _span(rows: list[Window]) -> float:
        """Return the duration of consecutive windows, s (one sample period included)."""
        n = sum(r.n for r in rows)
        return rows[-1].t1 - rows[0].t0 + (rows[-1].t1 - rows[0].t0) / max(n - 1, 1)

    def _commit(self) -> bool:
        """Learn a long stretch's windows so far (every ``commit_s``) while it goes on."""
        rows = self._stretch.rows
        done = self._done
        if (self._span(rows) < self.config.min_still_s
                or (done and rows[-1].t1 - rows[done].t0 < self.config.commit_s)):
            return False
        if not done:
            self.stretches += 1
        self._done = len(rows)
        return self._learn(rows[done:], rows)

    def _learn(self, new: list, rows: list) -> bool:
        """Bin new windows of the current stretch (merged per bin), refit, maybe swap."""
        if not new:
            return False
        n = sum(r.n for r in new)
        self.still_s += new[-1].t1 - new[0].t0 + (new[-1].t1 - new[0].t0) / max(n - 1, 1)
        groups: dict[int, list] = {}
        for r in new:
            groups.setdefault(int(math.floor(r.temp_c / self.config.bin_c)), []).append(r)
        sid = self.stretches
        for b, rs in groups.items():
            m = sum(r.n for r in rs)
            entry = [float(rs[-1].t1), float(m), sum(r.temp_c * r.n for r in rs) / m,
                     tuple(sum(r.gyro_mean[a] * r.n for r in rs) / m for a in range(3)), sid,
                     self.session]
            lst = self.bins.setdefault(b, [])
            if lst and lst[-1][4] == sid:          # the same stretch: one entry per bin
                o = lst[-1]
                tot = o[1] + m
                entry = [entry[0], tot, (o[2] * o[1] + entry[2] * m) / tot,
                         tuple((o[3][a] * o[1] + entry[3][a] * m) / tot for a in range(3)),
                         sid, self.session]
                lst[-1] = entry
            else:
                lst.append(entry)
            del lst[:-BIN_ENTRIES]
        recent = [[r.n, r.temp_c, *r.gyro_mean, r.t1] for r in rows]
        if self.recent and self.recent[-1][0] == sid:
            self.recent[-1] = [sid, self.session, recent]
        else:
            self.recent.append([sid, self.session, recent])
        del self.recent[:-CHECK_STRETCHES]
        return self._refit(new[-1].t1)

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
        e = self.entries()
        floor = float(np.nanmax(np.where(np.isfinite(self.gyro_floor), self.gyro_floor, 0.0)))
        fit = fit_points(e, grow_features(e[:, 2], len(self.bins)), t_now,
                         self.config.half_life_s, floor)
        try:
            cand = model_of(fit, self.thermal)
        except ModelFileError as exc:     # checked as a model file: never installed
            self.refused, self.refused_why = self.refused + 1, str(exc)
            return False
        new = self._score(cand)
        old = None if self.model is None else self._score(self.model)
        self.check = {'t': t_now, 'candidate_mse': new, 'current_mse': old,
                      'swapped': old is None or new < old}
        if old is not None and not new < old:
            return False
        trigger = t_now if self._trigger is None else max(self._trigger, t_now)
        self._swaps.append((trigger + self.config.swap_delay_s, cand))
        self.fit, self.model = fit, cand
        self.last_update_t = t_now
        self.swaps += 1
        return True

    def _score(self, model: CompensationModel) -> float:
        """Return the prediction check's error of ``model`` over this session's recent windows."""
        return prediction_mse(model, [r for s in self.recent if s[1] == self.session
                                      for r in s[2]], self.thermal)

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
