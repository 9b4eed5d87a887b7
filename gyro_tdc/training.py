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
Training: bags in, a fitted and saved compensation model out, with the coverage of the data.

One run per bag (a folder of bag folders, as ``simulate`` writes for a multi-run scenario,
expands to its bags, :func:`gyro_tdc.dataset.load_runs`); the model is fitted with
:func:`gyro_tdc.fitting.fit_model` and written with :func:`gyro_tdc.modelfile.save_model`; the
coverage of the training data comes from :func:`gyro_tdc.coverage.coverage`. The command line
is :mod:`gyro_tdc.cli.train`; :mod:`gyro_tdc.fleet` trains one model per sensor with it.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
from typing import Callable, Sequence

from gyro_tdc.coverage import Coverage, coverage
from gyro_tdc.dataset import load_runs, MAX_LOSS_FRACTION
from gyro_tdc.effects import normalise_ids
from gyro_tdc.errors import FitError
from gyro_tdc.fitting import estimate_t0, fit_model
from gyro_tdc.limits import check_bin_width, check_centers
from gyro_tdc.model import CompensationModel, KINDS
from gyro_tdc.modelfile import save_model
from gyro_tdc.runs import Run

__all__ = ['TrainResult', 'train']


@dataclass
class TrainResult:
    """
    What :func:`train` produced.

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

    """

    model: CompensationModel
    path: Path
    coverage: Coverage
    bags: list
    samples: int


def train(bags: Sequence[str | os.PathLike], *, out: str | os.PathLike,
          features: str | Sequence[str] = ('dT', 'dT2'), kind: str = 'rbf',
          n_centers: int = 12, refine: bool = False, t0: float | None = None, seed: int = 0,
          imu_topic: str = '/imu/data_raw', temperature_topic: str = '/imu/temperature',
          reference: Sequence[float] | None = None,
          reference_topic: str = '/rate_table/reference', progress: bool = False,
          bin_c: float = 5.0, command: str = '', max_loss: float = MAX_LOSS_FRACTION,
          log: Callable[[str], None] | None = None) -> TrainResult:
    """
    Load bags, fit a compensation model and save it.

    Parameters
    ----------
    bags : sequence of str or PathLike
        rosbag2 directories (or folders of them), one run each.
    out : str or PathLike
        Model file to write.
    features : str or sequence of str
        Effect ids (default ``dT,dT2``, the paper's modified model).
    kind : str
        ``'rbf'`` or ``'poly'``.
    n_centers : int
        RBF centres K.
    refine : bool
        Refine centres and widths by nonlinear least squares.
    t0 : float, optional, degC
        Reference temperature; default the stable initial temperature of the first bag.
    seed : int
        Seed of the centre placement.
    imu_topic, temperature_topic, reference_topic : str
        Topics.
    reference : sequence of 3 float, rad/s, optional
        Constant reference rate (overrides the reference topic).
    progress : bool
        Progress bar while reading.
    bin_c : float, degC
        Width of the coverage bins.
    command : str
        Command line recorded in the model's ``created``.
    max_loss : float
        Largest fraction of a topic's messages that may be unreadable in a bag (see
        :func:`gyro_tdc.dataset.load_run`).
    log : callable, optional
        Receives one line per bag read.

    Returns
    -------
    TrainResult
        The model, where it was written and the coverage of the data.

    Raises
    ------
    GyroTdcError
        DatasetError for a bag that cannot be read, FeatureError for an unknown effect id,
        FitError for a bad ``kind`` or data that cannot be fitted, ModelFileError or
        OutputError when the model cannot be written.

    """
    ids = normalise_ids(features)
    if kind not in KINDS:
        raise FitError(f'Expected `kind` to be one of {", ".join(KINDS)}, got {kind!r}.')
    check_centers(n_centers)      # sizes checked before any bag is read
    check_bin_width(bin_c)
    options = {'imu_topic': imu_topic, 'temperature_topic': temperature_topic,
               'reference': None if reference is None else tuple(reference),
               'reference_topic': reference_topic, 'progress': progress, 'max_loss': max_loss}
    runs: list[Run] = load_runs(bags, log=log, **options)
    names = [r.name for r in runs]
    if t0 is None:
        t0 = estimate_t0(runs[0])
    model = fit_model(runs, kind=kind, features=ids, t0=t0, n_centers=n_centers,
                      refine=refine, seed=seed,
                      frame_id=str(runs[0].info.get('frame_id') or 'imu_link'),
                      created={'command': command, 'bags': names})
    cov = coverage(runs, bin_c=bin_c)
    path = save_model(model, out)
    return TrainResult(model=model, path=path, coverage=cov, bags=names,
                       samples=sum(len(r) for r in runs))
