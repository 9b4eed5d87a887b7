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

"""What training produced: the model, where it went, the coverage, the choices made."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gyro_tdc.data import Coverage
from gyro_tdc.identify.accel import AccelFit
from gyro_tdc.identify.features import FeatureChoice
from gyro_tdc.model import CompensationModel

__all__ = ['TrainResult']


@dataclass
class TrainResult:
    """
    What :func:`gyro_tdc.identify.train.train` (or ``train_still_only``) produced.

    Parameters
    ----------
    model : CompensationModel
        The fitted model (as saved).
    path : Path
        Where it was written.
    coverage : Coverage
        Temperature and heating/cooling coverage of the training data.
    bags : list of str
        The bags trained on.
    samples : int
        Training samples.
    choice : FeatureChoice, optional
        What ``features='auto'`` chose and why (None for named features).
    accel : AccelFit, optional
        The accelerometer part's fit and figures, or why there is none (None with
        ``accel=False``).
    still : gyro_tdc.identify.still_only.StillReport, optional
        With ``train --still-only``: the still time, its coverage and what to record next.
    sessions : gyro_tdc.data.SessionSplit, optional
        The sessions the bags were cut into (one turn-on offset each).
    constant : dict
        The gyro axes whose readings never vary beyond one quantum, axis name (``'z'``) ->
        what they read in rad/s: not fitted, the model passes them through unchanged
        (``model.metrics['constant_axes']``); empty when every axis varies.
    held_out : gyro_tdc.identify.crossval.HeldOut, optional
        Leave-one-session-out figures and what each axis keeps (curve or offset only,
        re-anchoring); ``model.metrics['held_out']``.

    """

    model: CompensationModel
    path: Path
    coverage: Coverage
    bags: list
    samples: int
    choice: FeatureChoice | None = None
    accel: AccelFit | None = None
    still: object | None = None
    sessions: object | None = None
    constant: dict = field(default_factory=dict)
    held_out: object | None = None

    def constant_line(self) -> str:
        """Return the one report line naming the constant gyro axes ('' when none)."""
        if not self.constant:
            return ''
        many = len(self.constant) > 1
        values = ', '.join(f'{v:.6g}' for v in self.constant.values())
        return (f'gyro ax{"es" if many else "is"} {", ".join(self.constant)}: constant at '
                f'{values} rad/s (never varying beyond one quantum: a 2-axis gyro or a dead '
                f'axis); not fitted: the model passes {"them" if many else "it"} through '
                'unchanged')
