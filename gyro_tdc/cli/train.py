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
``python -m gyro_tdc train BAG... --out MODEL.yaml``: identify a model from recorded bags.

One run per bag (a folder of bag folders, as ``simulate`` writes for a multi-run scenario,
expands to its bags); the model is fitted with :func:`gyro_tdc.fitting.fit_model` and written
with :func:`gyro_tdc.modelfile.save_model`. The report on stdout: training bias stability per
axis raw and compensated, the temperature range, coverage per temperature bin (with a warning
naming the bins inside the span with too little data) and minutes heating, cooling and
steady. Bad input (missing bag or topic, unreadable bag, too small a span, too few samples,
unknown feature id, bad reference) exits 2 with one line on stderr.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import math
import os
from pathlib import Path
import sys
from typing import Callable, Optional, Sequence

from gyro_tdc.cli.common import add_bag_options, ArgumentParser, bag_options, command_line
from gyro_tdc.cli.common import finite_float, positive_float, positive_int, run_command
from gyro_tdc.cli.common import UsageError
from gyro_tdc.coverage import Coverage, coverage
from gyro_tdc.dataset import load_runs, MAX_LOSS_FRACTION
from gyro_tdc.effects import normalise_ids
from gyro_tdc.fitting import estimate_t0, fit_model
from gyro_tdc.model import CompensationModel, KINDS
from gyro_tdc.modelfile import save_model
from gyro_tdc.report import AXES, format_coverage
from gyro_tdc.runs import Run
import numpy as np

__all__ = ['TrainResult', 'add_train_options', 'build_parser', 'format_training', 'main',
           'train', 'train_options']


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

    """
    ids = normalise_ids(features)
    if kind not in KINDS:
        raise UsageError(f'--kind: expected one of {", ".join(KINDS)}, got {kind!r}')
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


def _row(label: str, values: Sequence[float]) -> str:
    """Format one table row of three per-axis numbers."""
    return f'  {label:<13}' + ''.join(f'{v:>12.4g}' for v in values)


def format_training(result: TrainResult) -> tuple[str, list]:
    """
    Return the training report and its warnings.

    Parameters
    ----------
    result : TrainResult
        What :func:`train` returned.

    Returns
    -------
    text : str
        Model summary, training BS raw and compensated per axis, coverage.
    warnings : list of str
        Coverage warnings.

    """
    m = result.model
    met = m.metrics
    feats = ', '.join(m.inputs) or 'bias only'
    params = '; '.join(f'{eid}.{k} = {v:.4g}' for eid, p in sorted(m.effect_params.items())
                       for k, v in p.items())
    head = (f'model: {m.kind} f({feats}), '
            + (f'{m.n_centers} centres, ' if m.kind == 'rbf' else '')
            + f'T0 = {m.t0_c:.3f} degC' + (f', {params}' if params else ''))
    lines = [head, f'training data: {len(result.bags)} bag(s), {result.samples} samples',
             'training bias stability BS, (deg/s)^2:',
             f'  {"":<13}' + ''.join(f'{a:>12}' for a in AXES),
             _row('raw', met.get('raw_bs_dps2', [math.nan] * 3)),
             _row('compensated', met.get('train_bs_dps2', [math.nan] * 3)),
             _row('RMS (deg/s)', met.get('train_rms_dps', [math.nan] * 3))]
    if np.any(m.scale != 0):
        lines.append(_row('scale (1/C)', m.scale))
    table, warns = format_coverage(result.coverage)
    lines.append(table)
    return '\n'.join(lines), warns


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``train``."""
    p = ArgumentParser(
        prog='python -m gyro_tdc train',
        description='Identify a temperature-drift compensation model from rosbag2 bags '
                    '(one run per bag; a folder of bag folders expands to its bags) and '
                    'write it as a YAML model file.')
    p.add_argument('bags', nargs='+', metavar='BAG', help='rosbag2 directory (sqlite3 or mcap)')
    p.add_argument('--out', required=True, metavar='MODEL.yaml', help='model file to write')
    add_train_options(p)
    return p


def add_train_options(p: argparse.ArgumentParser) -> None:
    """
    Add every option of ``train`` but the bags and ``--out`` (model and bag options).

    Commands that train (``fleet``) share the options and defaults through this function;
    :func:`train_options` turns the parsed arguments into keyword options of :func:`train`.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser.

    """
    p.add_argument('--features', default='dT,dT2', metavar='IDS',
                   help='comma-separated effect ids (default: %(default)s, the modified model '
                        'of the paper; dT alone is the conventional model; add lag to fit '
                        'a thermometer-to-die lag)')
    p.add_argument('--kind', default='rbf', choices=KINDS,
                   help='rbf network with a linear tail, or poly (linear in the features) '
                        '(default: %(default)s)')
    p.add_argument('--centers', type=positive_int, default=12, metavar='K',
                   help='RBF centres (default: %(default)s)')
    p.add_argument('--refine', action='store_true',
                   help='refine RBF centres and widths by nonlinear least squares')
    p.add_argument('--t0', type=finite_float, default=None, metavar='C',
                   help='reference temperature T0 in degC (default: the stable initial '
                        'temperature of the first bag)')
    p.add_argument('--seed', type=int, default=0, help='seed of the centre placement')
    p.add_argument('--bin', dest='bin_c', type=positive_float, default=5.0, metavar='C',
                   help='width of the coverage bins in degC (default: %(default)s)')
    add_bag_options(p)


def train_options(args: argparse.Namespace) -> dict:
    """
    Return the keyword options of :func:`train` from arguments of :func:`add_train_options`.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments.

    Returns
    -------
    dict
        ``features`` (normalised ids), ``kind``, ``n_centers``, ``refine``, ``t0``, ``seed``,
        ``bin_c`` and the bag options of :func:`gyro_tdc.cli.common.bag_options`.

    Raises
    ------
    FeatureError
        When ``--features`` names an unknown effect.

    """
    return {'features': normalise_ids(args.features), 'kind': args.kind,
            'n_centers': args.centers, 'refine': args.refine, 't0': args.t0,
            'seed': args.seed, 'bin_c': args.bin_c, **bag_options(args)}


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``train`` with parsed arguments; print the report."""
    opts = train_options(args)   # fails on a bad feature id before reading any bag
    result = train(args.bags, out=args.out, command=command_line('train', argv),
                   log=lambda line: print(line, flush=True), **opts)
    text, warns = format_training(result)
    print(text)
    for w in warns:
        print(f'warning: {w}')
    print(f'wrote {result.path} (model_id {result.model.model_id})', flush=True)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Run ``python -m gyro_tdc train``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the command name (``sys.argv[1:]`` when None).

    Returns
    -------
    int
        0 on success, 2 on bad input (one line on stderr).

    """
    return run_command('train', build_parser, _run, argv)


if __name__ == '__main__':
    sys.exit(main())
