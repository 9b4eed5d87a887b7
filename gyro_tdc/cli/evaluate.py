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
``python -m gyro_tdc evaluate BAG... --model A.yaml [--model B.yaml ...]``: score models.

For every held-out bag and axis: BS of the raw data (BS1, paper eq. 30-31) and after each
model, BS/BS1, RMS in deg/s, Allan deviation before and after with angle random walk and
bias instability. With exactly two models (or a ``--baseline``) the paper's tables 3-7 are
printed: ``BS1 BS2 BS3 P1 P2 P3`` with P1 = BS2/BS1, P2 = BS3/BS1 and P3 = BS3/BS2, the
baseline (first model) as the conventional one. ``--model px4 --train BAG...`` adds a
PX4-style cubic in T fitted on the training bags. Outputs: ``--json`` (the shape in
DESIGN.md), ``--plots DIR`` (PNGs per bag), ``--export DIR`` (a CSV per bag).

A bag whose temperature leaves a model's trained range is evaluated with the temperature
clamped to that range (as the compensator node does), and the output says so.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import math
import os
from pathlib import Path
import sys
from typing import Callable, Optional, Sequence

from gyro_tdc.cli.common import add_bag_options, ArgumentParser, bag_options, expand_bags
from gyro_tdc.cli.common import load_bag_runs, run_command, UsageError
from gyro_tdc.fitting import fit_px4_cubic
from gyro_tdc.metrics import allan_deviation, bias_stability, noise_readouts, rms_dps
from gyro_tdc.model import compensate, CompensationModel
from gyro_tdc.modelfile import load_model
from gyro_tdc.report import BagEval, format_allan, format_paper_table, format_summary
from gyro_tdc.report import ModelEval, safe_label, write_csv, write_json, write_plots
from gyro_tdc.resources import model_path
from gyro_tdc.runs import Run
import numpy as np
from numpy.typing import NDArray

__all__ = ['NamedModel', 'build_parser', 'evaluate', 'evaluate_run', 'load_models', 'main']

PX4 = 'px4'


@dataclass(frozen=True)
class NamedModel:
    """
    A model with the name it was given on the command line.

    Parameters
    ----------
    name : str
        A model file path as given, or ``px4``.
    label : str
        Short unique label (tables, CSV columns, legends).
    model : CompensationModel
        The model.

    """

    name: str
    label: str
    model: CompensationModel


def _labels(names: Sequence[str]) -> list:
    """Return short labels for ``names``, made unique with a numeric suffix."""
    out: list = []
    for name in names:
        base = PX4 if name == PX4 else safe_label(name)
        if base == 'raw':
            base = 'raw_model'
        label, k = base, 2
        while label in out:
            label, k = f'{base}_{k}', k + 1
        out.append(label)
    return out


def load_models(specs: Sequence[str], *, train_bags: Sequence[str] | None = None,
                options: dict | None = None,
                log: Callable[[str], None] | None = None) -> list:
    """
    Load model files and fit the ``px4`` baseline when asked.

    Parameters
    ----------
    specs : sequence of str
        Model file paths (or shipped model names), or ``px4``.
    train_bags : sequence of str, optional
        Bags the ``px4`` cubic is fitted on (required with ``px4``, used only by it).
    options : dict, optional
        Bag options of :func:`gyro_tdc.dataset.load_run`.
    log : callable, optional
        Receives progress lines.

    Returns
    -------
    list of NamedModel
        In the order of ``specs``.

    Raises
    ------
    UsageError
        ``px4`` without training bags or training bags without ``px4``.
    ModelFileError
        A model file is missing or malformed.

    """
    if not specs:
        raise UsageError('expected at least one --model')
    if PX4 in specs and not train_bags:
        raise UsageError('--model px4 needs --train BAG... (the bags to fit the cubic on)')
    if train_bags and PX4 not in specs:
        raise UsageError('--train is only used by --model px4; add --model px4 or drop --train')
    files = {s: load_model(model_path(s)) for s in specs if s != PX4}
    px4 = None
    if PX4 in specs:
        runs = load_bag_runs(train_bags, options or {}, out=log)
        px4 = fit_px4_cubic(runs, created={'bags': [r.name for r in runs]})
        if log is not None:
            lo, hi = px4.temp_range_c
            log(f'fitted px4 cubic in T - T0 on {len(runs)} bag(s): T0 = {px4.t0_c:.3f} degC, '
                f'range {lo:.2f} .. {hi:.2f} degC')
    return [NamedModel(s, label, px4 if s == PX4 else files[s])
            for s, label in zip(specs, _labels(specs))]


def _rate_hz(t: NDArray[np.float64]) -> float:
    """Return the sample rate from the median stamp step."""
    return 1.0 / float(np.median(np.diff(t))) if len(t) > 1 else 1.0


def _score(label: str, name: str, features: list, omega: NDArray[np.float64], run: Run,
           bs_raw: NDArray[np.float64] | None, rate: float) -> ModelEval:
    """Score one compensated (or raw) rate against the run's reference."""
    err = omega - run.omega_ref
    bs = bias_stability(omega, run.omega_ref)
    if len(run) >= 4:
        tau, adev = allan_deviation(err, rate)
    else:
        tau, adev = np.zeros(0), np.zeros((0, 3))
    nr = noise_readouts(tau, adev)
    with np.errstate(divide='ignore', invalid='ignore'):
        p = np.ones(3) if bs_raw is None else bs / bs_raw
    return ModelEval(model=name, label=label, features=list(features), bs=bs,
                     rms_dps=rms_dps(err), p_vs_raw=p, adev_tau_s=np.asarray(tau),
                     adev_dps=np.asarray(adev), arw_deg_sqrt_h=nr['arw_deg_sqrt_h'],
                     bias_instability_deg_h=nr['bias_instability_deg_h'], omega=omega)


def evaluate_run(run: Run, models: Sequence[NamedModel], *, label: str = '',
                 reanchor_s: float = 0.0) -> BagEval:
    """
    Score raw data and every model on one run.

    Parameters
    ----------
    run : Run
        A held-out run.
    models : sequence of NamedModel
        The models, in the order to report them.
    label : str
        Short label of the run (default from its name).
    reanchor_s : float, s
        When > 0, remove from each model's compensated rate its mean error over the first
        ``reanchor_s`` seconds (the run-to-run bias offset, as the compensator re-anchors at
        start-up while the sensor is still); the raw data are never re-anchored.

    Returns
    -------
    BagEval
        Scores, with the arrays kept for plots and export (call ``release()`` after).

    """
    rate = _rate_hz(run.t)
    raw = _score('raw', 'raw', [], run.omega, run, None, rate)
    out = []
    for nm in models:
        m = nm.model
        comp = compensate(m, run.t, run.temp, run.omega)
        if reanchor_s > 0:
            head = run.t <= run.t[0] + reanchor_s
            comp -= (comp[head] - run.omega_ref[head]).mean(axis=0)
        ev = _score(nm.label, nm.name, list(m.features), comp, run, raw.bs, rate)
        lo, hi = m.temp_range_c
        ev.temp_range_c = (lo, hi)
        ev.outside_fraction = float(np.count_nonzero((run.temp < lo) | (run.temp > hi))
                                    / max(len(run), 1))
        out.append(ev)
    return BagEval(bag=run.name, label=label or safe_label(run.name), samples=len(run),
                   temperature_c=(float(run.temp.min()), float(run.temp.max())),
                   duration_s=run.duration_s, reference=str(run.info.get('reference', '?')),
                   raw=raw, models=out, run=run)


def _bag_labels(paths: Sequence[Path]) -> list:
    """Return unique file-name labels for bag paths (parent folder added on clashes)."""
    base = [safe_label(str(p)) for p in paths]
    out = []
    for p, b in zip(paths, base):
        if base.count(b) > 1:
            b = safe_label(f'{Path(p).parent.name}_{b}')
        label, k = b, 2
        while label in out:
            label, k = f'{b}_{k}', k + 1
        out.append(label)
    return out


def evaluate(bags: Sequence[str | os.PathLike], models: Sequence[NamedModel], *,
             options: dict, plots: str | os.PathLike | None = None,
             export: str | os.PathLike | None = None,
             reanchor_s: float = 0.0, log: Callable[[str], None] | None = None,
             each: Callable[[BagEval], None] | None = None) -> list:
    """
    Evaluate models on held-out bags, one bag in memory at a time.

    Parameters
    ----------
    bags : sequence of str or PathLike
        Held-out bags (folders of bags expand to their bags).
    models : sequence of NamedModel
        Models to score.
    options : dict
        Bag options of :func:`gyro_tdc.dataset.load_run`.
    plots, export : str or PathLike, optional
        Directories for PNGs and CSVs.
    reanchor_s : float, s
        Start-up re-anchoring window (see :func:`evaluate_run`); 0 = off.
    log : callable, optional
        Receives one line per bag read and per file written.
    each : callable, optional
        Called with every :class:`BagEval` while its arrays are still held.

    Returns
    -------
    list of BagEval
        One per bag, arrays released.

    """
    paths = expand_bags(bags)
    labels = _bag_labels(paths)
    results = []
    for path, label in zip(paths, labels):
        run = load_bag_runs([path], options, out=log)[0]
        b = evaluate_run(run, models, label=label, reanchor_s=reanchor_s)
        if each is not None:
            each(b)
        if plots is not None:
            for f in write_plots(b, plots):
                if log is not None:
                    log(f'wrote {f}')
        if export is not None:
            f = write_csv(b, export)
            if log is not None:
                log(f'wrote {f}')
        b.release()
        results.append(b)
    return results


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``evaluate``."""
    p = ArgumentParser(
        prog='python -m gyro_tdc evaluate',
        description='Score compensation models on held-out rosbag2 bags in the terms of the '
                    'paper (BS, P ratios), plus RMS and Allan deviation.')
    p.add_argument('bags', nargs='+', metavar='BAG',
                   help='held-out rosbag2 directory (sqlite3 or mcap), or a folder of them')
    p.add_argument('--model', dest='models', action='append', required=True, metavar='MODEL',
                   help='model file (repeat for several; reported in this order), or px4 for '
                        'a PX4-style cubic in T fitted on the --train bags')
    p.add_argument('--train', nargs='+', metavar='BAG', default=None,
                   help='bags to fit the px4 cubic on')
    p.add_argument('--baseline', metavar='MODEL', default=None,
                   help='the conventional model of the paper tables (one of the --model '
                        'values, or another model file, evaluated too); default: the first '
                        'of exactly two models')
    p.add_argument('--reanchor', type=_non_negative, default=0.0, metavar='S',
                   help='remove from each model the mean error over the first S s of every bag '
                        '(the run-to-run bias offset, as the compensator re-anchors at '
                        'start-up while still); default 0: off')
    p.add_argument('--json', metavar='OUT', default=None, help='write the scores as JSON')
    p.add_argument('--plots', metavar='DIR', default=None, help='write PNGs per bag here')
    p.add_argument('--export', metavar='DIR', default=None,
                   help='write a CSV per bag here: time, temperature, raw, reference and '
                        'compensated rates (rad/s)')
    add_bag_options(p)
    return p


def _non_negative(text: str) -> float:
    """Parse a finite number >= 0 (argparse type)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f'expected a number >= 0, got {text!r}')
    return v


def _print_bag(b: BagEval, baseline: int | None) -> None:
    """Print the tables of one bag."""
    print(format_summary(b))
    if baseline is not None:
        for i in range(len(b.models)):
            if i != baseline:
                print(format_paper_table(b, baseline, i))
    print(format_allan(b), flush=True)


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``evaluate`` with parsed arguments; print the tables and write the outputs."""
    specs = list(args.models)
    if args.baseline is not None and args.baseline not in specs:
        specs.append(args.baseline)
    baseline = (specs.index(args.baseline) if args.baseline is not None
                else (0 if len(specs) == 2 else None))
    opts = bag_options(args)

    def log(line: str) -> None:
        print(line, flush=True)

    models = load_models(specs, train_bags=args.train, options=opts, log=log)
    for nm in models:
        m = nm.model
        lo, hi = m.temp_range_c
        log(f'model {nm.label}: {nm.name}, {m.kind} f({", ".join(m.inputs) or "bias"}), '
            f'trained {lo:.2f} .. {hi:.2f} degC')
    if args.reanchor > 0:
        log(f'models re-anchored: mean error over the first {args.reanchor:g} s of each bag '
            'removed (raw data untouched)')
    results = evaluate(args.bags, models, options=opts, plots=args.plots,
                       export=args.export, reanchor_s=args.reanchor, log=log,
                       each=lambda b: _print_bag(b, baseline))
    if args.json is not None:
        log(f'wrote {write_json(results, args.json)}')
    if len(results) > 1:
        _print_means(results)
    return 0


def _print_means(results: Sequence[BagEval]) -> None:
    """Print the mean BS per model and axis over all bags (BS/BS1 averaged per bag)."""
    labels = [m.label for m in results[0].models]
    w = max([len(x) for x in labels] + [12])
    print(f'mean over {len(results)} bags: BS in (deg/s)^2 and BS/BS1')
    print(f'  {"":<{w}} ' + ''.join(f'{"BS " + a:>11}' for a in 'xyz') + '  '
          + ''.join(f'{"BS/BS1 " + a:>11}' for a in 'xyz'))
    rows = [('raw', [b.raw for b in results])] + [
        (lab, [b.models[i] for b in results]) for i, lab in enumerate(labels)]
    for lab, evs in rows:
        bs = np.mean([e.bs for e in evs], axis=0)
        p = np.mean([e.p_vs_raw for e in evs], axis=0)
        print(f'  {lab:<{w}} ' + ''.join(_fmt(v) for v in bs) + '  '
              + ''.join(_fmt(v) for v in p))


def _fmt(v: float) -> str:
    """Format one table number."""
    return f'{v:>11.4g}' if math.isfinite(v) else f'{"-":>11}'


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Run ``python -m gyro_tdc evaluate``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the command name (``sys.argv[1:]`` when None).

    Returns
    -------
    int
        0 on success, 2 on bad input (one line on stderr).

    """
    return run_command('evaluate', build_parser, _run, argv)


if __name__ == '__main__':
    sys.exit(main())
