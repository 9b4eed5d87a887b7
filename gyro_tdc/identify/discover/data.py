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
The measured runs on the block grid, what they can excite, and the linear model fitted there.

:class:`BlockData` holds the block means of every run, the noise floor left in a block mean,
the effect columns (of the thermal state too) and which blocks heat or cool;
:func:`excitation` names the candidates the runs cannot excite. :class:`LinearModel` fits one
effect set by weighted least squares with held-out residuals; :func:`hac_pvalue` is the
guard's significance test, :func:`make_folds` its folds, :func:`bandwidth` the noise memory.
See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from collections import defaultdict
import math
from typing import Callable, Mapping, Sequence
import warnings

from gyro_tdc.base import DEG_PER_RAD as DEG, need
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.discover.results import Unidentifiable
from gyro_tdc.identify.fit import MIN_SPAN_C
from gyro_tdc.model import (batch_features, EFFECTS, first_order_lag, input_ids,
                            REFERENCE_EFFECTS, STATE_TERMS, STATIC_EFFECTS, TEMPERATURE_EFFECTS,
                            THERMAL_EFFECTS)
from gyro_tdc.signal import (BlockGrid, fit_columns, Folds, heldout, mad_sigma, pinv_fit,
                             session_columns, solve_normal)
import numpy as np
from numpy.typing import NDArray

__all__ = ['ar1', 'bandwidth', 'BlockData', 'COLLINEAR', 'corr', 'DEG', 'excitation', 'gap',
           'hac_pvalue', 'LinearModel', 'make_folds', 'mse', 'ols_hac', 'rel_residual',
           'unidentifiable', 'wsse']

#: Relative norm below which a column is taken as spanned by the others.
COLLINEAR = 1e-3
#: Effects whose block-mean column is the mean of their full-rate feature (no filter state).
_STATIC = input_ids(STATIC_EFFECTS)
#: The temperature terms, which follow the thermal state when the model has one.
_STATE = input_ids(STATE_TERMS)
#: Effects a temperature span excites (``scale`` needs rate-table steps too: its own test).
_SPAN = tuple(e for e in EFFECTS if e in TEMPERATURE_EFFECTS and e not in REFERENCE_EFFECTS)
#: Of those, the ones with time memory: excited by how the temperature changes.
_RATE = tuple(e for e in _SPAN if e not in STATIC_EFFECTS)
#: A soak (the temperature still) counts from this long, s (and three blocks).
_SOAK_S = 120.0


def unidentifiable(eid: str, reason: str, extra: str = '') -> Unidentifiable:
    """Return ``eid`` as not identifiable for ``reason``, with the experiment that excites it."""
    exp = EFFECTS[eid].excited_by
    return Unidentifiable(eid, reason, exp[0].upper() + exp[1:] + extra + '.')


def rel_residual(x: NDArray[np.float64], col: NDArray[np.float64]) -> float:
    """Return ``|col - projection on span(x)| / |col - mean|`` (0: col is in the span)."""
    nc = float(np.linalg.norm(col - col.mean()))
    if nc == 0.0:
        return 0.0
    if x.shape[1] == 0:
        return 1.0
    return float(np.linalg.norm(col - x @ fit_columns(x, col, normalise=True))) / nc


def _block_noise(y: NDArray[np.float64], first: NDArray[np.int64], cnt: NDArray[np.float64]
                 ) -> NDArray[np.float64]:
    """
    Return per block and axis the noise of a block mean, per-sample equivalent (NaN: unknown).

    The second difference of the block's thirds (a linear drift cancels); thirds of blocks
    of varying length are a labelled sum (bincount), not a blocking.
    """
    nb = cnt.shape[0]
    ids = np.repeat(np.arange(nb), cnt.astype(np.int64))
    third = np.minimum(3 * (np.arange(y.shape[0]) - first[ids]) // cnt[ids].astype(np.int64), 2)
    key = ids * 3 + third
    c3 = np.bincount(key, minlength=3 * nb).reshape(nb, 3)
    with np.errstate(invalid='ignore', divide='ignore'):
        m3 = np.stack([np.bincount(key, weights=y[:, a], minlength=3 * nb) for a in range(3)],
                      axis=1).reshape(nb, 3, 3) / c3[:, :, None]
        dd = (m3[:, 0] - 2.0 * m3[:, 1] + m3[:, 2]) / np.sqrt(
            1.0 / c3[:, 0] + 4.0 / c3[:, 1] + 1.0 / c3[:, 2])[:, None]
    return np.where(np.all(c3 > 0, axis=1)[:, None], dd, np.nan)


def _noise_floor(noise: NDArray[np.float64], white: Sequence[NDArray[np.float64]]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the per-sample noise per axis (robust, of the block noises) and the white noise.

    The white noise comes from first differences inside segments; it stands in for an axis
    whose blocks are too short for thirds.
    """
    finite = [noise[:, a][np.isfinite(noise[:, a])] for a in range(3)]
    sig = np.array([mad_sigma(v) if v.size >= 3 else np.nan for v in finite])
    wd = np.concatenate(white)
    wsig = mad_sigma(wd) / math.sqrt(2) if wd.shape[0] >= 3 else np.full(3, np.nan)
    sig = np.where(np.isfinite(sig), sig, wsig)
    if not np.all(np.isfinite(sig)):
        raise FitError('Cannot estimate the noise floor: blocks too short; '
                       'use a longer `block_s` or more samples per run.')
    return sig, wsig


class BlockData:
    """
    Block means of all runs, the noise floor, and the effect columns on the block grid.

    Samples are grouped into blocks of ``block_s`` inside each contiguous segment (a gap of
    more than half a block or 20 sample periods starts a new segment, so bursty recordings
    work); a segment tail shorter than half a block joins the previous block. Static
    features are block means of their full-rate values; the filtered ones (``dTdt``,
    ``warmup``) are computed on a regular grid (temperature interpolated across gaps) and
    averaged over each block's span; so are the temperature terms of the thermal state (the
    reference rate held on the grid for the ``scale`` term).
    """

    def __init__(self, runs: Sequence[Run], *, block_s: float, t0: float) -> None:
        self.runs, self.t0, self.block_s = list(runs), float(t0), float(block_s)
        parts: dict[str, list] = defaultdict(list)
        #: Per run: its regular grid, the temperature and the reference rate there, the
        #: grid span of each block, the block times and the run's rows of the blocks.
        self.grids: list[tuple] = []
        white, span, start = [], 0.0, 0
        for r, run in enumerate(self.runs):
            t = np.asarray(run.t, dtype=np.float64)
            n, dt = t.shape[0], np.diff(t)
            med = float(np.median(dt)) if n > 1 else self.block_s
            breaks = np.flatnonzero(dt > max(20.0 * med, 0.5 * self.block_s)) + 1
            grid = BlockGrid(n, max(1, int(round(self.block_s / med))),
                             bounds=np.concatenate([[0], breaks, [n]]), merge_tail=True)
            cnt = grid.counts
            span += n * med
            y = np.asarray(run.omega, dtype=np.float64) - run.omega_ref
            x = batch_features(_STATIC, t, run.temp, t0=self.t0)
            last = np.cumsum(cnt).astype(np.int64) - 1
            first = last - cnt.astype(np.int64) + 1
            for key, v in (('run', np.full(len(cnt), r, dtype=np.int64)), ('n', cnt),
                           ('t', grid.mean(t)), ('tfirst', t[first]), ('tlast', t[last]),
                           ('temp', grid.mean(run.temp)), ('y', grid.mean(y)),
                           ('ref', grid.mean(run.omega_ref)),
                           ('dtref', grid.mean(x[:, :1] * run.omega_ref)),
                           ('static', grid.mean(x)), ('noise', _block_noise(y, first, cnt))):
                parts[key].append(v)
            white.append(np.delete(np.diff(y, axis=0), breaks - 1, axis=0))  # inside segments
            # Regular grid for the filtered features; the reference rate held on it from the
            # last sample (a step schedule). It has two points at least (t[0] and one step on).
            step = min(max(med, self.block_s / 10.0), 1.0) if self.block_s > med else med
            tg = t[0] + np.arange(int(math.floor((t[-1] - t[0]) / step)) + 2) * step
            tg = tg[tg <= t[-1] + step]
            held = np.clip(np.searchsorted(t, tg, side='right') - 1, 0, n - 1)
            self.grids.append((tg, np.interp(tg, t, run.temp),
                               np.asarray(run.omega_ref, dtype=np.float64)[held],
                               np.searchsorted(tg, t[first], side='left'),
                               np.searchsorted(tg, t[last], side='right'), parts['t'][-1],
                               start, start + len(cnt)))
            start += len(cnt)

        cat = {k: np.concatenate(v) for k, v in parts.items()}
        for key in ('run', 'n', 't', 'tfirst', 'tlast', 'temp', 'y', 'ref', 'dtref'):
            setattr(self, key, cat[key])
        self.K = int(self.n.shape[0])
        self.w = self.n / self.n.mean()
        self.block_eff_s = span / self.K     # mean duration of a block
        self.sw = np.sqrt(self.w)
        self.static = {eid: cat['static'][:, j] for j, eid in enumerate(_STATIC)}
        self.n_runs = len(self.runs)
        self.t_since = self.t - np.array([self.runs[r].t[0] for r in self.run])
        self.offsets = session_columns(self.run)[0]      # one offset per run
        sig, wsig = _noise_floor(cat['noise'], white)      # per-sample equivalent, rad/s
        self.floor_axes = sig / math.sqrt(self.n.mean())   # on the block scale, rad/s
        self.floor = float(np.sqrt(np.mean(self.floor_axes ** 2)))
        self.white = float(np.sqrt(np.mean(np.nan_to_num(wsig) ** 2)))
        self._cache: dict = {}
        self.rate_cpm = self._grid_means(lambda tg, temp_g, _ref: batch_features(
            ('dTdt',), tg, temp_g, t0=self.t0, params={'dTdt': {'tau_s': 60.0}}) * 60.0)[0]
        #: The blocks whose temperature changes at a measurable rate, and whether the data
        #: heat and whether they cool there.
        self.moving = np.abs(self.rate_cpm) > max(0.02, 0.1 * float(np.max(np.abs(self.rate_cpm))))
        self.heating = bool(np.any(self.moving & (self.rate_cpm > 0)))
        self.cooling = bool(np.any(self.moving & (self.rate_cpm < 0)))
        # The axes whose reference rate the run offsets alone (gain), or with dT (scale),
        # do not explain.
        moves = [np.any(np.abs(self.ref[:, a]) > 1e-12) for a in range(3)]
        self.gain_axes = np.array([moves[a] and rel_residual(self.offsets, self.ref[:, a])
                                   > COLLINEAR for a in range(3)])
        self.scale_axes = np.array([moves[a] and rel_residual(
            np.hstack([self.offsets, self.static['dT'][:, None], self.ref[:, a:a + 1]]),
            self.dtref[:, a]) > COLLINEAR for a in range(3)])

    def _grid_means(self, f: Callable[..., NDArray[np.float64]]) -> NDArray[np.float64]:
        """
        Return ``f(grid, temperature, reference)`` (points, m) of every run, block means (m, K).

        A block's mean is over the grid points inside its span (interpolated when none falls
        inside); each row of the result is contiguous.
        """
        out = None
        for tg, temp_g, ref_g, lo, hi, tb, a, b in self.grids:
            fg = f(tg, temp_g, ref_g)
            out = np.empty((fg.shape[1], self.K)) if out is None else out
            cnt = hi - lo
            has = cnt > 0
            for k in range(fg.shape[1]):
                cs = np.concatenate([[0.0], np.cumsum(fg[:, k])])
                out[k, a:b] = np.interp(tb, tg, fg[:, k])
                out[k, a:b][has] = (cs[hi[has]] - cs[lo[has]]) / cnt[has]
        return out

    def _memo(self, key: tuple, make: Callable[[], object]) -> object:
        """Return ``make()`` cached under ``key`` (the cache is cleared when it grows large)."""
        if key not in self._cache:
            if len(self._cache) > 768:
                self._cache.clear()
            self._cache[key] = make()
        return self._cache[key]

    def state(self, r: int, tau: float) -> NDArray[np.float64]:
        """
        Return run ``r``'s thermal state at its N sample stamps, degC; ``tau`` in s.

        The first-order lag (:func:`gyro_tdc.model.lag.first_order_lag`, settled at the first
        temperature) runs on the run's regular grid, where the temperature is linear between
        grid points, and is interpolated back to the stamps.
        """
        tg, temp_g = self.grids[r][:2]
        return np.interp(self.runs[r].t, tg, self._grid_state(tg, temp_g, tau))

    @staticmethod
    def _grid_state(tg: NDArray[np.float64], temp_g: NDArray[np.float64], tau: float
                    ) -> NDArray[np.float64]:
        """Return the thermal state on a regular grid (temperature linear between points)."""
        return first_order_lag(float(tg[1] - tg[0]), temp_g, float(tau), hold='linear')

    def state_columns(self, tau: float) -> dict[str, NDArray[np.float64]]:
        """
        Return the block means of the temperature terms of the thermal state, cached by tau (s).

        ``dT``, ``dT2``, ``dT3`` (K,) of the state (:func:`gyro_tdc.model.effects.batch_features`
        with ``state``) and ``dtref`` (K, 3) of ``(s - T0) omega_ref`` (the ``scale`` term).
        """
        def make() -> dict[str, NDArray[np.float64]]:
            def f(tg: NDArray[np.float64], temp_g: NDArray[np.float64], ref_g: NDArray[np.float64]
                  ) -> NDArray[np.float64]:
                xg = batch_features(_STATE, tg, temp_g, t0=self.t0,
                                    state=self._grid_state(tg, temp_g, tau))
                return np.hstack([xg, xg[:, _STATE.index('dT')][:, None] * ref_g])

            x = self._grid_means(f)
            return {**{eid: x[k] for k, eid in enumerate(_STATE)},
                    'dtref': np.ascontiguousarray(x[len(_STATE):].T)}

        return self._memo(('state', round(float(tau), 9)), make)

    def column(self, eid: str, params: Mapping[str, Mapping[str, float]], *,
               state_tau: float | None = None) -> NDArray[np.float64]:
        """
        Return the K block means of input effect ``eid``'s column, cached by parameters.

        ``params`` is ``{effect: {param: value}}``. With ``state_tau`` (s, the thermal state's
        time constant) the temperature terms (``dT``, ``dT2``, ``dT3``) are powers of the state.
        """
        if state_tau is not None and eid in STATE_TERMS:
            return self.state_columns(state_tau)[eid]
        if eid in self.static:
            return self.static[eid]
        tau = float(params.get(eid, {}).get('tau_s', EFFECTS[eid].params['tau_s']))
        return self._memo((eid, round(tau, 9)), lambda: self._grid_means(
            lambda tg, temp_g, _ref: batch_features((eid,), tg, temp_g, t0=self.t0,
                                                    params={eid: {'tau_s': tau}}))[0])


def _soaks(data: BlockData) -> tuple[NDArray[np.float64], float]:
    """
    Return per run its soak after power-on, and the longest soak next to a ramp, s.

    The soak after power-on is the time before the temperature first moves, zero for a run
    with fewer than four blocks before its first move (one block is no soak). A soak next to
    a ramp is a stretch of still blocks in a run that moves: a change of rate between a ramp
    and a soak is what a time constant shows in (the die catching up, or starting to lag);
    a run that never moves, or never stops, has none.
    """
    first, longest = np.zeros(data.n_runs), 0.0
    for r in range(data.n_runs):
        idx = np.flatnonzero(data.run == r)
        tr, mv = data.t_since[idx], data.moving[idx]
        first_move = tr[np.argmax(mv)] if np.any(mv) else tr[-1]
        first[r] = first_move if np.count_nonzero(tr < first_move) >= 4 else 0.0
        if np.any(mv) and not np.all(mv):
            edges = np.flatnonzero(np.diff(np.concatenate([[1], mv.astype(np.int8), [1]])))
            for a, b in zip(edges[::2], edges[1::2]):      # still stretches [a, b)
                longest = max(longest, float(data.tlast[idx[b - 1]] - data.tfirst[idx[a]]))
    return first, longest


def excitation(data: BlockData, base: Sequence[str]) -> tuple[dict, list[str]]:
    """
    Decide which candidates this data cannot excite, before any fit.

    Returns ``{effect: Unidentifiable}`` and a list of notes about the data.
    """
    out: dict[str, Unidentifiable] = {}
    notes: list[str] = []
    span = float(data.temp.max() - data.temp.min())
    soak_min = max(_SOAK_S, 3.0 * data.block_s)    # 2 minutes and three blocks
    first_soaks, soak = _soaks(data)

    if span < MIN_SPAN_C:
        out.update({e: unidentifiable(e, f'the temperature spans only {span:.2f} degC',
                                      ', of at least 10 degC') for e in _SPAN})
    if not np.any(data.moving):
        out.update({e: unidentifiable(e, 'the temperature never changes at a measurable rate')
                    for e in _RATE if e not in out})
    elif data.heating != data.cooling:
        leg = 'heat' if data.heating else 'cool'
        r = np.abs(data.rate_cpm[data.moving])
        q1, q3 = np.percentile(r, [25, 75])
        one_rate = (q3 - q1) < 0.25 * float(np.median(r))
        one = f'The data only {leg} and at one rate (~{np.median(r):.2f} degC/min)'
        hysteresis = 'hysteresis between heating and cooling cannot be tested'
        if one_rate and soak < soak_min:
            # Scored all the same: a die settled at power-on falls behind at the start of the
            # ramp, which shows tau; a recording that starts mid-ramp shows nothing, and the
            # guard then rejects the lag (its profile is flat).
            notes.append(f'{one} with no soak before or after the ramp: a lag or dT/dt effect '
                         'can only show where the ramp starts from a die settled at power-on; '
                         'from a recording that starts mid-ramp it is not identifiable, and '
                         f'{hysteresis}.')
        elif one_rate:
            notes.append(f'{one}: a lag or dT/dt effect rests on the changes of rate between the '
                         f'ramp and the soaks (the longest {soak:.0f} s: the approach to '
                         f'equilibrium there shows a time constant); {hysteresis}.')
        else:
            notes.append(f'The data only {leg}: {hysteresis}; a dT/dt or lag effect seen here '
                         f'rests on the change of the {leg}ing rate alone.')
    if not np.any(data.scale_axes):
        out['scale'] = unidentifiable('scale', (
            'the reference rate is zero on every run: a sensitivity change has nothing to scale'
            if not np.any(np.abs(data.ref) > 1e-12) else 'the reference rate is constant on '
            'every run, so a sensitivity change is indistinguishable from dT'))
    # Warm-up: some run must start with a soak (no temperature change) after power-on.
    if not np.any(first_soaks >= soak_min):
        out['warmup'] = unidentifiable('warmup', 'no run starts with a soak after power-on: a '
                                       'warm-up transient cannot be told apart from the '
                                       'temperature response and the bias')
    return {e: u for e, u in out.items() if e not in base}, notes


def wsse(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the block-weighted sum of squares of a residual (K, 3) over blocks and axes."""
    return float((data.w[:, None] * r * r).sum())


def mse(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the block-weighted mean square of a residual (K, 3) over blocks and axes."""
    return float(wsse(data, r) / (3.0 * data.w.sum()))


def gap(data: BlockData, r: NDArray[np.float64]) -> float:
    """Return the weighted RMS over blocks and axes of a residual (K, 3), in deg/s."""
    return math.sqrt(mse(data, r)) * DEG


def make_folds(data: BlockData, memory: int, n_folds: int = 5) -> tuple[Folds, int]:
    """
    Return the cross-validation folds and the buffer used.

    Several runs: leave one run out. One run: blocked cross-validation over up to
    ``4 n_folds`` contiguous segments dealt round-robin into ``n_folds`` folds (so every fold
    is predicted by interpolation, never by extrapolation in temperature), with a buffer of
    ``memory`` blocks (the noise memory, at most one segment) on each side of every held-out
    segment left out of the training rows (h-block cross-validation), so that slowly varying
    noise cannot leak from the training rows into the held-out ones.
    """
    if data.n_runs >= 2:
        return Folds.sessions(data.run), 0
    k = data.K
    n_seg = int(min(4 * n_folds, max(k // 3, 2)))
    buffer = int(max(0, min(memory, k // n_seg)))
    return Folds.segments(k, n_segments=n_seg, n_folds=min(n_folds, n_seg), buffer=buffer,
                          min_train=max(4, k // 10)), buffer


def ar1(r: NDArray[np.float64]) -> float:
    """Return the lag-1 autocorrelation of ``r`` (0 for fewer than 3 values)."""
    if r.shape[0] < 3:
        return 0.0
    c = r - r.mean()
    den = float(c @ c)
    return float(c[1:] @ c[:-1]) / den if den > 0 else 0.0


def bandwidth(r: NDArray[np.float64], *, floor: bool = True) -> int:
    """
    Return a Newey-West bandwidth, in lags, that covers the residual's memory.

    Sokal's automatic window on the integrated autocorrelation time: the smallest ``M`` with
    ``M >= 5 (1 + 2 sum_{l<=M} rho_l)``; unlike an AR(1) plug-in it sees a slow component
    (bias instability) under white noise. With ``floor`` at least ``1.3 sqrt(K)`` (Lazarus,
    Lewis, Stock and Watson's rule for a test); without, the noise memory itself.
    """
    k = r.shape[0]
    n = 1 << int(math.ceil(math.log2(2 * k)))
    f = np.fft.rfft(r - r.mean(), n)
    acf = np.fft.irfft(f * np.conj(f), n)[:k]
    if acf[0] <= 0:
        return 1
    tau = 1.0 + 2.0 * np.cumsum((acf / acf[0])[1:])
    m = np.arange(1, k)
    ok = np.flatnonzero(m >= 5.0 * tau)
    lag = int(m[ok[0]]) if ok.size else k // 3
    lag = max(lag, int(math.ceil(1.3 * math.sqrt(k)))) if floor else lag
    return int(min(max(lag, 1), max(k // 3, 1)))


def ols_hac(y: NDArray[np.float64], x: NDArray[np.float64], maxlags: int
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return OLS coefficients (K,) and their small-sample corrected Newey-West covariance (K, K).

    Bit for bit statsmodels' ``OLS(y, x).fit(cov_type='HAC', cov_kwds={'maxlags': L,
    'use_correction': True})`` (``params``, ``cov_params()``): the same pseudo-inverse (SVD,
    singular values below 1e-15 of the largest dropped), sandwich and order of operations
    (checked in ``test/identify/discover/test_linear.py``), without importing statsmodels and
    pandas. ``y`` (N,), ``x`` (N, K); ``maxlags`` is the Bartlett bandwidth in lags.
    """
    x = np.asarray(x)
    params, pinv = pinv_fit(x, y)       # statsmodels' pinv_extended
    bread = np.dot(pinv, np.transpose(pinv))
    xu = x * (y - np.dot(x, params))[:, None]
    weights = 1 - np.arange(maxlags + 1) / (maxlags + 1.0)
    meat = weights[0] * np.dot(xu.T, xu)
    for lag in range(1, maxlags + 1):
        c = np.dot(xu[lag:].T, xu[:-lag])
        meat += weights[lag] * (c + c.T)
    cov = np.dot(np.dot(bread, meat), bread.T)
    nobs, k = xu.shape
    cov *= nobs / float(nobs - k)
    return params, cov


def hac_pvalue(model: LinearModel, cand: Sequence[int], lags: Sequence[int]) -> float:
    """
    Return the HAC Wald p-value of the columns ``cand`` (smallest over axes, times 3).

    Newey-West (Bartlett) errors of OLS (:func:`ols_hac`: statsmodels' ``cov_type='HAC'``
    with its small-sample correction), the bandwidth ``lags[a]`` from the noise's
    integrated autocorrelation time (:func:`bandwidth`); the Wald statistic is referred to
    an F distribution with the estimator's equivalent degrees of freedom, ``1.5 K / L`` (a
    long bandwidth leaves few independent pieces of information, so the test does not
    pretend to more).
    """
    fdtrc = need('scipy.special').fdtrc     # imported while the bags are read (cli.train)
    d = model.data
    ps = []
    for a in range(3):
        x = model.design(a) * d.sw[:, None]
        keep = np.linalg.norm(x, axis=0) > 0
        sel = [int(np.count_nonzero(keep[:i])) for i in cand if keep[i]]
        if not sel:
            continue
        xs = x[:, keep] / np.linalg.norm(x[:, keep], axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')   # near-collinear columns: the F test says so
            params, cov = ols_hac(d.y[:, a] * d.sw, xs, int(lags[a]))
        try:
            f = float(params[sel] @ solve_normal(cov[np.ix_(sel, sel)], params[sel],
                                                 fallback=False)) / len(sel)
        except np.linalg.LinAlgError:
            continue
        dof = max(min(1.5 * d.K / lags[a], d.K - xs.shape[1]), 1.0)
        # scipy.stats.f.sf(f, len(sel), dof), without importing scipy.stats (slow): the
        # same function, and 1 below the distribution's support.
        ps.append(1.0 if f <= 0.0 else float(fdtrc(len(sel), dof, f)))
    return min(1.0, 3.0 * min(ps)) if ps else 1.0


def corr(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Return the correlation (about zero) of two arrays, flattened (0 when one is zero)."""
    a, b = a.ravel(), b.ravel()
    den = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(a @ b) / den if den > 0 else 0.0


class LinearModel:
    """Design matrices, least squares, cross-validation and the HAC test for one effect set."""

    def __init__(self, data: BlockData, effects: Sequence[str],
                 params: Mapping[str, Mapping[str, float]], *,
                 extra: NDArray[np.float64] | None = None) -> None:
        self.data, self.effects = data, tuple(effects)
        self.params = {k: dict(v) for k, v in params.items()}
        #: Time constant of the thermal state (s), None without ``lag``.
        state = bool(THERMAL_EFFECTS & set(self.effects))
        self.state_tau = float(self.params['lag']['tau_s']) if state else None
        self.inputs = input_ids(self.effects, state=state)
        self.labels = [f'offset:{r}' for r in range(data.n_runs)] + list(self.inputs)
        self.common = np.hstack([data.offsets] + [data.column(
            e, self.params, state_tau=self.state_tau)[:, None] for e in self.inputs])
        # Per-axis columns: the rate table's gain, scale only on axes whose rate steps can
        # separate it, and a column of its own (the J test).
        ax = {'gain': data.ref * data.gain_axes[None, :] if np.any(data.gain_axes) else None,
              'scale': (data.dtref if self.state_tau is None else data.state_columns(
                  self.state_tau)['dtref']) * data.scale_axes[None, :]
              if 'scale' in self.effects else None,
              'extra': None if extra is None else np.asarray(extra, dtype=np.float64)}
        ax = {k: v for k, v in ax.items() if v is not None}
        self.axis_labels = list(ax)
        self.axis = np.stack(list(ax.values()), axis=2) if ax else np.zeros((data.K, 3, 0))
        self.p = self.common.shape[1] + self.axis.shape[2]

    def columns_of(self, eid: str) -> list[int]:
        """
        Return the design columns that belong to effect ``eid``.

        ``lag`` has none: it changes the temperature columns instead (the thermal state).
        ``'extra'`` is the per-axis column given to the constructor.
        """
        if eid in ('scale', 'extra'):
            return [self.common.shape[1] + self.axis_labels.index(eid)]
        return [i for i, lab in enumerate(self.labels) if lab == eid]

    def design(self, a: int) -> NDArray[np.float64]:
        """Return the design matrix of axis ``a`` (K, p)."""
        return np.hstack([self.common, self.axis[:, a, :]])

    def fit(self, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Return the coefficients (p, 3) fitted on ``rows`` (all by default)."""
        d, rows = self.data, slice(None) if rows is None else rows
        return np.column_stack([fit_columns(self.design(a)[rows], d.y[rows, a], weights=d.w[rows],
                                            normalise=True, rcond=1e-12) for a in range(3)])

    def predict(self, coef: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the simulated block means (K, 3)."""
        return np.column_stack([self.design(a) @ coef[:, a] for a in range(3)])

    def residual(self, coef: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return measured minus simulated (K, 3), rad/s."""
        return self.data.y - self.predict(self.fit() if coef is None else coef)

    def cv_residual(self, folds: Folds) -> NDArray[np.float64]:
        """
        Return held-out residuals (K, 3): each block predicted by a fit without its fold.

        A run with no block in the training rows (leave-one-run-out) has no fitted offset;
        its held-out residual is re-anchored to zero mean (:func:`gyro_tdc.signal.heldout`).
        """
        d = self.data
        return heldout(lambda test, train: d.y[test] - self.predict(self.fit(train))[test],
                       folds, (d.K, 3), groups=d.run, weights=d.w)
