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
Held-out evaluation on a bursty real recording: leave one block of bursts out.

The PAN CubeSat TVAC recording is one session of 25 bursts; each block of bursts is held out
in turn, every model fitted on the others and scored against the bursts' own noise floor,
interior and end blocks apart. The choices and why: ``doc/internals/evaluate.md``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import partial
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

from gyro_tdc.data import default_pan_csv, PanCubesat, read_pan_cubesat_csv, Run
from gyro_tdc.errors import FitError
from gyro_tdc.evaluate.score import score
from gyro_tdc.identify import estimate_t0, fit_linear, fit_model, fit_time_constant, rows_of
from gyro_tdc.model import (batch_features, compensate, EFFECTS,
                            normalise_ids, rbf_design, resolve_params)
from gyro_tdc.signal import bias_stability, Folds
import numpy as np
from numpy.typing import NDArray

__all__ = ['FullSeriesModel', 'HOLDOUT_MODELS', 'HoldoutModel', 'burst_holdout', 'burst_index',
           'fit_full_series', 'format_holdout', 'pan_holdout']

#: Summary groups of a scheme: interior blocks are interpolation, end blocks extrapolation.
GROUPS = ('interior', 'end', 'all')


@dataclass(frozen=True)
class HoldoutModel:
    """
    One model compared in the held-out evaluation.

    ``name`` is its JSON key and table label, ``kind`` ``'raw'`` (no compensation), ``'poly'``
    or ``'rbf'`` (``n_centers`` RBF centres), ``features`` its effect ids (``bias`` implied;
    empty: a constant offset); ``full_series``: the features computed on the whole recording
    (dynamic effects, :class:`FullSeriesModel`).
    """

    name: str
    description: str
    kind: str
    features: tuple[str, ...] = ()
    n_centers: int = 12
    full_series: bool = False

    def to_dict(self) -> dict:
        """Return the plain-type description written to the JSON."""
        return {**asdict(self), 'features': list(self.features),
                'n_centers': self.n_centers if self.kind == 'rbf' else 0}


HOLDOUT_MODELS: tuple[HoldoutModel, ...] = (
    HoldoutModel('raw', 'raw output around the reference 0 (BS1)', 'raw'),
    HoldoutModel('bias', 'constant offset fitted on the training bursts', 'poly'),
    HoldoutModel('conventional', 'poly f(dT)', 'poly', ('dT',)),
    HoldoutModel('modified', 'poly f(dT, dT^2)', 'poly', ('dT', 'dT2')),
    HoldoutModel('rbf', 'RBF f(dT, dT^2), K = 12 (the train default)', 'rbf', ('dT', 'dT2'),
                 12),
    HoldoutModel('rbf4', 'RBF f(dT, dT^2), K = 4', 'rbf', ('dT', 'dT2'), 4),
    HoldoutModel('px4', 'PX4-style cubic f(dT, dT^2, dT^3)', 'poly', ('dT', 'dT2', 'dT3')),
    HoldoutModel('lag', 'poly f(dT, lagged T) = f(dT, dT/dt), tau fitted on the training '
                 'rows, features on the full time series', 'poly', ('dT', 'lag'),
                 full_series=True))


def burst_index(t: NDArray[np.float64], *, gap_s: float = 2.0) -> NDArray[np.int64]:
    """Return the burst number (0, 1, ...) of each stamp ``t``: a gap over ``gap_s`` starts one."""
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.shape[0] == 0:
        raise FitError(f'Expected `t` of shape (N,) with N >= 1, got {t.shape}.')
    return np.concatenate([[0], np.cumsum(np.diff(t) > gap_s)]).astype(np.int64)


@dataclass(frozen=True)
class FullSeriesModel:
    """
    The comparator's own ``poly`` model: every feature of the measured temperature.

    Its ``lag`` is a column of its own (the lagged measured temperature beside ``dT``), a form
    a model file has no place for (there ``lag`` makes the thermal state every term is of),
    so the comparator evaluates it itself, the filters run over the whole recording.
    """

    features: tuple[str, ...]
    effect_params: dict
    t0_c: float
    norm: tuple
    coef: NDArray[np.float64]
    temp_range_c: tuple[float, float]

    def compensate(self, t: NDArray[np.float64], temp: NDArray[np.float64],
                   omega: NDArray[np.float64], *, clamp: bool = True) -> NDArray[np.float64]:
        """Return ``omega - b`` (N, 3), rad/s, the features of the temperature clamped or not."""
        temp = np.asarray(temp, dtype=np.float64)
        s = np.clip(temp, *self.temp_range_c) if clamp else temp
        x = batch_features(self.features, t, s, t0=self.t0_c, params=self.effect_params)
        return np.asarray(omega, dtype=np.float64) - rbf_design(self.norm, x) @ self.coef


def fit_full_series(run: Run, train: NDArray[np.bool_], *, features: Sequence[str],
                    t0: float, ridge: float = 1e-6, n_grid: int = 25) -> FullSeriesModel:
    """
    Fit the comparator's ``poly`` model on rows ``train``, the features computed on the whole run.

    The fitted effect parameters (the ``lag`` time constant) are chosen on the training rows:
    a log grid of ``n_grid`` points over the catalog bounds, then a bounded 1-D search. With
    static features this is :func:`gyro_tdc.identify.fit_model`'s least squares
    (``kind='poly'``, same ``ridge``). ``t0`` is the reference temperature (degC), the
    effect parameters start at the catalog's; ``temp_range_c`` is that of the training rows.
    """
    train = np.asarray(train, dtype=bool)
    if train.shape != (len(run),):
        raise FitError(f'Expected `train` of shape ({len(run)},), got {train.shape}.')
    if np.count_nonzero(train) < 2:
        raise FitError(f'Expected at least 2 training rows, got {np.count_nonzero(train)}.')
    ids = normalise_ids(features)
    par = resolve_params(ids)
    y = (run.omega - run.omega_ref)[train]

    def design(p: Mapping) -> NDArray[np.float64]:
        return batch_features(ids, run.t, run.temp, t0=t0, params=p)[train]

    for eid in ids:
        for name in EFFECTS[eid].fitted:

            def sse(tau: float, eid: str = eid, name: str = name) -> float:
                trial = {**par, eid: {**par[eid], name: tau}}       # par itself unchanged
                return fit_linear(design(trial), y, kind='poly', ridge=ridge).sse

            par[eid][name] = fit_time_constant(sse, EFFECTS[eid].bounds[name], n_grid=n_grid).tau
    fit = fit_linear(design(par), y, kind='poly', ridge=ridge)
    temp = run.temp[train]
    return FullSeriesModel(ids, par, float(t0), fit.norm,
                           np.ascontiguousarray(fit.coef, dtype=np.float64),
                           (float(temp.min()), float(temp.max())))


def _scored(omega: tuple[NDArray[np.float64], NDArray[np.float64]], held: Run,
            floor: NDArray[np.float64]) -> tuple[dict, NDArray[np.float64]]:
    """Score a clamped and an unclamped rate on held-out rows; return the row and BS."""
    ev, ev_u = (score(o, held, allan=False) for o in omega)
    return {'bs': ev.bs.tolist(), 'rms_dps': ev.rms_dps.tolist(),
            'floor_ratio': (ev.bs / floor).tolist(), 'bs_unclamped': ev_u.bs.tolist(),
            'floor_ratio_unclamped': (ev_u.bs / floor).tolist()}, ev.bs


def _scheme(run: Run, burst: NDArray[np.int64], means: NDArray[np.float64], n_blocks: int,
            models: Sequence[HoldoutModel], t0: float) -> dict:
    """Run one leave-one-block-out scheme (``means``: each burst's mean error, rad/s)."""
    n_bursts, err = len(means), run.omega - run.omega_ref

    def floor_of(idx: NDArray[np.int64]) -> NDArray[np.float64]:
        """BS of held-out samples around their own burst means (the white-noise floor)."""
        return bias_stability(err[idx], means[burst[idx]])

    folds = []
    # Held-out rows and rates of every fold, pooled per group for the summaries.
    pooled: dict[str, list] = {g: [] for g in GROUPS}
    blocks = np.array_split(np.arange(n_bursts, dtype=np.int64), n_blocks)
    block_of = np.repeat(np.arange(len(blocks)), [len(b) for b in blocks])[burst]
    # Leave one block of bursts out: a block is a session of the estimator's folds.
    for i, (held, train) in enumerate(Folds.sessions(block_of)):
        held_bursts, idx = blocks[i], np.flatnonzero(held)
        position = 'end' if held_bursts[0] == 0 or held_bursts[-1] == n_bursts - 1 else 'interior'
        floor, held_run = floor_of(idx), rows_of(run, idx)
        t_lo, t_hi = float(run.temp[train].min()), float(run.temp[train].max())
        temp_h = run.temp[held]
        fold = {'block': i, 'bursts': [int(held_bursts[0]), int(held_bursts[-1])],
                'samples': len(idx), 'position': position,
                'temperature_c': [float(temp_h.min()), float(temp_h.max())],
                'train_temperature_c': [t_lo, t_hi],
                'outside_fraction': float(np.mean((temp_h < t_lo) | (temp_h > t_hi))),
                'floor_bs_dps2': floor.tolist(), 'models': {}}
        rates = {}
        for spec in models:
            rates[spec.name], extra = (run.omega[held],) * 2, {}
            if spec.kind != 'raw':      # fitted on the training rows, the whole run compensated
                model = (fit_full_series(run, train, features=spec.features, t0=t0)
                         if spec.full_series else
                         fit_model([rows_of(run, train)], kind=spec.kind, features=spec.features,
                                   t0=t0, n_centers=spec.n_centers, seed=0))
                comp = (model.compensate if spec.full_series else partial(compensate, model))
                rates[spec.name] = tuple(comp(run.t, run.temp, run.omega, clamp=c)[held]
                                         for c in (True, False))
                extra = {'effect_params': {k: dict(v) for k, v in model.effect_params.items()}}
            fold['models'][spec.name] = {**_scored(rates[spec.name], held_run, floor)[0], **extra}
        for g in (position, 'all'):
            pooled[g].append((idx, rates))
        folds.append(fold)
    summary = dict.fromkeys(GROUPS)         # a group without a fold: None
    for g in filter(pooled.get, GROUPS):
        idx = np.concatenate([x[0] for x in pooled[g]])
        floor, group_run = floor_of(idx), rows_of(run, idx)
        summary[g] = {'folds': len(pooled[g]), 'samples': len(idx),
                      'floor_bs_dps2': floor.tolist(), 'models': {}}
        bs_of = {}
        for spec in models:
            rate = tuple(np.concatenate([x[1][spec.name][c] for x in pooled[g]]) for c in (0, 1))
            summary[g]['models'][spec.name], bs_of[spec.name] = _scored(rate, group_run, floor)
        for name, row in summary[g]['models'].items():
            row.update({f'p_vs_{base}': (bs_of[name] / bs_of[base]).tolist()
                        for base in ('raw', 'bias') if base in bs_of})
    return {'name': 'leave_one_burst_out' if n_blocks == n_bursts else 'leave_one_block_out',
            'n_blocks': n_blocks, 'bursts_per_block': sorted({len(b) for b in blocks}),
            'folds': folds, 'summary': summary}


def burst_holdout(run: Run, *, n_blocks: int = 5, leave_one_out: bool = True,
                  models: Sequence[HoldoutModel] = HOLDOUT_MODELS, gap_s: float = 2.0,
                  t0: float | None = None) -> dict:
    """
    Evaluate the models on a bursty recording by leave-one-burst-block-out.

    Parameters
    ----------
    run : Run
        The whole recording as one run (bursts separated by gaps longer than ``gap_s``).
    n_blocks : int
        Contiguous blocks of bursts (2 .. number of bursts).
    leave_one_out : bool
        Also run leave-one-burst-out (skipped when ``n_blocks`` already is the burst count).
    models : sequence of HoldoutModel
        Models compared (``raw`` and ``bias`` give the baselines and the ``p_vs_*`` ratios).
    gap_s : float, s
        Shortest gap between bursts.
    t0 : float, optional, degC
        Reference temperature of every fold (default: :func:`estimate_t0` of the run, the
        first burst; for models with an intercept it only re-parameterises).

    Returns
    -------
    dict
        Plain types (JSON): ``samples``, ``bursts``, ``burst_period_s``, ``temperature_c``,
        ``t0_c``, ``noise``, ``models`` and ``schemes`` (see ``doc/real_data.md``).

    """
    burst = burst_index(run.t, gap_s=gap_s)
    n_bursts = int(burst[-1]) + 1
    if not isinstance(n_blocks, (int, np.integer)) or not 2 <= n_blocks <= n_bursts:
        raise FitError(f'Expected `n_blocks` between 2 and the number of bursts '
                       f'({n_bursts}), got {n_blocks!r}.')
    names = [m.name for m in models]
    if len(set(names)) != len(names) or not names:
        raise FitError(f'Expected `models` with unique names, got {names}.')
    if (counts := np.bincount(burst)).min() < 2:
        raise FitError(f'Expected at least 2 samples per burst (gap_s = {gap_s} s), got a '
                       f'burst of {int(counts.min())}.')
    t0 = estimate_t0(run) if t0 is None else t0
    err = run.omega - run.omega_ref
    means = np.array([err[burst == b].mean(axis=0) for b in range(n_bursts)])
    sd = np.degrees(np.sqrt(((err - means[burst]) ** 2).mean(axis=0)))
    # First differences within bursts: an independent look at the white noise.
    same = np.diff(burst) == 0
    diff_sd = np.degrees(np.std(np.diff(err, axis=0)[same], axis=0)) / math.sqrt(2.0)
    starts = run.t[np.searchsorted(burst, np.arange(n_bursts))]      # each burst's first stamp
    return {'source': run.name, 'samples': len(run), 'bursts': n_bursts,
            'samples_per_burst': [int(counts.min()), int(counts.max())],
            'burst_period_s': float(np.median(np.diff(starts))) if n_bursts > 1 else 0.0,
            'temperature_c': [float(run.temp.min()), float(run.temp.max())],
            'temperature_first_last_c': [float(run.temp[burst == 0].mean()),
                                         float(run.temp[burst == n_bursts - 1].mean())],
            't0_c': float(t0),
            'noise': {'within_burst_sd_dps': sd.tolist(), 'floor_bs_dps2': (sd ** 2).tolist(),
                      'diff_sd_dps': diff_sd.tolist(),
                      'burst_mean_se_dps': (sd / math.sqrt(float(np.median(counts)))).tolist()},
            'drift_dps': np.degrees(means[-1] - means[0]).tolist(),
            'models': [m.to_dict() for m in models],
            'schemes': [_scheme(run, burst, means, n, models, t0) for n in (
                [n_blocks] + ([n_bursts] if leave_one_out and n_blocks != n_bursts else []))]}


def pan_holdout(csv: str | Path | PanCubesat | None = None, *, n_blocks: int = 5,
                leave_one_out: bool = True,
                models: Sequence[HoldoutModel] = HOLDOUT_MODELS) -> dict:
    """
    Evaluate the models on the PAN CubeSat TVAC recording (leave one burst block out).

    ``csv`` is ``TVCtest3_7_20.csv`` or its parsed content (default: the shared data set
    beside the repository), cut into ``n_blocks`` blocks of bursts; ``leave_one_out`` also
    runs leave-one-burst-out. Returns :func:`burst_holdout`'s dict with ``source``.

    Raises
    ------
    DatasetError
        When the CSV is missing or malformed.

    """
    if isinstance(csv, PanCubesat):
        data, source = csv, 'PanCubesat'
    else:
        path = Path(csv) if csv is not None else default_pan_csv()
        data, source = read_pan_cubesat_csv(path), str(path)
    run = Run(data.t, data.temp_c, data.gyro, np.zeros_like(data.gyro), source)
    return {**burst_holdout(run, n_blocks=n_blocks, leave_one_out=leave_one_out, models=models),
            'rows_removed': data.rows_removed}


def _f3(values: Sequence[float], fmt: str) -> str:
    """Format three per-axis values."""
    return ' '.join(format(v, fmt) for v in values)


def _model_rows(models: Mapping[str, Any], names: Sequence[str], *, unclamped: bool,
                ratios: bool) -> list[str]:
    """Format one row per model: BS, RMS and floor ratio per axis (x y z)."""
    u = '_unclamped' if unclamped else ''
    return [f'  {n:<13}{_f3(m["bs" + u], "10.3e")} | {_f3(np.sqrt(m["bs" + u]), "7.4f")} | '
            f'{_f3(m["floor_ratio" + u], "9.2f")}'
            + (f' | {_f3(m["p_vs_bias"], "7.3f")}' if ratios and 'p_vs_bias' in m and not u
               else '') for n, m in ((n, models[n]) for n in names)]


def _fitted(models: Mapping[str, Any]) -> str:
    """Return the effect parameters fitted in a fold, e.g. ``, lag model lag.tau_s = 1364``."""
    out = [f'{name} model {eid}.{k} = {v:.0f}' for name, m in models.items()
           for eid, p in m.get('effect_params', {}).items() for k, v in p.items()
           if EFFECTS[eid].fitted and k in EFFECTS[eid].fitted]
    return ''.join(f', {x}' for x in out)


def _head(ratios: bool) -> str:
    """Return the column header matching :func:`_model_rows`."""
    cols = [('BS', 10), ('RMS', 7), ('ratio', 9)] + ([('/bias', 7)] if ratios else [])
    return '  ' + 'model'.ljust(13) + ' | '.join(
        ' '.join(f'{n + " " + a:>{w}}' for a in 'xyz') for n, w in cols)


def format_holdout(result: Mapping[str, Any]) -> str:
    """
    Format the evaluation as the tables ``tools/pan_holdout.py`` prints.

    Parameters
    ----------
    result : mapping
        What :func:`burst_holdout` or :func:`pan_holdout` returned.

    Returns
    -------
    str
        Header, then per scheme: the per-block tables (small schemes), the x-axis floor
        ratios per fold (leave-one-burst-out) and the interior / end / all summaries.

    """
    r = result
    names = [m['name'] for m in r['models']]
    nz = r['noise']
    lines = [
        f'{r["source"]}: {r["samples"]} samples in {r["bursts"]} bursts of '
        f'{r["samples_per_burst"][0]}-{r["samples_per_burst"][1]} (one every '
        f'{r["burst_period_s"]:.0f} s), {r["temperature_first_last_c"][0]:.2f} -> '
        f'{r["temperature_first_last_c"][1]:.2f} degC, T0 = {r["t0_c"]:.2f} degC',
        f'drift of the burst means, last - first: x y z = {_f3(r["drift_dps"], "+.4f")} deg/s',
        f'white noise (within-burst sd at 50 Hz): {_f3(nz["within_burst_sd_dps"], ".4f")} '
        f'deg/s (first differences: {_f3(nz["diff_sd_dps"], ".4f")}); noise floor = '
        f'{_f3(nz["floor_bs_dps2"], ".3e")} (deg/s)^2; burst-mean s.e. '
        f'{_f3(nz["burst_mean_se_dps"], ".4f")} deg/s',
        'models: ' + '; '.join(f'{m["name"]} = {m["description"]}' for m in r['models']),
        'columns: BS in (deg/s)^2 around the reference 0, RMS in deg/s, ratio = BS / noise '
        'floor of the held-out samples (>= 1 up to the temperature-noise term), /bias = BS / '
        'BS of the bias-only baseline']
    for s in r['schemes']:
        sizes = '/'.join(str(v) for v in s['bursts_per_block'])
        lines += ['', f'== {s["name"]}: {s["n_blocks"]} blocks of {sizes} bursts; fit on the '
                  f'others, score the held-out block; temperatures outside the training range '
                  f'clamped =']
        if s['n_blocks'] <= 10:
            for f in s['folds']:
                how = ('interpolation' if f['position'] == 'interior' else
                       f'extrapolation, {100 * f["outside_fraction"]:.0f} % of samples outside '
                       'the training range')
                lines += ['', f'block {f["block"]}: bursts {f["bursts"][0]}-{f["bursts"][1]}, '
                          f'{f["temperature_c"][0]:.2f}..{f["temperature_c"][1]:.2f} degC, '
                          f'{f["position"]} ({how}), floor {_f3(f["floor_bs_dps2"], ".3e")}'
                          + _fitted(f['models']), _head(False)]
                lines += _model_rows(f['models'], names, unclamped=False, ratios=False)
        else:
            lines += ['', 'BS/floor on x per held-out fold:',
                      '  fold  T degC  pos       ' + ' '.join(f'{n:>12}' for n in names)]
            lines += [f'  {f["block"]:>4}  {0.5 * sum(f["temperature_c"]):6.2f}  '
                      f'{f["position"]:<8}  '
                      + ' '.join(f'{f["models"][n]["floor_ratio"][0]:12.2f}' for n in names)
                      for f in s['folds']]
        for g, label, unclamped in (
                ('interior', 'interior blocks (interpolation)', False),
                ('end', 'end blocks (extrapolation), clamped', False),
                ('end', 'end blocks, NOT clamped (models extrapolate)', True),
                ('all', 'all blocks, clamped', False)):
            if (sm := s['summary'][g]) is None:
                continue
            lines += ['', f'mean over {label}: {sm["folds"]} folds, {sm["samples"]} samples, '
                      f'floor {_f3(sm["floor_bs_dps2"], ".3e")}',
                      _head(not unclamped)]
            lines += _model_rows(sm['models'], names, unclamped=unclamped, ratios=True)
    return '\n'.join(lines)
