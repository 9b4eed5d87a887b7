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
Leave one session out: whether the thermal curve carries to a power cycle not fitted on.

:func:`validate_curve` refits the model without each session in turn (the same features,
thermal state and options, one offset per session), predicts the held-out session and
applies :mod:`gyro_tdc.model.no_harm`'s rule per axis: the curve is kept where it beats the
offset alone, and re-anchoring where it beats the model's offset. See
``doc/internals/identify.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.fit import fit_model
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.model import (compensate, CompensationModel, curve_kept, DEFAULT_OUT_OF_RANGE,
                            HELD_OUT_KEY, model_temperature, offset_only,
                            reanchor_kept, REANCHOR_SIGNIFICANCE)
from gyro_tdc.runtime import default_tolerance, reanchor_shift, STILL_WINDOW_MAX_S
from gyro_tdc.signal import STILL_WINDOW_S
import numpy as np
from numpy.typing import NDArray

__all__ = ['BLOCK_S', 'block_length', 'HeldOut', 'MAX_ANCHORS', 'validate_curve']

#: Errors are judged on means over blocks of this long (within a still stretch or a burst;
#: an eighth of a shorter session): the drift, not the white noise.
BLOCK_S = 60.0
#: Start-up anchors tried within one session at most (the anchor error of one session).
MAX_ANCHORS = 200
_DEG = 180.0 / math.pi
_AXES = ('x', 'y', 'z')
_NAN3 = (math.nan, math.nan, math.nan)


@dataclass
class HeldOut:
    """
    What leaving one session out showed, per axis, and what the model keeps.

    Parameters
    ----------
    sessions : int
        Sessions (power cycles) of the training data; fewer than two validate nothing.
    held_out : int
        Sessions predicted by a model fitted on the others.
    curve_ms, offset_ms : tuple of 3 float, (deg/s)^2
        Mean square of the held-out block means about each session's own mean, with the
        curve and with the offset alone (a constant: the raw rate).
    curve : tuple of 3 bool
        The axes that keep their curve (the others their offset only).
    reanchored_ms, kept_ms : tuple of 3 float, (deg/s)^2
        Mean square of the held-out block means re-anchored by the node's rule at the start
        of the session, and with the model's offset (the mean of the training sessions').
    reanchor : tuple of 3 bool
        The axes the node re-anchors.
    anchor_error_dps : tuple of 3 float, deg/s
        With one session: the RMS error of start-up anchors taken throughout it.
    reanchor_min_dps : tuple of 3 float, deg/s
        The smallest start-up shift the node takes per axis (0: any).
    constant : tuple of 3 bool
        Constant gyro axes (not fitted, not judged).

    """

    sessions: int
    held_out: int = 0
    curve_ms: tuple = _NAN3
    offset_ms: tuple = _NAN3
    curve: tuple = (True, True, True)
    reanchored_ms: tuple = _NAN3
    kept_ms: tuple = _NAN3
    reanchor: tuple = (True, True, True)
    anchor_error_dps: tuple = _NAN3
    reanchor_min_dps: tuple = (0.0, 0.0, 0.0)
    constant: tuple = field(default=(False, False, False))
    wins: tuple = (0, 0, 0)

    @property
    def validated(self) -> bool:
        """Return whether at least two sessions were each predicted from the others."""
        return self.held_out >= 2

    def to_dict(self) -> dict:
        """Return the record as plain types (``model.metrics['held_out']``, ``--json``)."""
        def vec(v):
            return [None if not math.isfinite(float(x)) else float(x) for x in v]

        return {'sessions': int(self.sessions), 'held_out': int(self.held_out),
                'validated': self.validated, 'block_s': BLOCK_S,
                'curve_ms_dps2': vec(self.curve_ms), 'offset_ms_dps2': vec(self.offset_ms),
                'curve': [bool(v) for v in self.curve],
                'curve_wins': [int(v) for v in self.wins],
                'reanchored_ms_dps2': vec(self.reanchored_ms), 'kept_ms_dps2': vec(self.kept_ms),
                'reanchor': [bool(v) for v in self.reanchor],
                'anchor_error_dps': vec(self.anchor_error_dps),
                'reanchor_min_dps': vec(self.reanchor_min_dps)}

    def lines(self) -> list[str]:
        """Return the report: the held-out figures per axis and what each axis keeps."""
        def row(label, ms):
            return f'  {label:<13}' + ''.join(
                f'{math.sqrt(v):>12.4g}' if math.isfinite(v) else f'{"-":>12}' for v in ms)

        live = [a for a, c in zip(_AXES, self.constant) if not c]
        if not self.validated:
            out = [f'thermal curve NOT validated across power cycles: {self.sessions} '
                   f'session(s), {self.held_out} held out (a session is held out where the '
                   "others' temperature range overlaps it; two are needed); the curve is kept "
                   f'on every axis ({", ".join(live)})']
            if any(v > 0 for v in self.reanchor_min_dps):
                err = ' '.join(f'{v:.3g}' for v in self.anchor_error_dps)
                least = ' '.join(f'{v:.3g}' for v in self.reanchor_min_dps)
                out.append(f'start-up re-anchoring within the session errs by {err} deg/s '
                           f'(x y z, RMS over anchors taken throughout it): the node shifts '
                           f'an axis only beyond {least} deg/s ({REANCHOR_SIGNIFICANCE:g} x; '
                           'a smaller shift is no evidence of a turn-on offset)')
            return out
        out = [f'held out across power cycles: each of {self.held_out} sessions predicted by '
               'the model fitted on the others, within their temperature range; RMS of '
               f'means over blocks of up to {BLOCK_S:g} s, deg/s:',
               f'  {"":<13}' + ''.join(f'{a:>12}' for a in _AXES),
               row('curve', self.curve_ms), row('offset only', self.offset_ms),
               row('re-anchored', self.reanchored_ms), row('not', self.kept_ms)]
        for a, c, keep, re, won in zip(_AXES, self.constant, self.curve, self.reanchor,
                                       self.wins):
            if c:
                continue
            what = ('curve kept (it predicts held-out power cycles better than its offset '
                    'alone' if keep else 'OFFSET ONLY: its curve does not predict held-out '
                    'power cycles better than a constant, so its curve terms are zeroed (')
            what += f'better in {won} of {self.held_out} sessions)'
            how = ('re-anchored at start-up' if re else 'NOT re-anchored (re-anchoring did '
                   "worse held out than the model's offset, in every session)")
            out.append(f'axis {a}: {what}; {how}')
        return out


def block_length(t: NDArray[np.float64]) -> float:
    """Return the block of a held-out session: :data:`BLOCK_S`, or an eighth of a short one."""
    span = float(t[-1] - t[0]) if t.size else 0.0
    return min(BLOCK_S, max(span / 8.0, 1e-9))


def _block_ss(t: NDArray[np.float64], e: NDArray[np.float64], block: float
              ) -> tuple[NDArray[np.float64], float]:
    """Return the sample-weighted sum of squared block means of ``e`` and its weight."""
    if t.size == 0:
        return np.zeros(3), 0.0
    seg = np.r_[0, np.cumsum(np.diff(t) > STILL_WINDOW_S)]
    first = np.r_[0, np.flatnonzero(np.diff(seg)) + 1]
    blk = np.floor((t - t[first][seg]) / block).astype(np.int64)
    key = seg * (int(blk.max()) + 1) + blk
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    means = np.stack([np.bincount(inv, weights=e[:, k]) for k in range(3)], axis=1)
    means /= cnt[:, None]
    return (cnt[:, None] * means ** 2).sum(axis=0), float(cnt.sum())


def _shift(t: NDArray[np.float64], x: NDArray[np.float64],
           var: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the node's start-up shift of ``x`` (rad/s) from its first sample on."""
    end = int(np.searchsorted(t, t[0] + STILL_WINDOW_MAX_S + 2.0 * STILL_WINDOW_S, 'right'))
    s = reanchor_shift(t[:end], x[:end], tolerance=default_tolerance(var))
    return np.asarray(s.delta, dtype=np.float64)


def _pieces(model: CompensationModel, runs: Sequence[Run],
            rows: Sequence[NDArray[np.bool_]] | None, idx: Sequence[int],
            in_range: bool = False) -> list:
    """
    Return (t, compensated error, raw error) on the rows that count of runs ``idx``.

    With ``in_range``, only the rows whose model temperature lies in ``model``'s trained
    range count: whether a curve carries to another power cycle is judged where it was
    fitted (extrapolation is the range rules' business, and the final model's range holds
    every session).
    """
    out = []
    lo, hi = model.temp_range_c
    for i in idx:
        r = runs[i]
        sel = np.ones(len(r), dtype=bool) if rows is None else np.asarray(rows[i], dtype=bool)
        if in_range:
            temp = model_temperature(model, r.t, r.temp)
            sel = sel & (temp >= lo) & (temp <= hi)
        c = compensate(model, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE)
        t = r.t[sel]
        if t.size:
            out.append((t, (c - r.omega_ref)[sel], (r.omega - r.omega_ref)[sel]))
    return out


def _levels(runs, rows, labels: Sequence[int]) -> dict:
    """Return each session's mean raw error (rad/s) and its scatter about it, (rad/s)^2."""
    acc: dict = {}
    for i, (r, g) in enumerate(zip(runs, labels)):
        sel = slice(None) if rows is None else np.asarray(rows[i], dtype=bool)
        e = (r.omega - r.omega_ref)[sel]
        s, q, n = acc.get(g, (np.zeros(3), np.zeros(3), 0))
        acc[g] = (s + e.sum(axis=0), q + np.einsum('ij,ij->j', e, e), n + e.shape[0])
    return {g: (s / max(n, 1), q / max(n, 1) - (s / max(n, 1)) ** 2, n)
            for g, (s, q, n) in acc.items()}


def _anchor_errors(pieces: list, var_c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return start-up anchors' errors (A, 3) taken throughout one session (in-sample)."""
    level = np.concatenate([c for _, c, _ in pieces]).mean(axis=0)
    starts = []
    for k, (t, _, _) in enumerate(pieces):
        cut = np.r_[0, np.flatnonzero(np.diff(t) > STILL_WINDOW_S) + 1, t.size]
        for a, b in zip(cut[:-1], cut[1:]):
            # One start per stretch or burst, and one every longest averaging within it.
            ends = np.searchsorted(t[a:b], np.arange(t[a], t[b - 1], STILL_WINDOW_MAX_S))
            starts += [(k, int(a + j)) for j in np.unique(ends)]
    if len(starts) > MAX_ANCHORS:
        pick = np.linspace(0, len(starts) - 1, MAX_ANCHORS).round().astype(int)
        starts = [starts[i] for i in pick]
    errs = [_shift(pieces[k][0][j:], pieces[k][1][j:], var_c) - level for k, j in starts
            if pieces[k][0].size - j >= 2]
    return np.asarray(errs, dtype=np.float64).reshape(-1, 3)


def _refit(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int],
           rows: Sequence[NDArray[np.bool_]] | None, o: TrainOptions) -> CompensationModel:
    """Fit ``model``'s form (features, thermal state, T0, options) on other sessions."""
    return fit_model(runs, kind=model.kind, features=model.features, t0=model.t0_c,
                     n_centers=max(model.n_centers, 1) if model.kind == 'rbf' else o.n_centers,
                     refine=o.refine, fit_params=False, params=model.effect_params,
                     ridge=o.ridge, seed=o.seed, thermal=model.thermal, rows=rows,
                     sessions=labels)


def validate_curve(model: CompensationModel, runs: Sequence[Run], labels: Sequence[int], *,
                   options: TrainOptions | None = None,
                   rows: Sequence[NDArray[np.bool_]] | None = None,
                   constant: Sequence[bool] = (False, False, False)
                   ) -> tuple[CompensationModel, HeldOut]:
    """
    Validate a fitted model's curve across sessions and keep, per axis, what does no harm.

    Each session is held out in turn: the model's form is refitted on the others (features,
    thermal state and T0 of ``model``, one offset per session) and predicts it within the
    others' temperature range. The curve is judged against the offset alone with the
    held-out session's own mean removed (its offset re-estimated as its mean: what is left
    is the drift within the power cycle), pooled and session by session
    (:func:`gyro_tdc.model.no_harm.curve_kept`); re-anchoring (the node's rule from the
    session's first sample) against the model's offset. With one session nothing is
    validated: the curve is kept, and the anchors taken throughout the session give the
    smallest shift the node takes.

    Parameters
    ----------
    model : CompensationModel
        The model fitted on every session.
    runs : sequence of Run
        The runs it was fitted on (constant axes neutral), one session label each.
    labels : sequence of int
        Session label per run.
    options : TrainOptions, optional
        The training options (ridge, refinement, seed, centres).
    rows : sequence of NDArray[np.bool_], optional
        Per run, the samples that count (``--still-only``: the still rows).
    constant : sequence of 3 bool
        Constant gyro axes: not judged.

    Returns
    -------
    model : CompensationModel
        ``model`` with the offset-only axes' curve terms zeroed and ``metrics['held_out']``.
    held : HeldOut
        The figures and the decisions.

    """
    o = TrainOptions() if options is None else options
    labels = [int(v) for v in labels]
    const = np.asarray(constant, dtype=bool).reshape(3)
    groups = sorted(set(labels))
    levels = _levels(runs, rows, labels)
    held = HeldOut(sessions=len(groups), constant=tuple(bool(v) for v in const))
    if len(groups) < 2:
        pieces = _pieces(model, runs, rows, range(len(runs)))
        errs = _anchor_errors(pieces, model.residual_var) if pieces else np.zeros((0, 3))
        if errs.shape[0] >= 3:
            rms = np.sqrt(np.mean(errs ** 2, axis=0)) * _DEG
            held.anchor_error_dps = tuple(float(v) for v in rms)
            held.reanchor_min_dps = tuple(float(v) for v in
                                          np.where(const, 0.0, REANCHOR_SIGNIFICANCE * rms))
        return _record(model, held, levels, labels), held
    ss = {k: np.zeros(3) for k in ('curve', 'offset', 're_c', 'kept_c', 're_o', 'kept_o')}
    weight = 0.0
    per: list = []
    anchors: list = []
    for g in groups:
        train = [i for i, v in enumerate(labels) if v != g]
        test = [i for i, v in enumerate(labels) if v == g]
        try:
            m = _refit(model, [runs[i] for i in train], [labels[i] for i in train],
                       None if rows is None else [rows[i] for i in train], o)
        except FitError:
            continue           # too little left to fit without this session
        pieces = _pieces(m, runs, rows, test, in_range=True)
        if not pieces:
            continue
        others = [levels[v] for v in groups if v != g]
        level = np.mean([lv[0] for lv in others], axis=0)
        var_o = np.mean([lv[1] for lv in others], axis=0)
        t0, c0, r0 = pieces[0]
        shift_c, shift_o = _shift(t0, c0, m.residual_var), _shift(t0, r0 - level, var_o)
        mean_c = np.concatenate([c for _, c, _ in pieces]).mean(axis=0)
        mean_r = np.concatenate([r for _, _, r in pieces]).mean(axis=0)
        block = max(block_length(t) for t, _, _ in pieces)
        mine = {k: np.zeros(3) for k in ss}
        for t, c, r in pieces:
            for key, e in (('curve', c - mean_c), ('offset', r - mean_r),
                           ('re_c', c - shift_c), ('kept_c', c),
                           ('re_o', r - level - shift_o), ('kept_o', r - level)):
                s, n = _block_ss(t, e, block)
                mine[key] += s
            weight += n           # the same blocks for every key
        for key in ss:
            ss[key] += mine[key]
        per.append((mine['curve'], mine['offset']))
        anchors.append(mine)
        held.held_out += 1
    if held.held_out:
        ms = {k: v / max(weight, 1.0) * _DEG ** 2 for k, v in ss.items()}
        held.wins = tuple(int(v) for v in np.sum([c < o for c, o in per], axis=0))
        held.curve_ms = tuple(float(v) for v in ms['curve'])
        held.offset_ms = tuple(float(v) for v in ms['offset'])
    if held.validated:          # one session held out decides nothing
        keep = curve_kept(ms['curve'], ms['offset'], per) | const
        held.curve = tuple(bool(v) for v in keep)
        re = np.where(keep, ms['re_c'], ms['re_o'])
        kept = np.where(keep, ms['kept_c'], ms['kept_o'])
        held.reanchored_ms = tuple(float(v) for v in re)
        held.kept_ms = tuple(float(v) for v in kept)
        each = [(np.where(keep, a['re_c'], a['re_o']), np.where(keep, a['kept_c'], a['kept_o']))
                for a in anchors]
        held.reanchor = tuple(bool(v) for v in (reanchor_kept(re, kept, each) | const))
    return _record(model, held, levels, labels), held


def _record(model: CompensationModel, held: HeldOut, levels: dict, labels: Sequence[int]
            ) -> CompensationModel:
    """Return ``model`` with the offset-only axes applied and the record in its metrics."""
    flat = ~np.asarray(held.curve, dtype=bool)
    met = dict(model.metrics)
    if flat.any():
        groups = sorted(levels)
        level = np.mean([levels[g][0] for g in groups], axis=0)
        n = np.array([levels[g][2] for g in groups], dtype=np.float64)
        var = np.average([levels[g][1] for g in groups], axis=0, weights=np.maximum(n, 1.0))
        model = offset_only(model, flat, level=level, residual_var=var)
        for key in ('train_bs_dps2', 'train_rms_dps'):
            if key in met:
                v = var * _DEG ** 2 if key == 'train_bs_dps2' else np.sqrt(var) * _DEG
                met[key] = [float(b) if f else float(a) for a, b, f in zip(met[key], v, flat)]
        info = met.get('sessions')
        if isinstance(info, dict) and 'offset_dps' in info:
            rel = [(levels[g][0] - level) * _DEG for g in groups]
            off = np.array([np.where(flat, r, o) for r, o in zip(rel, info['offset_dps'])])
            met['sessions'] = dict(info, offset_dps=off.tolist(),
                                   spread_dps=(off.max(axis=0) - off.min(axis=0)).tolist())
    met[HELD_OUT_KEY] = held.to_dict()
    return model.replace(metrics=met)
