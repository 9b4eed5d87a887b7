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
Do no harm across power cycles: the per-axis rule a model records and the node obeys.

An axis keeps its thermal curve only where the curve predicted held-out power cycles better
than its offset alone; elsewhere the model compensates a constant (:func:`offset_only`).
Re-anchoring is recorded per axis too: off where it did worse than the model's offset held
out, and gated by the anchor error seen within a session when there was no other session to
hold out (:func:`gated_shift`, the node's one call). The trainer decides
(:mod:`gyro_tdc.identify.crossval`); the learner keeps the decision of its prior
(:func:`learned_coef`).
"""

from __future__ import annotations

import math
from typing import Sequence

from gyro_tdc.model.compensation import CompensationModel
import numpy as np
from numpy.typing import NDArray

__all__ = ['CURVE_MARGIN', 'curve_kept', 'gated_shift', 'HELD_OUT_KEY', 'learned_coef',
           'LOSS_SHARE', 'offset_only', 'REANCHOR_SIGNIFICANCE', 'reanchor_kept',
           'reanchor_rule']

#: The model's ``metrics`` key of the held-out figures and decisions.
HELD_OUT_KEY = 'held_out'
#: A curve is kept on an axis when its held-out mean square is below this times the offset's.
CURVE_MARGIN = 1.0
#: A held-out session where the curve's mean square exceeds the offset's by more than this
#: share of the sessions' median offset figure is a loss (a tie within it is none).
LOSS_SHARE = 0.1
#: With one session, a start-up shift is taken on an axis only beyond this many times the
#: anchor error seen within the training session (a smaller one is that session's wander).
REANCHOR_SIGNIFICANCE = 2.0


def curve_kept(curve_ms: Sequence[float], offset_ms: Sequence[float],
               sessions: Sequence | None = None, margin: float = CURVE_MARGIN
               ) -> NDArray[np.bool_]:
    """
    Return, per axis, whether the curve predicted held-out power cycles better than its offset.

    Pooled over the held-out sessions the curve must do better than the offset alone, and
    it must lose in no session (worse than the offset by more than :data:`LOSS_SHARE` of the
    sessions' median offset figure): a curve that beats the offset in some power cycles and
    loses in others does not carry; it fits the cycles it was fitted on.

    Parameters
    ----------
    curve_ms, offset_ms : sequence of 3 float
        Held-out mean squares with the curve and with the offset alone (any one unit).
    sessions : sequence of (curve_ms, offset_ms) pairs, optional
        The same per held-out session, shape (S, 2, 3).
    margin : float
        The pooled test is ``curve_ms < margin * offset_ms``.

    Returns
    -------
    NDArray[np.bool_], shape (3,)
        A NaN figure, or no drift within the held-out sessions (``offset_ms`` 0), judges
        nothing: the curve is kept.

    """
    c = np.asarray(curve_ms, dtype=np.float64).reshape(3)
    o = np.asarray(offset_ms, dtype=np.float64).reshape(3)
    judged = o > 0
    keep = ~((c >= margin * o) & judged)
    if sessions is not None and len(sessions):
        per = np.asarray(sessions, dtype=np.float64).reshape(-1, 2, 3)
        lost = per[:, 0] - per[:, 1] > LOSS_SHARE * np.median(per[:, 1], axis=0)
        keep &= ~(lost.any(axis=0) & judged)
    return keep


def reanchor_kept(reanchored_ms: Sequence[float], kept_ms: Sequence[float],
                  sessions: Sequence | None = None) -> NDArray[np.bool_]:
    """
    Return, per axis, whether start-up re-anchoring stays on (the default), held out.

    It is turned off only where it did worse than the model's offset pooled over the held-out
    sessions and in every one of them (by more than :data:`LOSS_SHARE` of their median
    figure without it): a turn-on offset that varies from one power cycle to the next makes
    re-anchoring win some, and one cycle's noise must not turn it off.

    Parameters
    ----------
    reanchored_ms, kept_ms : sequence of 3 float
        Held-out mean squares re-anchored and with the model's offset.
    sessions : sequence of (reanchored_ms, kept_ms) pairs, optional
        The same per held-out session, shape (S, 2, 3).

    Returns
    -------
    NDArray[np.bool_], shape (3,)

    """
    r = np.asarray(reanchored_ms, dtype=np.float64).reshape(3)
    k = np.asarray(kept_ms, dtype=np.float64).reshape(3)
    worse = r > k
    if sessions is not None and len(sessions):
        per = np.asarray(sessions, dtype=np.float64).reshape(-1, 2, 3)
        worse &= (per[:, 0] - per[:, 1] > LOSS_SHARE * np.median(per[:, 1], axis=0)).all(axis=0)
    return ~worse


def offset_only(model: CompensationModel, axes: Sequence[bool], *,
                level: Sequence[float] | None = None,
                residual_var: Sequence[float] | None = None) -> CompensationModel:
    """
    Return ``model`` with the curve terms of ``axes`` zeroed: a constant the node re-anchors.

    Parameters
    ----------
    model : CompensationModel
        The fitted model.
    axes : sequence of 3 bool
        True on the axes that keep their offset only.
    level : sequence of 3 float, optional
        The constant of those axes, rad/s (default: the intercept, the curve at T0).
    residual_var : sequence of 3 float, optional
        The residual variance of those axes about their offset, (rad/s)^2 (default: kept).

    Returns
    -------
    CompensationModel
        The linear tail, RBF weights and scale of those axes zero, their intercept ``level``.

    """
    a = np.asarray(axes, dtype=bool).reshape(3)
    if not a.any():
        return model
    linear, weights, scale = model.linear.copy(), model.weights.copy(), model.scale.copy()
    linear[:, a] = 0.0
    weights[:, a] = 0.0
    scale[a] = 0.0
    intercept = model.intercept.copy()
    if level is not None:
        intercept[a] = np.asarray(level, dtype=np.float64).reshape(3)[a]
    resid = np.asarray(model.residual_var, dtype=np.float64).copy()
    if residual_var is not None:
        resid[a] = np.asarray(residual_var, dtype=np.float64).reshape(3)[a]
    return model.replace(linear=linear, weights=weights, scale=scale, intercept=intercept,
                         residual_var=resid)


def reanchor_rule(model: CompensationModel | None
                  ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """
    Return the model's re-anchoring per axis: whether to shift, and the smallest shift (rad/s).

    A model without the held-out record (an older file, a fitted model not from ``train``)
    re-anchors every axis, any shift.
    """
    rec = None if model is None else model.metrics.get(HELD_OUT_KEY)
    on, least = np.ones(3, dtype=bool), np.zeros(3)
    if not isinstance(rec, dict):
        return on, least
    try:
        on = np.asarray(rec.get('reanchor', on), dtype=bool).reshape(3)
        least = np.asarray([np.nan if v is None else v for v in rec.get(
            'reanchor_min_dps', least)], dtype=np.float64).reshape(3) * (math.pi / 180.0)
    except (TypeError, ValueError):
        return np.ones(3, dtype=bool), np.zeros(3)
    return on, np.where(np.isfinite(least), least, 0.0)


def gated_shift(model: CompensationModel | None, delta: Sequence[float]) -> NDArray[np.float64]:
    """
    Return a start-up shift with the axes the model does not re-anchor zeroed (the node's call).

    Parameters
    ----------
    model : CompensationModel or None
        The model in use.
    delta : sequence of 3 float, rad/s
        The shift the still windows gave.

    Returns
    -------
    NDArray[np.float64], shape (3,), rad/s

    """
    d = np.asarray(delta, dtype=np.float64).reshape(3)
    on, least = reanchor_rule(model)
    return np.where(on & (np.abs(d) > least), d, 0.0)


def learned_coef(coef: Sequence[Sequence[float]], prior: CompensationModel | None
                 ) -> list[list[float]]:
    """
    Return a learned fit's coefficients under its prior's decision (the learner's one call).

    ``coef`` is the learner's (1 + F, 3) intercept-then-features table; on the axes the
    prior keeps offset-only every feature row is zeroed, so the learner installs no curve the
    trainer found to do harm across power cycles (the intercept, the offset, stays).
    """
    rec = None if prior is None else prior.metrics.get(HELD_OUT_KEY)
    out = [[float(v) for v in row] for row in coef]
    if not isinstance(rec, dict) or 'curve' not in rec:
        return out
    flat = ~np.asarray(rec['curve'], dtype=bool).reshape(3)
    for row in out[1:]:
        for a in np.flatnonzero(flat):
            row[a] = 0.0
    return out
