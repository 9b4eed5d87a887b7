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


"""The choices of a training run, checked once (:class:`TrainOptions`), and what it produced."""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path

from gyro_tdc.base import check_bin_width, check_centers
from gyro_tdc.data import Coverage
from gyro_tdc.errors import FitError
from gyro_tdc.identify.accel import AccelFit
from gyro_tdc.identify.features import AUTO, FeatureChoice
from gyro_tdc.identify.fit import check_choices
from gyro_tdc.model import CompensationModel, normalise_ids

__all__ = ['TrainOptions', 'TrainResult']


@dataclass(frozen=True)
class TrainOptions:
    """
    How to train a model, checked when built so that a bad choice fails before any bag is read.

    ``features`` is ``'auto'`` (the paper's ``dT,dT2`` plus what
    :func:`~gyro_tdc.identify.features.choose_features` finds the data support) or effect ids
    (held in catalog order); ``kind``, ``n_centers``, ``refine``, ``t0``, ``seed``, ``ridge``
    and ``thermal`` are those of :class:`~gyro_tdc.identify.fit.FitOptions` (``t0`` by default
    the stable initial temperature of the first bag, with ``--still-only`` of the first still
    stretch); ``bin_c`` the coverage bins, degC; ``accel`` reads the accelerometer and fits its
    part; ``sensor_id`` goes to the model. ``window_s`` and ``min_still_s``: the still test of
    training without a reference (None: the window by the rate, a stretch judged by its
    samples and its noise, :func:`gyro_tdc.signal.detect_still`). FeatureError for an unknown
    effect id, FitError for a bad ``kind``, ``ridge`` or ``thermal``.
    """

    features: str | tuple[str, ...] = AUTO
    kind: str = 'rbf'
    n_centers: int = 12
    refine: bool = False
    t0: float | None = None
    seed: int = 0
    ridge: float | str = 'auto'
    thermal: str | None = None
    bin_c: float = 5.0
    accel: bool = True
    sensor_id: str = ''
    window_s: float | None = None
    min_still_s: float | None = None

    def __post_init__(self) -> None:
        """Normalise the features and check every choice."""
        f = self.features
        auto = isinstance(f, str) and f.strip() == AUTO
        object.__setattr__(self, 'features', AUTO if auto else normalise_ids(f))
        check_choices(self.kind, self.thermal)
        check_centers(self.n_centers)
        check_bin_width(self.bin_c)
        if self.ridge != 'auto' and not (isinstance(self.ridge, (int, float))
                                         and math.isfinite(self.ridge) and self.ridge >= 0):
            raise FitError(f"Expected `ridge` to be 'auto' or a number >= 0, got {self.ridge!r}.")

    @property
    def auto(self) -> bool:
        """Return True when the data choose the features (``features='auto'``)."""
        return self.features == AUTO

    def fit_kw(self) -> dict:
        """Return the fields ``fit_model`` shares (kind, centres, refine, ridge, seed, ...)."""
        return {'kind': self.kind, 'n_centers': self.n_centers, 'refine': self.refine,
                'ridge': self.ridge, 'seed': self.seed, 'thermal': self.thermal,
                'sensor_id': str(self.sensor_id)}


@dataclass
class TrainResult:
    """
    What :func:`gyro_tdc.identify.train.train` (or ``train_still_only``) produced.

    The model as saved and where; the coverage of the training data (of the still time kept
    with ``--still-only``), the bags and samples; the choice of ``features='auto'``; the
    accelerometer part's fit (None with ``accel=False``); with ``--still-only`` the
    :class:`~gyro_tdc.identify.still_only.StillReport`; the sessions
    (:class:`gyro_tdc.data.SessionSplit`); ``constant``: axis name -> reading (rad/s) of the
    gyro axes never varying beyond one quantum, passed through unchanged.
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
