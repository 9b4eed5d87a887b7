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
The training report: the model, its training figures, sessions and data coverage.

Formats only, for ``gyro-tdc train`` and the demo (see ``doc/internals/evaluate.md``).
"""

from __future__ import annotations

import math
from typing import Sequence

from gyro_tdc.data import Coverage
from gyro_tdc.evaluate.report import AXES
from gyro_tdc.identify import reanchor_lines, session_check_lines, TrainResult
from gyro_tdc.model import (MAX_EXTRAPOLATION_C, OPERATING_RANGE_C, range_shortfall,
                            static_slope)
import numpy as np

__all__ = ['format_coverage', 'format_sessions', 'format_training',
           'is_coverage_line', 'REANCHOR_SPREAD_DPS']


# --------------------------------------------------------------------------------------------
# Coverage of training data
# --------------------------------------------------------------------------------------------

def _bin_name(c: Coverage, i: int) -> str:
    """Return ``[a, b) degC`` for bin ``i``."""
    return f'[{c.edges[i]:g}, {c.edges[i + 1]:g}) degC'


def format_coverage(c: Coverage) -> tuple[str, list]:
    """
    Return the coverage summary (three lines) and the warning lines (no ``warning:`` prefix).

    Parameters
    ----------
    c : Coverage
        Coverage of the training data.

    Returns
    -------
    table : str
        The range covered; the bins in one line (how many, their minutes: least, median,
        most, and how many are thin, i.e. under a quarter of the median minutes per degC);
        minutes heating, cooling and steady.
    warnings : list of str
        The thin bins by name; no heating or no cooling data.

    """
    lo, hi = c.temp_range_c
    lines = [f'temperature range covered: {lo:.2f} .. {hi:.2f} degC (span {hi - lo:.2f} degC)']
    minutes = np.asarray(c.minutes, dtype=np.float64)
    if minutes.size:
        least, most = int(np.argmin(minutes)), int(np.argmax(minutes))
        thin = (f'{len(c.sparse)} thin (named in the warning below)' if c.sparse else 'none thin')
        lines.append(f'coverage per {c.bin_c:g} degC bin: {minutes.size} bins '
                     f'{c.edges[0]:g} .. {c.edges[-1]:g} degC; minutes per bin '
                     f'{minutes[least]:.1f} ({_bin_name(c, least)}) .. {minutes[most]:.1f} '
                     f'({_bin_name(c, most)}), median {float(np.median(minutes)):.1f}; '
                     f'{thin}')
    x = c.threshold_c_per_min
    lines.append(f'heating (dT/dt > +{x:g} degC/min): {c.heating_min:.1f} min; cooling '
                 f'(< -{x:g}): {c.cooling_min:.1f} min; steady: {c.steady_min:.1f} min')
    warns = []
    if c.sparse:
        names = ', '.join(_bin_name(c, i) for i in c.sparse)
        warns.append(f'little data in temperature bin(s) {names} (under a quarter of the '
                     'median minutes per degC): the model is poorly constrained there')
    total = c.heating_min + c.cooling_min
    if total > 0 and min(c.heating_min, c.cooling_min) == 0:
        missing = 'cooling' if c.cooling_min == 0 else 'heating'
        warns.append(f'no {missing} data: heating/cooling hysteresis and thermal lag cannot '
                     f'be told apart from static drift; record a {missing} leg too')
    return '\n'.join(lines), warns


def is_coverage_line(line: str) -> bool:
    """
    Return True for a line of :func:`format_coverage` (its table or warnings, prefixed or not).

    Lets a caller that trains several models on the same bags show the coverage once.
    """
    text = line.removeprefix('warning: ')
    return text.startswith(('temperature range covered:', 'coverage per ', 'heating (dT/dt',
                            'little data in temperature bin', 'no heating data:',
                            'no cooling data:', 'the training data cover '))


# --------------------------------------------------------------------------------------------
# Training report
# --------------------------------------------------------------------------------------------

def _row3(label: str, values: Sequence[float]) -> str:
    """Format one table row of three per-axis numbers."""
    return f'  {label:<13}' + ''.join(f'{v:>12.4g}' for v in values)


#: Turn-on offsets differing by more than this between sessions (deg/s, any axis) make
#: ``train`` say to re-anchor on the vehicle.
REANCHOR_SPREAD_DPS = 0.01


def format_sessions(result: TrainResult) -> list[str]:
    """
    Return the sessions of a training run and their turn-on offsets, one line each.

    Parameters
    ----------
    result : TrainResult
        What training produced (``sessions``, and the offsets in
        ``model.metrics['sessions']`` when there are several).

    Returns
    -------
    list of str
        How the bags were cut, then each session's offset from the model's (their mean,
        deg/s), the spread and, above :data:`REANCHOR_SPREAD_DPS` on an axis, the line that
        says to re-anchor on the vehicle, then how large a start-up shift the node takes
        per axis (:func:`~gyro_tdc.identify.power_cycles.reanchor_lines`); empty without
        sessions.

    """
    split = getattr(result, 'sessions', None)
    if split is None:
        return []
    out = list(split.lines())
    info = result.model.metrics.get('sessions')
    anchors = reanchor_lines(result.model.metrics.get('reanchor'))
    if not info:
        return out + anchors
    out.append("turn-on offset of each session against the model's (their mean), deg/s:")
    width = max(len(n) for n in info['names'])
    for name, off, n in zip(info['names'], info['offset_dps'], info['samples']):
        out.append(f'  {name:<{width}}  ' + '  '.join(f'{v:+10.5f}' for v in off)
                   + f'   ({n} samples)')
    spread = info['spread_dps']
    out.append(f'  {"spread":<{width}}  ' + '  '.join(f'{v:10.5f}' for v in spread)
               + '   (largest minus smallest)')
    if max(spread) > REANCHOR_SPREAD_DPS:
        out.append(f'the turn-on offset changes by up to {max(spread):.3g} deg/s from one '
                   'power cycle to the next: a model fixes the thermal curve, not the offset '
                   'of a new power cycle; re-anchor on the vehicle (compensator_node '
                   'reanchor_on_start, on by default) and score with evaluate --reanchor auto')
    return out + session_check_lines(info.get('heldout')) + anchors


def format_training(result: TrainResult) -> tuple[str, list]:
    """
    Return the training report and its warnings.

    Parameters
    ----------
    result : TrainResult
        What :func:`gyro_tdc.identify.train.train` returned.

    Returns
    -------
    text : str
        Model summary, the constant gyro axes (one line, when there are any: not fitted,
        passed through unchanged, their compensated figures the raw ones), training BS raw
        and compensated per axis, coverage.
    warnings : list of str
        Coverage warnings, and that the thermal state's tau is not identifiable when so.

    """
    m = result.model
    met = m.metrics
    feats = ', '.join(m.inputs) or 'bias only'
    th = m.thermal
    lagged = th is not None and th.kind != 'none'
    params = '; '.join(f'{eid}.{k} = {v:.4g}' for eid, p in sorted(m.effect_params.items())
                       for k, v in p.items() if not (lagged and eid == 'lag'))
    if lagged:    # the state's tau with its interval, or that the data cannot pin it
        ivs = th.tau_interval_s
        if th.identifiable is False:
            lo, hi = min(p[0] for p in ivs), max(p[1] for p in ivs)
            tau = f'lag.tau_s not identifiable (profile flat over {lo:.4g}..{hi:.4g} s)'
        else:
            tau = f'lag.tau_s = {th.tau_total_s:.4g}' + (
                '' if ivs is None or len(ivs) != 1 else
                f' (95 % interval {ivs[0][0]:.4g}..{ivs[0][1]:.4g})')
        params = '; '.join(v for v in (params, tau) if v)
    head = (f'model: {m.kind} f({feats}), '
            + (f'{m.n_centers} centres, ' if m.kind == 'rbf' else '')
            + f'T0 = {m.t0_c:.3f} degC' + (f', {params}' if params else ''))
    lo, hi = m.temp_range_c
    of = 'the model temperature, the thermal state' if lagged else 'the model temperature'
    lines = [head, f'TRAINED RANGE {lo:.2f} .. {hi:.2f} degC ({of}); beyond it the compensator '
                   'continues the correction along its tangent (out_of_range: linear) for up '
                   f'to {MAX_EXTRAPOLATION_C:g} degC, then holds it',
             f'training data: {len(result.bags)} bag(s), {result.samples} samples']
    constant = result.constant_line()
    if constant:                # one line: the axes not fitted, passed through unchanged
        lines.append(constant)
    lines += ['training bias stability BS, (deg/s)^2:',
              f'  {"":<13}' + ''.join(f'{a:>12}' for a in AXES),
              _row3('raw', met.get('raw_bs_dps2', [math.nan] * 3)),
              _row3('compensated', met.get('train_bs_dps2', [math.nan] * 3)),
              _row3('RMS (deg/s)', met.get('train_rms_dps', [math.nan] * 3))]
    if np.any(m.scale != 0):
        lines.append(_row3('scale (1/C)', m.scale))
    lines.append(_row3('drift/degC', np.degrees(static_slope(m)))
                 + '   (deg/s per degC: static drift, mean slope over the range)')
    table, warns = format_coverage(result.coverage)
    lines.append(table)
    short = range_shortfall((lo, hi))
    if short:
        a, b = OPERATING_RANGE_C
        warns = list(warns) + [
            f'the training data cover {lo:.1f} .. {hi:.1f} degC, less than a typical operating '
            f'range of {a:g} .. {b:g} degC ({short} missing): there the model is not '
            'calibrated; the compensator extrapolates along the tangent at the range end '
            f'(out_of_range: linear, up to {MAX_EXTRAPOLATION_C:g} degC, then held; clamp '
            'or extrapolate are the alternatives, see doc/real_data.md); record the missing '
            'temperatures to calibrate them']
    if lagged and th.identifiable is False:
        warns = list(warns) + [
            th.describe().split('; ', 1)[-1] + ': soaks after heating and cooling steps '
            '(the die catching up) pin it']
    return '\n'.join(lines), warns
