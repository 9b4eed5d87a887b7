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
The compensator's own backlog: how long samples wait, callback time, samples missing.

Pure (numpy). The IMU callbacks append each sample's stamp and their start and end on the
steady clock (``time.perf_counter``, never ROS time) to one flat array; once a report
:meth:`Backlog.report` judges them: queue age, callback time, samples missing by stamp.
"""

from __future__ import annotations

from array import array
import math
from typing import NamedTuple

import numpy as np

__all__ = ['BASELINE_DRIFT', 'Backlog', 'BacklogReport', 'GAP_PERIODS', 'JUMP_SAMPLES',
           'MIN_STEPS', 'PAUSE_S', 'PERIOD_QUANTILE', 'QUEUE_AGE_WARN_S', 'STAMP_JUMP_S']

#: A sample that waited longer than this in the input queue (its queue age) means the node
#: fell behind: WARN [s]. Above ``load_wait``'s default pause (0.1 s) and a garbage
#: collection; a quarter of the default 2000-sample queue at 2 kHz.
QUEUE_AGE_WARN_S = 0.25
#: A stamp step longer than this many input periods is a gap: ``round(step / period) - 1``
#: samples are missing.
GAP_PERIODS = 1.5
#: A gap longer than this, of stamps and of the node's idle time before the sample, after
#: which the sample came fresh (queue age under :data:`QUEUE_AGE_WARN_S`) is the IMU
#: pausing (counted apart), not samples lost [s].
PAUSE_S = 1.0
#: How fast the queue-age baseline may rise (an IMU clock and the host's drift apart by
#: less: crystals by some 50 ppm) [s/s].
BASELINE_DRIFT = 2e-4
#: A stamp more than this before or after the newest one starts another stream (a clock
#: reset, a bag replayed again, a stray stamp, after which the stream is taken up again):
#: no samples missing, no queue age across it, counted as a stamp jump [s].
STAMP_JUMP_S = 60.0
#: ... or more than this many input periods, when longer (a replay of a 5 Hz IMU: 20000 s).
JUMP_SAMPLES = 100_000
#: Stamp steps needed to learn the input period when ``expected_rate_hz`` is 0 ...
MIN_STEPS = 50
#: ... and the quantile of them taken for it (one step in ten a single period suffices).
PERIOD_QUANTILE = 0.1
#: Floats a sample in :attr:`Backlog.samples`: stamp, callback start, callback end.
SAMPLE = 3


class BacklogReport(NamedTuple):
    """One report: level (0 OK, 1 WARN), message ('' when OK) and the key/value pairs."""

    level: int
    message: str
    values: dict[str, str]


class Backlog:
    """
    Judge the node's own backlog from what its IMU callbacks record (module docstring).

    The queue age of a sample is its lag (callback start minus stamp) above the smallest lag
    seen (the baseline: a sample that did not wait), which may rise by
    :data:`BASELINE_DRIFT` per second and restarts at a stamp jump (:data:`STAMP_JUMP_S`:
    another stream); so it assumes stamps that advance with the steady clock (live data: a
    replay slower than real time reads as a growing age, one faster as none). Samples missing
    are counted from the gaps in the stamps (after the newest before them: a late stamp is
    none) at the input period (``expected_rate_hz``, else the :data:`PERIOD_QUANTILE`
    quantile of the first :data:`MIN_STEPS` steps): the node's own input queue overwriting
    its oldest samples while it is behind, the driver or the link dropping; a gap over
    :data:`PAUSE_S` that the node spent idle and after which the sample came fresh is the
    IMU pausing (``pauses``).

    Parameters
    ----------
    expected_rate_hz : float
        The IMU rate; 0 learns the period from the stamps.

    """

    def __init__(self, expected_rate_hz: float = 0.0) -> None:
        #: (stamp, start, end) per sample, appended by the callbacks.
        self.samples = array('d')
        #: The callbacks' one call per sample: ``record((stamp, start, end))``.
        self.record = self.samples.extend
        self.expected = expected_rate_hz > 0
        self.period: float | None = 1.0 / expected_rate_hz if self.expected else None
        #: Samples missing, gaps, IMU pauses and stamp jumps counted so far.
        self.missing = self.gaps = self.pauses = self.jumps = 0
        # The newest stamp of the stream, the queue-age baseline (as u in _ages), the report.
        self._high = self._base = self._reported_at = None
        self._before: tuple | None = None    # (newest stamp, baseline) before a stamp jump
        self._last_end = -math.inf
        self._learning: list[float] = []

    def report(self, now: float) -> BacklogReport:
        """
        Judge the samples recorded since the last report, at ``now`` (``perf_counter()``).

        WARN when a sample waited over :data:`QUEUE_AGE_WARN_S` or samples are missing.
        """
        x = np.array(self.samples, dtype=np.float64).reshape(-1, SAMPLE)
        del self.samples[:len(x) * SAMPLE]
        elapsed = None if self._reported_at is None else now - self._reported_at
        self._reported_at = now
        values = dict.fromkeys(('queue age s', 'queue age max s', 'callback median us',
                                'callback max us', 'callback load %'), '')
        problems = []
        if len(x):
            stamp, start, end = x[:, 0], x[:, 1], x[:, 2]
            idle = start - np.concatenate(([self._last_end], end[:-1]))
            self._last_end = float(end[-1])
            age, missing, gaps = self._judge(stamp, start, idle)
            dur = end - start
            values.update({'queue age s': f'{age[-1]:.4f}', 'queue age max s': f'{age.max():.4f}',
                           'callback median us': f'{np.median(dur) * 1e6:.0f}',
                           'callback max us': f'{dur.max() * 1e6:.0f}'})
            if elapsed:
                values['callback load %'] = f'{100.0 * dur.sum() / elapsed:.0f}'
            if age.max() > QUEUE_AGE_WARN_S:
                problems.append(
                    f'falling behind: a sample waited {age.max():.3f} s in the input queue '
                    f'(over {QUEUE_AGE_WARN_S:g} s, callbacks median '
                    f'{values["callback median us"]} us, max {values["callback max us"]} us)')
            if missing:
                problems.append(
                    f'input samples missing by stamp ({missing} in {gaps} gaps at the '
                    f"{self.period * 1e3:.4g} ms input period: dropped by this node's input "
                    'queue while it is behind, by the driver or by the link)')
        values['input period ms'] = (
            'learning' if self.period is None else
            f'{self.period * 1e3:.4g} ({"expected_rate_hz" if self.expected else "learnt"})')
        values.update({'input missing': str(self.missing), 'input gaps': str(self.gaps),
                       'input pauses': str(self.pauses), 'input stamp jumps': str(self.jumps)})
        return BacklogReport(1 if problems else 0, '; '.join(problems), values)

    def _judge(self, stamp: np.ndarray, start: np.ndarray, idle: np.ndarray
               ) -> tuple[np.ndarray, int, int]:
        """Return each sample's queue age, s, and the samples missing and gaps counted."""
        n, missing0, gaps0 = len(stamp), self.missing, self.gaps    # the counts before
        age = np.zeros(n)
        if self.period is None:           # learnt from the first MIN_STEPS steps
            steps = np.diff(stamp, prepend=stamp[0] if self._high is None else self._high)
            self._learning.extend(steps[(steps > 0) & (steps < STAMP_JUMP_S)].tolist())
            if len(self._learning) >= MIN_STEPS:
                # A low quantile, not the median: a node behind from its start already
                # loses samples, and its steps are then mostly longer than the period.
                self.period = float(np.quantile(self._learning, PERIOD_QUANTILE))
                self._learning = []
        jump = max(STAMP_JUMP_S, JUMP_SAMPLES * (self.period or 0.0))   # period: learning
        lo = 0
        while lo < n:
            if self._high is None:
                self._high = float(stamp[lo])
            # The newest stamp before each sample: a late one (a second publisher, a
            # reordering) is no gap, and the stream's next sample no gap either.
            newest = np.maximum.accumulate(np.concatenate(([self._high], stamp[lo:])))
            steps = stamp[lo:] - newest[:-1]
            far = np.flatnonzero(np.abs(steps) > jump)
            if far.size and far[0] == 0:
                if (back := self._before) is not None and abs(stamp[lo] - back[0]) <= jump:
                    # Back to the stream before a stray stamp: take it up where it was.
                    (self._high, self._base), self._before = back, None
                else:                         # another stream: both marks start again
                    self.jumps += 1
                    self._before = (self._high, self._base)
                    self._high = self._base = None
                continue
            hi = lo + (int(far[0]) if far.size else n - lo)
            age[lo:hi] = self._ages(newest[1:hi - lo + 1], start[lo:hi])
            self._gaps(steps[:hi - lo], age[lo:hi], idle[lo:hi])
            self._high = float(newest[hi - lo])
            lo = hi
        return age, self.missing - missing0, self.gaps - gaps0

    def _ages(self, newest: np.ndarray, start: np.ndarray) -> np.ndarray:
        """Return the queue ages of samples of one stream, s (from the newest stamp seen)."""
        # The baseline may rise by BASELINE_DRIFT a second: in u = lag - drift * start it is
        # a plain running minimum.
        u = (start - newest) - BASELINE_DRIFT * start
        floor = np.minimum.accumulate(u)
        if self._base is not None:
            floor = np.minimum(floor, self._base)
        self._base = float(floor[-1])
        return u - floor

    def _gaps(self, steps: np.ndarray, age: np.ndarray, idle: np.ndarray) -> None:
        """Count the samples missing in the stamp gaps of one stream, and the IMU pauses."""
        period = self.period
        big = np.flatnonzero(steps > GAP_PERIODS * period) if period is not None else ()
        if not len(big):
            return
        pause = ((steps[big] > PAUSE_S) & (idle[big] > PAUSE_S)
                 & (age[big] <= QUEUE_AGE_WARN_S))
        self.pauses += int(pause.sum())
        lost = big[~pause]
        self.missing += int(np.rint(steps[lost] / period).sum()) - lost.size
        self.gaps += int(lost.size)
