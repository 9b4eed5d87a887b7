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

"""What discovery may fit (never motion), and from a discovery to a compensation model file."""

from __future__ import annotations

from typing import Mapping, Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.axes import constant_gyro_axes, identity_axes, neutral_runs
from gyro_tdc.identify.discover.results import DiscoveryResult
from gyro_tdc.identify.fit import fit_model, MIN_SPAN_C
from gyro_tdc.identify.still_only import find_still, MAX_MOVING_SHARE, moving_share, rows_of
from gyro_tdc.model import TEMPERATURE_EFFECTS
import numpy as np

__all__ = ['build_model', 'model_features', 'still_only_runs']


def still_only_runs(runs: Sequence[Run], task: tuple[str, str] = ('discover', 'discovering')
                    ) -> tuple[list[Run], str | None]:
    """
    Return what discovery may fit of runs without a reference: the still samples only.

    Runs with no reference rate (a flight log) that move longer than ``train``'s
    :data:`~gyro_tdc.identify.still_only.MAX_MOVING_SHARE` are known to be at rest only
    while still: each keeps its still stretches (``train``'s still test, one noise floor for
    all, a constant axis at its reference), one offset per session as before; a session
    without still time is left out. Returns the runs and a line saying what was kept (None
    when every sample is kept). Motion is never fitted as drift. ``task`` words what is fitted
    in those lines ("no still stretch to TASK on", "DOING on the still stretches only").

    Raises
    ------
    FitError
        When no session holds a still stretch: nothing could be fitted but the motion.

    """
    if not runs or any(r.info.get('reference') != 'zero' for r in runs):
        return list(runs), None
    fitted = neutral_runs(runs, constant_gyro_axes(runs))
    share = moving_share(fitted)
    if share <= MAX_MOVING_SHARE:
        return list(runs), None
    masks = [st.mask for st in find_still(fitted)]
    kept = [rows_of(r, m) for r, m in zip(runs, masks) if np.count_nonzero(m) >= 16]
    moves = f'no reference rate and the IMU moves {100.0 * share:.3g} % of the time'
    if not kept:
        raise FitError(f'{moves}, with no still stretch to {task[0]} on (its motion is no '
                       'drift): record the vehicle parked with the IMU on.')
    still_s = sum(np.count_nonzero(m) * float(np.median(np.diff(r.t)))
                  for r, m in zip(runs, masks) if len(r) > 1)
    total_s = sum(r.duration_s for r in runs)
    pct = min(100.0 * still_s / total_s, 100.0) if total_s > 0 else 0.0
    return kept, (f'{moves}: {task[1]} on the still stretches only ({still_s:.0f} s of '
                  f'{total_s:.0f} s, {pct:.3g} %; {len(kept)} of {len(runs)} session(s)); '
                  'the motion is no drift')


def build_model(result: DiscoveryResult, runs: Sequence[Run], *, kind: str = 'poly',
                created: Mapping | None = None):
    """
    Fit the compensation model of the discovered effects, ready for ``save_model``.

    The per-run offsets and the constant scale-factor error :func:`discover` found in ``runs``
    (the runs of ``result``) are removed first: they are not thermal (the compensator
    re-anchors its offset at start-up; a rate-table gain error is a separate calibration).
    :func:`gyro_tdc.identify.fit_model` then fits the final effects with the fitted time
    constants and, with ``lag``, discovery's thermal state: a format 2 model whose every
    temperature term follows the state. ``kind``: ``'poly'`` (exactly the linear model
    discovery validated) or ``'rbf'``; ``created``: extra creation info. A constant gyro axis
    is passed through as ``train`` does (:func:`gyro_tdc.identify.axes.neutral_runs`).
    """
    if len(runs) != len(result.runs):
        raise FitError(f'Expected the {len(result.runs)} runs discovery analysed, '
                       f'got {len(runs)}.')
    off = np.asarray(result.coef['offsets'])
    mean_off = off.mean(axis=0)
    gain = np.asarray(result.coef['gain'])
    adjusted = [Run(run.t, run.temp, run.omega - (off[r] - mean_off)[None, :]
                    - gain[None, :] * run.omega_ref, run.omega_ref, run.name, dict(run.info))
                for r, run in enumerate(runs)]
    features = model_features(result, runs)
    info = {'discover': {'final_effects': list(result.final_effects),
                         'noise_floor_dps': result.noise_floor_dps,
                         'gain_removed': [float(g) for g in gain]}, **dict(created or {})}
    # A constant gyro axis (train's rule) is fitted as train fits it: not at all (its
    # columns exactly zero, passed through), its figures the raw ones.
    const = constant_gyro_axes(runs)
    model = fit_model(neutral_runs(adjusted, const), kind=kind, features=features,
                      t0=result.t0_c, fit_params=False, created=info,
                      params={k: v for k, v in result.params.items() if k != 'lag'},
                      thermal=result.thermal if 'lag' in features else None)
    return identity_axes(model, runs, const)


def model_features(result: DiscoveryResult, runs: Sequence[Run]) -> tuple[str, ...]:
    """
    Return the effects of the model file (catalog order): the final effects the data support.

    With a temperature span of ``runs`` under :data:`gyro_tdc.identify.MIN_SPAN_C` (a warm-up
    at a fixed ambient) the temperature effects, base ``dT`` included, are left out: the data
    say nothing about them.
    """
    span = max(float(np.max(r.temp)) for r in runs) - min(float(np.min(r.temp)) for r in runs)
    return tuple(e for e in result.final_effects
                 if span >= MIN_SPAN_C or e not in TEMPERATURE_EFFECTS)
