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
Input liveness for /diagnostics: the arrival rate of each input and how long it has been silent.

Pure (no rclpy, no clock of its own: the caller passes ``time.monotonic()``, so liveness holds
with ``use_sim_time`` whether or not a /clock runs). The ROS convention is
diagnostic_updater's ``FrequencyStatus``; that package is not installable here as a Python
package, so :class:`InputRate` is its small equivalent, with the same judgement: a minimum
and maximum expected frequency with a tolerance (10 %), measured over a window (5 s, the
default 5 events of a 1 Hz updater), WARN outside the band and ERROR when the window saw no
event. Three deliberate differences: events are read from the node's cumulative message
counters at each report (the message path is not touched); the window never starts before
the input's first message (so a driver that starts late is not reported slow); and the
window holds at least 20 expected messages (a 1 Hz IMU is judged over 20 s, not 5, where the
one-message granularity of a 5 s window would exceed the tolerance). An expected rate of 0
is learnt from the first :data:`LEARN_S` of arrivals, after which only slowing (and silence) is
judged. diagnostic_updater's ``TimeStampStatus`` compares stamps with the ROS clock; the
compensator's clock is the IMU stamp, so the stamp ages it shows are the other inputs'
stamps against the last IMU stamp (``temperature age s``, judged by ``temperature_timeout``),
and the IMU's own age is the wall time since its last message (``silent_s``).
"""

from __future__ import annotations

from collections import deque
import math
from typing import NamedTuple

from gyro_tdc.runtime.health import ERROR, OK, WARN

__all__ = ['InputRate', 'LEARN_S', 'MIN_EVENTS', 'RateReport', 'TOLERANCE', 'WINDOW_S']

#: diagnostic_updater FrequencyStatus's default tolerance on the expected frequency.
TOLERANCE = 0.1
#: The window of events [s] (FrequencyStatus's default window of 5 reports at 1 Hz).
WINDOW_S = 5.0
#: The window holds at least this many expected messages.
MIN_EVENTS = 20
#: How long the arrivals are counted to learn an expected rate of 0 [s].
LEARN_S = 5.0
#: A rate is judged over at least this much of the window [s].
MIN_WINDOW_S = 1.0


class RateReport(NamedTuple):
    """
    One input's liveness at one report.

    ``level`` OK, WARN or ERROR (always OK for an input that is not judged), ``message`` ''
    when OK; ``hz`` the arrival rate over the window (None before two reports saw it);
    ``events`` and ``window_s`` what it was measured on; ``silent_s`` the wall time since
    its last message (to one report period; since start when none came); ``expected_hz``
    the expected rate (None while learnt or not judged).
    """

    level: int
    message: str
    hz: float | None
    events: int
    window_s: float
    silent_s: float
    expected_hz: float | None

    def values(self, prefix: str) -> dict[str, str]:
        """Return the /diagnostics key/value pairs, keys starting with ``prefix``."""
        rate, expected = ('' if v is None else f'{v:.2f}' for v in (self.hz, self.expected_hz))
        return {f'{prefix} {k}': v for k, v in (
            ('rate Hz', rate), ('expected rate Hz', expected),
            ('events in window', str(self.events)), ('window s', f'{self.window_s:.3f}'),
            ('silent s', f'{self.silent_s:.3f}'))}


class InputRate:
    """
    The arrival rate of one input, judged as diagnostic_updater's FrequencyStatus judges it.

    Parameters
    ----------
    name : str
        The input, as messages name it (``imu/data_raw``).
    start : float, s
        Monotonic time the node started (silence before the first message counts from it).
    expected_hz : float
        Expected rate; 0: learnt from the first :data:`LEARN_S` of arrivals (then only a
        slower rate warns); None: not judged (rate and silence shown only).

    """

    def __init__(self, name: str, start: float, expected_hz: float | None) -> None:
        self.name = name
        self.judged = expected_hz is not None
        self.expected = expected_hz or None
        self.max_hz = self.expected or math.inf
        self._samples: deque[tuple[float, int]] = deque()
        self._first: tuple[float, int] | None = None
        self._count, self._changed = 0, start

    def window(self) -> float:
        """Return the window [s]: :data:`WINDOW_S`, or longer to hold ``MIN_EVENTS`` messages."""
        return max(WINDOW_S, MIN_EVENTS / self.expected) if self.expected else WINDOW_S

    def run(self, now: float, count: int) -> RateReport:
        """
        Judge the input at a report.

        Parameters
        ----------
        now : float, s
            Monotonic time of the report.
        count : int
            Messages of the input received so far (cumulative).

        Returns
        -------
        RateReport
            Level, message and figures.

        """
        if count != self._count:
            self._count, self._changed = count, now
            if self._first is None:
                self._first = (now, count)
        window, samples = self.window(), self._samples
        samples.append((now, count))
        while len(samples) > 1 and samples[1][0] <= now - window:
            samples.popleft()
        base_t, base_n = samples[0]
        if self._first is not None and base_t < self._first[0]:
            base_t, base_n = self._first
        span, events, silent = now - base_t, count - base_n, now - self._changed
        hz = events / span if span > 0.0 and self._first is not None else None
        if self.judged and self.expected is None and self._first is not None:
            first_t, first_n = self._first
            if now - first_t >= LEARN_S and count > first_n:
                self.expected = (count - first_n) / (now - first_t)
                window = self.window()
        level, message = OK, ''          # not judged: rate and silence shown only
        if self.judged and self._first is None:
            level = ERROR if silent >= window else WARN
            message = f'no {self.name} yet ({silent:.1f} s since start)'
        elif self.judged and silent >= window:    # FrequencyStatus: no events in the window
            level, message = ERROR, f'no {self.name} for {silent:.1f} s'
        elif self.expected and hz is not None and span >= MIN_WINDOW_S:   # judged only
            lo, hi = self.expected * (1.0 - TOLERANCE), self.max_hz * (1.0 + TOLERANCE)
            if not lo <= hz <= hi:
                too, at, bound = ('slow', 'least', lo) if hz < lo else ('fast', 'most', hi)
                level, message = WARN, (f'{self.name} too {too}: {hz:.2f} Hz over {span:.1f} s, '
                                        f'expected {self.expected:.2f} Hz (at {at} {bound:.2f})')
        return RateReport(level, message, hz, events, span, silent, self.expected)
