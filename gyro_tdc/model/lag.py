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
The first-order lag filter: the thermal state, the smoothed dT/dt and the simulator's heat flow.

:func:`first_order_lag` runs ``tau dy/dt = u - y`` over a whole signal with a step or a
linear input hold, as numpy scans (no Python loop per sample, no scipy).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['HOLDS', 'first_order_lag', 'lag_step']

#: Input holds of :func:`first_order_lag`.
HOLDS = ('step', 'linear')


def lag_step(y: float, u: float, dt_s: float, tau: float) -> float:
    """Return the lag's state ``dt_s`` s after ``y`` with the input ``u`` held (one step)."""
    a = math.exp(-dt_s / tau)
    return a * y + (1.0 - a) * u


def _doubling_scan(a: float, b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return ``x[k] = a x[k-1] + b[k]`` from ``x[-1] = 0`` by doubling (b is reused)."""
    m = b.shape[0]
    spare = np.empty(m)
    shift, power = 1, a
    while shift < m and power >= 1e-17:       # older terms weigh less than 1e-17
        np.multiply(b[:m - shift], power, out=spare[:m - shift])
        b[shift:] += spare[:m - shift]
        shift, power = 2 * shift, power * power
    return b


def _constant_scan(a: float, b: NDArray[np.float64], start: float) -> NDArray[np.float64]:
    """
    Return ``x[k] = a x[k-1] + b[k]`` from ``x[-1] = start``, for ``0 <= a <= 1``.

    Rows of ``L`` samples, ``a**-L`` at most ~15, are closed sums (one ``cumsum``, the
    rounding as small as the recursion's); the rows' ends chain by :func:`_doubling_scan`.
    """
    m = b.shape[0]
    decay = -math.log(a) if a > 0.0 else math.inf          # per sample; 0 when a rounds to 1
    width = m if decay == 0.0 else int(min(m, 2.7 / decay))
    if width < 16:                            # fast decay: doubling stops after a few passes
        x = _doubling_scan(a, b.copy())
        x[:] += start * np.power(a, np.arange(1, m + 1))
        return x
    rows = -(-m // width)
    grid = np.zeros(rows * width)
    grid[:m] = b
    grid = grid.reshape(rows, width)
    k = np.arange(width, dtype=np.float64)
    grid *= np.power(a, -k)
    np.cumsum(grid, axis=1, out=grid)
    grid *= np.power(a, k)                    # each row as if it started from 0
    ends = _doubling_scan(a ** width, grid[:, -1].copy())
    ends += start * np.power(a ** width, np.arange(1, rows + 1))
    grid += np.outer(np.r_[start, ends[:-1]], np.power(a, k + 1.0))
    return grid.reshape(-1)[:m]


def _affine_scan(a: NDArray[np.float64],
                 b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return ``(A, x)`` along the last axis: ``A[k] = a[0] ... a[k]``, ``x[k] = a[k] x[k-1] + b[k]``.

    ``x`` starts from 0: a prefix scan of the affine maps by doubling (``a`` and ``b`` are
    reused) that stops once the older maps weigh less than 1e-17.
    """
    m = a.shape[-1]
    spare = np.empty_like(a)
    shift = 1
    while shift < m:
        n = m - shift
        np.multiply(a[..., shift:], b[..., :n], out=spare[..., :n])
        np.add(spare[..., :n], b[..., shift:], out=b[..., shift:])
        spare[..., :shift] = a[..., :shift]
        np.multiply(a[..., shift:], a[..., :n], out=spare[..., shift:])
        a, spare = spare, a
        shift *= 2
        if shift < m and a[..., shift - 1:].max() < 1e-17:
            break
    return a, b


def _rows(m: int, decay: float) -> tuple[int, int]:
    """Return ``(rows, width)`` for :func:`_varying_scan`: rows decay by ~e**-8 on average."""
    width = m if decay <= 0.0 else max(16, int(min(m, 8.0 * m / decay)))
    rows = -(-m // width)
    return rows, -(-m // rows)


def _varying_scan(a: NDArray[np.float64], b: NDArray[np.float64], start: float) -> None:
    """
    Turn ``b`` into ``x[k] = a[k] x[k-1] + b[k]`` from ``x[-1] = start``, for ``0 <= a <= 1``.

    ``a`` and ``b`` are the samples laid in rows (``a`` padded with 1, ``b`` with 0). Each
    row is a closed sum against its running product ``P``, ``x = P cumsum(b / P)``, with the
    rounding of the recursion; a row whose product falls below 1e-30 (a gap, a fast decay)
    runs :func:`_affine_scan` instead. The rows' ends chain by :func:`_affine_scan`.
    """
    prod = np.cumprod(a, axis=1)
    gap = prod[:, -1] < 1e-30
    gap_b = b[gap]
    with np.errstate(all='ignore'):          # the gap rows, redone below, may overflow
        b /= prod
        np.cumsum(b, axis=1, out=b)
        b *= prod                               # each row as if it started from 0
    if gap.any():
        prod[gap], b[gap] = _affine_scan(a[gap], gap_b)
    ends_a, ends = _affine_scan(prod[:, -1].copy(), b[:, -1].copy())
    ends += start * ends_a
    prod *= np.r_[start, ends[:-1]][:, None]
    b += prod


def first_order_lag(t: ArrayLike | float, u: ArrayLike, tau: float, *, hold: str = 'step',
                    y0: float | None = None) -> NDArray[np.float64]:
    """
    Filter ``u`` through the first-order lag ``tau dy/dt = u - y``.

    With ``a_k = exp(-(t[k] - t[k-1]) / tau)`` the two input holds are

    * ``'step'``: ``u`` jumps to ``u[k]`` just after ``t[k-1]`` and holds,
      ``y[k] = a_k y[k-1] + (1 - a_k) u[k]``; exactly what :class:`StreamingFeatures` does one
      sample at a time (a feature can only use samples already received);
    * ``'linear'``: ``u`` is linear between samples (first-order hold),
      ``y[k] = a_k y[k-1] + (1 - c_k) u[k] + (c_k - a_k) u[k-1]`` with
      ``c_k = tau (1 - a_k) / (t[k] - t[k-1])``; exact for ramps (the simulator's heat
      conduction).

    Stamps run as a parallel prefix scan in numpy, so irregular stamps cost no Python loop; a
    uniform grid with the linear hold scans with one constant factor.

    Parameters
    ----------
    t : NDArray[np.float64], shape (N,), s, or float
        Stamps, non-decreasing (a stamp before the previous one counts as no time step); or
        the step of a uniform grid ``k * t``, > 0.
    u : ArrayLike, shape (N,)
        Input signal.
    tau : float, s
        Time constant, >= 0; 0 returns a copy of ``u``.
    hold : {'step', 'linear'}
        How ``u`` behaves between samples.
    y0 : float, optional
        Initial output; ``u[0]`` (settled) when None.

    Returns
    -------
    NDArray[np.float64], shape (N,)
        The lagged signal.

    """
    u = np.asarray(u, dtype=np.float64)
    if u.ndim != 1:
        raise ValueError(f'Expected `u` to have shape (N,), got {u.shape}.')
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f'Expected `tau` to be a finite number >= 0, got {tau!r}.')
    if hold not in HOLDS:
        raise ValueError(f'Expected `hold` to be one of {", ".join(HOLDS)}, got {hold!r}.')
    uniform = np.ndim(t) == 0
    if uniform:
        dt = float(t)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'Expected the uniform step `t` (dt) to be a finite number > 0, '
                             f'got {t!r}.')
    else:
        t = np.asarray(t, dtype=np.float64)
        if t.shape != u.shape:
            raise ValueError(f'Expected `t` of shape {u.shape} like `u`, got {t.shape}.')
    n = u.shape[0]
    if tau == 0.0 or n == 0:
        return u.copy()
    start = u[0] if y0 is None else float(y0)
    if n == 1:
        return np.full(1, start)
    if uniform and hold == 'linear':
        a = math.exp(-dt / tau)
        c = tau * -math.expm1(-dt / tau) / dt
        # y[k+1] = a y[k] + (1 - c) u[k+1] + (c - a) u[k]: one constant factor.
        return np.r_[start, _constant_scan(a, (1.0 - c) * u[1:] + (c - a) * u[:-1], start)]
    m = n - 1
    step = np.full(m, dt) if uniform else np.maximum(np.diff(t), 0.0)
    rows, width = _rows(m, float(step.sum()) / tau)
    a = np.ones((rows, width))
    y = np.zeros(1 + rows * width)      # y[1:] holds b, then the output, in rows
    y[0] = start
    av, bv = a.reshape(-1)[:m], y[1:n]
    np.exp(np.divide(step, -tau, out=av), out=av)
    if hold == 'step':
        np.subtract(1.0, av, out=bv)
        bv *= u[1:]
    else:
        with np.errstate(divide='ignore', invalid='ignore'):
            c = np.where(step > 0.0, tau * -np.expm1(-step / tau) / step, 1.0)
        bv[:] = (1.0 - c) * u[1:] + (c - av) * u[:-1]
    # y[k] = a_k y[k-1] + b_k: closed sums in rows, chained by a short prefix scan.
    _varying_scan(a, y[1:].reshape(rows, width), start)
    return y[:n]
