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
Where the model and the measurement disagree: residual maps and the Allan deviation.

:func:`residual_maps` bins the block-mean residual by temperature, dT/dt, reference rate and
time since power-on and flags the bins noise cannot explain; :func:`residual_adev` is the
Allan deviation of the full-rate residual of the longest run.
"""

from __future__ import annotations

import math

from gyro_tdc.identify.discover.data import BlockData
from gyro_tdc.identify.discover.linear import LinearModel
from gyro_tdc.identify.discover.results import BinMap
from gyro_tdc.identify.discover.stats import ar1, DEG
from gyro_tdc.model import batch_features
import numpy as np
from numpy.typing import NDArray

__all__ = ['residual_adev', 'residual_maps']


def residual_maps(data: BlockData, r: NDArray[np.float64]) -> tuple[BinMap, ...]:
    """Bin the residual by temperature, dT/dt, reference rate and time since start."""
    floor = data.floor_axes * DEG
    infl = np.empty(3)
    for a in range(3):
        # AR(1) of the noise from first differences (slow disagreements cancel there).
        rho = 1.0 + 2.0 * ar1(np.diff(r[:, a])) if data.K > 3 else 0.0
        rho = min(max(rho, 0.0), 0.9)
        infl[a] = math.sqrt((1.0 + rho) / (1.0 - rho))
    rd = r * DEG

    def binmap(name: str, label: str, keys: NDArray[np.int64], nb: int,
               centers: NDArray[np.float64], labels: tuple[str, ...] = ()) -> BinMap:
        mean = np.full((nb, 3), np.nan)
        se = np.full((nb, 3), np.nan)
        count = np.zeros((nb, 3), dtype=np.int64)
        for a in range(3):
            k = keys[:, a] if keys.ndim == 2 else keys
            ok = k >= 0
            wsum = np.bincount(k[ok], weights=data.w[ok], minlength=nb)
            s = np.bincount(k[ok], weights=data.w[ok] * rd[ok, a], minlength=nb)
            count[:, a] = np.bincount(k[ok], minlength=nb)
            has = wsum > 0
            mean[has, a] = s[has] / wsum[has]
            se[has, a] = floor[a] * infl[a] / np.sqrt(wsum[has])
        flagged = np.nan_to_num(np.abs(mean)) > 3.0 * np.nan_to_num(se, nan=np.inf)
        return BinMap(name, label, centers, mean, se, count, flagged, labels)

    out = []
    # Temperature: up to 10 equal-width bins.
    lo, hi = float(data.temp.min()), float(data.temp.max())
    nb = 10 if hi - lo > 1e-6 else 1
    edges = np.linspace(lo, hi, nb + 1)
    k = np.clip(np.searchsorted(edges, data.temp, side='right') - 1, 0, nb - 1)
    cen = np.repeat(((edges[:-1] + edges[1:]) / 2.0)[:, None], 3, axis=1)
    out.append(binmap('temperature', 'temperature (degC)', k, nb, cen))
    # dT/dt: cooling fast/slow, still, heating slow/fast.
    rate = data.rate_cpm
    thr = max(0.02, 0.1 * float(np.max(np.abs(rate))))
    k = np.full(data.K, 2, dtype=np.int64)
    for sign, (slow, fast) in ((1, (3, 4)), (-1, (1, 0))):
        m = sign * rate > thr
        if np.any(m):
            med = float(np.median(sign * rate[m]))
            k[m & (sign * rate <= med)] = slow
            k[m & (sign * rate > med)] = fast
    cen = np.array([rate[k == i].mean() if np.any(k == i) else np.nan for i in range(5)])
    out.append(binmap('dTdt', 'dT/dt (degC/min)', k, 5, np.repeat(cen[:, None], 3, axis=1),
                      ('cooling fast', 'cooling slow', 'still', 'heating slow',
                       'heating fast')))
    # Reference rate: each axis by its own rate, up to 8 levels or quantile bins.
    if np.any(np.abs(data.ref) > 1e-12):
        nb = 8
        keys = np.full((data.K, 3), -1, dtype=np.int64)
        cen = np.full((nb, 3), np.nan)
        for a in range(3):
            v = data.ref[:, a] * DEG
            levels = np.unique(np.round(v, 6))
            if levels.size <= nb:
                keys[:, a] = np.searchsorted(levels, np.round(v, 6))
            else:
                edges = np.unique(np.quantile(v, np.linspace(0, 1, nb + 1)))
                keys[:, a] = np.clip(np.searchsorted(edges, v, side='right') - 1, 0,
                                     edges.size - 2)
            for i in range(nb):
                if np.any(keys[:, a] == i):
                    cen[i, a] = v[keys[:, a] == i].mean()
        out.append(binmap('reference', 'reference rate (deg/s)', keys, nb, cen))
    # Time since the start of each run, log-like bins (warm-up shows at the start).
    tmax = float(data.t_since.max()) / 60.0
    edges = [0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 1280.0]
    edges = [e for e in edges if e < tmax] + [tmax + 1e-9]
    edges = np.asarray(edges)
    nb = edges.size - 1
    tm = data.t_since / 60.0
    k = np.clip(np.searchsorted(edges, tm, side='right') - 1, 0, nb - 1)
    cen = np.array([tm[k == i].mean() if np.any(k == i) else np.nan for i in range(nb)])
    out.append(binmap('time', 'time since start (min)', k, nb,
                      np.repeat(cen[:, None], 3, axis=1)))
    return tuple(out)


def _full_rate_residual(data: BlockData, model: LinearModel, coef: NDArray[np.float64]
                        ) -> tuple[NDArray[np.float64], float]:
    """Return the full-rate residual of the longest contiguous stretch of the longest run."""
    r = int(np.argmax([len(x) for x in data.runs]))
    run = data.runs[r]
    dt = np.diff(run.t)
    med = float(np.median(dt)) if dt.size else 1.0
    breaks = np.flatnonzero(dt > 1.5 * med + 1e-9) + 1
    bounds = np.concatenate([[0], breaks, [len(run)]])
    i = int(np.argmax(np.diff(bounds)))
    sl = slice(int(bounds[i]), int(bounds[i + 1]))
    # The temperature terms follow the thermal state when the model has one.
    state = None if model.state_tau is None else data.state(r, model.state_tau)
    x = batch_features(model.effects, run.t, run.temp, t0=data.t0, params=model.params,
                       state=state)
    d = (run.temp if state is None else state) - data.t0
    y = run.omega - run.omega_ref
    n = len(run)
    pred = np.zeros((n, 3))
    nr = data.n_runs
    for a in range(3):
        c = coef[:, a]
        pred[:, a] = c[r] + x @ c[nr:nr + x.shape[1]]
        j = nr + x.shape[1]
        for lab in model.axis_labels:
            if lab == 'gain':
                pred[:, a] += c[j] * run.omega_ref[:, a] * data.gain_axes[a]
            else:
                pred[:, a] += c[j] * d * run.omega_ref[:, a] * data.scale_axes[a]
            j += 1
    return (y - pred)[sl], 1.0 / med


def residual_adev(data: BlockData, model: LinearModel, coef: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return Allan deviation (taus, RMS over axes in deg/s) of the full-rate residual."""
    from gyro_tdc.signal import allan_deviation

    res, rate = _full_rate_residual(data, model, coef)
    if res.shape[0] < 16:
        return np.zeros(0), np.zeros(0)
    taus, dev = allan_deviation(res, rate)
    return np.asarray(taus), np.sqrt(np.mean(np.asarray(dev) ** 2, axis=1))
