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
The streaming form of the still test: windows judged one sample (or one chunk) at a time.

:class:`StillWindows` is the one streaming detector (windows, running noise floor, motion
reports, verdict); its users keep their own stretches of still windows. The rule, the floor,
the reports and the window statistics live in :mod:`gyro_tdc.signal.still`. See
doc/internals/signal.md.
"""

from __future__ import annotations

from array import array
import math
from typing import Any, NamedTuple, Sequence

from gyro_tdc.signal.still import (judge_windows, MAX_RATE, MIN_JUDGED, MotionReports,
                                   noise_thresholds, NOISE_WINDOWS, NoiseFloor, STILL_WINDOW_S,
                                   window_moments)
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['CUTS', 'StillWindows', 'Window']

#: How a stream is cut into windows: ``'grid'``, on ``floor((t - t_first) / window_s)`` (the
#: batch form's grid; a window is judged when the first sample of the next arrives), or
#: ``'span'``, a window ends with (and includes) its first sample at least ``window_s``
#: after its first one (the re-anchoring's windows).
CUTS = ('grid', 'span')

#: Columns of a buffered sample: stamp, raw rate (3), acceleration (3), rate (3), temperature.
_COLS = 11
_NAN3 = (math.nan, math.nan, math.nan)


class Window(NamedTuple):
    """
    One judged window of a stream (:class:`StillWindows`).

    Parameters
    ----------
    t0, t1 : float, s
        First and last stamp.
    n : int
        Samples.
    gyro_mean, gyro_std : tuple of 3 float, rad/s
        Raw-rate mean and standard deviation (ddof 1).
    accel_std : tuple of 3 float, m/s^2, or None
        The acceleration's standard deviation (None: the window has no accelerometer data).
    rate_mean : tuple of 3 float, rad/s, or None
        Mean of the ``rate`` given (None: none was).
    temp_c : float, degC
        Mean temperature given (NaN when a sample had none).
    moving : bool
        A motion report or flag vetoed it.
    why : str
        ``''`` for a still window, else why not (one of :data:`~gyro_tdc.signal.still.REASONS`).
    thresholds : tuple of two tuples of 3 float
        Gyro (rad/s) and accelerometer (m/s^2) thresholds in force when it was judged.
    t_next : float or None, s
        Stamp of the sample that ended it (``'grid'``: the next window's first; None when
        it ended with its own last sample or was flushed).
    samples : NDArray[np.float64], shape (n, 11), or None
        Its samples: stamp, raw rate, acceleration, rate, temperature (NaN: not given);
        None in a window kept without them (:meth:`light`).

    """

    t0: float
    t1: float
    n: int
    gyro_mean: tuple
    gyro_std: tuple
    accel_std: tuple | None
    rate_mean: tuple | None
    temp_c: float
    moving: bool
    why: str
    thresholds: tuple
    t_next: float | None
    samples: NDArray[np.float64] | None

    def light(self) -> 'Window':
        """Return the window without its samples (to keep many without their memory)."""
        return self._replace(samples=None)

    @property
    def t(self) -> NDArray[np.float64]:
        """Return the stamps, shape (n,), s."""
        return self.samples[:, 0]

    @property
    def rate(self) -> NDArray[np.float64]:
        """Return the ``rate`` given, shape (n, 3), rad/s (NaN: not given)."""
        return self.samples[:, 7:10]

    @property
    def temp(self) -> NDArray[np.float64]:
        """Return the temperatures, shape (n,), degC (NaN: not given)."""
        return self.samples[:, 10]


#: Samples of a window the finest step between readings is looked for in (its first).
_STEP_ROWS = 64


def _step(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """
    Return per column a finest positive step between readings (inf: none).

    The step is looked for among the first :data:`_STEP_ROWS` readings: on quantised data
    two neighbouring levels are there; on data that are not, any step found is far below
    the noise (the floor it bounds is then the pooled variance's).
    """
    d = np.diff(np.sort(x[:_STEP_ROWS], axis=0), axis=0)
    return np.where(d > 0.0, d, math.inf).min(axis=0, initial=math.inf)


def _floor(noise: str, doc: str) -> property:
    """Return a property reading and setting the ``floor`` (3,) of the NoiseFloor ``noise``."""
    def put(self: Any, value: ArrayLike) -> None:
        getattr(self, noise).floor = np.asarray(value, dtype=np.float64).reshape(3)
    return property(lambda self: getattr(self, noise).floor, put, doc=doc)


class StillWindows:
    """
    The still test one sample at a time: each window's statistics and verdict as it ends.

    The verdict is :func:`judge_windows` against :func:`noise_thresholds` of the running
    noise floor (:class:`NoiseFloor`: the quietest stretch of windows so far pooled to
    :data:`~gyro_tdc.signal.still.NOISE_DOF` degrees of freedom, windows of at least
    ``min_samples`` finite samples), held below the prior over the first
    :data:`NOISE_WINDOWS` windows and until a floor is known, when one is given; a window
    whose readings on an axis never change has a standard deviation of exactly zero there; a
    window is vetoed by a ``moving`` sample flag or a motion report (:meth:`observe_motion`),
    and with a ``rate`` its mean is at most ``max_rate``. Acceleration counts for a window
    when every sample has a finite one and not all are zero (as
    :func:`~gyro_tdc.signal.has_accelerometer`: a driver without one publishes zeros).

    Parameters
    ----------
    window_s : float, s
        Window length.
    cut : str
        One of :data:`CUTS`.
    gyro_std, accel_std : float
        Fixed thresholds, rad/s and m/s^2; 0: auto.
    max_rate : float, rad/s
        Largest mean of the ``rate`` given over a still window.
    min_samples : int
        Fewest samples of a window that may be still (and lower the floor).
    prior_std : sequence of 3 float, rad/s, optional
        Prior of the gyro's scatter (a model's residual standard deviation).

    """

    def __init__(self, window_s: float = STILL_WINDOW_S, *, cut: str = 'grid',
                 gyro_std: float = 0.0, accel_std: float = 0.0, max_rate: float = MAX_RATE,
                 min_samples: int = MIN_JUDGED, prior_std: ArrayLike | None = None) -> None:
        if not (math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f'Expected `window_s` > 0, got {window_s!r}.')
        if cut not in CUTS:
            raise ValueError(f'Expected `cut` in {CUTS}, got {cut!r}.')
        self.window_s, self.cut, self._grid = float(window_s), cut, cut == 'grid'
        self.gyro_std, self.accel_std = float(gyro_std), float(accel_std)
        self.max_rate, self.min_samples = float(max_rate), int(min_samples)
        self.motion = MotionReports()
        self.reset(prior_std=prior_std)

    # -- state -------------------------------------------------------------------------

    def reset(self, *, prior_std: ArrayLike | None = None) -> None:
        """Forget the floor and the window in progress (motion reports are kept)."""
        self.prior_std = None if prior_std is None else np.asarray(prior_std, float).reshape(3)
        self.gyro_noise, self.accel_noise, self.windows_seen = NoiseFloor(), NoiseFloor(), 0
        self.restart()

    def restart(self) -> None:
        """Drop the window in progress; the next sample starts the grid again (floor kept)."""
        self.t_first: float | None = None
        self.drop_window()

    def drop_window(self) -> None:
        """Drop the samples of the window in progress (the grid and the floor are kept)."""
        self._buf = array('d')
        self._chunk: NDArray[np.float64] | None = None
        self._k: int | None = None
        self._t0, self._moving = math.nan, False

    gyro_floor = _floor('gyro_noise', 'Gyro noise floor, shape (3,), rad/s (inf: none yet).')
    accel_floor = _floor('accel_noise',
                         'Accelerometer noise floor, shape (3,), m/s^2 (inf: none yet).')

    @property
    def window_end(self) -> float | None:
        """Return the grid stamp at which the window in progress ends (None: no window)."""
        ended = self._k is None or self.t_first is None or not self._grid
        return None if ended else self.t_first + (self._k + 1) * self.window_s

    def observe_motion(self, t: float, moving: bool) -> None:
        """Record a motion report: from stamp ``t`` (s) until the next, moving or not."""
        self.motion.add(t, moving)

    def thresholds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the gyro and accelerometer thresholds in force (fixed or auto)."""
        early = self.windows_seen < NOISE_WINDOWS or not np.isfinite(self.gyro_floor).any()
        return noise_thresholds(self.gyro_floor, self.accel_floor, gyro_std=self.gyro_std,
                                accel_std=self.accel_std,
                                prior_std=self.prior_std if early else None)

    def last_refused(self, windows: Sequence[Window], thresholds: tuple | None = None
                     ) -> tuple[int, str]:
        """
        Return the newest of ``windows`` the thresholds refuse, and why (-1, '': none).

        A lower floor may show earlier windows of a stretch as moving: what follows the
        newest refused one is kept. ``thresholds`` default to those in force.
        """
        g_thr, a_thr = self.thresholds() if thresholds is None else thresholds
        for j, w in reversed(list(enumerate(windows))):
            why = judge_windows([w.gyro_std], None if w.accel_std is None else [w.accel_std],
                                g_thr, a_thr)[0]
            if why:
                return j, str(why)
        return -1, ''

    # -- samples -----------------------------------------------------------------------

    def add(self, t: float, raw: Sequence[float], accel: Sequence[float] | None = None, *,
            rate: Sequence[float] | None = None, temp_c: float = math.nan, moving: bool = False
            ) -> Window | None:
        """
        Add one sample; return the window it ended, judged, if any (else None).

        ``t`` (s) increasing; ``raw`` rate and ``rate`` (compensated by a prior, for the rate
        test) rad/s, ``accel`` m/s^2 (both optional); ``temp_c`` (degC) is averaged over the
        window; ``moving`` (a motion flag) vetoes this sample's window.
        """
        done = None
        if self._grid:
            if self.t_first is None:
                self.t_first = float(t)
            k = math.floor((t - self.t_first) / self.window_s)
            if self._k is not None and k != self._k:
                done = self._end(t)
            self._k = k
        buf = self._buf
        if not buf and self._chunk is None:
            self._t0 = t
        buf.extend((t, *raw, *(_NAN3 if accel is None else accel),
                    *(_NAN3 if rate is None else rate), temp_c))
        self._moving = self._moving or bool(moving)
        if (not self._grid and t - self._t0 >= self.window_s
                and (len(buf) > _COLS or self._chunk is not None)):
            done = self._end(None)
        return done

    def extend(self, t: NDArray[np.float64], gyro: NDArray[np.float64],
               accel: NDArray[np.float64] | None = None, temp: NDArray[np.float64] | None = None
               ) -> list[Window]:
        """
        Add a chunk of samples (stamps increasing); return the windows it ended, judged.

        The same windows and statistics as :meth:`add` one sample at a time.
        """
        if not (t := np.asarray(t, dtype=np.float64)).size:
            return []
        x = np.full((t.size, _COLS), math.nan)
        x[:, 0], x[:, 1:4] = t, gyro
        for cols, v in ((slice(4, 7), accel), (10, temp)):       # optional: NaN without
            if v is not None:
                x[:, cols] = v
        if (pending := self._take()) is not None:
            x = np.concatenate([pending, x])
        tt = x[:, 0]
        if self._grid:
            if self.t_first is None:
                self.t_first = float(tt[0])
            k = np.floor((tt - self.t_first) / self.window_s).astype(np.int64)
            cut = np.flatnonzero(k != k[-1])
            done = int(cut[-1]) + 1 if cut.size else 0
            start = np.flatnonzero(np.diff(k[:done], prepend=k[0] - 1))     # where k changes
            nxt = np.r_[tt[start[1:]], tt[done]].tolist()
            self._k = int(k[-1])
        else:
            start, done = [], 0
            while done < tt.size:
                later = np.flatnonzero(tt[done + 1:] - tt[done] >= self.window_s)
                if not later.size:
                    break
                start.append(done)
                done += 2 + int(later[0])
            start = np.asarray(start, dtype=np.int64)
            nxt = [None] * start.size
        if done < tt.size:
            self._chunk = x[done:]
            self._t0 = float(tt[done])
        return self._finish(x[:done], start, nxt) if done else []

    def flush(self) -> Window | None:
        """Judge the window in progress (at shutdown, or a new session); None when empty."""
        self._k = None
        return self._end(None)

    def _take(self) -> NDArray[np.float64] | None:
        """Return the samples of the window in progress, shape (n, 11), and empty it (None)."""
        parts = [p for p in (self._chunk, np.frombuffer(self._buf).reshape(-1, _COLS)
                             if self._buf else None) if p is not None]
        self._buf, self._chunk = array('d'), None
        return None if not parts else parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _end(self, t_next: float | None) -> Window | None:
        """Judge the window in progress (it ends before the sample at ``t_next``; None: empty)."""
        x = self._take()
        return None if x is None else self._finish(x, np.zeros(1, dtype=np.int64), [t_next])[0]

    def _finish(self, x: NDArray[np.float64], start: NDArray[np.int64],
                t_next: list) -> list[Window]:
        """Compute the statistics of the windows of ``x`` starting at ``start``; judge them."""
        n = np.diff(np.r_[start, x.shape[0]])
        g_mean, g_std = window_moments(x[:, 1:4], start, n)
        fin_g = np.isfinite(g_mean).all(axis=1) & np.isfinite(g_std).all(axis=1)
        acc = x[:, 4:7]
        fin_a = np.logical_and.reduceat(np.isfinite(acc).all(axis=1), start)
        a_mean = a_std = None
        if fin_a.any():
            a_mean, a_std = window_moments(acc, start, n)
            # Finite rows, all zero exactly when mean and std are (has_accelerometer).
            fin_a &= ~(np.all(a_mean == 0.0, axis=1) & np.all(a_std == 0.0, axis=1))
        rate = x[:, 7:10]
        given = np.logical_or.reduceat(np.isfinite(rate).any(axis=1), start)
        r_mean = window_moments(rate, start, n)[0] if given.any() else None
        temp = np.add.reduceat(np.ascontiguousarray(x[:, 10]), start) / n
        flag, self._moving = self._moving, False     # the flag of the window in progress
        out = []
        # The windows in turn: each lowers the floor the next is judged by.
        for i, (a, k) in enumerate(zip(start.tolist(), n.tolist())):
            rows, finite = x[a:a + k], bool(fin_g[i])
            t0, t1 = float(rows[0, 0]), float(rows[-1, 0])
            self.windows_seen += 1
            stds = [tuple(g_std[i].tolist()), tuple(a_std[i].tolist()) if fin_a[i] else None]
            for j, noise in enumerate((self.gyro_noise, self.accel_noise)):
                if finite and stds[j] is not None and k >= self.min_samples:
                    noise.add(k - 1, np.asarray(stds[j]) ** 2, _step(rows[:, 1 + 3 * j:4 + 3 * j]))
            rm = None if r_mean is None or not given[i] else tuple(r_mean[i].tolist())
            g_thr, a_thr = self.thresholds()
            moving = self.motion.veto(t0, t1) or (flag and i == 0)
            why = str(judge_windows([stds[0]], None if stds[1] is None else [stds[1]], g_thr,
                                    a_thr, mean_rate=None if rm is None else [rm],
                                    max_rate=self.max_rate, moving=[moving], counts=[k],
                                    min_samples=self.min_samples, finite=[finite])[0])
            out.append(Window(t0, t1, k, tuple(g_mean[i].tolist()), *stds, rm, float(temp[i]),
                              moving, why, (tuple(g_thr.tolist()), tuple(a_thr.tolist())),
                              t_next[i], rows))
        return out
