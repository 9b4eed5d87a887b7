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
The evaluation core: score compensation models on held-out runs, in the paper's terms.

:func:`score` gives BS, BS/BS1, RMS and the Allan deviation of the error per axis;
:func:`evaluate_run` scores every :class:`NamedModel` on one run (a :class:`BagEval` of
:class:`ModelEval`) and :func:`evaluate` does so for bags, one in memory at a time, with
the out-of-range policy and re-anchoring of the compensator. The models and labels are
:mod:`gyro_tdc.evaluate.models`' (:class:`NamedModel` is re-exported here). See
``doc/internals/evaluate.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
import os
from typing import Callable, Sequence

from gyro_tdc.data import BagOptions, find_bags, iter_runs, Run, split_sessions
from gyro_tdc.errors import FitError
from gyro_tdc.evaluate.models import (bag_labels, NamedModel, ONBOARD, onboard_model, safe_label,
                                      with_accel)
from gyro_tdc.identify import (accel_scores, all_constant_error, constant_axes, find_still,
                               MAX_MOVING_SHARE, MIN_SAMPLES, moving_share, rows_of)
from gyro_tdc.model import (check_policy, compensate, CompensationModel, DEFAULT_OUT_OF_RANGE,
                            MAX_EXTRAPOLATION_C, model_temperature)
from gyro_tdc.runtime import default_tolerance, gated_shift, reanchor_shift, STILL_WINDOW_MAX_S
from gyro_tdc.signal import (allan_deviation, auto_window, bias_stability, noise_readouts, rms_dps,
                             STILL_WINDOW_S, stretch_edges)
import numpy as np
from numpy.typing import NDArray

__all__ = ['AUTO_REANCHOR', 'BagEval', 'ModelEval', 'NamedModel', 'evaluate', 'evaluate_run',
           'held_out_constant', 'mean_scores', 'rate_hz', 'score', 'still_rows']

#: ``reanchor_s`` value for the compensator's precision-driven rule.
AUTO_REANCHOR = 'auto'


# --------------------------------------------------------------------------------------------
# Result types
# --------------------------------------------------------------------------------------------

@dataclass
class ModelEval:
    """Scores of one model on one bag: one row of the evaluation's tables and plots."""

    #: The model as given on the command line (a path, or ``px4``).
    model: str
    #: Short unique label for tables, CSV columns and legends.
    label: str
    #: Effect ids of the model.
    features: list
    #: Bias stability after compensation (3,), (deg/s)^2.
    bs: NDArray[np.float64]
    #: RMS of compensated minus reference rate (3,), deg/s.
    rms_dps: NDArray[np.float64]
    #: ``bs`` / raw BS (3,).
    p_vs_raw: NDArray[np.float64]
    #: Allan averaging times (M,), s.
    adev_tau_s: NDArray[np.float64]
    #: Allan deviation of the compensated error (M, 3), deg/s.
    adev_dps: NDArray[np.float64]
    #: Angle random walk read off the Allan curve (3,), deg/sqrt(h).
    arw_deg_sqrt_h: NDArray[np.float64]
    #: Bias instability read off the Allan curve (3,), deg/h.
    bias_instability_deg_h: NDArray[np.float64]
    #: The model's trained range, degC.
    temp_range_c: tuple = (math.nan, math.nan)
    #: Fraction of the scored samples (all, or the still ones of a bag scored still-only)
    #: whose model temperature (the thermal state) lies outside ``temp_range_c`` (evaluated
    #: with the bag's out-of-range policy).
    outside_fraction: float = 0.0
    #: The compensated rate (N, 3), rad/s (kept only while plots and CSVs are written).
    omega: NDArray[np.float64] | None = field(default=None, repr=False)
    #: The re-anchoring with ``reanchor_s='auto'``, its ``samples``, ``duration_s``,
    #: ``shift_dps``, ``se_dps``, ``tolerance_dps`` (3 each) and ``reason``.
    reanchor: dict | None = None
    #: Accelerometer BS (3,), (m/s^2)^2 (variance around the run mean over the still
    #: samples) after the model's accelerometer part (raw: of the raw data); None when not
    #: applicable (no accelerometer data, a run not static, a model without an accelerometer
    #: part).
    accel_bs: NDArray[np.float64] | None = None
    #: The gyro axes the model does not correct, constant in its training data, passed
    #: through unchanged (``model.metrics['constant_axes']``; empty for the raw data).
    constant_axes: list = field(default_factory=list)


@dataclass
class BagEval:
    """Scores of every model on one held-out bag, the raw data scored alike beside them."""

    #: The bag path.
    bag: str
    #: Short unique label (file names of plots and CSVs).
    label: str
    #: Samples scored.
    samples: int
    #: Min and max temperature of the samples scored, degC.
    temperature_c: tuple
    #: Time scored, s, the bag's span or the still time of a bag scored still-only.
    duration_s: float
    #: Where the reference rate came from (``constant``, ``topic``, ``zero``).
    reference: str
    #: The uncompensated data scored like a model (``p_vs_raw`` = 1).
    raw: ModelEval
    #: One :class:`ModelEval` per model, in command-line order.
    models: list
    #: The data (kept only while plots and CSVs are written).
    run: Run | None = field(default=None, repr=False)
    #: The out-of-range policy the models were evaluated with (:func:`evaluate_run` sets
    #: it; ``'clamp'`` when a result is built by hand).
    out_of_range: str = 'clamp'
    #: The gyro axes that are constant on this bag by ``train``'s rule (readings never
    #: varying beyond one quantum, :func:`gyro_tdc.identify.constant_axes`: a 2-axis gyro's
    #: filled-in 0, a dead axis; judged on bags of at least ``MIN_SAMPLES`` = 50 samples, as
    #: many as ``train`` fits), or that read exactly their reference rate on every sample
    #: (raw BS 0): there is no signal to score, BS/BS1 does not apply there (NaN, not a
    #: number to read).
    constant_axes: list = field(default_factory=list)
    #: For data without a reference that move (:func:`still_rows`), only the still
    #: stretches were scored, raw and models alike each session re-anchored on its first
    #: still stretch (as the compensator does at start-up); what was scored: ``samples``,
    #: ``stretches``, ``still_s``, ``temperature_c``; the whole bag: ``total_samples``,
    #: ``total_s``, ``total_temperature_c``; ``share`` (``still_s / total_s``, at most 1),
    #: ``sessions`` (their number) and ``per_session`` (the same eight per session). None:
    #: every sample was scored.
    still: dict | None = None

    def release(self) -> None:
        """Drop the sample arrays (keep the scores)."""
        self.run = None
        for m in [self.raw, *self.models]:
            m.omega = None


# --------------------------------------------------------------------------------------------
# Scoring
# --------------------------------------------------------------------------------------------

def rate_hz(t: NDArray[np.float64]) -> float:
    """Return the sample rate in Hz from the median stamp step (1 for fewer than 2 stamps)."""
    return 1.0 / float(np.median(np.diff(t))) if len(t) > 1 else 1.0


def score(omega: NDArray[np.float64], run: Run, *, label: str = 'raw', model: str = 'raw',
          features: Sequence[str] = (), bs_raw: NDArray[np.float64] | None = None,
          allan: bool = True) -> ModelEval:
    """
    Score one compensated (or raw) rate ``omega`` (N, 3, rad/s) against the run's reference.

    BS = mean((omega - omega_ref)^2) per axis in (deg/s)^2 (paper eq. 30), RMS in deg/s,
    BS / ``bs_raw`` (ones when None; NaN without a warning where the raw BS is 0), the
    Allan deviation of the error at the stamps' rate (:func:`rate_hz`; empty below 4
    samples or with ``allan`` False, e.g. held-out samples with gaps) and its readouts;
    ``omega`` is kept. ``label``, ``model`` and ``features`` name what is scored.
    """
    err, bs = omega - run.omega_ref, bias_stability(omega, run.omega_ref)
    tau, adev = (allan_deviation(err, rate_hz(run.t)) if allan and len(run) >= 4
                 else (np.zeros(0), np.zeros((0, 3))))
    nr = noise_readouts(tau, adev)
    # An axis reading its reference exactly (raw BS 0): no ratio; one a hair off it
    # (a subnormal raw BS) overflows to inf, which the caller flags as constant.
    with np.errstate(over='ignore'):
        p = np.ones(3) if bs_raw is None else np.divide(
            bs, np.asarray(bs_raw, dtype=np.float64), out=np.full(3, math.nan),
            where=np.asarray(bs_raw) > 0)
    return ModelEval(model=model, label=label, features=list(features), bs=bs,
                     rms_dps=rms_dps(err), p_vs_raw=p, adev_tau_s=np.asarray(tau),
                     adev_dps=np.asarray(adev), arw_deg_sqrt_h=nr['arw_deg_sqrt_h'],
                     bias_instability_deg_h=nr['bias_instability_deg_h'], omega=omega)


def _reanchored(comp: NDArray[np.float64], run: Run, model: CompensationModel,
                reanchor_s: float | str) -> tuple[NDArray[np.float64], dict | None]:
    """Return ``comp`` minus its mean error over the head of the session, and what was done."""
    if reanchor_s == AUTO_REANCHOR:
        tol = default_tolerance(model.residual_var)
        r = reanchor_shift(run.t, comp - run.omega_ref, tolerance=tol, window=STILL_WINDOW_S,
                           window_max=STILL_WINDOW_MAX_S)
        deg, delta = np.degrees, gated_shift(model, r.delta)      # the model's gate, as the node
        return comp - delta, {
            'samples': int(r.samples), 'duration_s': float(r.duration_s),
            'shift_dps': deg(delta).tolist(), 'se_dps': deg(r.se).tolist(),
            'tolerance_dps': deg(tol).tolist(), 'reason': r.reason}
    if reanchor_s > 0:
        head = run.t <= run.t[0] + reanchor_s
        comp = comp - (comp[head] - run.omega_ref[head]).mean(axis=0)
    return comp, None


def _compensated(nm: NamedModel, parts: Sequence[Run], reanchor_s: float | str,
                 out_of_range: str, max_extrapolation_c: float
                 ) -> tuple[NDArray[np.float64], dict | None]:
    """
    Return a model's compensated rate over the sessions of a run, each re-anchored on its own.

    Each session is compensated from its start (the filters start over, as the compensator
    does on a new power cycle) and re-anchored over its own head; with several, the
    re-anchoring record is the first session's with ``sessions``: one record per session.
    """
    comps, infos = zip(*(_reanchored(compensate(nm.model, part.t, part.temp, part.omega,
                                                out_of_range=nm.out_of_range or out_of_range,
                                                max_extrapolation_c=max_extrapolation_c),
                                     part, nm.model, reanchor_s) for part in parts))
    if len(parts) == 1:
        return comps[0], infos[0]
    info = None if infos[0] is None else dict(infos[0], sessions=list(infos))
    return np.concatenate(comps), info


def evaluate_run(run: Run, models: Sequence[NamedModel], *, label: str = '',
                 reanchor_s: float | str = 0.0, out_of_range: str = DEFAULT_OUT_OF_RANGE,
                 max_extrapolation_c: float = MAX_EXTRAPOLATION_C, sessions: str = 'auto',
                 session_gap_s: float = 0.0, still: NDArray[np.bool_] | None = None
                 ) -> BagEval:
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
    reanchor_s : float (s) or ``'auto'``
        > 0: remove each session's mean model error over its first ``reanchor_s`` seconds,
        as the compensator re-anchors at start-up; ``'auto'``: the compensator's rule
        (:func:`gyro_tdc.runtime.reanchor.reanchor_shift`). Raw data are never re-anchored.
    out_of_range, max_extrapolation_c : str, float (degC)
        The policy beyond a model's range and the reach of the ``linear`` tangent.
    sessions, session_gap_s : str, float (s)
        How the run is cut into sessions (:func:`gyro_tdc.data.split_sessions`).
    still : NDArray[np.bool_], shape (N,), optional
        Score these samples only (data without a reference, :func:`still_rows`): raw and
        models re-anchored per session on its first still stretch, no Allan deviation.

    Returns
    -------
    BagEval
        With the arrays (call ``release()`` after); BS/BS1 NaN on the constant axes.

    """
    check_policy(out_of_range)
    const = _constant(run)
    parts = split_sessions([run], sessions, session_gap_s).runs
    bounds = np.cumsum([0] + [len(p) for p in parts])
    whole, summary, spans = run, None, None
    if still is not None:
        # The still stretches: the still test's gap rule, and each session's end.
        spans = stretch_edges(still, np.diff(run.t), auto_window(run.t), bounds[1:-1] - 1)
        summary = _still_summary(run, still, bounds, spans)
        whole, reanchor_s = rows_of(run, still), 0.0

    def pick(x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return what is scored of a rate: the still samples, each session anchored."""
        return x if still is None else _anchor_first_still(x, spans, bounds)[still]
    raw = score(pick(run.omega), whole, allan=still is None)
    const |= ~(raw.bs > 0)                  # an axis reading its reference exactly
    raw.accel_bs, per_model = accel_scores(run, [nm.model for nm in models],
                                           out_of_range=out_of_range,
                                           max_extrapolation_c=max_extrapolation_c)
    out = []
    for nm, accel_bs in zip(models, per_model):
        m = nm.model
        comp, info = _compensated(nm, parts, reanchor_s, out_of_range, max_extrapolation_c)
        ev = score(pick(comp), whole, label=nm.label, model=nm.name, features=list(m.features),
                   bs_raw=raw.bs, allan=still is None)
        ev.reanchor, ev.accel_bs = info, accel_bs
        ev.constant_axes = [str(a) for a in m.metrics.get('constant_axes', ())]
        ev.p_vs_raw[const] = math.nan       # no signal to score there
        ev.temp_range_c = lo, hi = tuple(m.temp_range_c)
        # The range is the thermal state's, which runs over the whole bag.
        temp = model_temperature(m, run.t, run.temp)[slice(None) if still is None else still]
        ev.outside_fraction = float(np.mean((temp < lo) | (temp > hi))) if len(temp) else 0.0
        out.append(ev)
    return BagEval(bag=run.name, label=label or safe_label(run.name), samples=len(whole),
                   temperature_c=(float(whole.temp.min()), float(whole.temp.max())),
                   duration_s=run.duration_s if still is None else summary['still_s'],
                   reference=str(run.info.get('reference', '?')),
                   raw=raw, models=out, run=whole, out_of_range=out_of_range,
                   constant_axes=[a for a, c in zip('xyz', const) if c], still=summary)


def still_rows(run: Run) -> NDArray[np.bool_] | None:
    """
    Return the samples to score of a run without a reference that moves, None for all.

    A run whose reference rate is zero only because it has none (a flight log, a bag
    without the reference topic) is known to be at rest only while still: where it moves
    longer than :data:`gyro_tdc.identify.MAX_MOVING_SHARE` of the time, only its still
    stretches (the trainers' still test with its defaults) are scored; its motion is no
    drift.
    """
    moving = run.info.get('reference') == 'zero' and not moving_share([run]) <= MAX_MOVING_SHARE
    return find_still([run])[0].mask if moving else None


def _anchor_first_still(x: NDArray[np.float64], spans: tuple,
                        bounds: NDArray[np.int64]) -> NDArray[np.float64]:
    """Return ``x`` less, per session, its mean over the session's first still stretch."""
    out = np.array(x, dtype=np.float64, copy=True)
    starts, stops = spans
    first = np.searchsorted(starts, bounds).tolist()    # session i: stretches first[i]:first[i+1]
    for a, b, k, end in zip(bounds[:-1].tolist(), bounds[1:].tolist(), first, first[1:]):
        if k < end:
            out[a:b] -= out[starts[k]:stops[k]].mean(axis=0)
    return out


def _span_c(temp: NDArray[np.float64]) -> list | None:
    """Return ``[min, max]`` of temperatures in degC (None for none)."""
    return [float(temp.min()), float(temp.max())] if temp.size else None


def _still_summary(run: Run, still: NDArray[np.bool_], bounds: NDArray[np.int64],
                   spans: tuple) -> dict:
    """
    Return how much of a run the still-only scoring covers, in all and per session.

    Each figure says whose it is: the scored part's (``samples``, ``stretches``, ``still_s``,
    ``temperature_c``) or the whole bag's or session's (``total_*``), so a flight log's range
    is never read as the range scored.
    """
    dt = float(np.median(np.diff(run.t))) if len(run) > 1 else 0.0

    def part(a: int, b: int, figures: dict | None = None) -> dict:
        """Return the figures of samples ``a:b``: counted, or (``figures``) summed."""
        if figures is None:
            n = int(np.count_nonzero(still[a:b]))
            figures = {'samples': n,
                       'stretches': int(np.diff(np.searchsorted(spans[0], [a, b]))[0]),
                       'total_samples': b - a,
                       'still_s': n * dt,           # a logging gap is no still time
                       'total_s': float(run.t[b - 1] - run.t[a] + dt) if b > a else 0.0}
        total_s, temp = figures['total_s'], run.temp[a:b]
        return {**figures, 'temperature_c': _span_c(temp[still[a:b]]),
                'total_temperature_c': _span_c(temp),
                'share': min(figures['still_s'] / total_s, 1.0) if total_s > 0 else 0.0}

    per = [part(a, b) for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist())]
    keys = ('samples', 'stretches', 'still_s', 'total_samples', 'total_s')
    whole = part(0, len(run), {k: sum(p[k] for p in per) for k in keys})
    return {**whole, 'sessions': len(per), 'per_session': per}


def _constant(run: Run) -> NDArray[np.bool_]:
    """Return ``train``'s constant axes of a run of at least as many samples as it fits."""
    # Too few samples to tell a constant axis from a quiet one: none.
    return np.zeros(3, dtype=bool) if len(run) < MIN_SAMPLES else constant_axes(run.omega)


def held_out_constant(run: Run) -> NDArray[np.bool_]:
    """
    Return, per axis, whether a held-out run's gyro is constant (``train``'s rule).

    An axis whose readings never vary beyond one quantum
    (:func:`gyro_tdc.identify.constant_axes`) over a run of at least
    :data:`gyro_tdc.identify.fit.MIN_SAMPLES` samples (what ``train`` needs) holds no
    signal to score.

    Raises
    ------
    DatasetError
        When every axis is: there is no gyro to evaluate.

    """
    if (const := _constant(run)).all():
        raise all_constant_error([run.omega], 'evaluate', run.name)
    return const


def evaluate(bags: Sequence[str | os.PathLike], models: Sequence[NamedModel], *,
             bag: BagOptions | None = None, reanchor_s: float | str = 0.0,
             out_of_range: str = DEFAULT_OUT_OF_RANGE,
             max_extrapolation_c: float = MAX_EXTRAPOLATION_C,
             log: Callable[[str], None] | None = None,
             each: Callable[[BagEval], None] | None = None,
             found: list | None = None) -> list:
    """
    Evaluate models on held-out bags, one bag in memory at a time.

    ``bags`` (folders walked; a log found there that cannot be read is skipped, said on
    ``log``) are read as ``bag`` says (the accelerometer always) and cut into sessions;
    ``reanchor_s``, ``out_of_range`` and ``max_extrapolation_c`` as in
    :func:`evaluate_run`. ``log`` receives one line per bag;
    ``each`` is called with every :class:`BagEval` while its arrays are held (tables, plots,
    CSV). A bag without a reference that moves is scored on its still stretches only; one
    with none is skipped, said on ``log`` (FitError when no bag is left to score).
    ``found``: :func:`gyro_tdc.data.find_bags` of ``bags``, when the caller has it.

    Raises
    ------
    GyroTdcError
        DatasetError: unreadable bag, or every gyro axis constant; FitError: no bag with a
        reference or a still stretch.

    """
    check_policy(out_of_range)
    o = with_accel(bag)
    found = find_bags(bags) if found is None else found
    paths = [p for p, _ in found]
    labels = dict(zip(map(str, paths), bag_labels(paths)))
    results, unscored = [], []
    for run in iter_runs(bags, o, log=log, found=found):   # unreadable skipped
        held_out_constant(run)              # every gyro axis constant: refused
        here = [replace(nm, model=onboard_model(nm.name, run)[0]) if nm.name in ONBOARD
                else nm for nm in models]         # each log's own on-board parameters
        # Nothing to score: said, skipped.
        if (still := still_rows(run)) is not None and not still.any():
            unscored.append(f'{run.name}: no reference rate and no still stretch to score '
                            '(the IMU moves throughout; its motion is no drift).')
            if log is not None:
                log(f'warning: skipped {unscored[-1]}')
            continue
        b = evaluate_run(run, here, label=labels[run.name], reanchor_s=reanchor_s,
                         out_of_range=out_of_range, max_extrapolation_c=max_extrapolation_c,
                         sessions=o.sessions, session_gap_s=o.session_gap_s, still=still)
        if each is not None:
            each(b)
        b.release()
        results.append(b)
    if unscored and not results:
        raise FitError(unscored[0] if len(unscored) == 1 else
                       f'no log has a still stretch to score ({len(unscored)} read); '
                       f'{unscored[0]}')
    return results


def mean_scores(results: Sequence[BagEval]) -> list:
    """
    Return the mean BS and BS/BS1 per model and axis over bags (BS/BS1 averaged per bag).

    ``(label, mean BS in (deg/s)^2, mean BS/BS1)`` for raw data, then each model; BS/BS1
    over the bags where it is a number (NaN, no warning, on an axis constant in every bag).
    """
    rows = [('raw', [b.raw for b in results])] + [
        (m.label, [b.models[i] for b in results]) for i, m in enumerate(results[0].models)]
    out = []
    for label, evs in rows:
        p = np.array([e.p_vs_raw for e in evs], dtype=np.float64)
        ok = np.isfinite(p)
        n = ok.sum(axis=0)
        mean_p = np.divide(np.where(ok, p, 0.0).sum(axis=0), n, out=np.full(3, math.nan),
                           where=n > 0)
        out.append((label, np.mean([e.bs for e in evs], axis=0), mean_p))
    return out
