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

"""The choices of a training run, checked once (:class:`TrainOptions`)."""

from __future__ import annotations

from dataclasses import dataclass
import math

from gyro_tdc.base import check_bin_width, check_centers
from gyro_tdc.errors import FitError
from gyro_tdc.identify.features import AUTO
from gyro_tdc.identify.fit import THERMAL_CHOICES
from gyro_tdc.model import KINDS, normalise_ids

__all__ = ['TrainOptions']


@dataclass(frozen=True)
class TrainOptions:
    """
    How to train a model: features, network, reference temperature, coverage bins, parts.

    Checked when built, so that a bad choice fails before any bag is read.

    Parameters
    ----------
    features : str or tuple of str
        ``'auto'`` (default: the paper's ``dT,dT2`` plus what
        :func:`gyro_tdc.identify.features.choose_features` finds the data support) or effect
        ids (``'dT,dT2'`` or a sequence: exactly that model); held as ``'auto'`` or the ids
        in catalog order.
    kind : str
        ``'rbf'`` or ``'poly'``.
    n_centers : int
        RBF centres K.
    refine : bool
        Refine centres and widths by nonlinear least squares.
    t0 : float, optional, degC
        Reference temperature; default the stable initial temperature of the first bag (with
        ``train_still_only``: of the first still stretch).
    seed : int
        Seed of the centre placement.
    ridge : float or 'auto'
        Relative ridge penalty on the RBF weights (:func:`gyro_tdc.identify.fit.fit_model`).
    thermal : str, optional
        The thermal front end (:data:`gyro_tdc.identify.fit.THERMAL_CHOICES`); default as
        ``fit_model``: first order with ``lag``, else none.
    bin_c : float, degC
        Width of the coverage bins.
    accel : bool
        Read the accelerometer and fit the model's accelerometer part on its still data
        (default); False skips both.
    sensor_id : str
        The sensor's id, written to the model's ``sensor.sensor_id``.
    window_s, min_still_s : float or None, s
        The still test of training without a reference: window and shortest still stretch
        kept; None (default): the window by the rate (:func:`gyro_tdc.signal.auto_window`),
        a stretch judged by its samples and its noise (:func:`gyro_tdc.signal.detect_still`).

    Raises
    ------
    GyroTdcError
        FeatureError for an unknown effect id, FitError for a bad ``kind``, ``ridge`` or
        ``thermal``, and the size checks of ``n_centers`` and ``bin_c``.

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
        if self.kind not in KINDS:
            raise FitError(f'Expected `kind` to be one of {", ".join(KINDS)}, '
                           f'got {self.kind!r}.')
        check_centers(self.n_centers)
        check_bin_width(self.bin_c)
        if self.ridge != 'auto' and not (isinstance(self.ridge, (int, float))
                                         and math.isfinite(self.ridge) and self.ridge >= 0):
            raise FitError(f"Expected `ridge` to be 'auto' or a number >= 0, got {self.ridge!r}.")
        if self.thermal is not None and self.thermal not in THERMAL_CHOICES:
            raise FitError(f'Expected `thermal` to be one of {", ".join(THERMAL_CHOICES)}, '
                           f'got {self.thermal!r}.')

    @property
    def auto(self) -> bool:
        """Return True when the data choose the features (``features='auto'``)."""
        return self.features == AUTO
