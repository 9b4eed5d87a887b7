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
The learner's prediction check: whether a candidate predicts the recent still time better.

Pure (numpy only): :func:`compare` scores a candidate and the current model on the recent
windows and decides the swap; :func:`offset_until` says whose still time a candidate's
offset comes from.
"""

from __future__ import annotations

import math

from gyro_tdc.learn.fit import predict_windows, window_error
from gyro_tdc.model import CompensationModel, ThermalState
import numpy as np
from numpy.typing import NDArray

__all__ = ['compare', 'offset_until', 'SWAP_CHANGE']

#: A candidate is swapped in only when its prediction over the recent windows differs from
#: the current model's by this fraction of the gyro noise floor (RMS, rad/s) or more.
SWAP_CHANGE = 0.02


def compare(cand: CompensationModel, current: CompensationModel | None,
            rows: NDArray[np.float64], thermal: ThermalState | None, anchor: float | None,
            floor: float) -> tuple[float, float | None, bool]:
    """
    Return the candidate's and the current model's error on ``rows`` and whether to swap.

    ``rows`` are windows ``[n, temp, bx, by, bz, t_end]``, ``anchor`` the stamp the error's
    offset is taken after (:func:`gyro_tdc.learn.fit.window_error`). A candidate is swapped
    in when better on the recent still time and different enough to matter: an RMS change
    of :data:`SWAP_CHANGE` noise floors ``floor`` (rad/s; a long stop refits every few
    minutes, each install replays the model's filters); always without a current model.
    """
    pred = predict_windows(cand, rows, thermal)
    new = window_error(rows, pred, anchor)
    if current is None:
        return new, None, True
    cur = predict_windows(current, rows, thermal)
    old = window_error(rows, cur, anchor)
    change = (float(np.sqrt(np.average(((pred - cur) ** 2).mean(axis=1), weights=rows[:, 0])))
              if rows.shape[0] else math.inf)
    return new, old, new < old and not change < SWAP_CHANGE * floor


def offset_until(rows: NDArray[np.float64], since: float, recent: bool,
                 entries: NDArray[np.float64], session: int) -> float | None:
    """
    Return the stamp of the newest still time a candidate's offset comes from, or None.

    The newest of ``rows`` after ``since`` when the offset is theirs (``recent``), else the
    newest of the point table's ``entries`` (rows ``t_end, ..., session``) of ``session``
    (the fit's intercept of its newest session); None when it has none (the offset is an
    older session's).
    """
    if recent:
        new = rows[rows[:, 5] > since, 5]
        return float(new.max()) if new.size else None
    mine = entries[entries[:, 6] == session, 0]
    return float(mine.max()) if mine.size else None
