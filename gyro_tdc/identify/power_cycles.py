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
Do no harm across power cycles: the thermal curve validated on held-out sessions.

:func:`check_sessions` holds each session out in turn (the estimator's
:meth:`gyro_tdc.signal.Folds.sessions`), fits the curve on the others and scores it on the
held-out session re-anchored, as the compensator re-anchors at start-up, against its offset
alone. An axis whose curve does not predict every held-out power cycle better, by
:data:`~gyro_tdc.signal.CURVE_SIGNIFICANCE` standard errors of its gain
(:func:`~gyro_tdc.signal.judge_curve`; the learner asks its pooled part), keeps the offset
only; :func:`session_check_lines` says so with the figures, or that no power cycle overlaps
the others' temperatures and the curve is kept unchecked. Unchecked, it must rest on
:data:`MIN_SESSION_SPAN_C` of one power cycle: each offset free, a curve is told only
within a power cycle, and one told over less (the short stops of flight logs) is kept off.

:func:`reanchor_rule` (the rule of :mod:`gyro_tdc.runtime.startup_gate`, which the learner
shares) decides the same way, per axis, how large a start-up shift the node takes (the gate
:func:`gyro_tdc.runtime.reanchor.gated_shift` applies): any, or only one beyond
:data:`SIGNIFICANCE` times the error of anchors taken throughout the training data (a
smaller one is no evidence of a turn-on offset: short bursts that jitter around the model).
With two sessions or more the choice is the one that did better held out;
:func:`reanchor_lines` reports it.
"""

from __future__ import annotations

from dataclasses import replace

from typing import Any, Callable, Sequence

from gyro_tdc.base import DEG2_PER_RAD2
from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.axes import AXES
from gyro_tdc.identify.linear import fit_linear, LinearFit
from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime import MAX_ANCHORS, MAX_ROWS, SIGNIFICANCE
from gyro_tdc.runtime import reanchor_rule as _rule
from gyro_tdc.signal import (CURVE_SIGNIFICANCE, curve_untold, Folds, heldout,
                             judge_curve, MIN_SESSION_SPAN_C, within)
import numpy as np
from numpy.typing import NDArray

__all__ = ['check_sessions', 'MAX_ANCHORS', 'MAX_ROWS', 'MIN_FOLDS',
           'offset_check_lines', 'reanchor_lines', 'reanchor_rule', 'session_check_lines',
           'SIGNIFICANCE', 'SLOW_CURVE_S', 'told_alone']

#: Fewest held-out power cycles that judge a curve of several stops (still-only training):
#: one that agrees is no evidence that the curve carries to the next.
MIN_FOLDS = 2
#: With one power cycle, a still stretch tells the curve on its own only if it lasts this
#: long (s) as well as spanning ``MIN_SESSION_SPAN_C``: a slow warm, not the power-on minutes.
SLOW_CURVE_S = 300.0


def told_alone(told: Sequence[tuple[float, float]]) -> bool:
    """Return whether one power cycle's still stretches (span degC, duration s) tell a curve."""
    return any(c >= MIN_SESSION_SPAN_C and s >= SLOW_CURVE_S for c, s in told)


def check_sessions(fit: LinearFit, offsets: NDArray[np.float64], x: NDArray[np.float64],
                   y: NDArray[np.float64], scale_cols: NDArray[np.float64] | None,
                   groups: NDArray[np.int64], counts: NDArray[np.float64],
                   temp: NDArray[np.float64], *, min_folds: int = 1,
                   units: NDArray[np.int64] | None = None,
                   unit: tuple[str, float] = ('dps2', DEG2_PER_RAD2), **linear: Any
                   ) -> tuple[LinearFit, NDArray[np.float64], dict | None]:
    """
    Validate the curve on held-out sessions (:func:`~gyro_tdc.signal.judge_curve`).

    ``x``, ``y``, ``scale_cols``, ``groups``, ``counts`` and ``temp`` are the fit's block rows
    (features, target, scale columns, session, samples, model temperature); ``offsets`` its
    session offsets. Returns the fit and offsets with the offset-only axes each session's mean
    only, and the record: ``folds``, ``blocks``, held-out mean squares of curve and offset,
    ``worse_folds``, ``gain_t``, ``offset_only``; with no fold ``folds`` 0 and ``sessions``
    (the curve kept unchecked unless no session spans :data:`MIN_SESSION_SPAN_C`,
    ``widest_span_c``), and with fewer than ``min_folds`` (still-only training:
    :data:`MIN_FOLDS`) every axis offset only (``min_folds``); None without a curve.
    ``units`` (default ``groups``) is the power cycle of each row where one holds several
    offsets (the accelerometer's orientation segments): a fold holds out a power cycle.
    ``unit`` names the mean squares' unit in the record's keys and scales them to it;
    ``linear`` (``kind``, ``n_centers``, ``seed``) are the refits' :func:`fit_linear` options.
    """
    if not x.shape[1]:                          # no curve: nothing to judge
        return fit, offsets, None
    units = groups if units is None else units
    folds = Folds.sessions(units, temp)
    if len(folds) < max(min_folds, 1):          # too few power cycles judge it
        record = {'folds': len(folds), 'sessions': int(np.unique(units).size), 'offset_only': []}
        if (widest := curve_untold(temp, groups)) is not None:
            record['widest_span_c'] = widest
        elif min_folds <= 1:                    # none judges it: kept unchecked, said
            return fit, offsets, record
        else:
            record['min_folds'] = min_folds
        record['offset_only'] = list(AXES)
        return (*_offset_only(fit, offsets, y, groups, np.arange(len(AXES))), record)

    def curve(test: NDArray[np.bool_], train: NDArray[np.bool_]) -> NDArray[np.float64]:
        f = fit_linear(x[train], y[train], ridge=fit.ridge, groups=groups[train],
                       scale_cols=None if scale_cols is None else scale_cols[train], **linear)
        return f.predict(x[test], None if scale_cols is None else scale_cols[test]) - y[test]

    r_curve, r_offset = (heldout(f, folds, y.shape, groups=groups, weights=counts)
                         for f in (curve, lambda test, train: -y[test]))
    v = judge_curve(r_curve, r_offset, folds, counts)
    drop = np.flatnonzero(v.drop)
    record = {'folds': len(folds), 'blocks': v.rows,
              f'curve_ms_{unit[0]}': (v.ms_curve * unit[1]).tolist(),
              f'offset_ms_{unit[0]}': (v.ms_offset * unit[1]).tolist(),
              'worse_folds': v.worse_folds.tolist(),
              'gain_t': [float(t) if np.isfinite(t) else None for t in v.gain_t],
              'offset_only': [AXES[a] for a in drop]}
    if not drop.size:           # every curve kept: the fit as it is, no copy, no pass over y
        return fit, offsets, record
    return (*_offset_only(fit, offsets, y, groups, drop), record)


def _offset_only(fit: LinearFit, offsets: NDArray[np.float64], y: NDArray[np.float64],
                 groups: NDArray[np.int64], drop: NDArray[np.int64]
                 ) -> tuple[LinearFit, NDArray[np.float64]]:
    """Return the fit and offsets with the axes ``drop`` each session's mean only."""
    means, centred = within(y, groups)
    coef, scale, resid, offsets = (a.copy() for a in (fit.coef, fit.scale, fit.resid, offsets))
    coef[:, drop], scale[drop] = 0.0, 0.0
    offsets[:, drop] = means[:, drop]
    resid[:, drop] = -centred[:, drop]
    return replace(fit, coef=coef, scale=scale, resid=resid,
                   sse=float((resid ** 2).sum())), offsets


def _figures(values: Sequence[float]) -> str:
    """Return a report row's figures: each in 10.3g, two spaces apart."""
    return '  '.join(f'{v:10.3g}' for v in values)


def offset_check_lines(record: dict | None) -> list[str]:
    """Return the report lines of :func:`~gyro_tdc.signal.check_offsets` (none without one)."""
    if not record:
        return []
    out = [f"the offset of the axes without curve ({', '.join(record['axes'])}) held out on each "
           f"of the {record['sessions']} power cycles: mean square x y z, (deg/s)^2 | mean "
           'absolute error x y z, deg/s:',
           *(f'  {name:<12} ' + _figures(record[f'{key}_ms_dps2']) + '  |'
             + _figures(record[f'{key}_mae_dps'])
             for name, key in (("others' mean", 'mean'), ('none', 'none')))]
    if record['no_offset']:
        out.append(f"axes {', '.join(record['no_offset'])}: the other power cycles' mean does "
                   "not predict a held-out one's offset better than none on both figures (a "
                   'board that zeroes its gyro at power-on): the model adds no offset there '
                   '(re-anchoring still applies)')
    return out


def session_check_lines(record: dict | None) -> list[str]:
    """Return the report lines of a held-out session check (empty without one)."""
    if not record:
        return []
    if 'worse_folds' not in record:
        head = ('the curve is not judged on a held-out power cycle: none of the '
                f"{record['sessions']} sessions with data has two blocks inside the others' "
                'temperatures' if not record['folds'] else
                f"the curve is judged on {record['folds']} held-out power cycle only (of the "
                f"{record['sessions']} sessions with data)")
        if 'widest_span_c' in record:
            return [f'{head}, and none spans {MIN_SESSION_SPAN_C:g} degC of its own (widest '
                    f"{record['widest_span_c']:.2f} degC): with an offset per power cycle the "
                    'curve would rest on less; the model keeps the offset only on every axis '
                    '(re-anchoring still applies)']
        if not record['offset_only']:
            return [f'{head}; the model keeps it on every axis unchecked (a power cycle over '
                    "the others' temperatures would judge it)"]
        return [f"{head}; fewer than {record['min_folds']} cannot tell whether a curve of "
                'stops carries to the next power cycle: the model keeps the offset only on '
                'every axis (re-anchoring still applies)']
    out = [f"the curve held out on each power cycle ({record['folds']} sessions, "
           f"{record['blocks']} blocks inside the others' temperatures, re-anchored), "
           'mean square, (deg/s)^2:',
           '  curve        ' + _figures(record['curve_ms_dps2']),
           '  offset only  ' + _figures(record['offset_ms_dps2'])]
    out.append('  power cycles predicted worse by the curve: '
               + '  '.join(f'{v:d}' for v in record['worse_folds']))
    out.append("  the curve's gain in standard errors: "
               + '  '.join('-' if v is None else f'{v:.1f}' for v in record['gain_t']))
    if record['offset_only']:
        out.append(f"axes {', '.join(record['offset_only'])}: the curve does not predict "
                   'every held-out power cycle better than its offset alone, by '
                   f'{CURVE_SIGNIFICANCE:g} standard errors; the model keeps the offset only '
                   'there (re-anchoring still applies)')
    return out


def reanchor_rule(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int],
                  refit: Callable[..., CompensationModel], rows: Sequence | None = None
                  ) -> CompensationModel:
    """
    Decide per axis the smallest start-up shift the node takes; record it in the model.

    :func:`gyro_tdc.runtime.startup_gate.reanchor_rule` (its parameters and record), with
    ``refit`` raising FitError where too little is left without a held-out session.
    """
    def fitted(*args: object, **kw: object) -> CompensationModel | None:
        try:
            return refit(*args, **kw)
        except FitError:
            return None

    return _rule(model, runs, labels, fitted, rows)


def reanchor_lines(record: dict | None) -> list[str]:
    """Return the report lines of the re-anchoring decision (empty without one)."""
    if not record:
        return []
    out = ['start-up anchors taken throughout the training data err by (RMS, deg/s) '
           + _figures(record['anchor_error_dps'])]
    if 'always_dps' in record:
        out += [f"held out on {record['held_out']} power cycles (each predicted by the model "
                'fitted on the others, re-anchored at its start), RMS of their mean error, deg/s:',
                *(f'  {k:<22}' + _figures(record[f'{k.split()[0]}_dps'])
                  for k in ('always (any shift)', 'gated (beyond the gate)', 'never'))]
    return out + [f'axis {a}: the node re-anchors only beyond {v:.3g} deg/s ({SIGNIFICANCE:g} x '
                  "its anchors' error: a smaller start-up shift is no evidence of a turn-on "
                  'offset)'
                  if v > 0 else f'axis {a}: the node re-anchors any start-up shift'
                  for a, v in zip(AXES, record['min_shift_dps'])]
