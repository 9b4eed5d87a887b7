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
The linear model discovery searches: per-run offsets, effect columns, gain and scale terms.

:class:`LinearModel` builds the design of one effect set on the block grid, fits it by
weighted least squares (on all blocks or a fold's training rows) and gives the held-out
residuals of cross-validation. See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from gyro_tdc.identify.discover.data import BlockData
from gyro_tdc.model import input_ids, THERMAL_EFFECTS
from gyro_tdc.signal import fit_columns, Folds, heldout
import numpy as np
from numpy.typing import NDArray

__all__ = ['LinearModel']


class LinearModel:
    """Design matrices, least squares, cross-validation and the HAC test for one effect set."""

    def __init__(self, data: BlockData, effects: Sequence[str],
                 params: Mapping[str, Mapping[str, float]], *,
                 extra: NDArray[np.float64] | None = None) -> None:
        self.data = data
        self.effects = tuple(effects)
        self.params = {k: dict(v) for k, v in params.items()}
        #: Time constant of the thermal state (s), None without ``lag``.
        state = bool(THERMAL_EFFECTS & set(self.effects))
        self.state_tau = float(self.params['lag']['tau_s']) if state else None
        self.inputs = input_ids(self.effects, state=state)
        self.labels = [f'offset:{r}' for r in range(data.n_runs)] + list(self.inputs)
        cols = [data.offsets] + [data.column(e, self.params, state_tau=self.state_tau)[:, None]
                                 for e in self.inputs]
        self.common = np.hstack(cols)
        ax = []
        self.axis_labels = []
        if np.any(data.gain_axes):
            ax.append(data.ref * data.gain_axes[None, :])
            self.axis_labels.append('gain')
        if 'scale' in self.effects:      # only on axes whose rate steps can separate it
            dtref = (data.dtref if self.state_tau is None
                     else data.state_columns(self.state_tau)['dtref'])
            ax.append(dtref * data.scale_axes[None, :])
            self.axis_labels.append('scale')
        if extra is not None:            # a per-axis column of its own (the J test)
            ax.append(np.asarray(extra, dtype=np.float64))
            self.axis_labels.append('extra')
        self.axis = np.stack(ax, axis=2) if ax else np.zeros((data.K, 3, 0))
        self.p = self.common.shape[1] + self.axis.shape[2]

    def columns_of(self, eid: str) -> list[int]:
        """
        Return the design columns that belong to effect ``eid``.

        ``lag`` has none: it changes the temperature columns instead (the thermal state).
        ``'extra'`` is the per-axis column given to the constructor.
        """
        if eid in ('scale', 'extra'):
            return [self.common.shape[1] + self.axis_labels.index(eid)]
        return [i for i, lab in enumerate(self.labels) if lab == eid]

    def design(self, a: int) -> NDArray[np.float64]:
        """Return the design matrix of axis ``a`` (K, p)."""
        return np.hstack([self.common, self.axis[:, a, :]])

    def fit(self, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Return the coefficients (p, 3) fitted on ``rows`` (all by default)."""
        d = self.data
        coef = np.zeros((self.p, 3))
        w = d.w if rows is None else d.w[rows]
        for a in range(3):
            x = self.design(a)
            y = d.y[:, a]
            if rows is not None:
                x, y = x[rows], y[rows]
            coef[:, a] = fit_columns(x, y, weights=w, normalise=True, rcond=1e-12)
        return coef

    def predict(self, coef: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the simulated block means (K, 3)."""
        return np.column_stack([self.design(a) @ coef[:, a] for a in range(3)])

    def residual(self, coef: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return measured minus simulated (K, 3), rad/s."""
        return self.data.y - self.predict(self.fit() if coef is None else coef)

    def sse(self) -> float:
        """Return the weighted sum of squared residuals over blocks and axes."""
        r = self.residual()
        return float((self.data.w[:, None] * r * r).sum())

    def cv_residual(self, folds: Folds) -> NDArray[np.float64]:
        """
        Return held-out residuals (K, 3): each block predicted by a fit without its fold.

        A run with no block in the training rows (leave-one-run-out) has no fitted offset;
        its held-out residual is re-anchored to zero mean (:func:`gyro_tdc.signal.heldout`).
        """
        d = self.data

        def residual(test: NDArray[np.bool_], train: NDArray[np.bool_]) -> NDArray[np.float64]:
            return d.y[test] - self.predict(self.fit(train))[test]

        return heldout(residual, folds, (d.K, 3), groups=d.run, weights=d.w)
