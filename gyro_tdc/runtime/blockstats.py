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
The re-anchoring's block statistics: the shift, its block-means standard error, tolerances.

Shared by :class:`gyro_tdc.runtime.reanchor.StillnessDetector` (streaming) and
:func:`gyro_tdc.runtime.reanchor.reanchor_shift` (batch).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import NamedTuple, Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ['Anchor', 'BLOCKS_PER_WINDOW', 'BlockStats', 'block_length', 'block_sums',
           'default_tolerance', 'EARLY_BLOCKS', 'early_allowed', 'MAX_BLOCK_S', 'max_windows',
           'Shift', 'standard_error', 'stats_of', 'STILL_WINDOW_MAX_S', 'TOLERANCE_FLOOR',
           'TOLERANCE_FRACTION', 'Vec3', 'window_stats']


Vec3 = tuple[float, float, float]

#: Default longest averaging, s.
STILL_WINDOW_MAX_S = 600.0
#: Blocks per window in the block-means standard error ...
BLOCKS_PER_WINDOW = 50
#: ... each at most this long, s.
MAX_BLOCK_S = 1.0
#: A bursty stream's window ends early, once precise, after at least this many whole blocks
#: (a tenth of a window: 1 s of a 10 s window from 5 Hz up) and MIN_WINDOW_SAMPLES samples.
EARLY_BLOCKS = 5
#: Default tolerance: this fraction of the model's residual standard deviation ...
TOLERANCE_FRACTION = 0.1
#: ... and at least this, rad/s.
TOLERANCE_FLOOR = 1e-5

_INF3 = (math.inf, math.inf, math.inf)


@dataclass(frozen=True)
class Anchor:
    """
    The result of re-anchoring: the offset shift that zeroes the compensated rate.

    It carries the evidence behind the shift (samples, spread, standard error against its
    tolerance) and why the averaging stopped.
    """

    #: Stamp of the last sample averaged, s.
    t: float
    #: Shift added to the model's drift (x, y, z), rad/s.
    delta: Vec3
    #: Samples averaged.
    samples: int
    #: Standard deviation of the raw rate within the still windows (RMS over them), rad/s.
    gyro_std: Vec3
    #: Temperature at the end, degC.
    temp_c: float
    #: Stamp of the last sample averaged minus that of the first, s.
    duration_s: float = 0.0
    #: Standard error of ``delta`` (block means; see the module docstring), rad/s.
    se: Vec3 = _INF3
    #: The tolerance the SE was held to, rad/s.
    tolerance: Vec3 = _INF3
    #: ``'precision'`` (SE within the tolerance), ``'longest'`` (``window_max`` reached),
    #: ``'motion'`` (motion ended the still run first: the stream's form of ``'end of
    #: data'``) or ``'end of data'`` (:func:`reanchor_shift` only); ``''`` for a single
    #: window.
    reason: str = ''


class BlockStats(NamedTuple):
    """
    Sums over blocks of ``x - c`` (``c`` a constant of the run) for the block-means SE.

    ``n`` samples, ``m`` non-empty blocks, ``s`` the sum, ``a`` the sum of squared block
    sums, ``b`` the sum of block sums times block counts (per axis), ``c2`` the sum of
    squared block counts. Window statistics add up.
    """

    n: int = 0
    m: int = 0
    s: Vec3 = (0.0, 0.0, 0.0)
    a: Vec3 = (0.0, 0.0, 0.0)
    b: Vec3 = (0.0, 0.0, 0.0)
    c2: float = 0.0

    def __add__(self, other: object) -> 'BlockStats':
        """Return the statistics of two sets of blocks together."""
        if not isinstance(other, BlockStats):
            return NotImplemented
        return BlockStats(*(x + y if not isinstance(x, tuple) else
                            tuple(u + v for u, v in zip(x, y)) for x, y in zip(self, other)))


class Shift(NamedTuple):
    """What :func:`reanchor_shift` found: the mean and its precision over the head of a run."""

    delta: Vec3
    se: Vec3
    samples: int
    duration_s: float
    reason: str


def block_length(window: float) -> float:
    """Return the block length (s) of the block-means SE for a stillness window (s)."""
    return min(MAX_BLOCK_S, float(window) / BLOCKS_PER_WINDOW)


def max_windows(window: float, window_max: float) -> int:
    """Return how many windows the averaging may hold: ``window_max / window``, at least 1."""
    return max(1, int(float(window_max) / float(window) + 1e-9))


def default_tolerance(residual_var: Sequence[float]) -> Vec3:
    """
    Return the default re-anchoring tolerance from a model's residual variance.

    Parameters
    ----------
    residual_var : sequence of 3 float, (rad/s)^2
        The model's residual variance per axis.

    Returns
    -------
    tuple of 3 float, rad/s
        ``max(TOLERANCE_FRACTION * sqrt(residual_var), TOLERANCE_FLOOR)`` per axis.

    """
    return tuple(max(TOLERANCE_FRACTION * math.sqrt(max(float(v), 0.0)), TOLERANCE_FLOOR)
                 for v in residual_var)


def standard_error(st: BlockStats) -> Vec3:
    """
    Return the standard error of the mean from block statistics (inf below two blocks).

    ``SE^2 = m / (m - 1) * sum_k (S_k - n_k mu)^2 / N^2`` with ``mu = S / N``, expanded
    over the running sums so a stream needs no block history.
    """
    if st.m < 2 or st.n == 0:
        return _INF3
    n, k = float(st.n), st.m / (st.m - 1.0)
    return tuple(math.sqrt(max(k * (a - 2.0 * mu * b + mu * mu * st.c2), 0.0)) / n
                 for mu, a, b in zip((s / n for s in st.s), st.a, st.b))


def window_stats(t: NDArray[np.float64], x: NDArray[np.float64], c: Sequence[float],
                 block_s: float) -> BlockStats:
    """
    Return the block statistics of one window (batch form of the streaming sums).

    ``t`` (s, N) are the stamps (blocks of ``block_s`` seconds start at ``t[0]``), ``x``
    (N, 3) the values averaged (the compensated rate, or its error), ``c`` the run's
    centring constant (3 floats); ``t`` not empty.
    """
    return stats_of(*block_sums(t, x, c, block_s, float(t[0]))[1:])


def block_sums(t: NDArray[np.float64], x: NDArray[np.float64], c: Sequence[float],
               block_s: float, origin: float
               ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """
    Return each block's first index, its sum of ``x - c`` and its sample count.

    Blocks of ``block_s`` on the grid from ``origin`` (a window's first stamp), in order;
    ``t`` not empty.
    """
    k = np.floor((t - origin) / block_s)
    starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
    sums = np.add.reduceat(np.asarray(x, dtype=np.float64) - np.asarray(c), starts, axis=0)
    return starts, sums, np.diff(np.append(starts, t.size)).astype(np.float64)


def stats_of(sums: NDArray[np.float64], counts: NDArray[np.float64]) -> BlockStats:
    """Return the block statistics of blocks with these sums and sample counts."""
    s, a, b = (tuple(v.sum(axis=0).tolist()) for v in (sums, sums ** 2, sums * counts[:, None]))
    return BlockStats(int(counts.sum()), int(counts.size), s, a, b, float((counts ** 2).sum()))


def early_allowed(tol: Sequence[float], window: float, window_max: float) -> bool:
    """Return whether a window may end early: a finite tolerance and more than one window."""
    return all(math.isfinite(v) for v in tol) and max_windows(window, window_max) > 1
