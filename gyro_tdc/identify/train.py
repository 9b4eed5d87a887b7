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

:func:`train` fits a chamber's (or any referenced) bags; :func:`train_still_only` the still
stretches of bags recorded in ordinary operation (``train --still-only``, and ``train`` on
moving data without a reference). Both cut the bags into sessions, pass constant gyro axes
through, choose the features (``--features auto``: :func:`choose_features`, the paper's
f(dT, dT2) plus what discovery finds the data support, recorded in a :class:`FeatureChoice`),
fit on the shared estimator, add the accelerometer part and save; the command line is
:mod:`gyro_tdc.cli.train`. See ``doc/internals/identify.md``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass, field, replace
import math
import os
from pathlib import Path
from typing import Any, Callable, Sequence

from gyro_tdc.base import check_bin_width, check_centers, DEG_PER_RAD
from gyro_tdc.data import (BagOptions, Coverage, coverage, imu_of, load_runs, read_motion, Run,
                           split_sessions)
from gyro_tdc.errors import DatasetError, FitError, ModelFileError
from gyro_tdc.identify.accel import AccelFit, fit_accel
from gyro_tdc.identify.axes import (constant_gyro_axes, constant_readings, identity_axes,
                                    neutral_runs)
from gyro_tdc.identify.discover.results import DiscoveryResult
from gyro_tdc.identify.discover.search import discover
from gyro_tdc.identify.fit import (check_choices, estimate_t0, fit_model, FitOptions, MIN_SPAN_C,
                                   span)
from gyro_tdc.identify.power_cycles import MIN_FOLDS, reanchor_rule, SLOW_CURVE_S, told_alone
from gyro_tdc.identify.still_only import (ADVICE_PARK_MIN, find_still, fit_without_outliers,
                                          MAX_MOVING_SHARE, MIN_STILL_SPAN_C, rows_of,
                                          still_report, Stretch, unreferenced,
                                          unreferenced_motion)
from gyro_tdc.model import check_model, CompensationModel, EFFECTS, normalise_ids, save_model
from gyro_tdc.signal import block_mean, MIN_SESSION_SPAN_C, motion_veto
import numpy as np
from numpy.typing import NDArray

__all__ = ['AUTO', 'AUTO_BASE', 'choose_features', 'data_frame', 'Decision', 'FeatureChoice',
           'features_for_fit', 'proxy_lag', 'SEARCH_RATE_HZ', 'train', 'train_still_only',
           'TrainOptions', 'TrainResult']

Log = Callable[[str], None] | None


#: The ``features`` value that lets the data choose (:func:`choose_features`).
AUTO = 'auto'
#: The starting model of ``auto``: the paper's modified model f(dT, dT2) (eq. 16).
AUTO_BASE: tuple[str, ...] = ('dT', 'dT2')
#: Sample rate (Hz) the feature search of ``auto`` runs at: faster runs are averaged down.
SEARCH_RATE_HZ = 20.0


@dataclass(frozen=True)
class Decision:
    """One effect of the automatic choice: base, added, rejected or unidentifiable, and why."""

    effect: str
    verdict: str
    why: str

    def line(self) -> str:
        """Return the decision as one line of the training report."""
        if self.verdict == 'added':
            return f'  + {self.effect}: {self.why}'
        verdict = {'unidentifiable': 'not identifiable'}.get(self.verdict, self.verdict)
        return f'  - {self.effect}: {verdict}: {self.why}'


@dataclass(frozen=True)
class FeatureChoice:
    """
    What ``features='auto'`` chose, and why.

    ``base`` the starting model, ``features`` the chosen effects (catalog order), ``decisions`` one
    per effect considered (the base, those added in order, rejected, not identifiable);
    ``discovery`` the search behind it (None when the data were too short, ``note`` says why);
    ``dropped`` why the model keeps none of them after all (empty: it keeps them).
    """

    base: tuple[str, ...]
    features: tuple[str, ...]
    decisions: tuple[Decision, ...]
    discovery: DiscoveryResult | None = field(default=None, repr=False)
    note: str = ''
    dropped: str = ''

    def lines(self) -> list[str]:
        """Return the report: a head line, one line per decision, notes, the features chosen."""
        d = self.discovery
        head = (f'features auto: start from {", ".join(self.base)} (the paper\'s f(dT, dT^2)); '
                + (f'discovery on {len(d.runs)} bag(s): noise floor {d.noise_floor_dps:.3g} '
                   f'deg/s on {d.block_s:g} s block means, held out by '
                   f'{d.settings["folds"]}' if d is not None else self.note))
        # What the data cannot test (one direction of temperature change): said once.
        notes = [f'  note: {n}' for n in (d.notes if d is not None else ())
                 if n.startswith('The data only')]
        return ([head] + [x.line() for x in self.decisions if x.verdict != 'base'] + notes
                + [f'features chosen: {", ".join(self.features)}'
                   + (f'; not kept: {self.dropped}' if self.dropped else '')])

    def to_dict(self) -> dict:
        """Return the choice as plain types (the model's ``training`` metrics)."""
        d = self.discovery
        out = {'mode': AUTO, 'base': list(self.base), 'chosen': list(self.features),
               'decisions': [asdict(x) for x in self.decisions],
               **({'dropped': self.dropped} if self.dropped else {})}
        if d is None:
            return {**out, 'note': self.note}
        out['discovery'] = {
            **{k: float(getattr(d, k)) for k in ('noise_floor_dps', 'gap_dps', 'heldout_gap_dps')},
            'folds': d.settings['folds'], 'block_s': float(d.block_s),
            'thermal': None if d.thermal is None else d.thermal.to_dict()}
        return out


def _for_search(run: Run) -> Run:
    """
    Return ``run`` averaged down to about :data:`SEARCH_RATE_HZ` for the feature search.

    The search works on block means of seconds; averaging groups of samples first leaves
    those block means and their white-noise floor as they are (a mean of means), and makes
    the search on a 1 kHz recording cost what it costs at 20 Hz.
    """
    dt = np.diff(run.t)
    rate = 1.0 / p if dt.size and (p := float(np.median(dt))) > 0 else 0.0
    m = int(rate // SEARCH_RATE_HZ)
    if m < 2 or len(run) < 2 * m:
        return run
    means = [block_mean(x, m, partial=False) for x in (run.t, run.temp, run.omega, run.omega_ref)]
    return Run(*means, run.name, dict(run.info))


def _floors(value: float, floor: float) -> str:
    """Return a gap in noise floors, e.g. ``2.3x``."""
    return f'{value / floor:.2f}x' if floor > 0 else f'{value:.3g} deg/s'


def choose_features(runs: Sequence[Run], *, t0: float | None = None,
                    base: Sequence[str] = AUTO_BASE, block_s: float = 10.0) -> FeatureChoice:
    """
    Choose the features of a model from the data: the paper's base plus what they support.

    :func:`gyro_tdc.identify.discover.discover` starts from ``bias`` and ``base`` and adds,
    one at a time, the catalog effect its false-discovery guard accepts (held-out gain, HAC
    test, effect size). The base is kept whatever the data say; data too short for the search
    keep it, with a note. Runs faster than :data:`SEARCH_RATE_HZ` are averaged down first (the
    search works on block means of ``block_s``).
    """
    base_ids = tuple(e for e in normalise_ids(base) if e != 'bias')
    decisions = [Decision(e, 'base', "the paper's model") for e in base_ids]
    if t0 is None and runs:
        t0 = estimate_t0(runs[0])
    try:
        res = discover([_for_search(r) for r in runs], base=('bias',) + base_ids, t0=t0,
                       block_s=block_s, allan=False)
    except FitError as exc:
        return FeatureChoice(base_ids, base_ids, tuple(decisions),
                             note=f'no search ({exc}); the base is kept')
    floor = res.noise_floor_dps
    for s in res.steps:
        b = s.best
        why = (f'held-out gap {_floors(s.heldout_gap_before_dps, floor)} -> '
               f'{_floors(s.heldout_gap_after_dps, floor)} floor, HAC p {b.p_value:.2g}, '
               f'effect {b.effect_rms_dps:.3g} deg/s')
        if s.effect == 'lag' and s.thermal is not None:
            why += f'; {s.thermal.describe()}'
        elif s.params:
            why += '; ' + ', '.join(f'{k} = {v:.4g}' for k, v in s.params.items())
        if s.aliases:
            why += f'; the data cannot tell it from {", ".join(s.aliases)}'
        decisions.append(Decision(s.effect, 'added', why))
    decisions += [Decision(c.effect, 'rejected', f'{c.why_not} (held-out gain '
                           f'{c.heldout_gain_dps2:+.2g} (deg/s)^2, HAC p {c.p_value:.2g})')
                  for c in res.candidates]
    decisions += [Decision(u.effect, 'unidentifiable', f'{u.reason}') for u in res.unidentifiable]
    seen = {x.effect for x in decisions}          # every catalog effect gets its line
    decisions += [Decision(e, 'rejected', 'not tested') for e in EFFECTS
                  if e != 'bias' and e not in seen]
    features = tuple(e for e in res.final_effects if e != 'bias')
    return FeatureChoice(base_ids, features, tuple(decisions), discovery=res)


def features_for_fit(runs: Sequence[Run], features: str | tuple[str, ...], *, t0: float | None
                     ) -> tuple[tuple[str, ...], dict, FeatureChoice | None]:
    """
    Return the features a fit takes, their fixed parameters and the choice behind them.

    ``features`` is ``'auto'`` (chosen on ``runs``; the parameters are the time constants
    discovery found that ``fit_model`` does not search itself) or effect ids (no choice: None).
    """
    if features != AUTO:
        return normalise_ids(features), {}, None
    # Data the search cannot analyse keep the base, and fit_model then says what is wrong
    # with them (span, samples) as it does for named features.
    choice = choose_features(runs, t0=t0)
    d = choice.discovery
    return choice.features, {} if d is None else {
        k: v for k, v in d.params.items() if k in choice.features and not EFFECTS[k].fitted
    }, choice


@dataclass(frozen=True)
class TrainOptions:
    """
    How to train a model, checked when built so that a bad choice fails before any bag is read.

    ``features`` is ``'auto'`` (the paper's ``dT,dT2`` plus what
    :func:`choose_features` finds the data support) or effect ids
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

    def fit_options(self, **kw: Any) -> FitOptions:
        """Return the :class:`FitOptions` of these choices (``kw``: the fit's other fields)."""
        return FitOptions(kind=self.kind, n_centers=self.n_centers, refine=self.refine,
                          ridge=self.ridge, seed=self.seed, thermal=self.thermal,
                          sensor_id=str(self.sensor_id), **kw)


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


def data_frame(runs: Sequence[Run]) -> str:
    """
    Return the one frame the runs were recorded in (``run.info['frame_id']``), '' for none.

    The model's ``sensor.frame_id``: the compensator warns when its input is in another one.
    DatasetError when the runs were recorded in different frames (a model corrects per axis).
    """
    frames: dict[str, str] = {}
    for run in runs:
        frames.setdefault(str(run.info.get('frame_id') or ''), run.name)
    frames.pop('', None)            # no frame recorded
    if len(frames) > 1:
        named = ', '.join(f'{name}: {frame!r}' for frame, name in frames.items())
        raise DatasetError(f'Expected the IMU data of every bag in one frame (a model corrects '
                           f'per axis), got {len(frames)} frames ({named}); train one model '
                           'per frame.')
    return next(iter(frames), '')


def proxy_lag(runs: Sequence[Run], ids: tuple, options: TrainOptions, log: Log = None) -> tuple:
    """
    Return the features with the thermal state (``lag``) added when a proxy is the thermometer.

    A barometer (``--temperature-source``) sits on the board beside the IMU and lags its
    die: with ``--features auto`` the thermal state is on by default for it.
    """
    if not options.auto or 'lag' in ids or not any(
            r.info.get('temperature_proxy') for r in runs):
        return ids
    if log is not None:
        log("features: lag added (the thermometer is a proxy of the IMU's, which lags it)")
    return normalise_ids(tuple(ids) + ('lag',))


def _features(o: TrainOptions, on: Sequence[Run], runs: Sequence[Run], t0: float, log: Log,
              **kw: Any) -> tuple[FitOptions, FeatureChoice | None]:
    """Return the fit's options (``kw``: its other fields) with the features chosen on ``on``."""
    ids, params, choice = features_for_fit(on, o.features, t0=t0)
    return o.fit_options(features=proxy_lag(runs, ids, o, log), params=params or None, t0=t0,
                         **kw), choice


def _finish(model, o: TrainOptions, out: str | os.PathLike, accel_runs: Sequence[Run], choice,
            metrics: dict, min_folds: int = 1, **result) -> TrainResult:
    """Add the accelerometer part and the training records, save, return the result."""
    accel_fit = (fit_accel(accel_runs, model, n_centers=o.n_centers, seed=o.seed, bin_c=o.bin_c,
                           min_folds=min_folds) if o.accel else None)
    model = model.replace(accel=None if accel_fit is None else accel_fit.part, metrics={
        **model.metrics, **metrics, **({} if choice is None else {'features': choice.to_dict()})})
    return TrainResult(model=model, path=Path(save_model(model, out)), choice=choice,
                       accel=accel_fit, **result)


def _gate(model, fo: FitOptions, runs: Sequence[Run], labels: Sequence[int],
          rows: Sequence[NDArray[np.bool_]] | None = None):
    """
    Return ``model`` with the start-up shift the node takes per axis, decided on the sessions.

    Each session is refitted without the others at the model's features, parameters and
    thermal state (on ``rows`` of each run when given: the still rows).
    """
    form = replace(fo, features=model.features, params=model.effect_params, fit_params=False,
                   thermal=model.thermal)
    return reanchor_rule(model, runs, labels, lambda others, g, **rows_kw: fit_model(
        others, form, sessions=g, **rows_kw), rows)


def train(bags: Sequence[str | os.PathLike], out: str | os.PathLike,
          options: TrainOptions | None = None, bag: BagOptions | None = None, *,
          command: str = '', log: Log = None) -> TrainResult:
    """
    Load bags (one run each, cut into sessions as ``bag.sessions`` says), fit a model, save it.

    Every session gets its own turn-on offset beside one shared thermal curve. Data without a
    reference rate that move longer than :data:`~gyro_tdc.identify.still_only.MAX_MOVING_SHARE`
    of the time are trained on their still stretches only (:func:`train_still_only`, said on
    ``log``): motion is no drift; still ones keep the offset only where one power cycle cannot
    tell its curve, as there (:func:`_one_power_cycle`). A constant gyro axis is not fitted:
    the model passes it through (``result.constant``, ``model.metrics['constant_axes']``).
    The start-up shift the node takes per axis is decided on the sessions
    (:func:`~gyro_tdc.identify.power_cycles.reanchor_rule`, ``model.metrics['reanchor']``).
    GyroTdcError
    (DatasetError, FitError, ModelFileError, OutputError) for what cannot be read, fitted or
    written.
    """
    o = TrainOptions() if options is None else options
    bag = replace(BagOptions() if bag is None else bag, accel=bool(o.accel))
    runs = _load(bags, bag, log, log)
    if (share := unreferenced_motion(runs)[0]) > MAX_MOVING_SHARE:
        if log is not None:
            log(f'no reference rate and the IMU moves {100.0 * share:.3g} % of the time: '
                'training on the still stretches only (as --still-only)')
        return train_still_only(bags, out, o, bag, command=command, log=log, runs=runs)
    names = [r.name for r in runs]
    split = split_sessions(runs, bag.sessions, bag.session_gap_s)
    runs = split.runs
    const = constant_gyro_axes(runs)
    fitted = neutral_runs(runs, const)
    fo, choice = _features(o, fitted, runs, estimate_t0(runs[0]) if o.t0 is None else o.t0, log)
    lo, hi = span([r.temp for r in runs])
    if hi - lo >= MIN_SPAN_C and unreferenced(runs):
        # Still, no reference: as --still-only (a smaller span is refused by the fit).
        fo, choice = _one_power_cycle(runs, [(i, 0, len(r)) for i, r in enumerate(runs)],
                                      split.labels, fo, choice, log)
    model = fit_model(fitted, fo, sessions=split.labels, frame_id=data_frame(runs),
                      created={'command': command, 'bags': names, **_imus(runs)})
    model = _gate(identity_axes(model, runs, const), fo, fitted, split.labels)
    return _finish(model, o, out, runs, choice, {}, coverage=coverage(runs, bin_c=o.bin_c),
                   bags=names, samples=sum(len(r) for r in runs), sessions=split,
                   constant=constant_readings(runs, const))


def _load(bags: Sequence[str | os.PathLike], bag: BagOptions, log: Log, said: Log) -> list[Run]:
    """
    Load the bags (what loading says goes to ``said``), one run each.

    Warns on ``log`` when the logs name more than one board: one model fits none of them.
    """
    runs = load_runs(bags, bag, log=said)
    boards = Counter(r.info['board'] for r in runs if r.info.get('board'))
    if len(boards) > 1 and log is not None:
        log(f'warning: the logs come from {len(boards)} boards ('
            + '; '.join(f"{b}: {n} log{'s' * (n > 1)}" for b, n in boards.items())
            + '): each board drifts its own way, and one model of them fits none; train '
            'each board apart (gyro-tdc fleet calibrates many)')
    return runs


def _imus(runs: Sequence[Run]) -> dict:
    """Return ``created['imus']``: the IMUs the logs name (``evaluate`` warns on another)."""
    imus = sorted({i for i in (imu_of(r.info) for r in runs) if i})
    return {'imus': imus} if imus else {}


def _drop_curve(fo: FitOptions, choice: FeatureChoice | None, log: Log, why: str,
                dropped: str) -> tuple[FitOptions, FeatureChoice | None]:
    """
    Return ``fo`` without features and ``choice`` saying why: the model keeps the offsets.

    ``why`` opens the line said on ``log`` (with its separator), ``dropped`` the choice's note.
    """
    if log is not None:
        log(f'{why} the model keeps the offset only on every axis (re-anchoring still applies)')
    return replace(fo, features=()), None if choice is None else replace(
        choice, dropped=f'{dropped}, the model keeps the offset only')


def _one_power_cycle(runs: Sequence[Run], spans: Sequence[tuple[int, int, int]],
                     labels: Sequence[int], fo: FitOptions, choice: FeatureChoice | None,
                     log: Log) -> tuple[FitOptions, FeatureChoice | None]:
    """
    Return ``fo`` and ``choice``, offset only where one power cycle's curve rests on stops.

    With one session no power cycle is held out (fewer than ``MIN_FOLDS`` judge the curve).
    Told across stops, none spanning ``MIN_SESSION_SPAN_C`` of its own (quarter means), it
    did not carry to the next power cycle on real boards: the offset only. A still stretch
    of ``SLOW_CURVE_S`` or more over that span (a parked day, a chamber ramp) tells the curve
    on its own: kept. A shorter one is the first minutes after power-on, when the gyro settles
    and the board self-heats fastest: on real boards its curve did not carry either.
    """
    if len(set(labels)) > 1 or not fo.features or not spans:
        return fo, choice
    told = [(float(np.ptp(block_mean(runs[i].temp[a:b], max(1, (b - a) // 4), partial=False))),
             float(runs[i].t[b - 1] - runs[i].t[a])) for i, a, b in spans]
    if told_alone(told):
        return fo, choice
    widest, lasting = max(told)
    return _drop_curve(
        fo, choice, log, f'one power cycle only, and no still stretch of {SLOW_CURVE_S / 60:g} '
        f'min or more spans {MIN_SESSION_SPAN_C:g} degC of its own (the widest {widest:.2f} '
        f'degC in {lasting / 60:.1f} min): no held-out power cycle can tell whether its curve '
        'of stops carries to the next;', 'one power cycle of stops cannot judge its curve')


def train_still_only(bags: Sequence[str | os.PathLike], out: str | os.PathLike,
                     options: TrainOptions | None = None, bag: BagOptions | None = None, *,
                     command: str = '', log: Log = None, runs: Sequence[Run] | None = None,
                     moving: Sequence[NDArray[np.bool_] | None] | None = None) -> TrainResult:
    """
    Fit a model on the still stretches of bags recorded in ordinary operation.

    As :func:`train`, with no reference read (the rate is zero while still) and
    ``bag.motion_topic`` (a Twist, TwistStamped or Odometry topic) vetoing stillness while it
    reports motion; ``runs`` (and their ``moving`` veto) are runs already loaded. The thermal
    state runs over every sample; stretches that look like slow turns are dropped; ``t0``
    defaults to the temperature at the start of the first still stretch; ``result.still`` is
    the :class:`~gyro_tdc.identify.still_only.StillReport` and ``coverage`` and ``samples``
    those of the still time kept; the start-up shift the node takes per axis is decided on
    the sessions' still rows, as :func:`train` decides it. FitError when no still stretch is
    found or their temperatures span less than ``MIN_STILL_SPAN_C`` (saying what to record).
    """
    o = TrainOptions() if options is None else options
    bag = BagOptions() if bag is None else bag
    if runs is None:    # no reference read (the rate is zero while still); the motion veto
        said = None if log is None else (lambda line: log(line.replace(
            'constant reference rate (--reference)', 'no reference read (still: zero rate)')))
        runs = _load(bags, replace(bag, reference=(0.0, 0.0, 0.0), accel=bool(o.accel)), log, said)
    else:
        runs = [replace(r, omega_ref=np.zeros_like(r.omega)) for r in runs]
    if moving is None and bag.motion_topic:
        reps = [read_motion(r.name, bag.motion_topic) for r in runs]
        moving = [motion_veto(r.t, rep.t, rep.twist) for r, rep in zip(runs, reps)]
    bags = [r.name for r in runs]
    split = split_sessions(runs, bag.sessions, bag.session_gap_s)
    if moving is not None:
        moving = [None if moving[j] is None else np.asarray(moving[j])[a:b]
                  for j, a, b in split.parts]
    runs, labels = split.runs, list(split.labels)
    names = [r.name for r in runs]
    # A constant gyro axis is not fitted: the still test, the choice and the fit see it at 0.
    const = constant_gyro_axes(runs)
    raw_runs, runs = runs, neutral_runs(runs, const)
    still = find_still(runs, moving=moving, window_s=o.window_s, min_still_s=o.min_still_s)
    rejected = dict(sum((Counter(st.rejected()) for st in still), Counter()))
    rows = [st.mask.copy() for st in still]
    if not any(m.any() for m in rows):
        why = '; '.join(sorted({st.reason for st in still if st.reason}))
        least = 'long enough' if o.min_still_s is None else f'of {o.min_still_s:g} s or more'
        raise FitError(f'still-only training: no still stretch {least} in '
                       f'{len(bags)} bag(s) ({why}): park the vehicle for '
                       f'{ADVICE_PARK_MIN} min with the IMU on, and record it.')
    whole_runs, whole_rows = list(runs), list(rows)     # the report covers every bag
    if not all(m.any() for m in rows):
        # A session without still time has no offset to fit: it is left out of the fit.
        keep = [i for i, m in enumerate(rows) if m.any()]
        runs, raw_runs, rows, still, names = ([x[i] for i in keep] for x in (
            runs, raw_runs, rows, still, names))
        relabel = {g: k for k, g in enumerate(dict.fromkeys(labels[i] for i in keep))}
        labels = [relabel[labels[i]] for i in keep]
    lo, hi = span([r.temp[m] for r, m in zip(runs, rows)])
    if hi - lo < MIN_STILL_SPAN_C:
        raise FitError(f'still-only training: the still time spans {hi - lo:.2f} degC only '
                       f'({lo:.1f} .. {hi:.1f} degC; need at least {MIN_STILL_SPAN_C:g} degC): '
                       'record stops at other temperatures (a cold morning, right after a long '
                       'drive).')
    first = np.flatnonzero(rows[0])      # t0: the first minute of the first still stretch
    t0 = (float(np.median(runs[0].temp[first[runs[0].t[first] <= runs[0].t[first[0]] + 60.0]]))
          if o.t0 is None else o.t0)
    subs = ([rows_of(r, m) for r, m in zip(runs, rows) if np.count_nonzero(m) >= 2]
            if o.auto else [])            # the still rows, for the choice of features
    # A curve of stops needs two power cycles to judge it.
    fo, choice = _features(o, subs, runs, t0, log, min_folds=MIN_FOLDS, frame_id=str(
        runs[0].info.get('frame_id') or 'imu_link'), created={
            'command': command, 'bags': bags, 'still_only': True, **_imus(runs)})
    spans = [(i, a, b) for i, st in enumerate(still) for a, b in st.segments]

    def fit(fo: FitOptions) -> tuple[CompensationModel, NDArray[np.float64], NDArray[np.bool_]]:
        model, means, bad = fit_without_outliers(runs, rows, spans, labels, fo)
        model = _gate(identity_axes(model, raw_runs, const, rows), fo, runs, labels, rows)
        return model, means, bad

    fo, choice = _one_power_cycle(runs, spans, labels, fo, choice, log)
    model, means, bad = fit(fo)
    try:
        check_model(model)
    except ModelFileError as exc:    # beyond belief: the offsets alone (dropped stay dropped)
        fo, choice = _drop_curve(fo, choice, log, 'the curve of the stops would be refused '
                                 f'on loading ({exc}):', 'its curve would be refused on loading')
        model, means, again = fit(fo)
        bad |= again
    stretches = [Stretch(names[i], float(runs[i].t[a]), float(runs[i].t[b - 1]),
                         float(runs[i].temp[a:b].mean()), not drop,
                         tuple(float(v) * DEG_PER_RAD for v in mu))
                 for (i, a, b), drop, mu in zip(spans, bad, means)]
    report = still_report(whole_runs, whole_rows, stretches, bin_c=o.bin_c,
                          motion_topic=bag.motion_topic, rejected=rejected)
    return _finish(model, o, out, runs, choice, {'still': report.to_dict()}, MIN_FOLDS,
                   coverage=report.coverage, bags=bags,
                   samples=int(sum(np.count_nonzero(m) for m in rows)), still=report,
                   sessions=split, constant=constant_readings(raw_runs, const))
