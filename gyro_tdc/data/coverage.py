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
Coverage of training data: how much of each temperature bin, heating and cooling, it holds.

Pure numpy. :func:`coverage` counts samples and minutes per temperature bin, names the bins
inside the covered span that hold too little data, and adds up the minutes heating, cooling
and steady by the rate :func:`temperature_rate` estimates.
:func:`gyro_tdc.evaluate.report.format_coverage`
prints the result.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

from gyro_tdc.data.runs import Run
import numpy as np
from numpy.typing import NDArray

__all__ = ['Coverage', 'RATE_THRESHOLD_C_PER_MIN', 'RATE_WINDOW_S', 'coverage', 'temperature_rate']

#: ``|dT/dt|`` (degC/min) above which a sample counts as heating or cooling.
RATE_THRESHOLD_C_PER_MIN = 0.05
#: Window (s) of the centred difference that estimates dT/dt.
RATE_WINDOW_S = 300.0


def temperature_rate(t: NDArray[np.float64], temp: NDArray[np.float64], *,
                     window_s: float = RATE_WINDOW_S) -> NDArray[np.float64]:
    """
    Estimate dT/dt (degC/min) at every sample by a centred difference over ``window_s``.

    ``t`` (s) increasing, ``temp`` degC. The window (shortened to the run's span) is wide
    enough that thermometer quantisation does not read as heating or cooling.
    """
    t, temp = np.asarray(t, dtype=np.float64), np.asarray(temp, dtype=np.float64)
    if t.shape[0] < 2 or t[-1] <= t[0]:
        return np.zeros(t.shape[0])
    half = 0.5 * min(window_s, t[-1] - t[0])
    a, b = np.clip(t - half, t[0], t[-1]), np.clip(t + half, t[0], t[-1])
    return (np.interp(b, t, temp) - np.interp(a, t, temp)) / np.maximum(b - a, 1e-9) * 60.0


def _sample_minutes(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the time each sample stands for, in minutes (gaps count at most 10 periods)."""
    if t.shape[0] < 2:
        return np.zeros(t.shape[0])
    d = np.empty(t.shape[0])               # in place: no temporaries of a long run
    np.subtract(t[1:], t[:-1], out=d[:-1])
    med = float(np.median(d[:-1]))
    d[-1] = med
    np.minimum(d, 10.0 * med, out=d)
    d /= 60.0
    return d


def _directions(run: Run, threshold: float, *, points: int = 100_000
                ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """
    Return the heating, cooling and steady samples of a run (dT/dt vs ``threshold``).

    The rate is :func:`temperature_rate` computed on at most ``points`` samples, each held
    over the samples it stands for (the masks are repeated, not the rates).
    """
    n = len(run)
    step = max(1, n // points)
    rate = temperature_rate(run.t[::step], run.temp[::step])
    masks = (rate > threshold, rate < -threshold, np.abs(rate) <= threshold)
    return masks if step == 1 else tuple(np.repeat(m, step)[:n] for m in masks)


@dataclass
class Coverage:
    """
    How well training data cover temperature and thermal direction.

    Per temperature bin, and in minutes heating, cooling and steady: what a model trained
    on the data has seen of each.
    """

    #: Bin width, degC.
    bin_c: float
    #: Bin edges (B + 1,), degC.
    edges: NDArray[np.float64]
    #: Samples per bin (B,).
    samples: NDArray[np.int64]
    #: Minutes per bin (B,).
    minutes: NDArray[np.float64]
    #: Indices of bins inside the span with too little data.
    sparse: list
    #: Min and max temperature, degC.
    temp_range_c: tuple
    #: Minutes with dT/dt above +``threshold_c_per_min``.
    heating_min: float
    #: Minutes with dT/dt below -``threshold_c_per_min``.
    cooling_min: float
    #: Minutes with dT/dt in between.
    steady_min: float
    #: The dT/dt threshold, degC/min.
    threshold_c_per_min: float


def coverage(runs: Sequence[Run], *, bin_c: float = 5.0,
             threshold_c_per_min: float = RATE_THRESHOLD_C_PER_MIN,
             sparse_fraction: float = 0.25) -> Coverage:
    """
    Measure the temperature and heating/cooling coverage of training runs.

    A bin is sparse when at least half of it lies inside the covered span and it holds fewer
    minutes per degC than ``sparse_fraction`` times the median over such bins (so a fast
    sweep through a range, or a gap, is named).

    Parameters
    ----------
    runs : sequence of Run
        Training runs.
    bin_c : float, degC
        Bin width; edges at multiples of it.
    threshold_c_per_min : float, degC/min
        ``|dT/dt|`` above which a sample counts as heating or cooling.
    sparse_fraction : float
        Fraction of the median density below which a bin is sparse.

    Returns
    -------
    Coverage
        Per-bin counts and minutes, sparse bins and direction minutes.

    """
    def joined(parts: Sequence[NDArray]) -> NDArray:
        return parts[0] if len(parts) == 1 else np.concatenate(parts)   # one run: no copy
    temp = joined([np.asarray(r.temp) for r in runs])
    minutes = joined([_sample_minutes(r.t) for r in runs])
    heating, cooling, steady = (joined(m) for m in zip(
        *(_directions(r, threshold_c_per_min) for r in runs)))
    lo, hi = float(temp.min()), float(temp.max())
    first = math.floor(lo / bin_c) * bin_c
    nb = max(1, int(math.floor((hi - first) / bin_c)) + 1)
    edges = first + bin_c * np.arange(nb + 1)
    v = np.subtract(temp, first)
    np.floor_divide(v, bin_c, out=v)
    idx = np.clip(v.astype(np.int64), 0, nb - 1)
    mins = np.bincount(idx, weights=minutes, minlength=nb)
    inside = np.clip(np.minimum(edges[1:], hi) - np.maximum(edges[:-1], lo), 0.0, None)
    full = inside >= 0.5 * bin_c
    sparse: list = []
    if np.count_nonzero(full) >= 2:
        density = mins / np.maximum(inside, 1e-9)
        ref = float(np.median(density[full]))
        sparse = [int(i) for i in np.flatnonzero(full & (density < sparse_fraction * ref))]
    return Coverage(float(bin_c), edges, np.bincount(idx, minlength=nb), mins, sparse, (lo, hi),
                    *(float(minutes[m].sum()) for m in (heating, cooling, steady)),
                    float(threshold_c_per_min))
