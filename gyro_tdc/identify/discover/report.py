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

"""The discovery report: ``report.md`` with PNG residual maps and the Allan deviation plot."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from gyro_tdc.base import atomic_write
from gyro_tdc.identify.discover.results import BinMap, DiscoveryResult
from gyro_tdc.model import ThermalState
import numpy as np

__all__ = ['write_report']


_AXES = ('x', 'y', 'z')
_COLORS = ('tab:blue', 'tab:orange', 'tab:green')


def _save(fig: Any, path: Path) -> None:
    """Write a matplotlib figure as a PNG, atomically."""
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=90, format='png'), binary=True,
                 what='plot')


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
    _save(fig, path)


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
    _save(fig, path)
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
        md += [f'## Step {i}: {s.effect}', '', s.description, '']
        if s.thermal is not None:
            md += [_thermal_line(s.thermal), '']
        md += ['Coefficients per axis (deg/s per feature unit; 1/degC for scale): '
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
    if result.thermal is not None:
        md += [_thermal_line(result.thermal), '']
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
    atomic_write(path, '\n'.join(md), what='report')
    return path
