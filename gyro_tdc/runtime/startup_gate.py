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
How large a start-up shift the node takes per axis, decided on the data a model was fitted on.

:func:`reanchor_rule` measures the error of start-up anchors taken throughout the data (the
node's rule, :func:`~gyro_tdc.runtime.reanchor.reanchor_shift`) and, with two sessions held
out or more, keeps the gate (:data:`SIGNIFICANCE` times that error) on an axis only where it
did better than any shift. One rule for what ``train`` fits
(:mod:`gyro_tdc.identify.power_cycles`) and what the learner installs (:mod:`gyro_tdc.learn`);
:func:`~gyro_tdc.runtime.reanchor.gated_shift` applies it.
"""

from __future__ import annotations

from itertools import compress
import math
from typing import Callable, Sequence

from gyro_tdc.base import DEG_PER_RAD
from gyro_tdc.model import compensate, CompensationModel, DEFAULT_OUT_OF_RANGE, model_temperature
from gyro_tdc.runtime.blockstats import default_tolerance, STILL_WINDOW_MAX_S
from gyro_tdc.runtime.reanchor import REANCHOR_KEY, reanchor_shift
from gyro_tdc.signal import block_mean, Folds, STILL_WINDOW_S
import numpy as np
from numpy.typing import NDArray

__all__ = ['MAX_ANCHORS', 'MAX_ROWS', 'reanchor_rule', 'SIGNIFICANCE']

#: A gated node takes a start-up shift on an axis only beyond this many times the RMS error
#: of start-up anchors taken throughout the training data.
SIGNIFICANCE = 2.0
#: Start-up anchors tried over the training data at most (evenly picked).
MAX_ANCHORS = 100
#: Rows per run the anchors are taken on at most (longer runs are block-averaged).
MAX_ROWS = 50_000


def _anchor(t: NDArray[np.float64], e: NDArray[np.float64], var: NDArray[np.float64],
            paused: bool = False) -> NDArray[np.float64]:
    """Return the node's start-up shift of the error ``e`` (rad/s) from its first sample on."""
    end = int(np.searchsorted(t, t[0] + STILL_WINDOW_MAX_S + 2.0 * STILL_WINDOW_S, 'right'))
    return np.asarray(reanchor_shift(t[:end], e[:end], tolerance=default_tolerance(var),
                                     paused=paused).delta)


def _sessions(model: CompensationModel, runs: Sequence, labels: Sequence[int],
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
        if np.count_nonzero(keep := (mt >= lo) & (mt <= hi)) >= 2:
            out.setdefault(int(g), []).append((t[keep], e[keep]))
    return out


def _anchor_error(model: CompensationModel, runs: Sequence, labels: Sequence[int],
                  rows: Sequence | None = None) -> NDArray[np.float64]:
    """
    Return the RMS error (rad/s) of start-up anchors taken throughout the training data.

    One anchor from each burst, still stretch or point (after a pause over the still window) and
    one every longest averaging within it, each against its session's mean error.
    """
    errs = []
    for parts in _sessions(model, runs, labels, rows=rows).values():
        level = np.concatenate([e for _, e in parts]).mean(axis=0)
        for t, e in parts:
            pause = np.flatnonzero(np.diff(t) > STILL_WINDOW_S) + 1
            for a, b in zip(np.r_[0, pause], np.r_[pause, t.size]):
                for j in np.unique(np.searchsorted(t[a:b], np.arange(
                        t[a], max(t[b - 1], t[a] + 1.0), STILL_WINDOW_MAX_S)) + a):
                    errs.append((t, e, int(j), bool(pause.size and j >= pause[0]), level))
    if len(errs) > MAX_ANCHORS:
        errs = [errs[i] for i in np.linspace(0, len(errs) - 1, MAX_ANCHORS).round().astype(int)]
    d = [_anchor(t[j:], e[j:], model.residual_var, paused) - level
         for t, e, j, paused, level in errs if t.size - j >= 2]
    return np.sqrt(np.mean(np.square(d), axis=0)) if d else np.zeros(3)


def _held_out(model: CompensationModel, runs: Sequence, labels: NDArray[np.int64],
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
        kw = {} if rows is None else {'rows': list(compress(rows, train))}
        if (m := refit(list(compress(runs, train)), labels[train].tolist(), **kw)) is None:
            continue                      # too little left without this session
        parts = _sessions(m, list(compress(runs, test)), labels[test], *m.temp_range_c,
                          rows=None if rows is None else list(compress(rows, test)))
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


def reanchor_rule(model: CompensationModel, runs: Sequence, labels: Sequence[int],
                  refit: Callable[..., CompensationModel], rows: Sequence | None = None
                  ) -> CompensationModel:
    """
    Decide per axis the smallest start-up shift the node takes; record it in the model.

    ``runs`` are ``model``'s training runs (as :class:`gyro_tdc.data.Run`, constant axes
    neutral) with a session label each; ``refit(runs, labels[, rows=masks])`` fits ``model``'s
    form on other runs (None when too little is left); ``rows`` the samples fitted on (None:
    all). Returns ``model`` with ``metrics['reanchor']``: ``anchor_error_dps`` (RMS error of
    start-up anchors), ``min_shift_dps`` (0: any shift), ``sessions``, ``held_out`` and, with
    two sessions held out or more, ``always_dps``, ``gated_dps``, ``never_dps`` (held-out RMS
    of the mean error re-anchored with any shift, beyond the gate, never). The gate is kept
    on an axis where, held out, it did better than any shift, and without a held-out session
    (one session cannot show that a shift within the anchors' error is a turn-on offset).
    """
    labels = np.asarray(labels, dtype=np.int64)
    gate = SIGNIFICANCE * _anchor_error(model, runs, labels, rows)
    rec = {'sessions': int(np.unique(labels).size), 'held_out': 0,
           'anchor_error_dps': (gate / SIGNIFICANCE * DEG_PER_RAD).tolist()}
    if rec['sessions'] >= 2:
        rec['held_out'], ms = _held_out(model, runs, labels, gate, refit, rows)
        if rec['held_out'] >= 2:
            rms = np.sqrt(ms) * DEG_PER_RAD
            rec.update(always_dps=rms[0].tolist(), gated_dps=rms[1].tolist(),
                       never_dps=rms[2].tolist())
            gate = np.where(ms[1] < ms[0], gate, 0.0)
    rec['min_shift_dps'] = (gate * DEG_PER_RAD).tolist()
    return model.replace(metrics={**model.metrics, REANCHOR_KEY: rec})
