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
The measured runs on the block grid: block means, the noise floor and the effect columns.

Everything discovery fits works on block means of ``block_s`` (default 10 s): the thermal
effects are slow, and the averages are what the noise floor and the gaps are measured on. The
noise floor is what white and short-term noise alone leave in a block mean, estimated from the
data inside the blocks (second differences of block thirds, so the drift cancels; robust
median scale).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

from gyro_tdc.discover.stats import COLLINEAR, rel_residual
from gyro_tdc.effects import EFFECTS, first_order_lag
from gyro_tdc.errors import FitError
from gyro_tdc.runs import Run
import numpy as np
from numpy.typing import NDArray

__all__ = ['BlockData']


class BlockData:
    """
    Block means of all runs, the noise floor, and the effect columns on the block grid.

    Samples are grouped into blocks of ``block_s`` inside each contiguous segment (a gap of
    more than half a block or 20 sample periods starts a new segment, so bursty recordings
    work); a segment tail shorter than half a block joins the previous block. Static
    features are block means of their full-rate values; the filtered ones (``lag``,
    ``dTdt``, ``warmup``) are computed on a regular grid (temperature interpolated across
    gaps) and averaged over each block's span.
    """

    def __init__(self, runs: Sequence[Run], *, block_s: float, t0: float) -> None:
        self.runs = list(runs)
        self.t0 = float(t0)
        self.block_s = float(block_s)
        n_runs = len(runs)
        parts: dict[str, list] = {k: [] for k in (
            'run', 'n', 't', 'tfirst', 'tlast', 'temp', 'y', 'ref', 'dtref', 'dT', 'dT2',
            'dT3', 'noise')}
        self.grids: list[tuple] = []
        white = []
        span = 0.0
        start = 0
        for r, run in enumerate(runs):
            t = np.asarray(run.t, dtype=np.float64)
            n = t.shape[0]
            dt = np.diff(t)
            med = float(np.median(dt)) if n > 1 else self.block_s
            per = max(1, int(round(self.block_s / med)))
            breaks = np.flatnonzero(dt > max(20.0 * med, 0.5 * self.block_s)) + 1
            bounds = np.concatenate([[0], breaks, [n]])
            ids = np.empty(n, dtype=np.int64)
            nb = 0
            for a, b in zip(bounds[:-1], bounds[1:]):
                m = b - a
                full = max(1, m // per)
                extra = 1 if (m - full * per) * 2 >= per and m > per else 0
                ids[a:b] = nb + np.minimum(np.arange(m) // per, full + extra - 1)
                nb += full + extra
            cnt = np.bincount(ids, minlength=nb).astype(np.float64)
            span += n * med

            def bmean(v: NDArray[np.float64], ids=ids, nb=nb, cnt=cnt) -> NDArray[np.float64]:
                return np.bincount(ids, weights=v, minlength=nb) / cnt

            y = np.asarray(run.omega, dtype=np.float64) - run.omega_ref
            d = run.temp - self.t0
            parts['run'].append(np.full(nb, r))
            parts['n'].append(cnt)
            parts['t'].append(bmean(t))
            first = np.searchsorted(ids, np.arange(nb))
            last = np.searchsorted(ids, np.arange(nb), side='right') - 1
            parts['tfirst'].append(t[first])
            parts['tlast'].append(t[last])
            parts['temp'].append(bmean(run.temp))
            parts['y'].append(np.column_stack([bmean(y[:, a]) for a in range(3)]))
            parts['ref'].append(np.column_stack([bmean(run.omega_ref[:, a]) for a in range(3)]))
            parts['dtref'].append(np.column_stack(
                [bmean(d * run.omega_ref[:, a]) for a in range(3)]))
            parts['dT'].append(bmean(d))
            parts['dT2'].append(bmean(d * d))
            parts['dT3'].append(bmean(d * d * d))
            # Noise: second difference of block thirds (linear drift cancels), per sample std.
            pos = np.arange(n) - first[ids]
            third = np.minimum(3 * pos // cnt[ids].astype(np.int64), 2)
            key = ids * 3 + third
            c3 = np.bincount(key, minlength=3 * nb).reshape(nb, 3)
            ok = np.all(c3 > 0, axis=1)
            with np.errstate(invalid='ignore', divide='ignore'):
                nz = []
                for a in range(3):
                    m3 = np.bincount(key, weights=y[:, a], minlength=3 * nb).reshape(nb, 3) / c3
                    dd = (m3[:, 0] - 2.0 * m3[:, 1] + m3[:, 2]) / np.sqrt(
                        1.0 / c3[:, 0] + 4.0 / c3[:, 1] + 1.0 / c3[:, 2])
                    nz.append(np.where(ok, dd, np.nan))
            parts['noise'].append(np.column_stack(nz))
            # White noise from first differences inside segments.
            inside = np.ones(max(n - 1, 0), dtype=bool)
            inside[breaks - 1] = False
            white.append(np.diff(y, axis=0)[inside])
            # Regular grid for the filtered features.
            step = min(max(med, self.block_s / 10.0), 1.0) if self.block_s > med else med
            tg = t[0] + np.arange(int(math.floor((t[-1] - t[0]) / step)) + 2) * step
            tg = tg[tg <= t[-1] + step]
            temp_g = np.interp(tg, t, run.temp)
            lo = np.searchsorted(tg, t[first], side='left')
            hi = np.searchsorted(tg, t[last], side='right')
            self.grids.append((tg, temp_g, lo, hi, bmean(t), start, start + nb))
            start += nb

        cat = {k: np.concatenate(v) for k, v in parts.items()}
        self.run = cat['run'].astype(np.int64)
        self.n = cat['n']
        self.K = int(self.n.shape[0])
        self.w = self.n / self.n.mean()
        self.block_eff_s = span / self.K     # mean duration of a block
        self.sw = np.sqrt(self.w)
        self.t = cat['t']
        self.tfirst = cat['tfirst']
        self.tlast = cat['tlast']
        self.temp = cat['temp']
        self.y = cat['y']
        self.ref = cat['ref']
        self.dtref = cat['dtref']
        self.static = {'dT': cat['dT'], 'dT2': cat['dT2'], 'dT3': cat['dT3']}
        self.n_runs = n_runs
        self.t_since = self.t - np.array([runs[r].t[0] for r in self.run])
        self.offsets = np.zeros((self.K, n_runs))
        self.offsets[np.arange(self.K), self.run] = 1.0

        noise = cat['noise']
        sig = np.empty(3)
        for a in range(3):
            v = noise[:, a][np.isfinite(noise[:, a])]
            sig[a] = 1.4826 * np.median(np.abs(v - np.median(v))) if v.size >= 3 else np.nan
        wd = np.concatenate(white) if white else np.zeros((0, 3))
        if wd.shape[0] >= 3:
            wsig = 1.4826 * np.median(np.abs(wd - np.median(wd, axis=0)), axis=0) / math.sqrt(2)
        else:
            wsig = np.full(3, np.nan)
        sig = np.where(np.isfinite(sig), sig, wsig)
        if not np.all(np.isfinite(sig)):
            raise FitError('Cannot estimate the noise floor: blocks too short; '
                           'use a longer `block_s` or more samples per run.')
        self.sigma = sig                            # per-sample equivalent, rad/s
        self.floor_axes = sig / math.sqrt(self.n.mean())   # on the block scale, rad/s
        self.floor = float(np.sqrt(np.mean(self.floor_axes ** 2)))
        self.white = float(np.sqrt(np.mean(np.nan_to_num(wsig) ** 2)))
        self.rate_cpm = self._rate_cpm()
        self._cache: dict = {}
        self.gain_axes = self._gain_axes()
        self.scale_axes = np.array([np.any(np.abs(self.ref[:, a]) > 1e-12) and rel_residual(
            np.hstack([self.offsets, self.static['dT'][:, None], self.ref[:, a:a + 1]]),
            self.dtref[:, a]) > COLLINEAR for a in range(3)])

    def _rate_cpm(self) -> NDArray[np.float64]:
        """Return the smoothed dT/dt of each block, degC/min (60 s first-order smoothing)."""
        out = np.empty(self.K)
        for tg, temp_g, lo, hi, tb, a, b in self.grids:
            f = (temp_g - first_order_lag(tg, temp_g, 60.0)) / 60.0 * 60.0
            out[a:b] = self._grid_mean(tg, f, lo, hi, tb)
        return out

    @staticmethod
    def _grid_mean(tg: NDArray[np.float64], f: NDArray[np.float64], lo: NDArray[np.int64],
                   hi: NDArray[np.int64], tb: NDArray[np.float64]) -> NDArray[np.float64]:
        """Average grid values over each block's span (interpolate when none falls inside)."""
        cs = np.concatenate([[0.0], np.cumsum(f)])
        cnt = hi - lo
        out = np.interp(tb, tg, f)
        has = cnt > 0
        out[has] = (cs[hi[has]] - cs[lo[has]]) / cnt[has]
        return out

    def _gain_axes(self) -> NDArray[np.bool_]:
        """Return the axes whose reference rate is not explained by the run offsets alone."""
        out = np.zeros(3, dtype=bool)
        for a in range(3):
            col = self.ref[:, a]
            if not np.any(np.abs(col) > 1e-12):
                continue
            out[a] = rel_residual(self.offsets, col) > COLLINEAR
        return out

    def column(self, eid: str, params: Mapping[str, Mapping[str, float]]) -> NDArray[np.float64]:
        """
        Return the block-mean column of one input effect (K,), cached by parameters.

        Parameters
        ----------
        eid : str
            An input effect id.
        params : mapping
            ``{effect: {param: value}}``.

        Returns
        -------
        NDArray[np.float64], shape (K,)
            The column.

        """
        if eid in self.static:
            return self.static[eid]
        base = eid.split('^')[0]
        tau = float(params.get(base, {}).get('tau_s', EFFECTS[base].params['tau_s']))
        key = (eid, round(tau, 9))
        if key in self._cache:
            return self._cache[key]
        out = np.empty(self.K)
        for tg, temp_g, lo, hi, tb, a, b in self.grids:
            if base == 'lag':
                f = (first_order_lag(tg, temp_g, tau) - self.t0) ** (
                    int(eid[4:]) if eid != 'lag' else 1)
            elif eid == 'dTdt':
                f = (temp_g - first_order_lag(tg, temp_g, tau)) / tau
            else:  # warmup
                f = np.exp(-(tg - tg[0]) / tau)
            out[a:b] = self._grid_mean(tg, f, lo, hi, tb)
        if len(self._cache) > 512:
            self._cache.clear()
        self._cache[key] = out
        return out
