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
alone. An axis whose curve does not predict every held-out power cycle better keeps the
offset only; :func:`session_check_lines` says so with the figures.

:func:`reanchor_rule` decides the same way, per axis, how large a start-up shift the node
takes (the gate :func:`gyro_tdc.runtime.reanchor.gated_shift` applies): any, or only one
beyond :data:`SIGNIFICANCE` times the error of anchors taken throughout the training data
(a smaller one is no evidence of a turn-on offset: short bursts that jitter around the
model). With two sessions or more the choice is the one that did better held out;
:func:`reanchor_lines` reports it.
"""

from __future__ import annotations

from dataclasses import replace
import math

from typing import Callable, Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.linear import fit_linear, LinearFit
from gyro_tdc.model import compensate, CompensationModel, DEFAULT_OUT_OF_RANGE, model_temperature
from gyro_tdc.runtime import default_tolerance, REANCHOR_KEY, reanchor_shift, STILL_WINDOW_MAX_S
from gyro_tdc.signal import block_mean, Folds, heldout, STILL_WINDOW_S, within
import numpy as np
from numpy.typing import NDArray

__all__ = ['check_sessions', 'MAX_ANCHORS', 'MAX_ROWS', 'reanchor_lines', 'reanchor_rule',
           'session_check_lines', 'SIGNIFICANCE']

_AXES = ('x', 'y', 'z')
_DEG = 180.0 / math.pi
_DEG2 = _DEG ** 2
#: A gated node takes a start-up shift on an axis only beyond this many times the RMS error
#: of start-up anchors taken throughout the training data.
SIGNIFICANCE = 2.0
#: Start-up anchors tried over the training data at most (evenly picked).
MAX_ANCHORS = 100
#: Rows per run the anchors are taken on at most (longer runs are block-averaged).
MAX_ROWS = 50_000


def check_sessions(fit: LinearFit, offsets: NDArray[np.float64], x: NDArray[np.float64],
                   y: NDArray[np.float64], scale_cols: NDArray[np.float64] | None,
                   groups: NDArray[np.int64], counts: NDArray[np.float64],
                   temp: NDArray[np.float64], *, kind: str, n_centers: int, seed: int
                   ) -> tuple[LinearFit, NDArray[np.float64], dict | None]:
    """
    Validate the curve on held-out sessions; keep the offset only where it does no better.

    Parameters
    ----------
    fit : LinearFit
        The fit on every session (``groups``: ``coef[0]`` zero, ``offsets`` per session).
    offsets : NDArray[np.float64], shape (G, 3), rad/s
        The session offsets of ``fit`` (after refinement, when refined).
    x, y, scale_cols, groups
        The block rows of the fit: features (K, F), target (K, 3), scale columns (K, 3) or
        None, session of each row (K,).
    counts : NDArray[np.float64], shape (K,)
        Samples per block (the weights of the held-out means).
    temp : NDArray[np.float64], shape (K,), degC
        Block-mean model temperature.
    kind, n_centers, seed
        As the fit's (its ridge is kept).

    Returns
    -------
    fit : LinearFit
        ``fit`` with the curve, scale term and residual of the offset-only axes replaced.
    offsets : NDArray[np.float64], shape (G, 3)
        Offsets, each session's mean on the offset-only axes.
    record : dict or None
        ``folds``, ``blocks``, ``curve_ms_dps2`` and ``offset_ms_dps2`` (held-out mean squares
        per axis, each session re-anchored), ``worse_folds`` (per axis, the held-out sessions
        the curve predicts worse) and ``offset_only`` (axis names); None when no
        session overlaps the others' temperatures or the model has no curve.

    """
    folds = Folds.sessions(groups, temp)
    if not len(folds) or not x.shape[1]:        # no session to judge on, or no curve
        return fit, offsets, None

    def curve(test: NDArray[np.bool_], train: NDArray[np.bool_]) -> NDArray[np.float64]:
        f = fit_linear(x[train], y[train], kind=kind, n_centers=n_centers, ridge=fit.ridge,
                       seed=seed, groups=groups[train],
                       scale_cols=None if scale_cols is None else scale_cols[train])
        return f.predict(x[test], None if scale_cols is None else scale_cols[test]) - y[test]

    shape, scored = y.shape, np.any(np.stack(folds.test), axis=0)

    def mean_square(r: NDArray[np.float64], m: NDArray[np.bool_]) -> NDArray[np.float64]:
        w = counts[m][:, None]
        return (w * r[m] ** 2).sum(axis=0) / w.sum()

    r_curve = heldout(curve, folds, shape, groups=groups, weights=counts)
    r_offset = heldout(lambda test, train: -y[test], folds, shape, groups=groups,
                       weights=counts)
    ms_curve, ms_offset = mean_square(r_curve, scored), mean_square(r_offset, scored)
    # Every held-out power cycle must be predicted better: a curve that misses one of a few
    # power cycles is as likely to miss the next one.
    worse = np.sum([~(mean_square(r_curve, t) < mean_square(r_offset, t)) for t in folds.test],
                   axis=0)
    drop = np.flatnonzero(~(ms_curve < ms_offset) | (worse > 0))
    record = {'folds': len(folds), 'blocks': int(np.count_nonzero(scored)),
              'curve_ms_dps2': [float(v) for v in ms_curve * _DEG2],
              'offset_ms_dps2': [float(v) for v in ms_offset * _DEG2],
              'worse_folds': [int(v) for v in worse],
              'offset_only': [_AXES[a] for a in drop]}
    if not drop.size:
        return fit, offsets, record
    means, centred = within(y, groups)
    coef, scale, resid = fit.coef.copy(), fit.scale.copy(), fit.resid.copy()
    offsets = offsets.copy()
    coef[:, drop], scale[drop] = 0.0, 0.0
    offsets[:, drop] = means[:, drop]
    resid[:, drop] = -centred[:, drop]
    return replace(fit, coef=coef, scale=scale, resid=resid,
                   sse=float((resid ** 2).sum())), offsets, record


def session_check_lines(record: dict | None) -> list[str]:
    """Return the report lines of a held-out session check (empty without one)."""
    if not record:
        return []
    out = [f"the curve held out on each power cycle ({record['folds']} sessions, "
           f"{record['blocks']} blocks inside the others' temperatures, re-anchored), "
           'mean square, (deg/s)^2:',
           '  curve        ' + '  '.join(f'{v:10.3g}' for v in record['curve_ms_dps2']),
           '  offset only  ' + '  '.join(f'{v:10.3g}' for v in record['offset_ms_dps2'])]
    if 'worse_folds' in record:
        out.append('  power cycles predicted worse by the curve: '
                   + '  '.join(f'{v:d}' for v in record['worse_folds']))
    if record['offset_only']:
        out.append(f"axes {', '.join(record['offset_only'])}: the curve does not predict "
                   'every held-out power cycle better than its offset alone; the model keeps '
                   'the offset only there (re-anchoring still applies)')
    return out


def _anchor(t: NDArray[np.float64], e: NDArray[np.float64], var: NDArray[np.float64],
            paused: bool = False) -> NDArray[np.float64]:
    """Return the node's start-up shift of the error ``e`` (rad/s) from its first sample on."""
    end = int(np.searchsorted(t, t[0] + STILL_WINDOW_MAX_S + 2.0 * STILL_WINDOW_S, 'right'))
    return np.asarray(reanchor_shift(t[:end], e[:end], tolerance=default_tolerance(var),
                                     paused=paused).delta)


def _sessions(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int],
              lo: float = -math.inf, hi: float = math.inf, rows: Sequence | None = None) -> dict:
    """
    Return per session label its runs' (stamps, error) inside ``lo .. hi`` model degC.

    ``rows`` (a mask per run, or None: every sample) keeps the still rows only, compensated
    over every sample (the thermal state runs through the motion). A run longer than
    :data:`MAX_ROWS` is averaged over blocks of consecutive samples first: an anchor is a
    mean, and a block mean's scatter keeps its standard error.
    """
    out: dict = {}
    for i, (run, g) in enumerate(zip(runs, labels)):
        arrays = (run.t, run.temp, run.omega, run.omega_ref)
        if rows is None:                  # block means first: a long run stays cheap
            k = -(-len(run) // MAX_ROWS)
            (t, temp, omega, ref), m, k = (block_mean(a, k) for a in arrays), slice(None), 1
        else:
            (t, temp, omega, ref), m = arrays, np.asarray(rows[i], dtype=bool)
            k = max(1, -(-np.count_nonzero(m) // MAX_ROWS))
        c = compensate(model, t, temp, omega, out_of_range=DEFAULT_OUT_OF_RANGE)
        t, e, mt = (block_mean(a[m], k) for a in (t, c - ref, model_temperature(model, t, temp)))
        keep = (mt >= lo) & (mt <= hi)
        if np.count_nonzero(keep) >= 2:
            out.setdefault(int(g), []).append((t[keep], e[keep]))
    return out


def _anchor_error(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int],
                  rows: Sequence | None = None) -> NDArray[np.float64]:
    """
    Return the RMS error (rad/s) of start-up anchors taken throughout the training data.

    One anchor from each burst or still stretch (after a pause over the still window) and
    one every longest averaging within it, each against its session's mean error.
    """
    errs = []
    for parts in _sessions(model, runs, labels, rows=rows).values():
        level = np.concatenate([e for _, e in parts]).mean(axis=0)
        for t, e in parts:
            pause = np.flatnonzero(np.diff(t) > STILL_WINDOW_S) + 1
            for a, b in zip(np.r_[0, pause], np.r_[pause, t.size]):
                for j in np.unique(np.searchsorted(t[a:b], np.arange(
                        t[a], t[b - 1], STILL_WINDOW_MAX_S)) + a):
                    errs.append((t, e, int(j), bool(pause.size and j >= pause[0]), level))
    if len(errs) > MAX_ANCHORS:
        errs = [errs[i] for i in np.linspace(0, len(errs) - 1, MAX_ANCHORS).round().astype(int)]
    d = [_anchor(t[j:], e[j:], model.residual_var, paused) - level
         for t, e, j, paused, level in errs if t.size - j >= 2]
    return np.sqrt(np.mean(np.square(d), axis=0)) if d else np.zeros(3)


def _held_out(model: CompensationModel, runs: Sequence[Run], labels: NDArray[np.int64],
              gate: NDArray[np.float64], refit, rows: Sequence | None = None
              ) -> tuple[int, NDArray[np.float64]]:
    """
    Return the sessions held out and the mean square of their mean errors (3 choices, 3 axes).

    Each session predicted by ``refit`` on the others, inside their temperature range, and
    re-anchored at its start by the node's rule: any shift, beyond ``gate``, none; ``rows``
    (a mask per run) keeps the still rows only, in the refit (``rows=``) and the scoring.
    """
    ss, n_all, held = np.zeros((3, 3)), 0.0, 0
    for test, train in Folds.sessions(labels):
        def pick(items: Sequence, on: NDArray[np.bool_]) -> list:
            return [v for v, k in zip(items, on) if k]

        kw = {} if rows is None else {'rows': pick(rows, train)}
        try:
            m = refit(pick(runs, train), labels[train].tolist(), **kw)
        except FitError:
            continue                      # too little left without this session
        parts = _sessions(m, pick(runs, test), labels[test], *m.temp_range_c,
                          rows=None if rows is None else pick(rows, test))
        if not parts:
            continue
        (session,) = parts.values()
        e_all = np.concatenate([e for _, e in session])
        mean, n = e_all.mean(axis=0), e_all.shape[0]
        s = _anchor(*session[0], m.residual_var)
        for i, shift in enumerate((s, np.where(np.abs(s) > gate, s, 0.0), np.zeros(3))):
            ss[i] += n * (mean - shift) ** 2
        n_all += n
        held += 1
    return held, ss / max(n_all, 1.0)


def reanchor_rule(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int],
                  refit: Callable[..., CompensationModel], rows: Sequence | None = None
                  ) -> CompensationModel:
    """
    Decide per axis the smallest start-up shift the node takes; record it in the model.

    Parameters
    ----------
    model : CompensationModel
        The model fitted on ``runs``.
    runs : sequence of Run
        Its training runs (constant axes neutral).
    labels : sequence of int
        Session label per run.
    refit : callable
        ``refit(runs, labels)``: ``model``'s form fitted on other runs (a held-out session's
        others); with ``rows``, ``refit(runs, labels, rows=masks)``.
    rows : sequence of bool arrays, optional
        The samples of each run the model was fitted on (``train --still-only``: the still
        rows); None: every sample.

    Returns
    -------
    CompensationModel
        ``model`` with ``metrics['reanchor']``: ``anchor_error_dps`` (RMS error of start-up
        anchors taken throughout the data), ``min_shift_dps`` (0: any shift), ``sessions``,
        ``held_out`` and, with two held out or more, ``always_dps``, ``gated_dps`` and
        ``never_dps`` (RMS over the held-out sessions of their mean error re-anchored with
        any shift, beyond the gate, never). Held out, the gate is kept on an axis where it
        did better than any shift; without, it is kept (one session cannot show that a
        shift within the anchors' own error is a turn-on offset).

    """
    labels = np.asarray(labels, dtype=np.int64)
    gate = SIGNIFICANCE * _anchor_error(model, runs, labels, rows)
    rec = {'sessions': int(np.unique(labels).size), 'held_out': 0,
           'anchor_error_dps': (gate / SIGNIFICANCE * _DEG).tolist()}
    if rec['sessions'] >= 2:
        held, ms = _held_out(model, runs, labels, gate, refit, rows)
        rec['held_out'] = held
        if held >= 2:
            rms = np.sqrt(ms) * _DEG
            rec.update(always_dps=rms[0].tolist(), gated_dps=rms[1].tolist(),
                       never_dps=rms[2].tolist())
            gate = np.where(ms[1] < ms[0], gate, 0.0)
    rec['min_shift_dps'] = (gate * _DEG).tolist()
    return model.replace(metrics={**model.metrics, REANCHOR_KEY: rec})


def reanchor_lines(record: dict | None) -> list[str]:
    """Return the report lines of the re-anchoring decision (empty without one)."""
    if not record:
        return []
    row = '  '.join(f'{v:10.3g}' for v in record['anchor_error_dps'])
    out = [f'start-up anchors taken throughout the training data err by (RMS, deg/s) {row}']
    if 'always_dps' in record:
        out += [f"held out on {record['held_out']} power cycles (each predicted by the model "
                'fitted on the others, re-anchored at its start), RMS of their mean error, deg/s:',
                *(f'  {k:<22}' + '  '.join(f'{v:10.3g}' for v in record[f'{k.split()[0]}_dps'])
                  for k in ('always (any shift)', 'gated (beyond the gate)', 'never'))]
    for a, v, e in zip(_AXES, record['min_shift_dps'], record['anchor_error_dps']):
        if v > 0:
            out.append(f'axis {a}: the node re-anchors only beyond {v:.3g} deg/s '
                       f"({SIGNIFICANCE:g} x its anchors' error: a smaller start-up shift is no "
                       'evidence of a turn-on offset)')
        else:
            out.append(f'axis {a}: the node re-anchors any start-up shift')
    return out
