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

__all__ = ['BASELINE_DRIFT', 'Backlog', 'BacklogReport', 'GAP_PERIODS', 'MIN_STEPS',
           'PAUSE_S', 'QUEUE_AGE_WARN_S']

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
#: Stamp steps needed to learn the input period when ``expected_rate_hz`` is 0.
MIN_STEPS = 20
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
    :data:`BASELINE_DRIFT` per second and restarts when the stamps step back; so it assumes
    stamps that advance with the steady clock (live data: a replay slower than real time
    reads as a growing age, one faster as none). Samples missing are counted from the gaps
    in the stamps at the input period (``expected_rate_hz``, else the median step of the
    first :data:`MIN_STEPS` steps): the node's own input queue overwriting its oldest
    samples while it is behind, the driver or the link dropping; a gap over
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
        self.missing = 0
        self.gaps = 0
        self.pauses = 0
        self._last_stamp: float | None = None
        self._last_end = -math.inf
        self._base: float | None = None      # the baseline, as u in _ages
        self._reported_at: float | None = None
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
        values = {'queue age s': '', 'queue age max s': '', 'callback median us': '',
                  'callback max us': '', 'callback load %': ''}
        problems = []
        if len(x):
            stamp, start, end = x[:, 0], x[:, 1], x[:, 2]
            steps = np.diff(stamp, prepend=stamp[0] if self._last_stamp is None
                            else self._last_stamp)
            self._last_stamp = float(stamp[-1])
            age = self._ages(stamp, start, steps)
            idle = start - np.concatenate(([self._last_end], end[:-1]))
            self._last_end = float(end[-1])
            missing, gaps = self._gaps(steps, age, idle)
            dur = end - start
            values['queue age s'] = f'{age[-1]:.4f}'
            values['queue age max s'] = f'{age.max():.4f}'
            values['callback median us'] = f'{np.median(dur) * 1e6:.0f}'
            values['callback max us'] = f'{dur.max() * 1e6:.0f}'
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
        values['input missing'] = str(self.missing)
        values['input gaps'] = str(self.gaps)
        values['input pauses'] = str(self.pauses)
        return BacklogReport(1 if problems else 0, '; '.join(problems), values)

    def _ages(self, stamp: np.ndarray, start: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """Return each sample's queue age, s, and carry the baseline on."""
        # The baseline may rise by BASELINE_DRIFT a second: in u = lag - drift * start it is
        # a plain running minimum.
        u = (start - stamp) - BASELINE_DRIFT * start
        floor = np.empty_like(u)
        bounds = [0, *np.flatnonzero(steps < 0).tolist(), len(u)]
        base = math.inf if self._base is None else self._base
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if hi <= lo:
                continue
            if steps[lo] < 0:                # stamps stepped back: another stream
                base = math.inf
            floor[lo:hi] = np.minimum(np.minimum.accumulate(u[lo:hi]), base)
            base = float(floor[hi - 1])
        self._base = base
        return u - floor

    def _gaps(self, steps: np.ndarray, age: np.ndarray, idle: np.ndarray) -> tuple[int, int]:
        """Count the samples missing in this report's stamp gaps; return (missing, gaps)."""
        if self.period is None:
            self._learning.extend(steps[steps > 0].tolist())
            if len(self._learning) < MIN_STEPS:
                return 0, 0
            self.period = float(np.median(self._learning))
            self._learning = []
        period = self.period
        big = np.flatnonzero(steps > GAP_PERIODS * period)
        if not big.size:
            return 0, 0
        pause = ((steps[big] > PAUSE_S) & (idle[big] > PAUSE_S)
                 & (age[big] <= QUEUE_AGE_WARN_S))
        self.pauses += int(pause.sum())
        lost = big[~pause]
        missing = int(np.rint(steps[lost] / period).sum()) - lost.size
        self.missing += missing
        self.gaps += int(lost.size)
        return missing, int(lost.size)
