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
Formatting of training and evaluation results: text tables, JSON, CSV export and plots.

Formats only; the numbers come from the evaluation core (:mod:`gyro_tdc.evaluation`: a
held-out bag is a :class:`~gyro_tdc.evaluation.BagEval` holding one
:class:`~gyro_tdc.evaluation.ModelEval` per model) and from :mod:`gyro_tdc.coverage`. The
functions here turn them into

* text: a summary table (BS in (deg/s)^2 and RMS in deg/s per axis), the paper's tables 3-7
  (``BS1 BS2 BS3 P1 P2 P3`` with P1 = BS2/BS1, P2 = BS3/BS1, P3 = BS3/BS2), the Allan
  readouts (angle random walk, bias instability), the means over bags, and the training
  report with the coverage of the training data;
* JSON (:func:`evaluation_json`, the shape documented in docs/json.md, nothing more);
* one CSV per bag (:func:`write_csv`) and three PNGs per bag (:func:`write_plots`, matplotlib
  with the Agg canvas, imported only when plots are asked for).

Every file is written atomically (:func:`gyro_tdc.atomicio.atomic_write`).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, IO, Sequence

from gyro_tdc.atomicio import atomic_write
from gyro_tdc.blocks import block_length, block_mean
from gyro_tdc.coverage import Coverage, RATE_THRESHOLD_C_PER_MIN, temperature_rate
from gyro_tdc.evaluation import BagEval, mean_scores
from gyro_tdc.out_of_range import DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C
from gyro_tdc.out_of_range import OPERATING_RANGE_C, range_shortfall
from gyro_tdc.training import TrainResult
import numpy as np
from numpy.typing import NDArray

__all__ = [
    'AXES', 'csv_columns', 'drift_slope', 'evaluation_json', 'format_allan', 'format_bag',
    'format_coverage', 'format_means', 'format_paper_table', 'format_summary', 'format_training',
    'is_coverage_line', 'model_description', 'write_csv', 'write_json', 'write_plots',
]

AXES = ('x', 'y', 'z')
_DEG = 180.0 / math.pi


# --------------------------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------------------------

def _finite(v: float) -> float | None:
    """Return ``v`` as a float, or None when it is NaN or infinite (JSON has neither)."""
    v = float(v)
    return v if math.isfinite(v) else None


def _vec(a: NDArray[np.float64]) -> list:
    """Return a (3,) array as a list of JSON-safe floats."""
    return [_finite(v) for v in np.asarray(a, dtype=np.float64).ravel()]


def _vec_or_null(a: NDArray[np.float64] | None) -> list | None:
    """Return :func:`_vec` of ``a``, or None when there is none (not applicable)."""
    return None if a is None else _vec(a)


def evaluation_json(bags: Sequence[BagEval]) -> dict:
    """
    Return the evaluation in the documented JSON shape (docs/json.md), nothing more.

    Parameters
    ----------
    bags : sequence of BagEval
        Evaluated bags.

    Returns
    -------
    dict
        ``{"bags": [{"bag", "samples", "temperature_c", "raw": {"bs", "rms_dps"},
        "models": [{"model", "features", "bs", "rms_dps", "p_vs_raw",
        "adev": {"tau_s", "dps"}, "reanchor"?}]}], "out_of_range"}``; BS in (deg/s)^2, RMS
        and ADEV in deg/s, non-finite values as null; ``out_of_range`` the policy beyond the
        trained range, ``reanchor`` (``--reanchor auto`` only) ``{samples, duration_s,
        shift_dps, se_dps, tolerance_dps, reason}``; ``accel_bs`` beside ``bs`` in ``raw``
        and each model: the accelerometer BS in (m/s^2)^2, null when not applicable.

    """
    doc = {'bags': [{
        'bag': b.bag,
        'samples': int(b.samples),
        'temperature_c': [_finite(b.temperature_c[0]), _finite(b.temperature_c[1])],
        'raw': {'bs': _vec(b.raw.bs), 'accel_bs': _vec_or_null(b.raw.accel_bs),
                'rms_dps': _vec(b.raw.rms_dps)},
        'models': [{
            'model': m.model,
            'features': list(m.features),
            'bs': _vec(m.bs),
            'accel_bs': _vec_or_null(m.accel_bs),
            'rms_dps': _vec(m.rms_dps),
            'p_vs_raw': _vec(m.p_vs_raw),
            'adev': {'tau_s': _vec(m.adev_tau_s),
                     'dps': [_vec(row) for row in np.asarray(m.adev_dps)]},
            **({} if m.reanchor is None else {'reanchor': m.reanchor}),
        } for m in b.models],
    } for b in bags]}
    doc['out_of_range'] = bags[0].out_of_range if bags else DEFAULT_OUT_OF_RANGE
    return doc


def write_json(bags: Sequence[BagEval], path: str | os.PathLike) -> Path:
    """Write :func:`evaluation_json` to ``path`` atomically (parents created); return it."""
    return atomic_write(path, json.dumps(evaluation_json(bags), indent=1, allow_nan=False)
                        + '\n', what='JSON file')


# --------------------------------------------------------------------------------------------
# Text tables
# --------------------------------------------------------------------------------------------

def _g(v: float, width: int = 11) -> str:
    """Format one number for a table column."""
    if not math.isfinite(v):
        return f'{"-":>{width}}'
    return f'{v:>{width}.4g}'


# BagEval.reference (where the reference rate came from) in words.
_REFERENCE = {'topic': 'reference rate from the reference topic',
              'constant': 'constant reference rate (--reference)',
              'zero': 'reference rate zero (no reference topic)'}


def format_summary(b: BagEval) -> str:
    """
    Return the per-bag summary: BS, RMS and BS/BS1 per axis for raw data and every model.

    Parameters
    ----------
    b : BagEval
        One evaluated bag.

    Returns
    -------
    str
        Multi-line table (no trailing newline).

    """
    lo, hi = b.temperature_c
    reference = _REFERENCE.get(b.reference, f'reference {b.reference}')
    lines = [f'bag {b.bag}: {b.samples} samples over {b.duration_s / 3600.0:.2f} h, '
             f'temperature {lo:.2f} .. {hi:.2f} degC, {reference}']
    w = max([len(m.label) for m in b.models] + [12])
    head = (f'  {"":<{w}} ' + ''.join(f'{"BS " + a:>11}' for a in AXES) + '  '
            + ''.join(f'{"RMS " + a:>11}' for a in AXES) + '  '
            + ''.join(f'{"BS/BS1 " + a:>11}' for a in AXES))
    lines += ['  BS in (deg/s)^2 (paper eq. 30), RMS in deg/s, BS/BS1 against the raw data',
              head]
    for m in [b.raw] + list(b.models):
        lines.append(f'  {m.label:<{w}} ' + ''.join(_g(v) for v in m.bs) + '  '
                     + ''.join(_g(v) for v in m.rms_dps) + '  '
                     + ''.join(_g(v) for v in m.p_vs_raw))
    note = _outside_note(b)
    if note:
        lines.append(note)
    lines += _accel_rows(b, w)
    return '\n'.join(lines)


def _accel_rows(b: BagEval, w: int) -> list:
    """Return the accelerometer rows of a bag's summary (none when not applicable)."""
    if b.raw.accel_bs is None:
        return []
    lines = ['  accelerometer (still run): BS = variance around the run mean in (m/s^2)^2, '
             'BS/BS1 against the raw data; - : no accelerometer part',
             f'  {"":<{w}} ' + ''.join(f'{"aBS " + a:>11}' for a in AXES) + '  '
             + ''.join(f'{"aBS/BS1 " + a:>11}' for a in AXES)]
    for m in [b.raw] + list(b.models):
        bs = np.full(3, math.nan) if m.accel_bs is None else np.asarray(m.accel_bs)
        lines.append(f'  {m.label:<{w}} ' + ''.join(_g(v) for v in bs) + '  '
                     + ''.join(_g(v) for v in bs / b.raw.accel_bs))
    return lines


def _outside_note(b: BagEval) -> str:
    """Return one note for every model the bag leaves the trained range of ('' if none)."""
    groups: dict = {}       # (fraction text, range) -> labels, in model order
    for m in b.models:
        if m.outside_fraction > 0:
            key = (f'{100.0 * m.outside_fraction:.3g} %',
                   f'[{m.temp_range_c[0]:.2f}, {m.temp_range_c[1]:.2f}] degC')
            groups.setdefault(key, []).append(m.label)
    parts = [f'{pct} of the samples lie outside the trained range of {", ".join(labels)} '
             f'{span}' if i == 0 else f'{pct} outside that of {", ".join(labels)} {span}'
             for i, ((pct, span), labels) in enumerate(groups.items())]
    how = {'clamp': 'evaluated clamped at the range ends',
           'extrapolate': 'the models evaluated there (extrapolated, not clamped)',
           'linear': 'the correction continued along its tangent at the range end, held '
                     f'beyond {MAX_EXTRAPOLATION_C:g} degC (out-of-range policy linear, not '
                     'clamped)'}
    return (f'  note: {"; ".join(parts)}: {how.get(b.out_of_range, b.out_of_range)}'
            if parts else '')


def format_paper_table(b: BagEval, conventional: int, modified: int) -> str:
    """
    Return the paper's table 3-7 layout for one bag: BS1 BS2 BS3 P1 P2 P3 per axis.

    Parameters
    ----------
    b : BagEval
        One evaluated bag.
    conventional, modified : int
        Indices into ``b.models`` of the conventional (BS2) and modified (BS3) models.

    Returns
    -------
    str
        Multi-line table; P1 = BS2/BS1, P2 = BS3/BS1, P3 = P2/P1 = BS3/BS2 (in %).

    """
    from gyro_tdc.metrics import p_ratios
    conv, modi = b.models[conventional], b.models[modified]
    p = p_ratios(b.raw.bs, conv.bs, modi.bs)
    lines = [f'  paper table (eq. 31-32), {b.label}: BS1 raw, BS2 {conv.label} '
             f'(conventional), BS3 {modi.label} (modified); BS in (deg/s)^2',
             f'  {"":<7}' + ''.join(f'{h:>11}' for h in ('BS1', 'BS2', 'BS3', 'P1', 'P2'))
             + f'{"P3":>10}']
    for i, a in enumerate(AXES):
        p3 = p['P3'][i]
        p3s = f'{100.0 * p3:>9.2f}%' if math.isfinite(p3) else f'{"-":>10}'
        lines.append(f'  {a + "-axis":<7}' + _g(b.raw.bs[i]) + _g(conv.bs[i]) + _g(modi.bs[i])
                     + _g(p['P1'][i]) + _g(p['P2'][i]) + p3s)
    return '\n'.join(lines)


def format_allan(b: BagEval) -> str:
    """Return the Allan readouts (ARW, deg/sqrt(h); bias instability, deg/h) per axis."""
    w = max([len(m.label) for m in b.models] + [12])
    lines = ['  Allan deviation: angle random walk ARW in deg/sqrt(h), bias instability BI '
             'in deg/h',
             f'  {"":<{w}} ' + ''.join(f'{"ARW " + a:>11}' for a in AXES)
             + '  ' + ''.join(f'{"BI " + a:>11}' for a in AXES)]
    for m in [b.raw] + list(b.models):
        lines.append(f'  {m.label:<{w}} ' + ''.join(_g(v) for v in m.arw_deg_sqrt_h) + '  '
                     + ''.join(_g(v) for v in m.bias_instability_deg_h))
    return '\n'.join(lines)


def format_bag(b: BagEval, baseline: int | None = None) -> str:
    """
    Return every table of one bag: summary, paper tables against ``baseline``, Allan readouts.

    Parameters
    ----------
    b : BagEval
        One evaluated bag.
    baseline : int, optional
        Index into ``b.models`` of the conventional model; one paper table (tables 3-7) is
        added per other model. None: no paper table.

    Returns
    -------
    str
        Multi-line text (no trailing newline).

    """
    parts = [format_summary(b)]
    if baseline is not None:
        parts += [format_paper_table(b, baseline, i) for i in range(len(b.models))
                  if i != baseline]
    parts.append(format_allan(b))
    return '\n'.join(parts)


def format_means(results: Sequence[BagEval]) -> str:
    """
    Return the mean BS and BS/BS1 per model and axis over several bags.

    Parameters
    ----------
    results : sequence of BagEval
        Evaluated bags (the same models in each).

    Returns
    -------
    str
        Multi-line table (no trailing newline); see :func:`gyro_tdc.evaluation.mean_scores`.

    """
    rows = mean_scores(results)
    w = max([len(label) for label, _, _ in rows[1:]] + [12])
    lines = [f'mean over {len(results)} bags: BS in (deg/s)^2 and BS/BS1',
             f'  {"":<{w}} ' + ''.join(f'{"BS " + a:>11}' for a in AXES) + '  '
             + ''.join(f'{"BS/BS1 " + a:>11}' for a in AXES)]
    for label, bs, p in rows:
        lines.append(f'  {label:<{w}} ' + ''.join(_g(v) for v in bs) + '  '
                     + ''.join(_g(v) for v in p))
    return '\n'.join(lines)


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
        thin = (f'{len(c.sparse)} thin (named in the warning below)' if c.sparse
                else 'none thin')
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
    Return True for a line of :func:`format_coverage` (its table or its warnings).

    Lets a caller that trains several models on the same bags show the coverage once.

    Parameters
    ----------
    line : str
        One printed line (with or without the ``warning:`` prefix).

    Returns
    -------
    bool
        Whether the line belongs to the coverage report.

    """
    text = line.removeprefix('warning: ')
    return text.startswith(('temperature range covered:', 'coverage per ', 'heating (dT/dt',
                            'little data in temperature bin', 'no heating data:',
                            'no cooling data:', 'the training data cover '))


# --------------------------------------------------------------------------------------------
# Training report
# --------------------------------------------------------------------------------------------

def drift_slope(model: Any) -> NDArray[np.float64]:
    """
    Return the mean slope of a model's static drift over its trained range, per axis.

    The static drift is the drift at thermal equilibrium (each temperature held until lag,
    dT/dt and warm-up terms have settled); the slope is its change from the cold end of
    ``temp_range_c`` to the warm end, divided by the span. For the conventional model f(dT)
    it is the fitted zero-rate level change per degC (eq. 18, alpha).

    Parameters
    ----------
    model : CompensationModel
        A fitted model.

    Returns
    -------
    NDArray[np.float64], shape (3,), deg/s per degC
        The slope on x, y and z; NaN when the range has no span.

    """
    from gyro_tdc.model import drift

    lo, hi = (float(v) for v in model.temp_range_c)
    if not hi > lo:
        return np.full(3, math.nan)
    temp = np.array([lo, lo, hi])            # a settling sample, then the two ends
    t = np.arange(3, dtype=np.float64) * 1e7    # far apart: every dynamic term has settled
    b = np.degrees(drift(model, t, temp, clamp=True))
    return (b[2] - b[1]) / (hi - lo)


def _row3(label: str, values: Sequence[float]) -> str:
    """Format one table row of three per-axis numbers."""
    return f'  {label:<13}' + ''.join(f'{v:>12.4g}' for v in values)


def format_training(result: TrainResult) -> tuple[str, list]:
    """
    Return the training report and its warnings.

    Parameters
    ----------
    result : TrainResult
        What :func:`gyro_tdc.training.train` returned.

    Returns
    -------
    text : str
        Model summary, training BS raw and compensated per axis, coverage.
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
             f'training data: {len(result.bags)} bag(s), {result.samples} samples',
             'training bias stability BS, (deg/s)^2:',
             f'  {"":<13}' + ''.join(f'{a:>12}' for a in AXES),
             _row3('raw', met.get('raw_bs_dps2', [math.nan] * 3)),
             _row3('compensated', met.get('train_bs_dps2', [math.nan] * 3)),
             _row3('RMS (deg/s)', met.get('train_rms_dps', [math.nan] * 3))]
    if np.any(m.scale != 0):
        lines.append(_row3('scale (1/C)', m.scale))
    lines.append(_row3('drift/degC', drift_slope(m)) + '   (deg/s per degC: static drift, '
                 'mean slope over the range)')
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
            'or extrapolate are the alternatives, see docs/real_data.md); record the missing '
            'temperatures to calibrate them']
    if lagged and th.identifiable is False:
        warns = list(warns) + [
            th.describe().split('; ', 1)[-1] + ': soaks after heating and cooling steps '
            '(the die catching up) pin it']
    return '\n'.join(lines), warns


# --------------------------------------------------------------------------------------------
# CSV export and plots
# --------------------------------------------------------------------------------------------

def csv_columns(b: BagEval) -> list:
    """Return the CSV header of a bag: time, temperature, raw, reference, each model."""
    cols = ['t_s', 'temp_c']
    for who in ['raw', 'ref'] + [m.label for m in b.models]:
        cols += [f'{who}_{a}_rad_s' for a in AXES]
    return cols


def write_csv(b: BagEval, directory: str | os.PathLike, *, chunk: int = 100_000) -> Path:
    """
    Write ``DIR/<bag label>.csv``: every sample with the raw, reference and compensated rates.

    Parameters
    ----------
    b : BagEval
        One evaluated bag, with its arrays (``run`` and each model's ``omega``).
    directory : str or PathLike
        Output directory (created).
    chunk : int
        Rows formatted at once.

    Returns
    -------
    Path
        The CSV written; columns from :func:`csv_columns`, rates in rad/s.

    """
    run = b.run
    if run is None:
        raise ValueError('Expected `b.run` to hold the data; it was released.')
    path = Path(directory) / f'{b.label}.csv'
    cols = csv_columns(b)
    fmt = ['%.6f', '%.6g'] + ['%.9g'] * (len(cols) - 2)

    def rows(fh: IO[str]) -> None:
        fh.write(','.join(cols) + '\n')
        for i in range(0, len(run), chunk):
            sl = slice(i, i + chunk)
            block = np.column_stack([run.t[sl], run.temp[sl], run.omega[sl], run.omega_ref[sl]]
                                    + [m.omega[sl] for m in b.models])
            np.savetxt(fh, block, fmt=fmt, delimiter=',')

    return atomic_write(path, rows, what='CSV file', newline='\n')


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


def model_description(name: str, kind: str, features: Sequence[str], *,
                      tau_s: float | None = None) -> str:
    """
    Return the legend text of a model: its file (or ``px4``) and what it is.

    Parameters
    ----------
    name : str
        The model as given on the command line (a path, a shipped name or ``px4``).
    kind : str
        ``rbf`` or ``poly``.
    features : sequence of str
        Its effect ids (``lag`` included when the model has a thermal state).
    tau_s : float, s, optional
        The thermal state's total tau, shown beside ``lag``.

    Returns
    -------
    str
        E.g. ``modified.yaml: poly f(dT, dT2)``, ``auto.yaml: rbf f(dT, dT2, lag 176 s)`` or
        ``px4: cubic in T fitted on --train``.

    """
    if name == 'px4':
        return 'px4: cubic in T fitted on --train'
    shown = [f'lag {tau_s:.3g} s' if f == 'lag' and tau_s is not None else f
             for f in features if f != 'bias']          # bias is in every model
    return f'{Path(name).name}: {kind} f({", ".join(shown) or "bias"})'


def _save(fig: Any, path: Path) -> None:
    """Write a matplotlib figure as a PNG, atomically."""
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=90, format='png'), binary=True,
                 what='plot')


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
    Write three PNGs for one bag (Agg canvas, no display needed).

    * ``<label>_timeseries.png``: per axis the rate error against time, raw and every model
      (left) and the models alone on a zoomed scale (right), then the temperature; the
      re-anchoring window and the stretches outside a model's trained range are shaded and
      labelled;
    * ``<label>_residual_vs_temperature.png``: rate error against temperature, raw and per
      model, coloured by heating, cooling and steady temperature;
    * ``<label>_allan.png``: Allan deviation per axis, raw and compensated.

    Each figure's title names the bag, the models and the options (``options``: re-anchoring
    applied or not); every model keeps one colour, line style and marker in all three.

    Parameters
    ----------
    b : BagEval
        One evaluated bag, with its arrays.
    directory : str or PathLike
        Output directory (created).
    points : int
        Block means plotted per curve (long runs are averaged down to this).
    descriptions : sequence of str, optional
        Legend text per model of ``b.models`` (see :func:`model_description`); default: the
        model as given and its effect ids.
    options : str
        What was applied, for the titles (e.g. ``re-anchored: mean error of the first 300 s
        removed``); empty: nothing said.
    reanchor_s : float, s
        The re-anchoring window to shade (0: none).

    Returns
    -------
    list of Path
        The PNGs written.

    """
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    run = b.run
    if run is None:
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

    th = (_bmean(run.t) - run.t[0]) / 3600.0
    temp = _bmean(run.temp)
    n_models = len(b.models)
    raw_err = _bmean((run.omega - run.omega_ref) * _DEG)
    model_err = [_bmean((m.omega - run.omega_ref) * _DEG) for m in b.models]
    legends = [f'raw ({b.raw.label})' if b.raw.label != 'raw' else 'raw, uncompensated'] + [
        str(d) for d in descriptions]
    styles = [_RAW_STYLE] + [_style(i, len(th), n_models) for i in range(n_models)]
    models_text = ', '.join(Path(str(m.model)).name for m in b.models) or 'none'
    head = f'{b.bag}: models {models_text}' + (f'; {options}' if options else '')
    written = []
    with matplotlib.rc_context(_FONTS):
        written.append(_plot_timeseries(b, out, th, temp, raw_err, model_err, legends, styles,
                                        head, block, reanchor_s, FigureCanvasAgg, Figure))
        written.append(_plot_residual_vs_temperature(b, out, run, th, temp, raw_err, model_err,
                                                     legends, head, _bmean, FigureCanvasAgg,
                                                     Figure))
        written.append(_plot_allan(b, out, legends, styles, head, FigureCanvasAgg, Figure))
    return written


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
                     reanchor_s, canvas, figure_cls) -> Path:
    """Write ``<label>_timeseries.png``: full scale, zoomed models, temperature."""
    fig = figure_cls(figsize=(15, 11.5), constrained_layout=True)
    canvas(fig)
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
        near = [e[:, k] for m, e in zip(b.models, zerr)
                if math.isfinite(best) and float(m.bs[k]) <= _ZOOM_BS_FACTOR * best]
        limits = _zoom_limits(near)
        if limits is not None:
            right[k].set_ylim(*limits)
        right[k].axhline(0.0, color='0.3', lw=0.8)
        for ax in (left[k], right[k]):
            ax.grid(True, alpha=0.3)
            _flag_spans(ax, th, temp, b, legends, labelled=(ax is left[0]),
                        reanchor_s=reanchor_s)
    left[0].set_title('raw and compensated, full scale')
    right[0].set_title(f'zoom: compensated only, {zoom_s:.3g} s means, scaled to the models '
                       f'within {_ZOOM_BS_FACTOR:g}x of the best BS')
    left[0].legend(loc='best', framealpha=0.85)
    bottom.plot(th, temp, color='black', lw=1.2)
    bottom.set_ylabel('temperature (degC)')
    bottom.set_xlabel('time since the start of the bag (h)')
    bottom.grid(True, alpha=0.3)
    fig.suptitle(f'Rate error vs time (left: {block}-sample means)\n{head}')
    path = out / f'{b.label}_timeseries.png'
    _save(fig, path)
    return path


def _plot_residual_vs_temperature(b, out, run, th, temp, raw_err, model_err, legends, head,
                                  bmean, canvas, figure_cls) -> Path:
    """Write ``<label>_residual_vs_temperature.png``: one row per series, heating/cooling."""
    rate = bmean(temperature_rate(run.t, run.temp))
    x = RATE_THRESHOLD_C_PER_MIN
    groups = [(f'heating (> +{x:g} degC/min)', rate > x, 'tab:red'),
              (f'cooling (< -{x:g} degC/min)', rate < -x, 'tab:blue'),
              ('steady', np.abs(rate) <= x, 'tab:gray')]
    series = [raw_err] + list(model_err)
    fig = figure_cls(figsize=(14, 2.9 * len(series) + 1.0), constrained_layout=True)
    canvas(fig)
    axs = np.atleast_2d(fig.subplots(len(series), 3, squeeze=False))
    for r, e in enumerate(series):
        for k, a in enumerate(AXES):
            ax = axs[r, k]
            for name, sel, color in groups:
                if np.any(sel):
                    ax.scatter(temp[sel], e[sel, k], s=4, color=color, label=name)
            ax.set_title(f'{legends[r]} - {a}')
            ax.grid(True, alpha=0.3)
            if k == 0:
                ax.set_ylabel('rate error (deg/s)')
            if r == len(series) - 1:
                ax.set_xlabel('temperature (degC)')
    axs[0, 0].legend(loc='best', markerscale=3)
    fig.suptitle(f'Rate error vs temperature, by heating and cooling\n{head}')
    path = out / f'{b.label}_residual_vs_temperature.png'
    _save(fig, path)
    return path


def _plot_allan(b, out, legends, styles, head, canvas, figure_cls) -> Path:
    """Write ``<label>_allan.png``: Allan deviation per axis, raw and every model."""
    fig = figure_cls(figsize=(15, 5.2), constrained_layout=True)
    canvas(fig)
    axs = fig.subplots(1, 3, sharey=True)
    for k, a in enumerate(AXES):
        for i, m in enumerate([b.raw] + list(b.models)):
            if len(m.adev_tau_s):
                style = dict(styles[i])
                style['markevery'] = None if i == 0 else (i % 3, 3)
                axs[k].loglog(m.adev_tau_s, m.adev_dps[:, k], label=legends[i], **style)
        axs[k].set_title(f'{a} axis')
        axs[k].set_xlabel('averaging time tau (s)')
        axs[k].grid(True, which='both', alpha=0.3)
    axs[0].set_ylabel('Allan deviation of the rate error (deg/s)')
    axs[0].legend(loc='best')
    fig.suptitle(f'Allan deviation\n{head}')
    path = out / f'{b.label}_allan.png'
    _save(fig, path)
    return path
