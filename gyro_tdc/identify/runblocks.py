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
The trainer's view of a run on the block grid: block means, scatter, features, thermal state.

:class:`RunBlocks` reduces one run to block means (over the rows that count) on
:class:`gyro_tdc.signal.BlockGrid`; :func:`run_state` holds each run's full-rate thermal
state once for the gyro fit and the accelerometer part.
"""

from __future__ import annotations

from typing import Mapping, Sequence
import weakref

from gyro_tdc.data import Run
from gyro_tdc.model import batch_features, ThermalState
from gyro_tdc.signal import block_mean, BlockGrid
import numpy as np
from numpy.typing import NDArray

__all__ = ['block_groups', 'run_state', 'RunBlocks']


# Full-rate thermal states by run, while the run lives (a weak reference to it: a run
# dropped drops its state): fit_model's are the accelerometer part's.
_STATES: dict[int, tuple[weakref.ref, tuple, NDArray[np.float64]]] = {}
_STATES_KEPT = 8


def run_state(thermal: ThermalState, run: Run) -> NDArray[np.float64]:
    """
    Return ``thermal.temperature(run.t, run.temp)``, computed once per run and front end.

    The result is read-only (shared by the callers: the fit and the accelerometer part).
    """
    key = (thermal.kind, tuple(float(v) for v in thermal.tau_s), id(run.t), id(run.temp))
    hit = _STATES.get(id(run))
    if hit is not None and hit[0]() is run and hit[1] == key:
        return hit[2]
    state = thermal.temperature(run.t, run.temp)
    state.flags.writeable = False
    rid = id(run)
    _STATES.pop(rid, None)
    _STATES[rid] = (weakref.ref(run, lambda _ref, rid=rid: _STATES.pop(rid, None)), key, state)
    while len(_STATES) > _STATES_KEPT:
        _STATES.pop(next(iter(_STATES)))
    return state


class RunBlocks:
    """
    Block means of one run: stamps, temperature, drift target and reference rate.

    With ``rows`` (the samples that count, e.g. the still ones of ``train --still-only``)
    every mean but the stamps' and the temperature's is over those rows only and the blocks
    without any are dropped; the filters (thermal state, dT/dt, warm-up) still run over every
    sample, so the die temperature evolves through the rows that do not count.
    """

    def __init__(self, run: Run, block: int, rows: NDArray[np.bool_] | None = None) -> None:
        self.run = run
        self.block = block
        self.t = block_mean(run.t, block)
        self.temp = block_mean(run.temp, block)
        # A chamber run has no reference rate: skip subtracting and averaging its zeros (the
        # same numbers: x - 0 is x, and the block means of zeros are zeros).
        self.has_ref = bool(np.any(run.omega_ref))
        err = run.omega - run.omega_ref if self.has_ref else run.omega
        self.grid = BlockGrid(len(run), block, rows=rows)
        self.rows, self.counts = self.grid.rows, self.grid.counts
        e = err if self.rows is None else err[self.rows]
        self.ss_raw = np.einsum('ij,ij->j', e, e)
        self.y = self.mean(err)
        self.ref = self.mean(run.omega_ref) if self.has_ref else np.zeros(self.y.shape)
        self.ss_within = self.grid.scatter(err, self.y)

    def sel(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the rows of ``x`` (one per block) of the blocks kept."""
        return self.grid.sel(x)

    def mean(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the block means of ``x`` (N, ...) over the rows that count."""
        return self.grid.mean(x)

    def state(self, thermal: ThermalState) -> NDArray[np.float64]:
        """Return the thermal state at full rate (N,), degC."""
        return run_state(thermal, self.run)

    def scatter(self, scale: NDArray[np.float64], t0: float,
                state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return, per block, the sum of squared deviations from the block mean (per axis).

        The error is taken after removing the sensitivity term ``scale * dT * omega_ref``
        (``dT`` of the full-rate ``state``, or of the measured temperature), which changes
        within a block when the rate table steps.
        """
        err = self.run.omega - self.run.omega_ref if self.has_ref else self.run.omega
        if np.any(scale):
            temp = self.run.temp if state is None else state
            err = err - (temp - t0)[:, None] * self.run.omega_ref * scale
        return self.grid.scatter(err, self.mean(err))

    def features(self, ids: Sequence[str], t0: float, params: Mapping, *,
                 exact: bool, thermal: ThermalState,
                 state: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """
        Return block-mean features with the model temperature of ``thermal``.

        ``exact`` computes them at full rate first (with the full-rate ``state`` when
        given); else from the block means (the parameter search).
        """
        if exact and self.block > 1:
            run = self.run
            s = self.state(thermal) if state is None else state
            x = batch_features(ids, run.t, run.temp, t0=t0, params=params, state=s)
            return self.mean(x)
        return self.sel(batch_features(ids, self.t, self.temp, t0=t0, params=params,
                                       state=thermal.temperature(self.t, self.temp)))

    def scale_cols(self, t0: float, state: NDArray[np.float64] | None = None,
                   thermal: ThermalState | None = None) -> NDArray[np.float64]:
        """
        Return block means of ``dT * omega_ref`` (N, 3).

        ``dT`` of the full-rate ``state`` (exact), else with ``thermal`` of the block-mean
        state times the block-mean rate (the parameter search; the temperature is slow).
        """
        if thermal is not None:
            return (self.sel(thermal.temperature(self.t, self.temp)) - t0)[:, None] * self.ref
        d = (self.run.temp if state is None else state) - t0
        return self.mean(d[:, None] * self.run.omega_ref)


def block_groups(blocks: Sequence[RunBlocks], labels: Sequence[int] | None
                 ) -> NDArray[np.int64] | None:
    """Return the session of every block row (None: one session)."""
    if labels is None:
        return None
    return np.concatenate([np.full(b.y.shape[0], g, dtype=np.int64)
                           for b, g in zip(blocks, labels)])
