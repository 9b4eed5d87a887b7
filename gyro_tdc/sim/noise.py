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
Stochastic gyro errors, vectorised: white rate noise, bias instability, rate random walk.

Conventions (IEEE Std 952 / Kalibr): a white rate noise of density ``N`` (rad/s/sqrt(Hz))
sampled at ``f`` Hz has a per-sample standard deviation ``N sqrt(f)``; a rate random walk
``K`` (rad/s/sqrt(s)) adds increments of standard deviation ``K sqrt(dt)``. Bias instability
is a sum of first-order Gauss-Markov processes with spread correlation times, a common
approximation of the flicker floor of the Allan deviation.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

__all__ = ['gauss_markov', 'quantise', 'random_walk', 'white_noise']


def white_noise(rng: np.random.Generator, n: int, *, density: ArrayLike,
                rate_hz: float) -> NDArray[np.float64]:
    """
    Return ``n`` x 3 samples of white noise of spectral ``density`` (unit/sqrt(Hz) per axis).

    Sampled at ``rate_hz``: standard deviation ``density * sqrt(rate_hz)``.
    """
    sigma = np.asarray(density, dtype=np.float64) * math.sqrt(rate_hz)
    return rng.standard_normal((n, 3)) * sigma


def gauss_markov(rng: np.random.Generator, n: int, *, sigma: ArrayLike,
                 tau_s: Sequence[float], dt: float) -> NDArray[np.float64]:
    """
    Return ``n`` x 3 samples of a sum of stationary first-order Gauss-Markov processes.

    One process per correlation time of ``tau_s`` (s, > 0), each with an equal share of the
    variance so the sum has standard deviation ``sigma`` per axis; each starts in its
    stationary distribution. ``dt`` is the sample interval (s).
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    out = np.zeros((n, 3))
    if n == 0 or not tau_s or not np.any(sigma > 0.0):
        return out
    share = sigma / math.sqrt(len(tau_s))
    for tau in tau_s:
        phi = math.exp(-dt / tau)
        drive = math.sqrt(-math.expm1(-2.0 * dt / tau))
        w = rng.standard_normal((n, 3))
        # x[k] = phi x[k-1] + drive w[k], with x[-1] drawn from the stationary N(0, 1).
        zi = (phi * rng.standard_normal(3))[np.newaxis, :]
        out += lfilter([drive], [1.0, -phi], w, axis=0, zi=zi)[0] * share
    return out


def random_walk(rng: np.random.Generator, n: int, *, k: ArrayLike,
                dt: float) -> NDArray[np.float64]:
    """
    Return ``n`` x 3 samples of a random walk from 0, increments of std ``k sqrt(dt)``.

    ``k`` per axis in unit/sqrt(s), ``dt`` in s; row 0 is zero.
    """
    k = np.asarray(k, dtype=np.float64)
    steps = rng.standard_normal((n, 3)) * (k * math.sqrt(dt))
    steps[:1] = 0.0
    return np.cumsum(steps, axis=0)


def quantise(x: NDArray[np.float64], step: float, *, limit: float = 0.0) -> NDArray[np.float64]:
    """
    Round ``x`` to a multiple of ``step`` and clip at ``+-limit``, in place; return ``x``.

    ``step`` is one digit, ``limit`` the saturation magnitude; 0 skips either.
    """
    if limit > 0.0:
        np.clip(x, -limit, limit, out=x)
    if step > 0.0:
        np.multiply(np.rint(np.divide(x, step, out=x), out=x), step, out=x)
    return x
