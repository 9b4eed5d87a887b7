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
Still stretches of a stream as they end: :class:`StillWindows` with a stretch on top.

The tests' check that the streaming still test finds the batch form's stretches
(:func:`gyro_tdc.signal.detect_still`); the learner keeps its own stretch of windows.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.signal.still import MAX_RATE, MIN_STILL_S, REASONS, STILL_WINDOW_S
from gyro_tdc.signal.still_stream import StillWindows, Window
from numpy.typing import ArrayLike


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
    Still stretches of a stream as they end: consecutive still windows of :class:`StillWindows`.

    When the floor drops, the windows of the current stretch that the new thresholds refuse
    are dropped with everything before them; a stretch is returned when the first window
    that is not still ends it, if it lasted ``min_still_s``. With fixed thresholds the
    stretches are exactly those of :func:`detect_still` on the same samples; with auto
    thresholds they match once the floor is known (the batch form knows it from the start).

    Parameters
    ----------
    window_s : float, s
        Window length (at least :data:`MIN_WINDOW_SAMPLES` sample periods).
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
        self.windows = StillWindows(window_s, gyro_std=gyro_std, accel_std=accel_std,
                                    max_rate=max_rate, prior_std=prior_std)
        self.min_still_s = float(min_still_s)
        self.reset()

    def reset(self) -> None:
        """Forget everything (noise floor included); the next sample starts the grid."""
        self.windows.reset(prior_std=self.windows.prior_std)
        self.rejected = {r: 0 for r in REASONS}
        self._stretch: list[Window] = []

    def update(self, t: float, raw: ArrayLike, accel: ArrayLike | None = None, *,
               rate: ArrayLike | None = None, temp_c: float = math.nan,
               moving: bool = False) -> StillSegment | None:
        """
        Add one sample (as :meth:`StillWindows.add`); return the still stretch it ended, if any.

        Returns
        -------
        StillSegment or None
            The stretch that just ended (at least ``min_still_s``), else None.

        """
        return self._take(self.windows.add(t, raw, accel, rate=rate, temp_c=temp_c,
                                           moving=moving))

    def flush(self) -> StillSegment | None:
        """Judge the window in progress and return the stretch it ends (at shutdown)."""
        done = self._take(self.windows.flush())
        return done if done is not None else self._close()

    def _take(self, w: Window | None) -> StillSegment | None:
        """Extend the stretch with a judged window (None: none ended), or end it."""
        if w is None:
            return None
        if w.why:
            self.rejected[w.why] += 1
            return self._close()
        st = self._stretch
        j, why = self.windows.last_refused(st, w.thresholds)
        if j >= 0:
            self.rejected[why] += j + 1
            del st[:j + 1]
        st.append(w.light())
        return None

    def _close(self) -> StillSegment | None:
        """End the current stretch; return it when long enough."""
        st, self._stretch = self._stretch, []
        if not st:
            return None
        t0, t1 = st[0].t0, st[-1].t1
        n = sum(w.n for w in st)
        period = (t1 - t0) / max(n - 1, 1)
        if t1 - t0 + period + 1e-9 < self.min_still_s:
            self.rejected['brief'] += len(st)
            return None
        g_mean = tuple(sum(w.gyro_mean[i] * w.n for w in st) / n for i in range(3))
        g_std = tuple(math.sqrt(sum(w.gyro_std[i] ** 2 for w in st) / len(st)) for i in range(3))
        r_mean = (None if any(w.rate_mean is None for w in st) else
                  tuple(sum(w.rate_mean[i] * w.n for w in st) / n for i in range(3)))
        temp = sum(w.temp_c * w.n for w in st) / n
        return StillSegment(float(t0), float(t1), int(n), g_mean, g_std, r_mean, float(temp))
