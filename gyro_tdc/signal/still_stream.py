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
The streaming form of the still test: :class:`StreamingStill`, one sample at a time.

It returns each still stretch (:class:`StillSegment`: its mean rate and temperature) as it
ends, equal to :func:`gyro_tdc.signal.detect_still` on the same samples once the noise
floor is known. See :mod:`gyro_tdc.signal` for the test.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.signal.still_verdict import (has_accelerometer, judge_windows, MAX_RATE, MIN_STILL_S,
                                           MIN_WINDOW_SAMPLES, noise_thresholds, NOISE_WINDOWS,
                                           REASONS, STILL_WINDOW_S)
import numpy as np
from numpy.typing import ArrayLike

__all__ = ['StillSegment', 'StreamingStill']


def _accumulate(v: ArrayLike, c: list, s: list, q: list | None = None) -> None:
    """Add ``v - c`` to the running sums ``s`` and, when given, its square to ``q``."""
    for i in range(3):
        d = v[i] - c[i]
        s[i] += d
        if q is not None:
            q[i] += d * d


def _std(s: list, q: list, n: int) -> list:
    """Return per-axis standard deviations (ddof 1) from centred sums (NaN below 2 samples)."""
    return [math.sqrt(max(qi - si * si / n, 0.0) / (n - 1)) if n > 1 else math.nan
            for si, qi in zip(s, q)]


@dataclass(frozen=True)
class StillSegment:
    """
    One finished still stretch of a stream (:class:`StreamingStill`).

    Parameters
    ----------
    t0_s, t1_s : float, s
        First and last stamp.
    samples : int
        Samples in it.
    gyro_mean : tuple of 3 float, rad/s
        Mean raw rate (the bias while still).
    gyro_std : tuple of 3 float, rad/s
        Standard deviation of the raw rate around its window means (RMS over the windows).
    rate_mean : tuple of 3 float, rad/s, or None
        Mean of the ``rate`` given (e.g. the compensated rate), None when none was.
    temp_c : float, degC
        Mean of the ``temp_c`` given (e.g. the model temperature); NaN when none was.

    """

    t0_s: float
    t1_s: float
    samples: int
    gyro_mean: tuple
    gyro_std: tuple
    rate_mean: tuple | None
    temp_c: float

    @property
    def duration_s(self) -> float:
        """Return the span of the stamps, s."""
        return self.t1_s - self.t0_s


class StreamingStill:
    """
    The still test one sample at a time: still stretches as they end (the streaming form).

    Windows are cut on the grid ``floor((t - t_first) / window_s)`` as in
    :func:`detect_still` (a window is judged when the first sample of the next one arrives;
    set ``window_s`` to at least :data:`MIN_WINDOW_SAMPLES` sample periods, the batch form
    lengthens it itself); the verdict is :func:`judge_windows` with :func:`noise_thresholds`
    of the running noise floor (the quietest window so far that a motion report did not
    veto), held below the prior over the first :data:`NOISE_WINDOWS` windows when one is
    given; when the floor drops, the windows of the current stretch that the new thresholds
    refuse are dropped with everything before them. Consecutive still windows make a
    stretch; it is returned by :meth:`update` when the first window that is not still ends
    it, if it lasted ``min_still_s``. With fixed
    thresholds the stretches are exactly those of :func:`detect_still` on the same samples;
    with auto thresholds they match once the floor is known (the batch form knows it from
    the start).

    Parameters
    ----------
    window_s : float, s
        Window length.
    min_still_s : float, s
        Shortest stretch returned.
    gyro_std, accel_std : float
        Fixed thresholds, rad/s and m/s^2; 0: auto.
    max_rate : float, rad/s
        Largest mean of the ``rate`` given over a still window.
    prior_std : sequence of 3 float, rad/s, optional
        Prior of the gyro's scatter (a model's residual standard deviation).

    """

    def __init__(self, window_s: float = STILL_WINDOW_S, *, min_still_s: float = MIN_STILL_S,
                 gyro_std: float = 0.0, accel_std: float = 0.0, max_rate: float = MAX_RATE,
                 prior_std: ArrayLike | None = None) -> None:
        if not (math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f'Expected `window_s` > 0, got {window_s!r}.')
        self.window_s = float(window_s)
        self.min_still_s = float(min_still_s)
        self.gyro_std, self.accel_std, self.max_rate = float(gyro_std), float(accel_std), \
            float(max_rate)
        self.prior_std = None if prior_std is None else np.asarray(prior_std, float).reshape(3)
        self.reset()

    def reset(self) -> None:
        """Forget everything (noise floor included); the next sample starts the grid."""
        self.gyro_floor = np.full(3, math.inf)
        self.accel_floor = np.full(3, math.inf)
        self.windows_seen = 0
        self.rejected = {r: 0 for r in REASONS}
        self.last_why: str | None = None
        self._t_first: float | None = None
        self._k: int | None = None
        self._stretch: list[tuple] = []
        self._w: dict | None = None

    def _new(self, t: float, raw: ArrayLike, accel: ArrayLike | None,
             rate: ArrayLike | None) -> dict:
        """Return the sums of a window starting at this sample."""
        return {'t0': t, 't1': t, 'n': 0, 'cg': [float(v) for v in raw], 'sg': [0.0] * 3,
                'qg': [0.0] * 3,
                'ca': None if accel is None else [float(v) for v in accel],
                'sa': [0.0] * 3, 'qa': [0.0] * 3,
                'cr': None if rate is None else [float(v) for v in rate], 'sr': [0.0] * 3,
                'temp': 0.0, 'nt': 0, 'moving': False}

    def update(self, t: float, raw: ArrayLike, accel: ArrayLike | None = None, *,
               rate: ArrayLike | None = None, temp_c: float = math.nan,
               moving: bool = False) -> StillSegment | None:
        """
        Add one sample; return the still stretch it ended, if any.

        Parameters
        ----------
        t : float, s
            Stamp (increasing).
        raw : sequence of 3 float, rad/s
            Raw rate.
        accel : sequence of 3 float, m/s^2, optional
            Acceleration (an IMU with an accelerometer gives it with every sample).
        rate : sequence of 3 float, rad/s, optional
            The rate compensated by a prior: a still window's mean of it is at most
            ``max_rate``.
        temp_c : float, degC
            Temperature to average over the stretch (e.g. the model temperature).
        moving : bool
            A motion report vetoes this sample (:func:`motion_veto` of the latest report).

        Returns
        -------
        StillSegment or None
            The stretch that just ended (at least ``min_still_s``), else None.

        """
        if self._t_first is None:
            self._t_first = float(t)
        k = int(math.floor((t - self._t_first) / self.window_s))
        done = None
        if self._w is not None and k != self._k:
            done = self._judge()
        if self._w is None:
            self._w = self._new(t, raw, accel, rate)
            self._k = k
        w = self._w
        w['t1'] = t
        w['n'] += 1
        _accumulate(raw, w['cg'], w['sg'], w['qg'])
        if accel is not None and w['ca'] is not None:
            _accumulate(accel, w['ca'], w['sa'], w['qa'])
        if rate is not None and w['cr'] is not None:
            _accumulate(rate, w['cr'], w['sr'])
        if temp_c == temp_c:              # not NaN
            w['temp'] += temp_c
            w['nt'] += 1
        if moving:
            w['moving'] = True
        return done

    def flush(self) -> StillSegment | None:
        """Judge the window in progress and return the stretch it ends (at shutdown)."""
        done = self._judge() if self._w is not None else None
        return done if done is not None else self._close()

    def _judge(self) -> StillSegment | None:
        """Judge the finished window; extend the stretch, or end it."""
        w, self._w = self._w, None
        n = w['n']
        finite = all(math.isfinite(v) for v in w['sg'] + w['qg'] + w['sa'] + w['qa'])
        mean = [c + s / n for c, s in zip(w['cg'], w['sg'])]
        std = _std(w['sg'], w['qg'], n)
        a_std = None
        if w['ca'] is not None and has_accelerometer([w['ca']]):
            a_std = _std(w['sa'], w['qa'], n)
        self.windows_seen += 1
        if finite and not w['moving'] and n >= max(3, MIN_WINDOW_SAMPLES // 2):
            self.gyro_floor = np.minimum(self.gyro_floor, np.where(np.asarray(std) > 0,
                                                                   std, math.inf))
            if a_std is not None:
                self.accel_floor = np.minimum(self.accel_floor, np.where(
                    np.asarray(a_std) > 0, a_std, math.inf))
        early = self.windows_seen < NOISE_WINDOWS
        g_thr, a_thr = noise_thresholds(self.gyro_floor,
                                        None if a_std is None else self.accel_floor,
                                        gyro_std=self.gyro_std, accel_std=self.accel_std,
                                        prior_std=self.prior_std if early else None)
        rate_mean = (None if w['cr'] is None else
                     [c + s / n for c, s in zip(w['cr'], w['sr'])])
        why = str(judge_windows([std], None if a_std is None else [a_std], g_thr, a_thr,
                                mean_rate=None if rate_mean is None else [rate_mean],
                                max_rate=self.max_rate, moving=[w['moving']])[0])
        if not finite:
            why = 'non-finite'
        if n < max(3, MIN_WINDOW_SAMPLES // 2):
            why = 'samples'
        self.last_why = why
        if why:
            self.rejected[why] += 1
            return self._close()
        # A lower floor may show earlier windows of the stretch as moving: keep what follows.
        st = self._stretch
        for j in range(len(st) - 1, -1, -1):
            old = judge_windows([st[j][2]], None if st[j][4] is None else [st[j][4]], g_thr,
                                a_thr)[0]
            if old:
                self.rejected[str(old)] += j + 1
                del st[:j + 1]
                break
        st.append((w, mean, std, rate_mean, a_std))
        return None

    def _close(self) -> StillSegment | None:
        """End the current stretch; return it when long enough."""
        st, self._stretch = self._stretch, []
        if not st:
            return None
        t0, t1 = st[0][0]['t0'], st[-1][0]['t1']
        n = sum(w['n'] for w, *_ in st)
        period = (t1 - t0) / max(n - 1, 1)
        if t1 - t0 + period + 1e-9 < self.min_still_s:
            self.rejected['brief'] += len(st)
            return None
        g_mean = tuple(sum(m[i] * w['n'] for w, m, *_ in st) / n for i in range(3))
        g_std = tuple(math.sqrt(sum(s[i] ** 2 for _, _, s, *_ in st) / len(st))
                      for i in range(3))
        r_mean = None
        if all(x[3] is not None for x in st):
            r_mean = tuple(sum(x[3][i] * x[0]['n'] for x in st) / n for i in range(3))
        nt = sum(w['nt'] for w, *_ in st)
        temp = sum(w['temp'] for w, *_ in st) / nt if nt else math.nan
        return StillSegment(float(t0), float(t1), int(n), g_mean, g_std, r_mean, float(temp))
