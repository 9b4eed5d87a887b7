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
Formatting of evaluation results (text tables, JSON and CSV export) and the training report.

Formats only: the summary and the paper's tables, :func:`evaluation_json` (the shape of
``doc/json.md``) and :func:`write_csv`, each written atomically; the training report (the
model, its training figures, sessions and data coverage) for ``gyro-tdc train`` and the demo.
See ``doc/internals/evaluate.md``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, IO, Sequence

from gyro_tdc.base import atomic_json, atomic_write, AXES, plain
from gyro_tdc.data import Coverage
from gyro_tdc.evaluate.models import axes_words
from gyro_tdc.evaluate.score import BagEval, mean_scores
from gyro_tdc.identify import (offset_check_lines, reanchor_lines, session_check_lines,
                               TrainResult)
from gyro_tdc.model import (DEFAULT_OUT_OF_RANGE, MAX_EXTRAPOLATION_C, OPERATING_RANGE_C,
                            range_shortfall, static_slope)
import numpy as np
from numpy.typing import NDArray

__all__ = ['csv_columns', 'evaluation_json', 'format_allan', 'format_bag',
           'format_coverage', 'format_means', 'format_paper_table', 'format_sessions',
           'format_still', 'format_summary', 'format_training', 'is_coverage_line',
           'POLICY_WORDS', 'REANCHOR_SPREAD_DPS', 'write_csv', 'write_json']

#: What each out-of-range policy does beyond a model's trained range (notes, console).
POLICY_WORDS = {
    'linear': 'the correction continues along its tangent at the range end, held beyond '
              f'{MAX_EXTRAPOLATION_C:g} degC',
    'clamp': 'the correction is held at the range end',
    'extrapolate': 'the model is evaluated there'}


# --------------------------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------------------------

def _vec(a: NDArray[np.float64] | None) -> list | None:
    """Return an array as a list of JSON-safe floats (NaN and inf as null); None stays None."""
    return None if a is None else plain(np.asarray(a, dtype=np.float64), nan_to_none=True)


def _scores(m: Any, floor: Sequence[float] | None, accel_floor: Sequence[float] | None) -> dict:
    """Return the ``bs``, ``accel_bs`` (each with its ratio to a floor) and ``rms_dps`` keys."""
    out = {}
    for key, bs, fl in (('bs', m.bs, floor), ('accel_bs', m.accel_bs, accel_floor)):
        out[key] = _vec(bs)
        if fl is not None:
            out[f'{key}_over_floor'] = None if bs is None else _vec(np.divide(bs, fl))
    return {**out, 'rms_dps': _vec(m.rms_dps)}


def _still_json(still: dict) -> dict:
    """Return the still-only record of a bag: what was scored, in all and per session."""
    keys = ('samples', 'stretches', 'still_s', 'temperature_c', 'total_samples', 'total_s',
            'total_temperature_c', 'share')
    return {**{k: still[k] for k in keys},
            'sessions': [{k: p[k] for k in keys} for p in still['per_session']]}


def evaluation_json(bags: Sequence[BagEval], *, floor: Sequence[float] | None = None,
                    accel_floor: Sequence[float] | None = None) -> dict:
    """
    Return the evaluation in the documented JSON shape (doc/json.md), nothing more.

    BS in (deg/s)^2, RMS and ADEV in deg/s, non-finite values as null. ``floor`` and
    ``accel_floor`` (known white-noise floors per axis, (deg/s)^2 and (m/s^2)^2, from
    ``--floor`` / ``--accel-floor``) add ``bs_over_floor`` / ``accel_bs_over_floor`` beside
    every BS and the floors at the top.
    """
    doc = {'bags': [{
        'bag': b.bag, 'samples': int(b.samples), 'temperature_c': _vec(b.temperature_c),
        'raw': _scores(b.raw, floor, accel_floor),
        'models': [{
            'model': m.model, 'features': list(m.features), **_scores(m, floor, accel_floor),
            'p_vs_raw': _vec(m.p_vs_raw),
            'adev': {'tau_s': _vec(m.adev_tau_s),
                     'dps': [_vec(row) for row in np.asarray(m.adev_dps)]},
            **({} if m.reanchor is None else {'reanchor': m.reanchor}),
            **({'constant_axes': list(m.constant_axes)} if m.constant_axes else {}),
        } for m in b.models],
        **({'constant_axes': list(b.constant_axes)} if b.constant_axes else {}),
        **({} if b.still is None else {'still': _still_json(b.still)}),
    } for b in bags]}
    doc['out_of_range'] = bags[0].out_of_range if bags else DEFAULT_OUT_OF_RANGE
    doc.update({key: _vec(fl) for key, fl in (('floor', floor), ('accel_floor', accel_floor))
                if fl is not None})
    return doc


def write_json(bags: Sequence[BagEval], path: str | os.PathLike, *,
               floor: Sequence[float] | None = None,
               accel_floor: Sequence[float] | None = None) -> Path:
    """Write :func:`evaluation_json` to ``path`` atomically (parents created); return it."""
    doc = evaluation_json(bags, floor=floor, accel_floor=accel_floor)
    return atomic_json(path, doc, allow_nan=False)


# --------------------------------------------------------------------------------------------
# Text tables
# --------------------------------------------------------------------------------------------

def _g(v: float, width: int = 11) -> str:
    """Format one number for a table column."""
    return f'{v:>{width}.4g}' if math.isfinite(v) else f'{"-":>{width}}'


#: The BS/BS1 cell of an axis with nothing to score (it reads its reference exactly).
_CONST = 'const'


def _ratio_cells(p: Sequence[float], constant: Sequence[str], width: int = 11) -> str:
    """Return the BS/BS1 cells of one row, ``const`` on the constant axes."""
    return ''.join(f'{_CONST:>{width}}' if a in constant else _g(v, width)
                   for a, v in zip(AXES, p))


def _constant_notes(b: BagEval) -> list:
    """Return the lines naming a bag's constant gyro axes and the models' identity axes."""
    exact = [a for a, v in zip(AXES, b.raw.bs) if a in b.constant_axes and not v > 0]
    says = ((exact, 'reads', 'read', 'the reference rate exactly on every sample'),
            ([a for a in b.constant_axes if a not in exact], 'never varies', 'never vary',
             'beyond one quantum'))
    out = [f'  note: gyro {axes_words(axes)} {many if len(axes) > 1 else one} {what} '
           f'(constant: a 2-axis gyro or a dead axis): no signal to score, BS/BS1 {_CONST}'
           for axes, one, many, what in says if axes]
    return out + [f'  note: {m.label} passes gyro {axes_words(m.constant_axes)} through '
                  'unchanged (constant in its training data: not fitted)'
                  for m in b.models if m.constant_axes]


# BagEval.reference (where the reference rate came from) in words.
_REFERENCE = {'topic': 'reference rate from the reference topic',
              'constant': 'constant reference rate (--reference)',
              'zero': 'reference rate zero (no reference topic)'}


def _floor_text(floor: Sequence[float]) -> str:
    """Return a floor as ``0.009`` when the axes agree, else ``x, y, z``."""
    f = [float(v) for v in floor]
    return f'{f[0]:.4g}' if f[0] == f[1] == f[2] else ', '.join(f'{v:.4g}' for v in f)


def _head(w: int, *names: str) -> str:
    """Return a table's header: a label column ``w`` wide, then ``NAME x y z`` per name."""
    return f'  {"":<{w}} ' + '  '.join(''.join(f'{n + " " + a:>11}' for a in AXES) for n in names)


def _row(label: str, w: int, *groups: Any) -> str:
    """Return a table row: the label, then per group its three cells (or a ready string)."""
    return f'  {label:<{w}} ' + '  '.join(g if isinstance(g, str) else ''.join(_g(v) for v in g)
                                          for g in groups)


def _per_floor(bs: NDArray[np.float64] | None, floor: Sequence[float] | None) -> list:
    """Return ``[BS / floor]`` (NaN where there is no BS) with a floor, else ``[]``."""
    return [] if floor is None else [
        np.full(3, math.nan) if bs is None else np.asarray(bs) / np.asarray(floor)]


def _range_text(span: Sequence[float] | None) -> str:
    """Return a temperature range ``[lo, hi]`` as ``lo .. hi degC`` (``no sample``: None)."""
    return 'no sample' if span is None else f'{span[0]:.2f} .. {span[1]:.2f} degC'


def _time_text(seconds: float) -> str:
    """Return a duration in s below 2 min, in min below 2 h, else in h."""
    if seconds < 120.0:
        return f'{seconds:.0f} s'
    return f'{seconds / 60.0:.1f} min' if seconds < 7200.0 else f'{seconds / 3600.0:.2f} h'


def format_still(b: BagEval) -> list:
    """
    Return the lines saying what of a bag without a reference was scored (none: all).

    Every figure says whose it is: the still stretches scored (samples, seconds, temperature
    range) beside the whole bag's (or session's) samples, seconds and temperature range.
    """
    if (s := b.still) is None:
        return []

    def what(p: dict, whole: str) -> str:
        return (f"{p['samples']} samples in {p['stretches']} stretch(es), {p['still_s']:.0f} s "
                f"of {p['total_s']:.0f} s ({100.0 * p['share']:.3g} %), at "
                f"{_range_text(p['temperature_c'])}; the whole {whole}: {p['total_samples']} "
                f"samples at {_range_text(p['total_temperature_c'])}")

    lines = [f'{b.label}: no reference rate and the IMU moves: scored the still stretches '
             f"only, {what(s, 'bag')}; raw and models re-anchored on the first still stretch "
             f"of each of the {s['sessions']} session(s), as the compensator does at start-up"]
    if s['sessions'] > 1:
        lines += [f"  session {k}: {what(p, 'session')}"
                  for k, p in enumerate(s['per_session'], 1)]
    return lines


def format_summary(b: BagEval, *, floor: Sequence[float] | None = None,
                   accel_floor: Sequence[float] | None = None) -> str:
    """
    Return the per-bag summary: BS, RMS and BS/BS1 per axis for raw data and every model.

    ``floor`` / ``accel_floor`` (white-noise floors per axis, (deg/s)^2 and (m/s^2)^2) add
    the columns ``BS/fl`` and ``aBS/fl``. No trailing newline.
    """
    span = _range_text(b.temperature_c)
    reference = _REFERENCE.get(b.reference, f'reference {b.reference}')
    s = b.still
    lines = [f'bag {b.bag}: {b.samples} samples over {_time_text(b.duration_s)}, '
             f'temperature {span}, {reference}' if s is None else
             f'bag {b.bag}: scored {b.samples} still samples over {_time_text(b.duration_s)} '
             f'of still time at {span} (the whole bag: '
             f"{s['total_samples']} samples over {_time_text(s['total_s'])} at "
             f"{_range_text(s['total_temperature_c'])}), {reference}"]
    w = max([len(m.label) for m in b.models] + [12])
    lines += ['  BS in (deg/s)^2 (paper eq. 30), RMS in deg/s, BS/BS1 against the raw data'
              + ('' if floor is None else
                 f', BS/fl against the floor {_floor_text(floor)} (deg/s)^2 (--floor)'),
              _head(w, 'BS', 'RMS', 'BS/BS1', *(['BS/fl'] if floor else []))]
    lines += [_row(m.label, w, m.bs, m.rms_dps, _ratio_cells(m.p_vs_raw, b.constant_axes),
                   *_per_floor(m.bs, floor)) for m in [b.raw] + list(b.models)]
    lines += _outside_note(b) + _constant_notes(b) + _accel_rows(b, w, accel_floor)
    return '\n'.join(lines)


def _accel_rows(b: BagEval, w: int, accel_floor: Sequence[float] | None = None) -> list:
    """Return the accelerometer rows of a bag's summary (none when not applicable)."""
    if b.raw.accel_bs is None:
        return []
    lines = ['  accelerometer (still run): BS = variance around the run mean in (m/s^2)^2, '
             + ('' if b.still is None else
                "over the still samples of the whole bag by the accelerometer's still test, ")
             + 'BS/BS1 against the raw data'
             + ('' if accel_floor is None else
                f', aBS/fl against the floor {_floor_text(accel_floor)} (m/s^2)^2 '
                '(--accel-floor)') + '; - : no accelerometer part',
             _head(w, 'aBS', 'aBS/BS1', *(['aBS/fl'] if accel_floor else []))]
    for m in [b.raw] + list(b.models):
        bs = np.full(3, math.nan) if m.accel_bs is None else np.asarray(m.accel_bs)
        with np.errstate(divide='ignore', invalid='ignore', over='ignore'):   # a constant axis
            ratio = bs / np.asarray(b.raw.accel_bs)
        lines.append(_row(m.label, w, bs, ratio, *_per_floor(m.accel_bs, accel_floor)))
    return lines


def _outside_note(b: BagEval) -> list:
    """Return one note for every model the bag leaves the trained range of (none: [])."""
    groups: dict = {}       # (fraction text, range) -> labels, in model order
    for m in b.models:
        if m.outside_fraction > 0:
            key = (f'{100.0 * m.outside_fraction:.3g} %',
                   f'[{m.temp_range_c[0]:.2f}, {m.temp_range_c[1]:.2f}] degC')
            groups.setdefault(key, []).append(m.label)
    whose = 'the samples' if b.still is None else 'the still samples scored'
    parts = [f'{pct} of {whose} lie outside the trained range of {", ".join(labels)} '
             f'{span}' if i == 0 else f'{pct} outside that of {", ".join(labels)} {span}'
             for i, ((pct, span), labels) in enumerate(groups.items())]
    p = b.out_of_range
    return [f'  note: {"; ".join(parts)}: {POLICY_WORDS.get(p, p)} (out-of-range policy {p}'
            + ('' if p == 'clamp' else ', not clamped') + ')'] if parts else []


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
    from gyro_tdc.signal import p_ratios
    conv, modi = b.models[conventional], b.models[modified]
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):   # a constant axis
        p = p_ratios(b.raw.bs, conv.bs, modi.bs)
    lines = [f'  paper table (eq. 31-32), {b.label}: BS1 raw, BS2 {conv.label} '
             f'(conventional), BS3 {modi.label} (modified); BS in (deg/s)^2',
             f'  {"":<7}' + ''.join(f'{h:>11}' for h in ('BS1', 'BS2', 'BS3', 'P1', 'P2'))
             + f'{"P3":>10}']
    for i, a in enumerate(AXES):
        p3 = p['P3'][i]
        ratios = (f'{_CONST:>11}{_CONST:>11}{_CONST:>10}' if a in b.constant_axes else
                  _g(p['P1'][i]) + _g(p['P2'][i])
                  + (f'{100.0 * p3:>9.2f}%' if math.isfinite(p3) else f'{"-":>10}'))
        lines.append(f'  {a + "-axis":<7}' + _g(b.raw.bs[i]) + _g(conv.bs[i]) + _g(modi.bs[i])
                     + ratios)
    return '\n'.join(lines)


def format_allan(b: BagEval) -> str:
    """Return the Allan readouts (ARW, deg/sqrt(h); bias instability, deg/h) per axis."""
    w = max([len(m.label) for m in b.models] + [12])
    lines = ['  Allan deviation: angle random walk ARW in deg/sqrt(h), bias instability BI '
             'in deg/h',
             _head(w, 'ARW', 'BI')]
    lines += [_row(m.label, w, m.arw_deg_sqrt_h, m.bias_instability_deg_h)
              for m in [b.raw] + list(b.models)]
    if b.still is not None:
        lines.append('  note: no Allan deviation on still stretches (the gaps between them '
                     'break the time series)')
    return '\n'.join(lines)


def format_bag(b: BagEval, baseline: int | None = None, *,
               floor: Sequence[float] | None = None,
               accel_floor: Sequence[float] | None = None) -> str:
    """
    Return every table of one bag: summary, paper tables against ``baseline``, Allan readouts.

    ``baseline`` indexes ``b.models`` (the conventional model): one paper table (tables 3-7)
    per other model; None: none. ``floor``, ``accel_floor``: see :func:`format_summary`.
    """
    tables = [format_paper_table(b, baseline, i) for i in range(len(b.models))
              if baseline is not None and i != baseline]
    return '\n'.join([format_summary(b, floor=floor, accel_floor=accel_floor), *tables,
                      format_allan(b)])


def format_means(results: Sequence[BagEval], *, floor: Sequence[float] | None = None) -> str:
    """
    Return the mean BS and BS/BS1 per model and axis over several bags (:func:`mean_scores`).

    ``floor`` ((deg/s)^2 per axis) adds the mean BS / floor (``BS/fl``). No trailing newline.
    """
    rows = mean_scores(results)
    w = max([len(label) for label, _, _ in rows[1:]] + [12])
    lines = [f'mean over {len(results)} bags: BS in (deg/s)^2 and BS/BS1'
             + ('' if floor is None else f', BS/fl against the floor {_floor_text(floor)}'),
             _head(w, 'BS', 'BS/BS1', *(['BS/fl'] if floor else []))]
    constant = [a for a in AXES if all(a in b.constant_axes for b in results)]
    lines += [_row(label, w, bs, _ratio_cells(p, constant), *_per_floor(bs, floor))
              for label, bs, p in rows]
    return '\n'.join(lines)


# --------------------------------------------------------------------------------------------
# CSV export and plots
# --------------------------------------------------------------------------------------------

def csv_columns(b: BagEval) -> list:
    """Return the CSV header of a bag: time, temperature, raw, reference, each model."""
    who = ['raw', 'ref'] + [m.label for m in b.models]
    return ['t_s', 'temp_c'] + [f'{w}_{a}_rad_s' for w in who for a in AXES]


def write_csv(b: BagEval, directory: str | os.PathLike, *, chunk: int = 100_000) -> Path:
    """
    Write ``DIR/<bag label>.csv``: every sample scored, raw, reference and compensated rates.

    Columns from :func:`csv_columns`, rates in rad/s, ``chunk`` rows formatted at once; a bag
    scored on its still stretches only gives those samples (the models re-anchored as scored,
    the raw rate as read). Returns the path.
    """
    if (run := b.run) is None:
        raise ValueError('Expected `b.run` to hold the data; it was released.')
    cols = csv_columns(b)
    fmt = ['%.6f', '%.6g'] + ['%.9g'] * (len(cols) - 2)

    def rows(fh: IO[str]) -> None:
        fh.write(','.join(cols) + '\n')
        for i in range(0, len(run), chunk):
            sl = slice(i, i + chunk)
            block = np.column_stack([run.t[sl], run.temp[sl], run.omega[sl], run.omega_ref[sl]]
                                    + [m.omega[sl] for m in b.models])
            np.savetxt(fh, block, fmt=fmt, delimiter=',')

    return atomic_write(Path(directory) / f'{b.label}.csv', rows, what='CSV file', newline='\n')


# --------------------------------------------------------------------------------------------
# Coverage of training data
# --------------------------------------------------------------------------------------------

def _bin_name(c: Coverage, i: int) -> str:
    """Return ``[a, b) degC`` for bin ``i``."""
    return f'[{c.edges[i]:g}, {c.edges[i + 1]:g}) degC'


def format_coverage(c: Coverage) -> tuple[str, list]:
    """
    Return the coverage summary (three lines) and the warning lines (no ``warning:`` prefix).

    The table: the range covered; the bins in one line (how many, their minutes: least,
    median, most, and how many are thin, i.e. under a quarter of the median minutes per
    degC); minutes heating, cooling and steady. The warnings: the thin bins by name; no
    heating or no cooling data.
    """
    lo, hi = c.temp_range_c
    lines = [f'temperature range covered: {lo:.2f} .. {hi:.2f} degC (span {hi - lo:.2f} degC)']
    if (minutes := np.asarray(c.minutes, dtype=np.float64)).size:
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
    if c.heating_min + c.cooling_min > 0 and min(c.heating_min, c.cooling_min) == 0:
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

    How the bags were cut, then each session's offset from the model's (their mean, deg/s),
    the spread and, above :data:`REANCHOR_SPREAD_DPS` on an axis, the line that says to
    re-anchor on the vehicle, then the start-up shift the node takes per axis
    (:func:`~gyro_tdc.identify.power_cycles.reanchor_lines`); empty without sessions.
    """
    if (split := getattr(result, 'sessions', None)) is None:
        return []
    out = list(split.lines())
    info = result.model.metrics.get('sessions')
    anchors = reanchor_lines(result.model.metrics.get('reanchor'))
    if not info:
        return out + anchors
    width, spread = max(len(n) for n in info['names']), info['spread_dps']
    none = info.get('turn_on', {}).get('no_offset')
    level = f"their mean; none on {', '.join(none)}" if none else 'their mean'
    out += [f"turn-on offset of each session against the model's ({level}), deg/s:",
            *(f'  {name:<{width}}  ' + '  '.join(f'{v:+10.5f}' for v in off) + f'   ({n} samples)'
              for name, off, n in zip(info['names'], info['offset_dps'], info['samples'])),
            f'  {"spread":<{width}}  ' + '  '.join(f'{v:10.5f}' for v in spread)
            + '   (largest minus smallest)']
    if max(spread) > REANCHOR_SPREAD_DPS:
        out.append(f'the turn-on offset changes by up to {max(spread):.3g} deg/s from one '
                   'power cycle to the next: a model fixes the thermal curve, not the offset '
                   'of a new power cycle; re-anchor on the vehicle (compensator_node '
                   'reanchor_on_start, on by default) and score with evaluate --reanchor auto')
    return (out + session_check_lines(info.get('heldout'))
            + offset_check_lines(info.get('turn_on')) + anchors)


def format_training(result: TrainResult) -> tuple[str, list]:
    """
    Return the training report of what :func:`gyro_tdc.identify.train.train` returned.

    The text: the model, the constant gyro axes (one line when there are any: not fitted,
    passed through unchanged), training BS raw and compensated per axis, coverage. The
    warnings: coverage, and that the thermal state's tau is not identifiable when so.
    """
    m = result.model
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
    lines = [head, f'TRAINED RANGE {lo:.2f} .. {hi:.2f} degC ({of}); beyond it (the '
                   f"compensator's out_of_range: linear) {POLICY_WORDS['linear']}",
             f'training data: {len(result.bags)} bag(s), {result.samples} samples']
    # One line (when any): the constant axes, not fitted, passed through unchanged.
    lines += [line for line in [result.constant_line()] if line]
    lines += ['training bias stability BS, (deg/s)^2:',
              f'  {"":<13}' + ''.join(f'{a:>12}' for a in AXES),
              *(_row3(label, m.metrics.get(key, [math.nan] * 3)) for label, key in (
                  ('raw', 'raw_bs_dps2'), ('compensated', 'train_bs_dps2'),
                  ('RMS (deg/s)', 'train_rms_dps')))]
    lines += [_row3('scale (1/C)', m.scale)] if np.any(m.scale != 0) else []
    table, warns = format_coverage(result.coverage)
    lines += [_row3('drift/degC', np.degrees(static_slope(m)))
              + '   (deg/s per degC: static drift, mean slope over the range)', table]
    if short := range_shortfall((lo, hi)):
        a, b = OPERATING_RANGE_C
        warns = list(warns) + [
            f'the training data cover {lo:.1f} .. {hi:.1f} degC, less than a typical operating '
            f'range of {a:g} .. {b:g} degC ({short} missing): there the model is not '
            f"calibrated and (the compensator's out_of_range: linear) {POLICY_WORDS['linear']} "
            '(clamp or extrapolate are the alternatives, see doc/real_data.md); record the '
            'missing temperatures to calibrate them']
    if lagged and th.identifiable is False:
        warns = list(warns) + [
            th.describe().split('; ', 1)[-1] + ': soaks after heating and cooling steps '
            '(the die catching up) pin it']
    return '\n'.join(lines), warns
