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
The start-up shift gate of a learned model: the trainer's rule on the learner's still data.

:func:`learned_gate` applies :func:`gyro_tdc.runtime.startup_gate.reanchor_rule` to the point
table: each power cycle (the table's session) a run of its points in time order, a held-out
power cycle predicted by the learner's fit of the others' points. With one power cycle the
gate is kept, as the trainer keeps it: one cycle cannot show that a shift within its
anchors' error is a turn-on offset.
"""

from __future__ import annotations

from typing import Callable

from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.fit import at_state, model_of
from gyro_tdc.model import CompensationModel, ThermalState
from gyro_tdc.runtime import REANCHOR_KEY, reanchor_rule
import numpy as np
from numpy.typing import NDArray

__all__ = ['learned_gate', 'PointRun']


class PointRun:
    """One power cycle's rows of the point table, as a run of still means (rad/s, degC)."""

    def __init__(self, rows: NDArray[np.float64]) -> None:
        self.rows = rows
        #: Stamps (the points' ends), model temperatures and still means (N, 3).
        self.t, self.temp, self.omega = rows[:, 0], rows[:, 2], rows[:, 3:6]
        #: The reference rate: zero while still.
        self.omega_ref = np.zeros_like(self.omega)

    def __len__(self) -> int:
        """Return the number of points."""
        return self.rows.shape[0]


def learned_gate(model: CompensationModel, e: NDArray[np.float64],
                 fit_table: Callable[[NDArray[np.float64]], dict],
                 thermal: ThermalState | None,
                 prior: CompensationModel | None = None) -> dict:
    """
    Return the start-up shift record of a learned model (``metrics['reanchor']``).

    ``e`` is the point table it was fitted on (:meth:`gyro_tdc.learn.Learner.entries`),
    ``fit_table`` the learner's fit of a point table (a held-out power cycle's others),
    ``thermal`` the front end the points were binned with, ``prior`` the model a
    correction fit is learned over (:func:`gyro_tdc.learn.fit.model_of`).
    """
    labels = np.unique(e[:, 6])         # one run per power cycle, in time order
    runs = [PointRun(p[np.argsort(p[:, 0], kind='stable')])
            for p in (e[e[:, 6] == g] for g in labels)]

    def refit(others: list, g: list) -> CompensationModel | None:
        try:
            return at_state(model_of(fit_table(np.vstack([r.rows for r in others])), thermal,
                                     prior))
        except (ModelFileError, ValueError, np.linalg.LinAlgError):
            return None                   # too little left without this power cycle

    rule = reanchor_rule(at_state(model), runs, labels.astype(int).tolist(), refit)
    return rule.metrics[REANCHOR_KEY]
