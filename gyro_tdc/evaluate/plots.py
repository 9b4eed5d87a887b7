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
Plots of one evaluated bag: three PNGs (matplotlib, Agg canvas, no display needed).

:func:`write_plots` draws the rate error against time and temperature and its Allan
deviation for the raw rate and every model; matplotlib is imported only when a plot is
asked for. See ``doc/internals/evaluate.md``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Sequence

from gyro_tdc.base import AXES, figure, save_png
from gyro_tdc.data import RATE_THRESHOLD_C_PER_MIN, temperature_rate
from gyro_tdc.evaluate.score import BagEval
from gyro_tdc.signal import block_length, block_mean
import numpy as np
from numpy.typing import NDArray

__all__ = ['model_description', 'write_plots']


# Plot styles: raw in grey, each model its own colour, line style and marker, so traces that
# lie on top of each other stay visible; fonts 9 pt and up.
_RAW_STYLE = {'color': '0.45', 'linestyle': '-', 'linewidth': 1.0}
_MODEL_STYLES = [('tab:blue', '-', 'o'), ('tab:orange', '--', 's'), ('tab:green', '-.', '^'),
                 ('tab:red', ':', 'D'), ('tab:purple', (0, (6, 2, 1, 2)), 'v'),
                 ('tab:brown', (0, (3, 1, 1, 1, 1, 1)), 'P'), ('tab:pink', '--', 'X'),
                 ('tab:olive', '-.', '*'), ('tab:cyan', ':', 'h')]
_FONTS = {'font.size': 10, 'axes.titlesize': 10, 'axes.labelsize': 10, 'legend.fontsize': 9,
          'xtick.labelsize': 9, 'ytick.labelsize': 9, 'figure.titlesize': 12}
_MARKERS_PER_CURVE = 12
_ZOOM_BS_FACTOR = 10.0
_ZOOM_POINTS = 150


def _style(i: int, n_points: int, n_models: int) -> dict:
    """Return the matplotlib style of model ``i``: markers staggered between models."""
    color, ls, marker = _MODEL_STYLES[i % len(_MODEL_STYLES)]
    step = max(n_points // _MARKERS_PER_CURVE, 1)
    return {'color': color, 'linestyle': ls, 'linewidth': 1.3, 'marker': marker,
            'markersize': 5, 'markevery': (i * step // max(n_models, 1), step)}


def model_description(name: str, model: Any) -> str:
    """
    Return the legend text of a model (a ``CompensationModel``): its file (or ``px4``), what it is.

    E.g. ``modified.yaml: poly f(dT, dT2)``, ``auto.yaml: rbf f(dT, dT2, lag 176 s)`` (the
    thermal state's total tau) or ``px4: cubic in T fitted on --train``.
    """
    if name == 'px4':
        return 'px4: cubic in T fitted on --train'
    th = getattr(model, 'thermal', None)
    tau_s = None if th is None or th.kind == 'none' else float(th.tau_total_s)
    shown = [f'lag {tau_s:.3g} s' if f == 'lag' and tau_s is not None else f
             for f in model.features if f != 'bias']          # bias is in every model
    return f'{Path(name).name}: {model.kind} f({", ".join(shown) or "bias"})'


def _zoom_limits(curves: Sequence[NDArray[np.float64]]) -> tuple[float, float] | None:
    """Return y-limits holding 99 % of the points of ``curves`` (None when there are none)."""
    values = np.concatenate([c[np.isfinite(c)] for c in curves]) if curves else np.zeros(0)
    if values.size == 0:
        return None
    lo, hi = np.percentile(values, [0.5, 99.5])
    pad = 0.15 * max(hi - lo, 1e-9)
    return float(lo - pad), float(hi + pad)


def write_plots(b: BagEval, directory: str | os.PathLike, *, points: int = 3000,
                descriptions: Sequence[str] | None = None, options: str = '',
                reanchor_s: float = 0.0) -> list:
    """
    Write three PNGs of one bag into ``directory`` (Agg canvas, no display needed).

    ``<label>_timeseries.png`` (rate error against time, raw and models, then zoomed, then
    the temperature; re-anchoring window and out-of-range stretches shaded),
    ``<label>_residual_vs_temperature.png`` (coloured by heating, cooling, steady) and
    ``<label>_allan.png``. Every model keeps one colour, line style and marker in all
    three. ``points``: block means per curve; ``descriptions``: legend text per model
    (:func:`model_description`); ``options``: what was applied, for the titles;
    ``reanchor_s``: the window to shade (0: none). A bag scored on its still stretches only
    shows those, as the titles say. Returns the paths written.
    """
    import matplotlib

    if (run := b.run) is None:
        raise ValueError('Expected `b.run` to hold the data; it was released.')
    if descriptions is None:
        descriptions = [f'{m.model} ({", ".join(m.features) or "bias"})' for m in b.models]
    if len(descriptions) != len(b.models):
        raise ValueError(f'Expected {len(b.models)} `descriptions` (one per model), got '
                         f'{len(descriptions)}.')
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    block = block_length(len(run), points)

    def _bmean(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return block_mean(a, block, partial=False)   # a trailing partial block is dropped

    th, temp = (_bmean(run.t) - run.t[0]) / 3600.0, _bmean(run.temp)
    raw_err = _bmean(np.degrees(run.omega - run.omega_ref))
    model_err = [_bmean(np.degrees(m.omega - run.omega_ref)) for m in b.models]
    legends = [f'raw ({b.raw.label})' if b.raw.label != 'raw' else 'raw, uncompensated'] + [
        str(d) for d in descriptions]
    styles = [_RAW_STYLE] + [_style(i, len(th), len(b.models)) for i in range(len(b.models))]
    models_text = ', '.join(Path(str(m.model)).name for m in b.models) or 'none'
    head = (f'{b.bag}: models {models_text}' + (f'; {options}' if options else '')
            + ('' if b.still is None else
               f"; scored the still stretches only, {b.samples} of {b.still['total_samples']} "
               'samples'))
    with matplotlib.rc_context(_FONTS):
        return [_plot_timeseries(b, out, th, temp, raw_err, model_err, legends, styles, head,
                                 block, reanchor_s),
                _plot_residual_vs_temperature(b, out, run, temp, raw_err, model_err, legends,
                                              head, _bmean),
                _plot_allan(b, out, legends, styles, head)]


def _flag_spans(ax: Any, th: NDArray[np.float64], temp: NDArray[np.float64], b: BagEval,
                legends: Sequence[str], labelled: bool, reanchor_s: float) -> None:
    """Shade the re-anchoring window and the time outside each model's trained range."""
    if reanchor_s > 0:
        ax.axvspan(0.0, reanchor_s / 3600.0, color='gold', alpha=0.35, lw=0,
                   label=f're-anchoring window (first {reanchor_s:g} s)' if labelled else None)
    for i, m in enumerate(b.models):
        if m.outside_fraction <= 0:
            continue
        lo, hi = m.temp_range_c
        outside = (temp < lo) | (temp > hi)
        ax.fill_between(th, 0, 1, where=outside, transform=ax.get_xaxis_transform(),
                        color=_MODEL_STYLES[i % len(_MODEL_STYLES)][0], alpha=0.12, lw=0,
                        label=(f'outside the trained range of {legends[i + 1].split(":")[0]} '
                               f'({b.out_of_range})') if labelled else None)


def _plot_timeseries(b, out, th, temp, raw_err, model_err, legends, styles, head, block,
                     reanchor_s) -> Path:
    """Write ``<label>_timeseries.png``: full scale, zoomed models, temperature."""
    fig = figure(figsize=(15, 11.5))
    grid = fig.add_gridspec(4, 2, height_ratios=[1, 1, 1, 0.8])
    first = fig.add_subplot(grid[0, 0])
    left = [first] + [fig.add_subplot(grid[k, 0], sharex=first) for k in (1, 2)]
    right = [fig.add_subplot(grid[k, 1], sharex=first) for k in range(3)]
    bottom = fig.add_subplot(grid[3, :], sharex=first)
    # The zoom averages further (about _ZOOM_POINTS means per curve), so the drift a model
    # leaves shows above the white noise and models that nearly agree can be told apart.
    coarse = max(len(th) // _ZOOM_POINTS, 1)
    zth = block_mean(th, coarse, partial=False)
    zerr = [block_mean(e, coarse, partial=False) for e in model_err]
    zstyles = [_style(i, len(zth), len(model_err)) for i in range(len(model_err))]
    zoom_s = 3600.0 * (th[1] - th[0]) * coarse if len(th) > 1 else 0.0
    for k, a in enumerate(AXES):
        left[k].plot(th, raw_err[:, k], label=legends[0], **styles[0])
        for i, e in enumerate(model_err):
            left[k].plot(th, e[:, k], label=legends[i + 1], **styles[i + 1])
            right[k].plot(zth, zerr[i][:, k], label=legends[i + 1], **zstyles[i])
        left[k].set_ylabel(f'{a}: rate error (deg/s)')
        # Zoom on the models within ZOOM_BS_FACTOR of the best BS on this axis; a model far
        # worse runs off this scale (it is on the full-scale panel).
        best = min((float(m.bs[k]) for m in b.models), default=math.nan)
        limits = _zoom_limits([e[:, k] for m, e in zip(b.models, zerr) if math.isfinite(best)
                               and float(m.bs[k]) <= _ZOOM_BS_FACTOR * best])
        if limits is not None:
            right[k].set_ylim(*limits)
        right[k].axhline(0.0, color='0.3', lw=0.8)
        for ax in (left[k], right[k]):
            ax.grid(True, alpha=0.3)
            _flag_spans(ax, th, temp, b, legends, labelled=(ax is left[0]), reanchor_s=reanchor_s)
    left[0].set_title('raw and compensated, full scale')
    right[0].set_title(f'zoom: compensated only, {zoom_s:.3g} s means, scaled to the models '
                       f'within {_ZOOM_BS_FACTOR:g}x of the best BS')
    left[0].legend(loc='best', framealpha=0.85)
    bottom.plot(th, temp, color='black', lw=1.2)
    bottom.set(ylabel='temperature (degC)', xlabel='time since the start of the bag (h)'
               if b.still is None else 'time since the first still sample scored (h)')
    bottom.grid(True, alpha=0.3)
    fig.suptitle(f'Rate error vs time (left: {block}-sample means)\n{head}')
    return save_png(fig, out / f'{b.label}_timeseries.png')


def _plot_residual_vs_temperature(b, out, run, temp, raw_err, model_err, legends, head,
                                  bmean) -> Path:
    """Write ``<label>_residual_vs_temperature.png``: one row per series, heating/cooling."""
    rate = bmean(temperature_rate(run.t, run.temp))
    x = RATE_THRESHOLD_C_PER_MIN
    groups = [(f'heating (> +{x:g} degC/min)', rate > x, 'tab:red'),
              (f'cooling (< -{x:g} degC/min)', rate < -x, 'tab:blue'),
              ('steady', np.abs(rate) <= x, 'tab:gray')]
    series = [raw_err] + list(model_err)
    fig = figure(figsize=(14, 2.9 * len(series) + 1.0))
    axs = np.atleast_2d(fig.subplots(len(series), 3, squeeze=False))
    for r, e in enumerate(series):
        for k, a in enumerate(AXES):
            ax = axs[r, k]
            for name, sel, color in groups:
                if np.any(sel):
                    ax.scatter(temp[sel], e[sel, k], s=4, color=color, label=name)
            ax.set(title=f'{legends[r]} - {a}', ylabel='rate error (deg/s)' if k == 0 else '',
                   xlabel='temperature (degC)' if r == len(series) - 1 else '')
            ax.grid(True, alpha=0.3)
    axs[0, 0].legend(loc='best', markerscale=3)
    fig.suptitle(f'Rate error vs temperature, by heating and cooling\n{head}')
    return save_png(fig, out / f'{b.label}_residual_vs_temperature.png')


def _plot_allan(b, out, legends, styles, head) -> Path:
    """Write ``<label>_allan.png``: Allan deviation per axis, raw and every model."""
    fig = figure(figsize=(15, 5.2))
    axs = fig.subplots(1, 3, sharey=True)
    for k, a in enumerate(AXES):
        for i, m in enumerate([b.raw] + list(b.models)):
            if len(m.adev_tau_s):
                axs[k].loglog(m.adev_tau_s, m.adev_dps[:, k], label=legends[i],
                              **{**styles[i], 'markevery': None if i == 0 else (i % 3, 3)})
        axs[k].set(title=f'{a} axis', xlabel='averaging time tau (s)')
        axs[k].grid(True, which='both', alpha=0.3)
    axs[0].set_ylabel('Allan deviation of the rate error (deg/s)')
    if any(len(m.adev_tau_s) for m in [b.raw] + list(b.models)):
        axs[0].legend(loc='best')
    else:                   # still stretches (gaps break the series) or under 4 samples
        axs[1].text(0.5, 0.5, 'no Allan deviation: ' + ('still stretches' if b.still else
                                                        'fewer than 4 samples'),
                    ha='center', transform=axs[1].transAxes)
    fig.suptitle(f'Allan deviation\n{head}')
    return save_png(fig, out / f'{b.label}_allan.png')
