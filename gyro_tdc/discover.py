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
The discrepancy workflow: where the model and the measurement disagree, and why.

:func:`discover` fits the simulation model with the current effects (default ``bias`` and
``dT``, the conventional model of paper eq. 18) to measured runs, driven by their measured
temperature and reference rate, and then, step by step, names the catalog effect that the
model is missing, adds it and shows the gap shrink, until no candidate is supported by the
data. The model searched is linear in its coefficients, per axis ``a``::

    omega_a - omega_ref_a = o_{run,a} + sum_j c_{j,a} x_j(T, t) + s_a dT omega_ref_a
                            + g_a omega_ref_a + e_a

with ``x_j`` the effect features of :mod:`gyro_tdc.effects` (their time constants fitted by a
bounded 1-D search on the residual: variable projection), ``o`` one offset per run (session-to-
session offsets are not thermal), ``s`` the ``scale`` effect and ``g`` a constant scale-factor
error of the rate table (a nuisance, present only when the reference rate varies). With
``lag`` the die, not the thermometer, feels the curvature too: ``lag`` brings the lagged
powers of the curvature effects present (``lag^2`` with ``dT2``, ``lag^3`` with ``dT3``).

Everything works on block means (``block_s``, default 10 s): the thermal effects are slow, and
the averages are what the noise floor and the gaps are measured on. The *gap* is the RMS over
all axes of the block means of measured minus simulated rate, in deg/s; the *noise floor* is
what white and short-term noise alone leave in a block mean, estimated from the data inside
the blocks (second differences of block thirds, so the drift cancels; robust median scale).

A candidate is named only when three independent tests agree (the false-discovery guard):

* held-out gain: the mean squared held-out gap falls by at least ``min_heldout`` squared noise
  floors (and 1 %) under leave-one-run-out cross-validation, or, for one run, blocked
  cross-validation over interleaved segments with a noise-memory buffer around each held-out
  segment;
* significance: a Wald F test of its columns with HAC (Newey-West, statsmodels) errors, the
  bandwidth from the memory of the noise, below ``alpha`` after a Bonferroni correction over
  candidates and axes. Slow bias instability makes any HAC p-value optimistic on one run,
  which is why it is never the only test;
* size: it explains at least ``min_effect`` noise floors (RMS).

The best candidate (largest held-out gain) is added, the time constants are refitted, and the
search repeats until none passes. Candidates within ``alias_margin`` of its gain whose fitted
contribution correlates with its own by ``alias_corr`` or more are its aliases; effects the
data cannot excite are reported as unidentifiable with the experiment that would excite them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any, Mapping, Sequence
import warnings

from gyro_tdc.effects import batch_features, EFFECTS, first_order_lag, input_ids, normalise_ids
from gyro_tdc.errors import FitError
from gyro_tdc.fitting import estimate_t0
from gyro_tdc.runs import Run
import numpy as np
from numpy.typing import NDArray
from scipy import stats
from scipy.optimize import minimize_scalar

__all__ = ['BinMap', 'CandidateScore', 'DiscoveryResult', 'Step', 'Unidentifiable',
           'build_model', 'discover', 'format_summary', 'model_features', 'model_kind',
           'write_report']

_DEG = 180.0 / math.pi
#: Effects whose time constant is fitted by the 1-D search.
_NONLINEAR = ('lag', 'warmup')
#: Candidate order (catalog order without ``bias``).
_CANDIDATES = tuple(e for e in EFFECTS if e != 'bias')
#: Relative norm below which a column is taken as spanned by the others.
_COLLINEAR = 1e-3


# ----------------------------------------------------------------------------- results


@dataclass(frozen=True)
class BinMap:
    """
    The residual binned by one quantity, per axis, with the bins noise cannot explain marked.

    Parameters
    ----------
    name : str
        ``temperature``, ``dTdt``, ``reference`` or ``time``.
    label : str
        What the bins are, with unit (x axis of a plot).
    centers : NDArray[np.float64], shape (B, 3)
        Bin centres per axis (the reference map bins each axis by its own rate); NaN where a
        bin is empty on that axis.
    mean_dps : NDArray[np.float64], shape (B, 3), deg/s
        Weighted mean residual per bin and axis.
    se_dps : NDArray[np.float64], shape (B, 3), deg/s
        Its standard error from the noise floor, inflated for autocorrelated noise.
    count : NDArray[np.int64], shape (B, 3)
        Blocks per bin and axis.
    flagged : NDArray[np.bool_], shape (B, 3)
        ``|mean| > 3 se``: a disagreement noise does not explain.
    labels : tuple of str
        Bin labels (e.g. ``cooling fast``), one per bin.

    """

    name: str
    label: str
    centers: NDArray[np.float64]
    mean_dps: NDArray[np.float64]
    se_dps: NDArray[np.float64]
    count: NDArray[np.int64]
    flagged: NDArray[np.bool_]
    labels: tuple[str, ...] = ()

    @property
    def n_flagged(self) -> int:
        """Return the number of flagged (bin, axis) cells."""
        return int(np.count_nonzero(self.flagged))


@dataclass(frozen=True)
class CandidateScore:
    """
    How well one candidate effect explains what the current model misses.

    Parameters
    ----------
    effect : str
        Effect id.
    params : dict
        Fitted effect parameters (e.g. ``{'tau_s': 180.0}``).
    p_value : float
        HAC Wald test of the added columns, smallest over axes times 3 (Bonferroni over axes).
    heldout_gain_dps2 : float, (deg/s)^2
        Held-out mean squared gap of the model minus that with the candidate.
    effect_rms_dps : float, deg/s
        RMS of the in-sample improvement (what the candidate explains), over blocks and axes.
    gap_dps, heldout_gap_dps : float, deg/s
        In-sample and held-out gap with the candidate added.
    passed : bool
        Significant, held-out gain and effect size all above their thresholds.
    why_not : str
        Which test failed (empty when passed).
    coef : NDArray[np.float64], shape (q, 3)
        Fitted coefficients of the candidate's columns (SI units of the feature).

    """

    effect: str
    params: dict
    p_value: float
    heldout_gain_dps2: float
    effect_rms_dps: float
    gap_dps: float
    heldout_gap_dps: float
    passed: bool
    why_not: str
    coef: NDArray[np.float64] = field(repr=False)


@dataclass(frozen=True)
class Unidentifiable:
    """
    An effect this data cannot excite or cannot tell apart from the model's effects.

    Parameters
    ----------
    effect : str
        Effect id.
    reason : str
        Why, in terms of this data.
    experiment : str
        The experiment that would excite or separate it.

    """

    effect: str
    reason: str
    experiment: str


@dataclass(frozen=True)
class Step:
    """
    One discovery step: the effect named, the evidence and the gap before and after.

    Parameters
    ----------
    effect : str
        The effect added.
    aliases : tuple of str
        Candidates this data cannot tell apart from it.
    description : str
        Its physics (``EFFECTS[effect].description``).
    params : dict
        Its fitted parameters (time constants, s).
    coef_dps : NDArray[np.float64], shape (q, 3)
        Its coefficients per axis in deg/s per feature unit (after the refit).
    gap_before_dps, gap_after_dps : float, deg/s
        In-sample gap before and after.
    heldout_gap_before_dps, heldout_gap_after_dps : float, deg/s
        Held-out gap before and after.
    candidates : tuple of CandidateScore
        Every candidate scored at this step, best first.
    maps_before, maps_after : tuple of BinMap
        Residual maps before and after.
    adev_tau_s : NDArray[np.float64], shape (M,), s
        Allan deviation averaging times (longest run, full rate).
    adev_before_dps, adev_after_dps : NDArray[np.float64], shape (M,), deg/s
        Allan deviation of the residual before and after (RMS over axes).

    """

    effect: str
    aliases: tuple[str, ...]
    description: str
    params: dict
    coef_dps: NDArray[np.float64]
    gap_before_dps: float
    gap_after_dps: float
    heldout_gap_before_dps: float
    heldout_gap_after_dps: float
    candidates: tuple[CandidateScore, ...] = field(repr=False)
    maps_before: tuple[BinMap, ...] = field(repr=False)
    maps_after: tuple[BinMap, ...] = field(repr=False)
    adev_tau_s: NDArray[np.float64] = field(repr=False)
    adev_before_dps: NDArray[np.float64] = field(repr=False)
    adev_after_dps: NDArray[np.float64] = field(repr=False)
    best: CandidateScore | None = field(default=None, repr=False)


@dataclass(frozen=True)
class DiscoveryResult:
    """
    Everything :func:`discover` found; :meth:`to_json` gives the ``discover --json`` document.

    Parameters
    ----------
    base_effects : tuple of str
        Effects of the starting model (``bias`` always included).
    final_effects : tuple of str
        Effects of the final model, catalog order.
    params : dict
        Fitted effect parameters of the final model, ``{effect: {param: value}}``.
    noise_floor_dps : float, deg/s
        Noise floor on the scale of the gap (block means), RMS over axes.
    noise_floor_axes_dps : NDArray[np.float64], shape (3,), deg/s
        The same per axis.
    white_noise_dps : float, deg/s
        Per-sample white-noise standard deviation (first differences), RMS over axes.
    block_s : float, s
        Nominal block length.
    t0_c : float, degC
        Reference temperature of the features.
    steps : tuple of Step
        Discovery steps, in order.
    unidentifiable : tuple of Unidentifiable
        Effects this data cannot excite.
    candidates : tuple of CandidateScore
        Candidates scored against the final model (none passed).
    maps : tuple of BinMap
        Residual maps of the final model.
    gap_dps, heldout_gap_dps : float, deg/s
        Gaps of the final model.
    coef : dict
        Final coefficients: ``offsets`` (R, 3) rad/s per run, ``gain`` (3,) constant
        scale-factor error, ``scale`` (3,) 1/degC, and per input effect (3,) in rad/s per
        feature unit.
    runs : tuple of str
        Run names.
    blocks : int
        Number of blocks analysed.
    notes : tuple of str
        Caveats about this data (confounded candidates, untestable hysteresis...).
    settings : dict
        Thresholds used.
    adev_tau_s : NDArray[np.float64], shape (M,), s
        Allan deviation averaging times of the final residual (empty without ``allan``).
    adev_dps : NDArray[np.float64], shape (M,), deg/s
        Allan deviation of the final residual (longest run, full rate, RMS over axes).

    """

    base_effects: tuple[str, ...]
    final_effects: tuple[str, ...]
    params: dict
    noise_floor_dps: float
    noise_floor_axes_dps: NDArray[np.float64]
    white_noise_dps: float
    block_s: float
    t0_c: float
    steps: tuple[Step, ...]
    unidentifiable: tuple[Unidentifiable, ...]
    candidates: tuple[CandidateScore, ...]
    maps: tuple[BinMap, ...]
    gap_dps: float
    heldout_gap_dps: float
    coef: dict
    runs: tuple[str, ...]
    blocks: int
    notes: tuple[str, ...]
    settings: dict
    adev_tau_s: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)
    adev_dps: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)

    @property
    def named(self) -> tuple[str, ...]:
        """Return the effects named, in step order."""
        return tuple(s.effect for s in self.steps)

    @property
    def consistent_with_noise(self) -> bool:
        """Return True when the final gap is within 1.3 times the noise floor."""
        return self.gap_dps <= 1.3 * self.noise_floor_dps

    def to_json(self, model_file: str | None = None) -> dict:
        """
        Return the ``discover --json`` document (plain types).

        Parameters
        ----------
        model_file : str, optional
            Path of the model file written, or None.

        Returns
        -------
        dict
            ``base_effects``, ``noise_floor_dps``, ``steps``, ``final_effects``,
            ``unidentifiable``, ``model_file``.

        """
        steps = []
        for s in self.steps:
            b = s.best
            steps.append({
                'effect': s.effect, 'aliases': list(s.aliases), 'description': s.description,
                'gap_before_dps': float(s.gap_before_dps), 'gap_after_dps': float(s.gap_after_dps),
                'heldout_gap_before_dps': float(s.heldout_gap_before_dps),
                'heldout_gap_after_dps': float(s.heldout_gap_after_dps),
                'params': _plain(s.params),
                'coef_dps': _plain(s.coef_dps),
                'p_value': None if b is None else float(b.p_value),
                'heldout_gain_dps2': None if b is None else float(b.heldout_gain_dps2),
                'effect_rms_dps': None if b is None else float(b.effect_rms_dps),
                'flagged_bins_before': int(sum(m.n_flagged for m in s.maps_before)),
                'flagged_bins_after': int(sum(m.n_flagged for m in s.maps_after)),
                'adev': {'tau_s': _plain(s.adev_tau_s), 'before_dps': _plain(s.adev_before_dps),
                         'after_dps': _plain(s.adev_after_dps)},
            })
        return {
            'base_effects': list(self.base_effects),
            'noise_floor_dps': float(self.noise_floor_dps),
            'steps': steps,
            'final_effects': list(self.final_effects),
            'unidentifiable': [{'effect': u.effect, 'reason': u.reason,
                                'experiment': u.experiment} for u in self.unidentifiable],
            'model_file': None if model_file is None else str(model_file),
        }


def _plain(value: Any) -> Any:
    """Convert numpy values to plain Python types (NaN becomes None)."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


# ----------------------------------------------------------------------------- the data


class _Data:
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
        self.scale_axes = np.array([np.any(np.abs(self.ref[:, a]) > 1e-12) and _rel_residual(
            np.hstack([self.offsets, self.static['dT'][:, None], self.ref[:, a:a + 1]]),
            self.dtref[:, a]) > _COLLINEAR for a in range(3)])

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
            out[a] = _rel_residual(self.offsets, col) > _COLLINEAR
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


def _rel_residual(x: NDArray[np.float64], col: NDArray[np.float64]) -> float:
    """Return |col - projection on span(x)| / |col - mean| (0: col is in the span)."""
    c = col - col.mean()
    nc = float(np.linalg.norm(c))
    if nc == 0.0:
        return 0.0
    if x.shape[1] == 0:
        return 1.0
    scale = np.linalg.norm(x, axis=0)
    scale[scale == 0] = 1.0
    beta = np.linalg.lstsq(x / scale, col, rcond=None)[0]
    return float(np.linalg.norm(col - (x / scale) @ beta)) / nc


# ----------------------------------------------------------------------------- the model


class _Model:
    """Design matrices, least squares, cross-validation and the HAC test for one effect set."""

    def __init__(self, data: _Data, effects: Sequence[str],
                 params: Mapping[str, Mapping[str, float]]) -> None:
        self.data = data
        self.effects = tuple(effects)
        self.params = {k: dict(v) for k, v in params.items()}
        self.inputs = input_ids(self.effects)
        self.labels = [f'offset:{r}' for r in range(data.n_runs)] + list(self.inputs)
        if 'lag' in self.effects:
            # The die, not the thermometer, feels the curvature: lagged powers too.
            self.labels += [f'lag^{k}' for k, e in ((2, 'dT2'), (3, 'dT3')) if e in self.effects]
        cols = [data.offsets] + [data.column(e, self.params)[:, None]
                                 for e in self.labels[data.n_runs:]]
        self.common = np.hstack(cols)
        ax = []
        self.axis_labels = []
        if np.any(data.gain_axes):
            ax.append(data.ref * data.gain_axes[None, :])
            self.axis_labels.append('gain')
        if 'scale' in self.effects:      # only on axes whose rate steps can separate it
            ax.append(data.dtref * data.scale_axes[None, :])
            self.axis_labels.append('scale')
        self.axis = np.stack(ax, axis=2) if ax else np.zeros((data.K, 3, 0))
        self.p = self.common.shape[1] + self.axis.shape[2]

    def columns_of(self, eid: str) -> list[int]:
        """Return the design columns that belong to effect ``eid``."""
        if eid == 'scale':
            return [self.common.shape[1] + self.axis_labels.index('scale')]
        own = {'lag': ('lag', 'lag^2', 'lag^3'), 'dT2': ('dT2', 'lag^2'),
               'dT3': ('dT3', 'lag^3')}.get(eid, (eid,))
        return [i for i, lab in enumerate(self.labels) if lab in own]

    def design(self, a: int) -> NDArray[np.float64]:
        """Return the design matrix of axis ``a`` (K, p)."""
        return np.hstack([self.common, self.axis[:, a, :]])

    def fit(self, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Return the coefficients (p, 3) fitted on ``rows`` (all by default)."""
        d = self.data
        coef = np.zeros((self.p, 3))
        sw = d.sw if rows is None else d.sw[rows]
        for a in range(3):
            x = self.design(a)
            y = d.y[:, a]
            if rows is not None:
                x, y = x[rows], y[rows]
            coef[:, a] = _lstsq(x * sw[:, None], y * sw)
        return coef

    def predict(self, coef: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the simulated block means (K, 3)."""
        return np.column_stack([self.design(a) @ coef[:, a] for a in range(3)])

    def residual(self, coef: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return measured minus simulated (K, 3), rad/s."""
        return self.data.y - self.predict(self.fit() if coef is None else coef)

    def sse(self) -> float:
        """Return the weighted sum of squared residuals over blocks and axes."""
        r = self.residual()
        return float((self.data.w[:, None] * r * r).sum())

    def cv_residual(self, folds: Sequence[tuple]) -> NDArray[np.float64]:
        """
        Return held-out residuals (K, 3): each block predicted by a fit without its fold.

        A run with no block in the training rows (leave-one-run-out) has no fitted offset;
        its held-out residual is re-anchored to zero mean, as the compensator re-anchors its
        offset at start-up.
        """
        d = self.data
        out = np.empty((d.K, 3))
        for test, train in folds:
            coef = self.fit(train)
            pred = self.predict(coef)
            r = d.y[test] - pred[test]
            runs_test = d.run[test]
            seen = np.unique(d.run[train])
            for rr in np.unique(runs_test):
                if rr not in seen:
                    m = runs_test == rr
                    w = d.w[test][m]
                    r[m] -= (w[:, None] * r[m]).sum(axis=0) / w.sum()
            out[test] = r
        return out


def _lstsq(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least squares with column scaling (zero columns get a zero coefficient)."""
    scale = np.linalg.norm(x, axis=0)
    scale[scale == 0] = 1.0
    beta = np.linalg.lstsq(x / scale, y, rcond=1e-12)[0]
    return beta / scale


def _gap(data: _Data, r: NDArray[np.float64]) -> float:
    """Return the weighted RMS over blocks and axes of a residual (K, 3), in deg/s."""
    return float(np.sqrt((data.w[:, None] * r * r).sum() / (3.0 * data.w.sum()))) * _DEG


def _folds(data: _Data, memory: int, n_folds: int = 5) -> tuple[list[tuple], int]:
    """
    Return cross-validation folds as ``(test, train)`` row masks, and the buffer used.

    Several runs: leave one run out. One run: blocked cross-validation over up to
    ``4 n_folds`` contiguous segments dealt round-robin into ``n_folds`` folds (so every fold
    is predicted by interpolation, never by extrapolation in temperature), with a buffer of
    ``memory`` blocks (the noise memory, at most one segment) on each side of every held-out
    segment left out of the training rows (h-block cross-validation), so that slowly varying
    noise cannot leak from the training rows into the held-out ones.
    """
    if data.n_runs >= 2:
        return [(data.run == r, data.run != r) for r in range(data.n_runs)], 0
    k = data.K
    n_seg = int(min(4 * n_folds, max(k // 3, 2)))
    nf = min(n_folds, n_seg)
    seg = np.minimum(np.arange(k) * n_seg // k, n_seg - 1)
    buffer = int(max(0, min(memory, k // n_seg)))
    out = []
    for f in range(nf):
        test = seg % nf == f
        near = np.convolve(test.astype(float), np.ones(2 * buffer + 1), mode='same') > 0.5
        train = ~near
        if np.count_nonzero(train) < max(4, k // 10):
            train = ~test
        out.append((test, train))
    return out, buffer


def _ar1(r: NDArray[np.float64]) -> float:
    """Return the lag-1 autocorrelation of ``r`` (0 for fewer than 3 values)."""
    if r.shape[0] < 3:
        return 0.0
    c = r - r.mean()
    den = float(c @ c)
    return float(c[1:] @ c[:-1]) / den if den > 0 else 0.0


def _bandwidth(r: NDArray[np.float64], *, floor: bool = True) -> int:
    """
    Return a Newey-West bandwidth (lags) that covers the residual's memory.

    Sokal's automatic window on the integrated autocorrelation time: the smallest ``M`` with
    ``M >= 5 (1 + 2 sum_{l<=M} rho_l)``. Unlike an AR(1) plug-in it sees a weak but slow
    component (bias instability) under white noise, which is what makes a smooth candidate
    look significant when it is not. With ``floor`` the bandwidth is at least ``1.3 sqrt(K)``
    (the rule of Lazarus, Lewis, Stock and Watson for a test's bandwidth); without, it is the
    noise memory itself.
    """
    k = r.shape[0]
    c = r - r.mean()
    n = 1 << int(math.ceil(math.log2(2 * k)))
    f = np.fft.rfft(c, n)
    acf = np.fft.irfft(f * np.conj(f), n)[:k]
    if acf[0] <= 0:
        return 1
    rho = acf / acf[0]
    tau = 1.0 + 2.0 * np.cumsum(rho[1:])
    m = np.arange(1, k)
    ok = np.flatnonzero(m >= 5.0 * tau)
    lag = int(m[ok[0]]) if ok.size else k // 3
    if floor:
        lag = max(lag, int(math.ceil(1.3 * math.sqrt(k))))
    return int(min(max(lag, 1), max(k // 3, 1)))


def _hac_pvalue(model: _Model, coef: NDArray[np.float64], cand: Sequence[int],
                lags: Sequence[int]) -> float:
    """
    Return the HAC Wald p-value of the columns ``cand`` (smallest over axes, times 3).

    Newey-West (Bartlett) errors from statsmodels OLS with ``cov_type='HAC'``, the bandwidth
    ``lags[a]`` from the noise's integrated autocorrelation time (:func:`_noise_lags`); the Wald
    statistic is referred to an F distribution with the estimator's equivalent degrees of
    freedom, ``1.5 K / L`` (a long bandwidth leaves few independent pieces of information,
    so the test does not pretend to more).
    """
    import statsmodels.api as sm

    d = model.data
    ps = []
    for a in range(3):
        x = model.design(a) * d.sw[:, None]
        y = d.y[:, a] * d.sw
        keep = np.linalg.norm(x, axis=0) > 0
        idx = [i for i in cand if keep[i]]
        if not idx:
            continue
        xs = x[:, keep]
        xs = xs / np.linalg.norm(xs, axis=0)
        pos = np.cumsum(keep) - 1
        sel = [int(pos[i]) for i in idx]
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')   # near-collinear columns: the F test says so
            res = sm.OLS(y, xs).fit(cov_type='HAC', cov_kwds={'maxlags': int(lags[a]),
                                                              'use_correction': True})
        b = np.asarray(res.params)[sel]
        v = np.asarray(res.cov_params())[np.ix_(sel, sel)]
        try:
            f = float(b @ np.linalg.solve(v, b)) / len(sel)
        except np.linalg.LinAlgError:
            continue
        dof = max(min(1.5 * d.K / lags[a], d.K - xs.shape[1]), 1.0)
        ps.append(float(stats.f.sf(f, len(sel), dof)))
    return min(1.0, 3.0 * min(ps)) if ps else 1.0


# ----------------------------------------------------------------------------- search


def _tau_bounds(data: _Data, eid: str) -> tuple[float, float]:
    """Return the search bounds of an effect's time constant, s."""
    lo, hi = EFFECTS[eid].bounds['tau_s']
    longest = max(r.duration_s for r in data.runs)
    grid_step = max(float(g[0][1] - g[0][0]) if g[0].size > 1 else 1.0 for g in data.grids)
    lo = max(lo, 2.0 * grid_step)
    if eid == 'warmup':
        lo = max(lo, 3.0 * data.block_s)   # shorter decays are a dummy for the first block
    hi = min(hi, max(2.0 * longest, 4.0 * lo))
    return lo, hi


def _fit_taus(data: _Data, effects: Sequence[str], params: dict, which: Sequence[str]) -> dict:
    """
    Fit the time constants of ``which`` by a bounded 1-D search on the residual each.

    The linear coefficients are re-solved at every trial (variable projection); a log-spaced
    grid finds the basin, a bounded Brent search refines it.
    """
    params = {k: dict(v) for k, v in params.items()}
    for eid in which:
        lo, hi = _tau_bounds(data, eid)

        def sse(log_tau: float, eid: str = eid) -> float:
            trial = {k: dict(v) for k, v in params.items()}
            trial.setdefault(eid, {})['tau_s'] = math.exp(log_tau)
            return _Model(data, effects, trial).sse()

        grid = np.linspace(math.log(lo), math.log(hi), 14)
        vals = np.array([sse(g) for g in grid])
        i = int(np.argmin(vals))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        best = grid[i]
        if b > a:
            res = minimize_scalar(sse, bounds=(a, b), method='bounded',
                                  options={'xatol': 0.01})
            if res.fun <= vals[i]:
                best = float(res.x)
        params.setdefault(eid, {})['tau_s'] = float(math.exp(best))
    return params


def _excitation(data: _Data, base: Sequence[str]) -> tuple[dict, list[str]]:
    """
    Decide which candidates this data cannot excite, before any fit.

    Returns ``{effect: Unidentifiable}`` and a list of notes about the data.
    """
    out: dict[str, Unidentifiable] = {}
    notes: list[str] = []
    span = float(data.temp.max() - data.temp.min())
    rate = data.rate_cpm
    max_rate = float(np.max(np.abs(rate))) if rate.size else 0.0
    moving = np.abs(rate) > max(0.02, 0.1 * max_rate)
    heating = bool(np.any(moving & (rate > 0)))
    cooling = bool(np.any(moving & (rate < 0)))

    def add(eid: str, reason: str, extra: str = '') -> None:
        exp = EFFECTS[eid].excited_by
        out[eid] = Unidentifiable(eid, reason, exp[0].upper() + exp[1:] + extra + '.')

    if span < 0.5:
        for eid in ('dT', 'dT2', 'dT3', 'lag', 'dTdt'):
            add(eid, f'the temperature spans only {span:.2f} degC', ', of at least 10 degC')
    if not np.any(moving):
        for eid in ('dTdt', 'lag'):
            if eid not in out:
                add(eid, 'the temperature never changes at a measurable rate')
    elif heating != cooling:
        leg = 'heat' if heating else 'cool'
        r = np.abs(rate[moving])
        q1, q3 = np.percentile(r, [25, 75])
        if (q3 - q1) < 0.25 * float(np.median(r)):
            for eid in ('dTdt', 'lag'):
                add(eid, f'the data only {leg} and at one rate (~{np.median(r):.2f} degC/min): '
                    'a rate-dependent term is then a constant offset during the ramp, '
                    'confounded with the bias',
                    '; at least two rates, heating and cooling, with soaks between legs')
        else:
            notes.append(f'The data only {leg}: hysteresis between heating and cooling cannot '
                         'be tested; a dT/dt or lag effect seen here rests on the change of '
                         f'the {leg}ing rate alone.')
    if not np.any(data.scale_axes):
        if not np.any(np.abs(data.ref) > 1e-12):
            add('scale', 'the reference rate is zero on every run: a sensitivity change has '
                'nothing to scale')
        else:
            add('scale', 'the reference rate is constant on every run, so a sensitivity '
                'change is indistinguishable from dT')
    # Warm-up: some run must start with a soak (no temperature change) after power-on.
    soak_ok = False
    for r in range(data.n_runs):
        m = data.run == r
        tr, mv = data.t_since[m], moving[m]
        first_move = tr[np.argmax(mv)] if np.any(mv) else tr[-1]
        if first_move >= max(120.0, 3.0 * data.block_s) and np.count_nonzero(tr < first_move) >= 4:
            soak_ok = True
    if not soak_ok:
        add('warmup', 'no run starts with a soak after power-on: a warm-up transient cannot be '
            'told apart from the temperature response and the bias')
    for eid in base:
        out.pop(eid, None)
    return out, notes


def _candidate_params(data: _Data, model: _Model, eid: str) -> dict:
    """Return the model's parameters plus those of candidate ``eid`` (its tau fitted)."""
    params = {k: dict(v) for k, v in model.params.items()}
    if eid in _NONLINEAR:
        effects = tuple(e for e in EFFECTS if e in set(model.effects) | {eid})
        params = _fit_taus(data, effects, params, [eid])
    return params


def _noise_lags(data: _Data, model: _Model, todo: Sequence[str], cparams: Mapping
                ) -> tuple[list, int]:
    """
    Return per-axis HAC bandwidths and the noise memory (blocks) from the richest model.

    The memory of the noise is measured on the residual of the model plus every candidate
    (each with its fitted time constant), so that a second effect not yet in the model does
    not pass for long-memory noise and hide the first.
    """
    params = {k: dict(v) for k, v in model.params.items()}
    for eid in todo:
        if eid in _NONLINEAR:
            params[eid] = dict(cparams[eid][eid])
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | set(todo))
    rich = _Model(data, effects, params)
    r = (data.y - rich.predict(rich.fit())) * data.sw[:, None]
    memory = max(_bandwidth(r[:, a], floor=False) for a in range(3))
    return [_bandwidth(r[:, a]) for a in range(3)], int(memory)


def _score(data: _Data, model: _Model, coef_m: NDArray[np.float64], sse_m: float,
           mse_ho_m: float, folds: list, eid: str, params: dict, *, lags: Sequence[int],
           n_cand: int, alpha: float, min_heldout: float, min_effect: float
           ) -> tuple[CandidateScore, NDArray[np.float64] | None, dict]:
    """Score one candidate against ``model``; returns the score, its contribution and params."""
    effects = tuple(e for e in EFFECTS if e in set(model.effects) | {eid})
    cand = _Model(data, effects, params)
    idx = cand.columns_of(eid)
    own = dict(params[eid]) if eid in _NONLINEAR else {}
    # Is it spanned by the current model (per axis)?
    rel = []
    for a in range(3):
        xa = cand.design(a) * data.sw[:, None]
        for i in idx:
            if np.linalg.norm(xa[:, i]) > 0:
                rel.append(_rel_residual(np.delete(xa, idx, axis=1), xa[:, i]))
    if not rel or max(rel) < _COLLINEAR:
        sc = CandidateScore(eid, own, 1.0, 0.0, 0.0, math.nan, math.nan, False,
                            'collinear', np.zeros((len(idx), 3)))
        return sc, None, params
    coef = cand.fit()
    r = data.y - cand.predict(coef)
    sse = float((data.w[:, None] * r * r).sum())
    contrib = cand.predict(coef) - model.predict(coef_m)
    ho = cand.cv_residual(folds)
    mse_ho = float((data.w[:, None] * ho * ho).sum() / (3.0 * data.w.sum()))
    gain = (mse_ho_m - mse_ho) * _DEG ** 2
    eff = math.sqrt(max(sse_m - sse, 0.0) / (3.0 * data.w.sum())) * _DEG
    p = _hac_pvalue(cand, coef, idx, lags)
    floor = data.floor * _DEG
    why = []
    if p >= alpha / max(n_cand, 1):
        why.append(f'p={p:.2g}')
    if gain <= max(min_heldout * floor ** 2, 0.01 * mse_ho_m * _DEG ** 2):
        why.append('no held-out gain')
    if eff < min_effect * floor:
        why.append('effect below noise')
    sc = CandidateScore(eid, own, p, gain, eff, _gap(data, r), _gap(data, ho), not why,
                        ', '.join(why), coef[idx])
    return sc, contrib, params


def _corr(a: NDArray[np.float64], b: NDArray[np.float64], w: NDArray[np.float64]) -> float:
    """Return the weighted correlation of two (K, 3) contributions, flattened."""
    wa = (a * np.sqrt(w)[:, None]).ravel()
    wb = (b * np.sqrt(w)[:, None]).ravel()
    den = float(np.linalg.norm(wa) * np.linalg.norm(wb))
    return float(wa @ wb) / den if den > 0 else 0.0


# ----------------------------------------------------------------------------- maps, Allan


def _maps(data: _Data, r: NDArray[np.float64]) -> tuple[BinMap, ...]:
    """Bin the residual by temperature, dT/dt, reference rate and time since start."""
    floor = data.floor_axes * _DEG
    infl = np.empty(3)
    for a in range(3):
        # AR(1) of the noise from first differences (slow disagreements cancel there).
        rho = 1.0 + 2.0 * _ar1(np.diff(r[:, a])) if data.K > 3 else 0.0
        rho = min(max(rho, 0.0), 0.9)
        infl[a] = math.sqrt((1.0 + rho) / (1.0 - rho))
    rd = r * _DEG

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
            v = data.ref[:, a] * _DEG
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


def _full_rate_residual(data: _Data, model: _Model, coef: NDArray[np.float64]
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
    x = batch_features(model.inputs, run.t, run.temp, t0=data.t0, params=model.params)
    if len(model.labels) > data.n_runs + len(model.inputs):
        lag = x[:, model.inputs.index('lag')]
        x = np.column_stack([x] + [lag ** int(lab[4:]) for lab in
                                   model.labels[data.n_runs + len(model.inputs):]])
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
                pred[:, a] += c[j] * (run.temp - data.t0) * run.omega_ref[:, a] \
                    * data.scale_axes[a]
            j += 1
    return (y - pred)[sl], 1.0 / med


def _adev(data: _Data, model: _Model, coef: NDArray[np.float64]
          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return Allan deviation (taus, RMS over axes in deg/s) of the full-rate residual."""
    from gyro_tdc.metrics import allan_deviation

    res, rate = _full_rate_residual(data, model, coef)
    if res.shape[0] < 16:
        return np.zeros(0), np.zeros(0)
    taus, dev = allan_deviation(res, rate)
    return np.asarray(taus), np.sqrt(np.mean(np.asarray(dev) ** 2, axis=1))


# ----------------------------------------------------------------------------- public API


def discover(runs: Sequence[Run], *, base: str | Sequence[str] = ('bias', 'dT'),
             candidates: str | Sequence[str] | None = None, block_s: float = 10.0,
             t0: float | None = None, alpha: float = 0.01, min_heldout: float = 0.1,
             min_effect: float = 0.6, alias_margin: float = 0.25, alias_corr: float = 0.9,
             max_steps: int = 6, n_folds: int = 5, allan: bool = True) -> DiscoveryResult:
    """
    Find the effects a drift model is missing, one step at a time.

    Parameters
    ----------
    runs : sequence of Run
        Measured runs (each a continuous recording from power-on; filters restart per run).
    base : str or sequence of str
        Effects of the starting model (``'bias,dT'``: eq. 18's conventional model); ``bias``
        is always included, as one offset per run.
    candidates : str or sequence of str, optional
        Effects to try (default: every catalog effect not in ``base``).
    block_s : float, s
        Block length of the analysis; gaps and the noise floor are RMS of block means.
    t0 : float, optional, degC
        Reference temperature (default :func:`gyro_tdc.fitting.estimate_t0` of the first run).
    alpha : float
        Family-wise significance level per step (Bonferroni over candidates and axes).
    min_heldout : float
        Smallest held-out gain, as a fraction of the squared noise floor.
    min_effect : float
        Smallest effect RMS, as a fraction of the noise floor.
    alias_margin : float
        A candidate within this fraction of the best held-out gain...
    alias_corr : float
        ...whose fitted contribution correlates at least this much with the best's is an alias.
    max_steps : int
        Most effects added.
    n_folds : int
        Cross-validation folds for a single run (see :func:`_folds`; several runs: leave one
        run out).
    allan : bool
        Compute the Allan deviation of the residual before and after each step.

    Returns
    -------
    DiscoveryResult
        Steps, final model, unidentifiable effects, maps.

    Raises
    ------
    FitError
        When the runs cannot support the analysis (too few blocks, non-finite values...).
    FeatureError
        When an effect id is unknown.

    """
    runs = list(runs)
    _check(runs, block_s)
    base_ids = normalise_ids(tuple(normalise_ids(base)) + ('bias',))
    if candidates is None:
        cand_ids = tuple(e for e in _CANDIDATES if e not in base_ids)
    else:
        cand_ids = tuple(e for e in normalise_ids(candidates) if e not in base_ids and e != 'bias')
    if t0 is None:
        t0 = estimate_t0(runs[0])
    data = _Data(runs, block_s=block_s, t0=t0)
    if data.K < 8:
        raise FitError(f'Too few blocks to analyse: {data.K} blocks of {block_s:g} s '
                       '(need at least 8); record longer or use a shorter block.')
    if 'scale' in base_ids and not np.any(np.abs(data.ref) > 1e-12):
        raise FitError('Effect `scale` in the base model needs a non-zero reference rate '
                       '(rate-table data); every run has omega_ref = 0.')
    p_base = len(base_ids) - 1 + data.n_runs + 2
    if data.K <= p_base + 2:
        raise FitError(f'Too few blocks ({data.K}) for the base model '
                       f'({", ".join(base_ids)}); record longer or use a shorter block.')
    unident, notes = _excitation(data, base_ids)
    params: dict = {}
    for eid in base_ids:
        if EFFECTS[eid].params:
            params[eid] = dict(EFFECTS[eid].params)
    nonlin = [e for e in base_ids if e in _NONLINEAR]
    if nonlin:
        params = _fit_taus(data, base_ids, params, nonlin)
    effects = base_ids
    model = _Model(data, effects, params)
    steps: list[Step] = []
    collinear: list[str] = []
    scores: tuple[CandidateScore, ...] = ()
    adev_cache: tuple | None = None
    first_round = True
    while True:
        coef_m = model.fit()
        r_m = data.y - model.predict(coef_m)
        sse_m = float((data.w[:, None] * r_m * r_m).sum())
        todo = [e for e in cand_ids if e not in effects and e not in unident]
        results = []
        cparams = {eid: _candidate_params(data, model, eid) for eid in todo}
        lags, memory = _noise_lags(data, model, todo, cparams)
        folds, buffer = _folds(data, memory, n_folds)
        ho_m = model.cv_residual(folds)
        mse_ho_m = float((data.w[:, None] * ho_m * ho_m).sum() / (3.0 * data.w.sum()))
        for eid in todo:
            sc, contrib, p = _score(data, model, coef_m, sse_m, mse_ho_m, folds, eid,
                                    cparams[eid], lags=lags, n_cand=len(todo), alpha=alpha,
                                    min_heldout=min_heldout, min_effect=min_effect)
            if sc.why_not == 'collinear':
                if eid not in collinear:
                    collinear.append(eid)
                continue
            results.append((sc, contrib, p))
        results.sort(key=lambda x: (not x[0].passed, -x[0].heldout_gain_dps2))
        scores = tuple(x[0] for x in results)
        if not steps and first_round:
            notes += _confounded(data, model, scores, params)
            first_round = False
        passing = [x for x in results if x[0].passed]
        if not passing or len(steps) >= max_steps:
            break
        best, contrib_b, p_b = passing[0]
        aliases = []
        for sc, contrib, _p in results[1:]:
            if contrib is None or sc.heldout_gain_dps2 <= 0:
                continue
            if (sc.heldout_gain_dps2 >= (1.0 - alias_margin) * best.heldout_gain_dps2
                    and abs(_corr(contrib, contrib_b, data.w)) >= alias_corr):
                aliases.append(sc.effect)
        new_effects = tuple(e for e in EFFECTS if e in set(effects) | {best.effect})
        new_params = {k: dict(v) for k, v in p_b.items()}
        refit = [e for e in new_effects if e in _NONLINEAR]
        if len(refit) > 1:
            new_params = _fit_taus(data, new_effects, new_params, refit)
        new_model = _Model(data, new_effects, new_params)
        coef_n = new_model.fit()
        r_n = data.y - new_model.predict(coef_n)
        ho_n = new_model.cv_residual(folds)
        if allan:
            before = adev_cache or _adev(data, model, coef_m)
            after = _adev(data, new_model, coef_n)
            adev_cache = after
        else:
            before = after = (np.zeros(0), np.zeros(0))
        idx = new_model.columns_of(best.effect)
        unit = 1.0 if best.effect == 'scale' else _DEG
        steps.append(Step(
            effect=best.effect, aliases=tuple(aliases),
            description=EFFECTS[best.effect].description,
            params=dict(new_params.get(best.effect, {})) if best.effect in _NONLINEAR else {},
            coef_dps=coef_n[idx] * unit,
            gap_before_dps=_gap(data, r_m), gap_after_dps=_gap(data, r_n),
            heldout_gap_before_dps=_gap(data, ho_m), heldout_gap_after_dps=_gap(data, ho_n),
            candidates=scores, maps_before=_maps(data, r_m), maps_after=_maps(data, r_n),
            adev_tau_s=before[0], adev_before_dps=before[1], adev_after_dps=after[1],
            best=best))
        effects, params, model = new_effects, new_params, new_model

    coef = model.fit()
    r = data.y - model.predict(coef)
    ho = model.cv_residual(folds)
    for eid in collinear:
        if eid not in effects and eid not in unident:
            unident[eid] = Unidentifiable(
                eid, 'on this data its feature is a combination of the effects of the model '
                f'({", ".join(effects)})', EFFECTS[eid].excited_by[0].upper()
                + EFFECTS[eid].excited_by[1:] + '.')
    final_coef = _coef_dict(data, model, coef)
    if allan:
        adev = adev_cache or _adev(data, model, coef)
    else:
        adev = (np.zeros(0), np.zeros(0))
    return DiscoveryResult(
        base_effects=base_ids, final_effects=effects,
        params={k: dict(v) for k, v in params.items() if k in effects and k in _NONLINEAR},
        noise_floor_dps=data.floor * _DEG, noise_floor_axes_dps=data.floor_axes * _DEG,
        white_noise_dps=data.white * _DEG, block_s=float(block_s), t0_c=float(t0),
        steps=tuple(steps),
        unidentifiable=tuple(unident[e] for e in EFFECTS if e in unident and e in cand_ids),
        candidates=scores, maps=_maps(data, r), gap_dps=_gap(data, r),
        heldout_gap_dps=_gap(data, ho), coef=final_coef, runs=tuple(x.name for x in runs),
        blocks=data.K, notes=tuple(notes),
        settings={'alpha': alpha, 'min_heldout': min_heldout, 'min_effect': min_effect,
                  'alias_margin': alias_margin, 'alias_corr': alias_corr,
                  'folds': 'leave-one-run-out' if data.n_runs >= 2 else
                  f'{len(folds)} blocked folds, buffer {buffer} blocks',
                  'block_s': float(block_s),
                  'block_mean_s': float(data.block_eff_s)},
        adev_tau_s=adev[0], adev_dps=adev[1])


def _confounded(data: _Data, model: _Model, scores: Sequence[CandidateScore],
                params: dict) -> list[str]:
    """Return notes on candidate pairs whose columns are strongly correlated on this data."""
    notes = []
    x = model.common
    cols = {}
    for sc in scores:
        if sc.effect in ('scale',) or sc.effect not in input_ids([sc.effect]):
            continue
        p = {k: dict(v) for k, v in params.items()}
        p.update({sc.effect: dict(sc.params)} if sc.params else {})
        col = data.column(sc.effect, p)
        beta = _lstsq(x * data.sw[:, None], col * data.sw)
        cols[sc.effect] = (col - x @ beta) * data.sw
    ids = list(cols)
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            a, b = cols[ids[i]], cols[ids[j]]
            den = float(np.linalg.norm(a) * np.linalg.norm(b))
            c = float(a @ b) / den if den > 0 else 0.0
            if abs(c) >= 0.7:
                notes.append(f'{ids[i]} and {ids[j]} are partly confounded on this data '
                             f'(correlation {c:+.2f} after removing the effects of the model).')
    return notes


def _coef_dict(data: _Data, model: _Model, coef: NDArray[np.float64]) -> dict:
    """Return the final coefficients by name (SI units)."""
    nr = data.n_runs
    out: dict[str, Any] = {'offsets': coef[:nr].copy()}
    for i, lab in enumerate(model.labels[nr:]):
        out[lab] = coef[nr + i].copy()
    j = model.common.shape[1]
    out['gain'] = np.zeros(3)
    out['scale'] = np.zeros(3)
    for lab in model.axis_labels:
        out[lab] = coef[j] * (data.gain_axes if lab == 'gain' else data.scale_axes)
        j += 1
    return out


def _check(runs: Sequence[Run], block_s: float) -> None:
    """Reject input that cannot be analysed, naming what is wrong."""
    if not isinstance(block_s, (int, float)) or not math.isfinite(block_s) or block_s <= 0:
        raise FitError(f'Expected `block_s` to be a positive number of seconds, got {block_s!r}.')
    if not runs:
        raise FitError('No runs given to discover.')
    for r in runs:
        if not isinstance(r, Run):
            raise FitError(f'Expected gyro_tdc.runs.Run objects, got {type(r).__name__}.')
        if len(r) < 16:
            raise FitError(f'Run {r.name!r} has {len(r)} samples; need at least 16.')
        for key in ('t', 'temp', 'omega', 'omega_ref'):
            if not np.all(np.isfinite(getattr(r, key))):
                raise FitError(f'Run {r.name!r} has non-finite values in `{key}`.')


def model_kind(effects: Sequence[str]) -> str:
    """
    Return the model kind that holds what discovery fitted for ``effects``.

    ``poly`` is exactly the linear model discovery validated, except when ``lag`` meets a
    curvature (``dT2``, ``dT3``): the die's curvature then needs powers of the lagged
    temperature, which a ``poly`` model of the catalog features cannot hold and an ``rbf``
    network over them can.

    Parameters
    ----------
    effects : sequence of str
        Effect ids.

    Returns
    -------
    str
        ``'poly'`` or ``'rbf'``.

    """
    ids = set(effects)
    return 'rbf' if 'lag' in ids and ids & {'dT2', 'dT3'} else 'poly'


def build_model(result: DiscoveryResult, runs: Sequence[Run], *, kind: str | None = None,
                created: Mapping | None = None):
    """
    Fit the compensation model of the discovered effects, ready for ``save_model``.

    The per-run offsets and the constant scale-factor error found by :func:`discover` are
    removed from the runs first (they are not thermal: the compensator re-anchors its offset
    at start-up, and a rate-table gain error belongs to a separate calibration); then
    :func:`gyro_tdc.fitting.fit_model` fits the final effects with the fitted time constants.

    Parameters
    ----------
    result : DiscoveryResult
        What :func:`discover` returned for ``runs``.
    runs : sequence of Run
        The same runs.
    kind : str, optional
        ``'poly'`` or ``'rbf'``; default :func:`model_kind` of the final effects.
    created : mapping, optional
        Extra creation info (command line, bags).

    Returns
    -------
    gyro_tdc.model.CompensationModel
        The fitted model.

    """
    from gyro_tdc.fitting import fit_model

    if len(runs) != len(result.runs):
        raise FitError(f'Expected the {len(result.runs)} runs discovery analysed, '
                       f'got {len(runs)}.')
    off = np.asarray(result.coef['offsets'])
    mean_off = off.mean(axis=0)
    gain = np.asarray(result.coef['gain'])
    adjusted = []
    for r, run in enumerate(runs):
        omega = run.omega - (off[r] - mean_off)[None, :] - gain[None, :] * run.omega_ref
        adjusted.append(Run(run.t, run.temp, omega, run.omega_ref, run.name, dict(run.info)))
    features = model_features(result, runs)
    info = {'discover': {'final_effects': list(result.final_effects),
                         'noise_floor_dps': result.noise_floor_dps,
                         'gain_removed': [float(g) for g in gain]}}
    info.update(dict(created or {}))
    kind = model_kind(features) if kind is None else kind
    return fit_model(adjusted, kind=kind, features=features, t0=result.t0_c,
                     fit_params=False, params=result.params, created=info)


def model_features(result: DiscoveryResult, runs: Sequence[Run]) -> tuple[str, ...]:
    """
    Return the effects of the model file: the final effects the data can support.

    With a temperature span under :data:`gyro_tdc.fitting.MIN_SPAN_C` (a warm-up test at a
    fixed ambient) the temperature effects, base ``dT`` included, are left out: the data say
    nothing about them.

    Parameters
    ----------
    result : DiscoveryResult
        A discovery.
    runs : sequence of Run
        The runs it analysed.

    Returns
    -------
    tuple of str
        Effect ids, catalog order.

    """
    from gyro_tdc.fitting import MIN_SPAN_C

    lo = min(float(np.min(r.temp)) for r in runs)
    hi = max(float(np.max(r.temp)) for r in runs)
    if hi - lo >= MIN_SPAN_C:
        return tuple(result.final_effects)
    thermal = {'dT', 'dT2', 'dT3', 'dTdt', 'lag', 'scale'}
    return tuple(e for e in result.final_effects if e not in thermal)


def format_summary(result: DiscoveryResult) -> str:
    """
    Return a readable multi-line summary of a discovery.

    Parameters
    ----------
    result : DiscoveryResult
        A discovery.

    Returns
    -------
    str
        The summary, ending with a newline.

    """
    lines = [
        f'discover: {len(result.runs)} run(s), {result.blocks} blocks of {result.block_s:g} s, '
        f'T0 = {result.t0_c:.2f} degC',
        f'base model: {", ".join(result.base_effects)}  '
        f'(one offset per run; cross-validation: {result.settings["folds"]})',
        f'noise floor: {result.noise_floor_dps:.3g} deg/s on block means of '
        f'{result.settings["block_mean_s"]:.3g} s (white noise {result.white_noise_dps:.3g} '
        'deg/s per sample); gaps are RMS of block means',
    ]
    if not result.steps:
        lines.append('no missing effect found: no candidate is significant, gains on held-out '
                     'data and exceeds the noise')
    for i, s in enumerate(result.steps, 1):
        par = ', '.join(f'{k} = {v:.4g}' for k, v in s.params.items())
        b = s.best
        lines.append(f'step {i}: add {s.effect}' + (f' ({par})' if par else '')
                     + (f'; aliases: {", ".join(s.aliases)}' if s.aliases else ''))
        lines.append(f'  {s.description}')
        if b is not None:
            lines.append(f'  evidence: HAC p = {b.p_value:.2g}, held-out gain '
                         f'{b.heldout_gain_dps2:.3g} (deg/s)^2, effect RMS '
                         f'{b.effect_rms_dps:.3g} deg/s')
        lines.append(f'  gap {s.gap_before_dps:.4g} -> {s.gap_after_dps:.4g} deg/s, held-out '
                     f'{s.heldout_gap_before_dps:.4g} -> {s.heldout_gap_after_dps:.4g} deg/s')
    lines.append(f'final model: {", ".join(result.final_effects)}; gap {result.gap_dps:.4g} '
                 f'deg/s = {result.gap_dps / result.noise_floor_dps:.2f} x noise floor '
                 f'(held-out {result.heldout_gap_dps:.4g})')
    if result.candidates:
        lines.append('remaining candidates (none passed):')
        for c in result.candidates:
            lines.append(f'  {c.effect:7s} p = {c.p_value:.2g}, held-out gain '
                         f'{c.heldout_gain_dps2:+.2g} (deg/s)^2, effect {c.effect_rms_dps:.2g} '
                         f'deg/s: {c.why_not}')
    for u in result.unidentifiable:
        lines.append(f'unidentifiable: {u.effect}: {u.reason}. Experiment: {u.experiment}')
    for n in result.notes:
        lines.append(f'note: {n}')
    gain = np.asarray(result.coef.get('gain', np.zeros(3)))
    if np.any(gain != 0):
        lines.append('constant scale-factor error vs the reference (not thermal, not in the '
                     'model file): ' + ', '.join(f'{g * 1e6:+.0f} ppm' for g in gain))
    return '\n'.join(lines) + '\n'


# ----------------------------------------------------------------------------- report


_AXES = ('x', 'y', 'z')
_COLORS = ('tab:blue', 'tab:orange', 'tab:green')


def _plot_maps(maps_rows: Sequence[tuple[str, Sequence[BinMap]]], path: Path) -> None:
    """Plot rows of residual maps (one row per model state) into one PNG."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure

    ncol = max(len(m) for _t, m in maps_rows)
    fig = Figure(figsize=(4.0 * ncol, 3.0 * len(maps_rows)), constrained_layout=True)
    axes = fig.subplots(len(maps_rows), ncol, squeeze=False)
    for i, (title, maps) in enumerate(maps_rows):
        for j in range(ncol):
            ax = axes[i][j]
            if j >= len(maps):
                ax.set_visible(False)
                continue
            m = maps[j]
            for a in range(3):
                x, y, e = m.centers[:, a], m.mean_dps[:, a], m.se_dps[:, a]
                ok = np.isfinite(x) & np.isfinite(y)
                if not np.any(ok):
                    continue
                ax.errorbar(x[ok], y[ok], yerr=3.0 * e[ok], color=_COLORS[a], marker='.',
                            capsize=2, lw=1, label=_AXES[a])
                fl = ok & m.flagged[:, a]
                ax.plot(x[fl], y[fl], 'o', mfc='none', mec='red', ms=9)
            ax.axhline(0.0, color='k', lw=0.5)
            if m.name == 'time' and np.nanmin(m.centers) > 0:
                ax.set_xscale('log')
            ax.set_xlabel(m.label)
            ax.set_title(f'{title}: by {m.name} ({m.n_flagged} flagged)', fontsize=9)
            if j == 0:
                ax.set_ylabel('mean residual (deg/s), +-3 se')
            if i == 0 and j == 0:
                ax.legend(fontsize=7)
    fig.savefig(path, dpi=90)


def _plot_allan(result: DiscoveryResult, path: Path) -> bool:
    """Plot the Allan deviation of the residual before and after each step."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure

    curves = []
    for i, s in enumerate(result.steps):
        if s.adev_tau_s.size == 0:
            continue
        if i == 0:
            curves.append((', '.join(result.base_effects), s.adev_tau_s, s.adev_before_dps))
        curves.append((f'+ {s.effect}', s.adev_tau_s, s.adev_after_dps))
    if not curves and result.adev_tau_s.size:
        curves.append((', '.join(result.final_effects), result.adev_tau_s, result.adev_dps))
    if not curves:
        return False
    fig = Figure(figsize=(6.0, 4.2), constrained_layout=True)
    ax = fig.subplots()
    for label, tau, dev in curves:
        ax.loglog(tau, dev, marker='.', label=label)
    tb = result.settings.get('block_mean_s', result.block_s)
    ax.plot([tb], [result.noise_floor_dps], 'k*', ms=10,
            label=f'noise floor (block means, {tb:.3g} s)')
    ax.set_xlabel('averaging time tau (s)')
    ax.set_ylabel('Allan deviation of the residual (deg/s)')
    ax.grid(True, which='both', lw=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=90)
    return True


def write_report(result: DiscoveryResult, out_dir: str | Path) -> Path:
    """
    Write ``report.md`` with PNG residual maps and the Allan deviation of the residual.

    Parameters
    ----------
    result : DiscoveryResult
        A discovery.
    out_dir : str or Path
        Directory (created if needed).

    Returns
    -------
    Path
        The path of ``report.md``.

    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = ['# Discovery report', '',
          f'Runs: {", ".join(f"`{r}`" for r in result.runs)} ({result.blocks} blocks of '
          f'{result.block_s:g} s; T0 = {result.t0_c:.2f} degC).', '',
          f'Base model: **{", ".join(result.base_effects)}** (one offset per run). '
          f'Cross-validation: {result.settings["folds"]}.', '',
          f'Noise floor: **{result.noise_floor_dps:.4g} deg/s** on block means of '
          f'{result.settings["block_mean_s"]:.3g} s (x, y, z: '
          + ', '.join(f'{v:.3g}' for v in result.noise_floor_axes_dps)
          + f'); white noise {result.white_noise_dps:.4g} deg/s per sample. The *gap* is the '
          'RMS over blocks and axes of measured minus simulated block means.', '']
    if not result.steps:
        md += ['**No missing effect found**: no candidate is significant (HAC), gains on '
               'held-out data and exceeds the noise at once.', '']
    else:
        md += ['| step | effect | aliases | parameters | HAC p | held-out gain (deg/s)^2 | '
               'gap before -> after (deg/s) | held-out gap before -> after (deg/s) |',
               '|---|---|---|---|---|---|---|---|']
        for i, s in enumerate(result.steps, 1):
            par = ', '.join(f'{k} = {v:.4g}' for k, v in s.params.items()) or '-'
            b = s.best
            md.append(f'| {i} | `{s.effect}` | {", ".join(s.aliases) or "-"} | {par} | '
                      f'{b.p_value:.2g} | {b.heldout_gain_dps2:.3g} | '
                      f'{s.gap_before_dps:.4g} -> {s.gap_after_dps:.4g} | '
                      f'{s.heldout_gap_before_dps:.4g} -> {s.heldout_gap_after_dps:.4g} |')
        md.append('')
    for i, s in enumerate(result.steps, 1):
        name = f'step{i}_maps.png'
        _plot_maps([('before', s.maps_before), (f'after + {s.effect}', s.maps_after)],
                   out / name)
        md += [f'## Step {i}: {s.effect}', '', s.description, '',
               'Coefficients per axis (deg/s per feature unit; 1/degC for scale): '
               + ', '.join(f'{v:.4g}' for v in np.ravel(s.coef_dps)), '',
               '| candidate | parameters | HAC p | held-out gain (deg/s)^2 | effect RMS (deg/s) '
               '| verdict |', '|---|---|---|---|---|---|']
        for c in s.candidates:
            par = ', '.join(f'{k} = {v:.4g}' for k, v in c.params.items()) or '-'
            md.append(f'| `{c.effect}` | {par} | {c.p_value:.2g} | {c.heldout_gain_dps2:.3g} | '
                      f'{c.effect_rms_dps:.3g} | {"passes" if c.passed else c.why_not} |')
        md += ['', f'![residual maps, step {i}]({name})', '']
    md += ['## Final model', '',
           f'Effects: **{", ".join(result.final_effects)}**; gap {result.gap_dps:.4g} deg/s = '
           f'{result.gap_dps / result.noise_floor_dps:.2f} x the noise floor (held-out '
           f'{result.heldout_gap_dps:.4g} deg/s).', '']
    if result.params:
        md += ['Fitted time constants: ' + '; '.join(
            f'{e}: ' + ', '.join(f'{k} = {v:.4g} s' for k, v in p.items())
            for e, p in result.params.items()), '']
    if result.candidates:
        md += ['| remaining candidate | HAC p | held-out gain (deg/s)^2 | effect RMS (deg/s) | '
               'why not |', '|---|---|---|---|---|']
        for c in result.candidates:
            md.append(f'| `{c.effect}` | {c.p_value:.2g} | {c.heldout_gain_dps2:.3g} | '
                      f'{c.effect_rms_dps:.3g} | {c.why_not} |')
        md.append('')
    _plot_maps([('final model', result.maps)], out / 'final_maps.png')
    md += ['![residual maps, final model](final_maps.png)', '']
    if _plot_allan(result, out / 'allan.png'):
        md += ['![Allan deviation of the residual](allan.png)', '']
    if result.unidentifiable:
        md += ['## Not identifiable from this data', '', '| effect | why | experiment |',
               '|---|---|---|']
        md += [f'| `{u.effect}` | {u.reason} | {u.experiment} |' for u in result.unidentifiable]
        md.append('')
    if result.notes:
        md += ['## Notes', ''] + [f'- {n}' for n in result.notes] + ['']
    path = out / 'report.md'
    path.write_text('\n'.join(md), encoding='utf-8')
    return path
