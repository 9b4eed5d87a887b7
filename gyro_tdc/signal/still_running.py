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
The running state of the streaming still test: the pooled noise floor and motion reports.

:class:`NoiseFloor` and :class:`MotionReports` are what
:class:`~gyro_tdc.signal.still_stream.StillWindows` keeps from window to window; neither
depends on how a stream is cut into windows.
"""

from __future__ import annotations

from collections import deque
import math

from gyro_tdc.signal.still_verdict import NOISE_DOF, windows_moving
import numpy as np
from numpy.typing import NDArray

__all__ = ['MotionReports', 'NoiseFloor']


class MotionReports:
    """
    Outside motion reports (``cmd_vel``, odometry): each holds from its stamp to the next.

    A window that overlaps a moving interval is vetoed (:func:`windows_moving`; before the
    first report nothing is). Reports are kept from the one held at the window in progress on.
    """

    def __init__(self) -> None:
        #: Reports (stamp, moving), in stamp order.
        self.reports: list[tuple[float, bool]] = []

    def add(self, t: float, moving: bool) -> None:
        """Record a report (a non-finite stamp is ignored)."""
        t = float(t)
        if not math.isfinite(t):
            return
        rep = (t, bool(moving))
        self.reports.append(rep)
        if len(self.reports) > 1 and t < self.reports[-2][0]:     # out of order
            self.reports.sort(key=lambda r: r[0])

    def veto(self, t0: float, t1: float) -> bool:
        """Return whether ``[t0, t1]`` overlaps motion; drop reports before the one held at t1."""
        mo = self.reports
        if not mo:
            return False
        mt = [r[0] for r in mo]
        moving = bool(windows_moving([t0], [t1], mt, [r[1] for r in mo])[0])
        held = max(int(np.searchsorted(mt, t1, side='right')) - 1, 0)
        del mo[:held]
        return moving


class NoiseFloor:
    """
    A running noise floor per axis: the lowest standard deviation pooled over windows.

    Each window adds its variance and degrees of freedom (samples - 1); the variance pooled
    over the newest consecutive windows holding at least :data:`NOISE_DOF` of them is a
    candidate, and the floor is the lowest candidate so far, at least the quantisation noise
    ``q / sqrt(12)`` of the finest step seen between two readings (``q``). An axis whose
    windows never vary has no floor (inf). Pooling makes the floor a property of the noise,
    not of the window's sample count or of how many windows the stream has had: the lowest
    single window of ten samples sinks to a sixth of the noise over a day of them.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the windows and the floor."""
        self.floor = np.full(3, math.inf)
        self.quantum = np.full(3, math.inf)
        self._windows: deque[tuple[int, NDArray[np.float64]]] = deque()
        self._dof = 0

    def add(self, dof: int, var: NDArray[np.float64], step: NDArray[np.float64]) -> None:
        """Add a window: its degrees of freedom, variance (3,) and finest step (3,; inf)."""
        self.quantum = np.minimum(self.quantum, step)
        win = self._windows
        win.append((dof, var))
        self._dof += dof
        while win and self._dof - win[0][0] >= NOISE_DOF:
            self._dof -= win.popleft()[0]
        if self._dof < NOISE_DOF:
            return
        pooled = sum(d * v for d, v in win) / self._dof
        q = np.where(np.isfinite(self.quantum), self.quantum, 0.0)
        cand = np.maximum(np.sqrt(pooled), q / math.sqrt(12.0))
        cand = np.where(cand > 0.0, cand, math.inf)
        self.floor = np.minimum(self.floor, cand)
