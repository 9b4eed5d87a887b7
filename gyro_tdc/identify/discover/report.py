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
Where the model and the measurement disagree, and the discovery report that shows it.

:func:`residual_maps` bins the block-mean residual by temperature, dT/dt, reference rate and
time since power-on and flags the bins noise cannot explain; :func:`residual_adev` is the
Allan deviation of the full-rate residual of the longest run; :func:`write_report` writes
``report.md`` with PNG residual maps and the Allan deviation plot.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

from gyro_tdc.base import atomic_write, AXES, figure, save_png
from gyro_tdc.identify.discover.data import ar1, BlockData, DEG, LinearModel
from gyro_tdc.identify.discover.results import BinMap, DiscoveryResult
from gyro_tdc.model import batch_features, ThermalState
from gyro_tdc.signal import allan_deviation
import numpy as np
from numpy.typing import NDArray

__all__ = ['residual_adev', 'residual_maps', 'write_report']

_COLORS = ('tab:blue', 'tab:orange', 'tab:green')


#: Edges of the time-since-start bins, min (log-like: a warm-up shows at the start).
_TIME_EDGES_MIN = (0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 1280.0)


def _bins(v: NDArray[np.float64], edges: NDArray[np.float64]) -> NDArray[np.int64]:
    """Return the bin of each value between ``edges`` (values beyond the ends in the end bins)."""
    return np.clip(np.searchsorted(edges, v, side='right') - 1, 0, edges.size - 2)


def _centers(v: NDArray[np.float64], k: NDArray[np.int64], nb: int) -> NDArray[np.float64]:
    """Return the mean of ``v`` in each of the ``nb`` bins ``k`` (NaN in an empty bin)."""
    return np.array([v[k == i].mean() if np.any(k == i) else np.nan for i in range(nb)])


def residual_maps(data: BlockData, r: NDArray[np.float64]) -> tuple[BinMap, ...]:
    """Bin the residual by temperature, dT/dt, reference rate and time since start."""
    floor = data.floor_axes * DEG
    # AR(1) of the noise from first differences (slow disagreements cancel there).
    rho = [min(max(1.0 + 2.0 * ar1(np.diff(r[:, a])) if data.K > 3 else 0.0, 0.0), 0.9)
           for a in range(3)]
    infl = np.array([math.sqrt((1.0 + x) / (1.0 - x)) for x in rho])
    rd = r * DEG

    def binmap(name: str, label: str, keys: NDArray[np.int64], centers: NDArray[np.float64],
               labels: tuple[str, ...] = ()) -> BinMap:
        nb = centers.shape[0]
        mean, se = np.full((2, nb, 3), np.nan)
        count = np.zeros((nb, 3), dtype=np.int64)
        for a in range(3):
            k = keys[:, a] if keys.ndim == 2 else keys
            wsum = np.bincount(k, weights=data.w, minlength=nb)
            s = np.bincount(k, weights=data.w * rd[:, a], minlength=nb)
            count[:, a] = np.bincount(k, minlength=nb)
            has = wsum > 0
            mean[has, a] = s[has] / wsum[has]
            se[has, a] = floor[a] * infl[a] / np.sqrt(wsum[has])
        flagged = np.nan_to_num(np.abs(mean)) > 3.0 * np.nan_to_num(se, nan=np.inf)
        centers = np.repeat(centers[:, None], 3, axis=1) if centers.ndim == 1 else centers
        return BinMap(name, label, centers, mean, se, count, flagged, labels)

    # Temperature: up to 10 equal-width bins.
    lo, hi = float(data.temp.min()), float(data.temp.max())
    edges = np.linspace(lo, hi, (10 if hi - lo > 1e-6 else 1) + 1)
    out = [binmap('temperature', 'temperature (degC)', _bins(data.temp, edges),
                  (edges[:-1] + edges[1:]) / 2.0)]
    # dT/dt: cooling fast/slow, still, heating slow/fast.
    rate = data.rate_cpm
    k = np.full(data.K, 2, dtype=np.int64)
    for sign, (slow, fast) in ((1, (3, 4)), (-1, (1, 0))):
        if np.any(m := data.moving & (sign * rate > 0)):
            k[m] = np.where(sign * rate[m] <= float(np.median(sign * rate[m])), slow, fast)
    out.append(binmap('dTdt', 'dT/dt (degC/min)', k, _centers(rate, k, 5),
                      ('cooling fast', 'cooling slow', 'still', 'heating slow', 'heating fast')))
    # Reference rate: each axis by its own rate, up to 8 levels or quantile bins.
    if np.any(np.abs(data.ref) > 1e-12):
        keys = np.empty((data.K, 3), dtype=np.int64)
        cen = np.empty((8, 3))
        for a in range(3):
            v = data.ref[:, a] * DEG
            levels = np.unique(np.round(v, 6))
            keys[:, a] = (np.searchsorted(levels, np.round(v, 6)) if levels.size <= 8
                          else _bins(v, np.unique(np.quantile(v, np.linspace(0, 1, 9)))))
            cen[:, a] = _centers(v, keys[:, a], 8)
        out.append(binmap('reference', 'reference rate (deg/s)', keys, cen))
    # Time since the start of each run.
    tm, tmax = data.t_since / 60.0, float(data.t_since.max()) / 60.0
    edges = np.asarray([e for e in _TIME_EDGES_MIN if e < tmax] + [tmax + 1e-9])
    k = _bins(tm, edges)
    out.append(binmap('time', 'time since start (min)', k, _centers(tm, k, edges.size - 1)))
    return tuple(out)


def residual_adev(data: BlockData, model: LinearModel, coef: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return Allan deviation (taus, RMS over axes in deg/s) of the full-rate residual.

    The residual is that of the longest contiguous stretch of the longest run.
    """
    r = int(np.argmax([len(x) for x in data.runs]))
    run, dt = data.runs[r], np.diff(data.runs[r].t)
    med = float(np.median(dt)) if dt.size else 1.0
    bounds = np.concatenate([[0], np.flatnonzero(dt > 1.5 * med + 1e-9) + 1, [len(run)]])
    i = int(np.argmax(np.diff(bounds)))
    # The temperature terms follow the thermal state when the model has one.
    state = None if model.state_tau is None else data.state(r, model.state_tau)
    x = batch_features(model.effects, run.t, run.temp, t0=data.t0, params=model.params,
                       state=state)
    d = (run.temp if state is None else state)[:, None] - data.t0
    nr, m = data.n_runs, x.shape[1]
    pred = coef[r] + x @ coef[nr:nr + m]
    for j, lab in enumerate(model.axis_labels, nr + m):     # gain, scale: per-axis columns
        on = data.gain_axes if lab == 'gain' else d * data.scale_axes
        pred += coef[j] * run.omega_ref * on
    res = (run.omega - run.omega_ref - pred)[bounds[i]:bounds[i + 1]]
    if res.shape[0] < 16:
        return np.zeros(0), np.zeros(0)
    taus, dev = allan_deviation(res, 1.0 / med)
    return np.asarray(taus), np.sqrt(np.mean(np.asarray(dev) ** 2, axis=1))


def _table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """Return a markdown table (its lines, then an empty one)."""
    return ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)] + [
        '| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows] + ['']


def _par(params: dict, unit: str = '') -> str:
    """Return fitted parameters as ``k = v`` (``-`` when there are none)."""
    return ', '.join(f'{k} = {v:.4g}{unit}' for k, v in params.items()) or '-'


def _plot_maps(maps_rows: Sequence[tuple[str, Sequence[BinMap]]], path: Path) -> None:
    """Plot rows of residual maps (one row per model state) into one PNG."""
    ncol = max(len(m) for _t, m in maps_rows)
    fig = figure(figsize=(4.0 * ncol, 3.0 * len(maps_rows)))
    axes = fig.subplots(len(maps_rows), ncol, squeeze=False)
    for i, (title, maps) in enumerate(maps_rows):
        for ax in axes[i][len(maps):]:
            ax.set_visible(False)
        for j, (ax, m) in enumerate(zip(axes[i], maps)):
            for a in range(3):
                x, y, e = m.centers[:, a], m.mean_dps[:, a], m.se_dps[:, a]
                ok = np.isfinite(x) & np.isfinite(y)
                if not np.any(ok):
                    continue
                ax.errorbar(x[ok], y[ok], yerr=3.0 * e[ok], color=_COLORS[a], marker='.',
                            capsize=2, lw=1, label=AXES[a])
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
    save_png(fig, path)


def _plot_allan(result: DiscoveryResult, path: Path) -> bool:
    """Plot the Allan deviation of the residual before and after each step."""
    s = result.steps
    if s and s[0].adev_tau_s.size:      # every step has its Allan deviation, or none does
        curves = [(', '.join(result.base_effects), s[0].adev_tau_s, s[0].adev_before_dps)] + [
            (f'+ {x.effect}', x.adev_tau_s, x.adev_after_dps) for x in s]
    elif result.adev_tau_s.size:
        curves = [(', '.join(result.final_effects), result.adev_tau_s, result.adev_dps)]
    else:
        return False
    fig = figure(figsize=(6.0, 4.2))
    ax = fig.subplots()
    for label, tau, dev in curves:
        ax.loglog(tau, dev, marker='.', label=label)
    tb = result.settings.get('block_mean_s', result.block_s)
    ax.plot([tb], [result.noise_floor_dps], 'k*', ms=10,
            label=f'noise floor (block means, {tb:.3g} s)')
    ax.set(xlabel='averaging time tau (s)', ylabel='Allan deviation of the residual (deg/s)')
    ax.grid(True, which='both', lw=0.3)
    ax.legend(fontsize=8)
    save_png(fig, path)
    return True


def _thermal_line(thermal: ThermalState) -> str:
    """Return the markdown line of a thermal state: tau, its interval, identifiability."""
    text = thermal.describe()
    line = text[0].upper() + text[1:] + '.'
    if thermal.identifiable is False:
        line += (' The drift is fitted on the lagged state all the same; read tau as '
                 'unknown and excite the lag (steps or ramps with soaks, heating and '
                 'cooling) to pin it.')
    return line


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

    Raises
    ------
    OutputError
        When a file cannot be written (each is written atomically,
        :func:`gyro_tdc.base.atomicio.atomic_write`).

    """
    out = Path(out_dir)
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
        md += _table(('step', 'effect', 'aliases', 'parameters', 'HAC p',
                      'held-out gain (deg/s)^2', 'gap before -> after (deg/s)',
                      'held-out gap before -> after (deg/s)'), [
            (i, f'`{s.effect}`', ', '.join(s.aliases) or '-', _par(s.params),
             f'{s.best.p_value:.2g}', f'{s.best.heldout_gain_dps2:.3g}',
             f'{s.gap_before_dps:.4g} -> {s.gap_after_dps:.4g}',
             f'{s.heldout_gap_before_dps:.4g} -> {s.heldout_gap_after_dps:.4g}')
            for i, s in enumerate(result.steps, 1)])
    for i, s in enumerate(result.steps, 1):
        name = f'step{i}_maps.png'
        _plot_maps([('before', s.maps_before), (f'after + {s.effect}', s.maps_after)], out / name)
        md += [f'## Step {i}: {s.effect}', '', s.description, '']
        if s.thermal is not None:
            md += [_thermal_line(s.thermal), '']
        md += ['Coefficients per axis (deg/s per feature unit; 1/degC for scale): '
               + ', '.join(f'{v:.4g}' for v in np.ravel(s.coef_dps)), '']
        md += _table(('candidate', 'parameters', 'HAC p', 'held-out gain (deg/s)^2',
                      'effect RMS (deg/s)', 'verdict'), [
            (f'`{c.effect}`', _par(c.params), f'{c.p_value:.2g}', f'{c.heldout_gain_dps2:.3g}',
             f'{c.effect_rms_dps:.3g}', 'passes' if c.passed else c.why_not)
            for c in s.candidates])
        md += [f'![residual maps, step {i}]({name})', '']
    md += ['## Final model', '',
           f'Effects: **{", ".join(result.final_effects)}**; gap {result.gap_dps:.4g} deg/s = '
           f'{result.gap_dps / result.noise_floor_dps:.2f} x the noise floor (held-out '
           f'{result.heldout_gap_dps:.4g} deg/s).', '']
    if result.thermal is not None:
        md += [_thermal_line(result.thermal), '']
    if result.params:
        md += ['Fitted time constants: ' + '; '.join(
            f'{e}: {_par(p, " s")}' for e, p in result.params.items()), '']
    if result.candidates:
        md += _table(('remaining candidate', 'HAC p', 'held-out gain (deg/s)^2',
                      'effect RMS (deg/s)', 'why not'), [
            (f'`{c.effect}`', f'{c.p_value:.2g}', f'{c.heldout_gain_dps2:.3g}',
             f'{c.effect_rms_dps:.3g}', c.why_not) for c in result.candidates])
    _plot_maps([('final model', result.maps)], out / 'final_maps.png')
    md += ['![residual maps, final model](final_maps.png)', '']
    if _plot_allan(result, out / 'allan.png'):
        md += ['![Allan deviation of the residual](allan.png)', '']
    if result.unidentifiable:
        md += ['## Not identifiable from this data', ''] + _table(
            ('effect', 'why', 'experiment'),
            [(f'`{u.effect}`', u.reason, u.experiment) for u in result.unidentifiable])
    if result.notes:
        md += ['## Notes', ''] + [f'- {n}' for n in result.notes] + ['']
    return atomic_write(out / 'report.md', '\n'.join(md), what='report')
