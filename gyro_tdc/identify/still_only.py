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
The still time of ordinary operation: found, judged, reported (``train --still-only``).

:func:`find_still` finds the still stretches of every bag with one noise floor;
:func:`fit_without_outliers` fits on them and drops those that look like slow turns;
:func:`still_report` says what the still time covered and what to record next
(:class:`StillReport`). The trainer is :func:`gyro_tdc.identify.train.train_still_only`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Sequence

from gyro_tdc.base import DEG_PER_RAD, plain
from gyro_tdc.data import Coverage, coverage, RATE_THRESHOLD_C_PER_MIN, Run, temperature_rate
from gyro_tdc.errors import FitError
from gyro_tdc.identify.axes import constant_gyro_axes, neutral_runs
from gyro_tdc.identify.fit import fit_model, FitOptions, MIN_SPAN_C, span
from gyro_tdc.model import compensate, CompensationModel, DEFAULT_OUT_OF_RANGE, OPERATING_RANGE_C
from gyro_tdc.signal import detect_still, mad_sigma, NOISE_FACTOR, Stillness
import numpy as np
from numpy.typing import NDArray

__all__ = ['ADVICE_PARK_MIN', 'find_still', 'fit_without_outliers', 'MAX_MOVING_SHARE',
           'MIN_STILL_SPAN_C', 'moving_share', 'OUTLIER_FLOOR_RAD_S', 'OUTLIER_SIGMAS', 'rows_of',
           'STILL_STD_CEILING', 'still_only_runs', 'still_report', 'StillReport', 'Stretch',
           'unreferenced', 'unreferenced_motion']

#: Smallest temperature span of the still time a model is fitted on, degC.
MIN_STILL_SPAN_C = 2.0
#: A still stretch whose mean compensated rate departs from the others' by more than this
#: many robust standard deviations ...
OUTLIER_SIGMAS = 5.0
#: ... and more than this (rad/s, 0.02 deg/s) is dropped as motion (a slow turn).
OUTLIER_FLOOR_RAD_S = 3.5e-4
#: A window whose raw rate scatters more than this (rad/s, 2 deg/s, any axis) is never still
#: for the trainers, whatever the log's quietest window: a log that never stops (a hover)
#: would otherwise take its own vibration for the noise floor.
STILL_STD_CEILING = 0.035
#: Data without a reference rate moving longer than this share of the time are trained on
#: their still stretches only (``train`` as ``--still-only``): the motion is no drift.
MAX_MOVING_SHARE = 0.01
#: The advice asks for still stretches of this many minutes.
ADVICE_PARK_MIN = 20
#: A bin (or direction) with less still time than this is named in the advice, min.
_FEW_MIN = 10.0


@dataclass(frozen=True)
class Stretch:
    """One still stretch of a bag: stamps, mean temperature, kept, mean rate left (deg/s)."""

    bag: str
    t0_s: float
    t1_s: float
    temp_c: float
    kept: bool = True
    offset_dps: tuple = (0.0, 0.0, 0.0)

    @property
    def minutes(self) -> float:
        """Return the duration in minutes."""
        return (self.t1_s - self.t0_s) / 60.0


@dataclass
class StillReport:
    """
    What the still time of ``train --still-only`` covered, and what to record next.

    ``total_s`` the bags' duration, ``still_s`` the still time kept; ``stretches`` every still
    stretch found; ``coverage`` the still time's bins and heating/cooling minutes (the direction
    from the temperature over the whole bag); ``rejected`` windows refused per test.
    """

    total_s: float
    still_s: float
    stretches: list
    coverage: Coverage
    motion_topic: str = ''
    rejected: dict = field(default_factory=dict)
    advice: list = field(default_factory=list)

    def lines(self) -> list[str]:
        """Return the report, one line each: still time, coverage, direction, advice."""
        kept = [s for s in self.stretches if s.kept]
        longest = max((s.minutes for s in kept), default=0.0)
        veto = f'; motion veto {self.motion_topic}' if self.motion_topic else ''
        out = [f'still time: {self.still_s / 3600.0:.2f} h of {self.total_s / 3600.0:.2f} h '
               f'({100.0 * self.still_s / max(self.total_s, 1e-9):.0f} %) in {len(kept)} '
               f'stretches, longest {longest:.0f} min{veto}']
        cov = self.coverage
        bins = ' | '.join(f'{lo:g}..{hi:g} {m:.0f}' for lo, hi, m in
                          zip(cov.edges[:-1], cov.edges[1:], cov.minutes))
        out.append(f'still time per {cov.bin_c:g} degC (min): {bins}')
        out.append(f'still time heating {cov.heating_min:.0f} min, cooling '
                   f'{cov.cooling_min:.0f} min, steady {cov.steady_min:.0f} min (|dT/dt| '
                   f'above {cov.threshold_c_per_min:g} degC/min)')
        for s in self.stretches:
            if not s.kept:
                off = ', '.join(f'{v:+.3f}' for v in s.offset_dps)
                out.append(f'dropped still stretch {s.bag} at {s.t0_s:.0f}..{s.t1_s:.0f} s '
                           f'({s.minutes:.0f} min, {s.temp_c:.1f} degC): mean rate ({off}) '
                           'deg/s off the others (a slow turn? use --motion-topic)')
        out += [f'record next: {a}' for a in self.advice]
        return out

    def to_dict(self) -> dict:
        """Return the report as plain types (the model's ``training`` metrics)."""
        cov, kept = self.coverage, len([s for s in self.stretches if s.kept])
        return plain({'still_s': float(self.still_s), 'total_s': float(self.total_s),
                      'stretches': kept, 'dropped': len(self.stretches) - kept,
                      'bin_c': float(cov.bin_c), 'edges_c': cov.edges, 'minutes': cov.minutes,
                      'heating_min': float(cov.heating_min), 'cooling_min': float(cov.cooling_min),
                      'steady_min': float(cov.steady_min), 'motion_topic': self.motion_topic,
                      'advice': self.advice})


def find_still(runs: Sequence[Run], *, moving: Sequence[NDArray[np.bool_] | None] | None = None,
               window_s: float | None = None, min_still_s: float | None = None
               ) -> list[Stillness]:
    """
    Find the still samples of runs of one sensor, with one noise floor for them all.

    The quietest window of any run is the floor, so a bag that never stops does not look still
    to itself, and the threshold is never above :data:`STILL_STD_CEILING` (a log of a hover).
    ``moving`` is a motion veto per run; ``window_s`` and ``min_still_s`` as
    :func:`gyro_tdc.signal.detect_still` (None: by each run's rate, a stretch judged by its
    samples and its noise).
    """
    moving = [None] * len(runs) if moving is None else list(moving)
    first = [detect_still(r.t, r.omega, r.accel, moving=m, window_s=window_s,
                          min_still_s=min_still_s) for r, m in zip(runs, moving)]
    g_floor = np.min([s.gyro_floor for s in first], axis=0)
    capped = np.minimum(g_floor, STILL_STD_CEILING / NOISE_FACTOR)
    if len(runs) < 2 and np.array_equal(capped, g_floor):
        return first
    a_floors = [s.accel_floor for s in first if s.accel_floor is not None]
    a_floor = np.min(a_floors, axis=0) if a_floors else None
    return [detect_still(r.t, r.omega, r.accel, moving=m, window_s=window_s,
                         min_still_s=min_still_s, gyro_floor=capped, accel_floor=a_floor,
                         again=s) for r, m, s in zip(runs, moving, first)]


def moving_share(runs: Sequence[Run]) -> float:
    """
    Return the share of the samples of ``runs`` in windows the still test finds moving.

    Windows refused for their gyro or accelerometer scatter count (a flight, a drive); those
    refused for too few samples or non-finite values do not.
    """
    still = find_still(runs, min_still_s=0.0)
    moving = sum(int(st.counts[np.isin(st.why, ('gyro', 'accel'))].sum()) for st in still)
    total = sum(len(r) for r in runs)
    return moving / total if total else 0.0


def unreferenced(runs: Sequence[Run]) -> bool:
    """Return whether every run was read without a reference rate (none: False)."""
    return bool(runs) and all(r.info.get('reference') == 'zero' for r in runs)


def unreferenced_motion(runs: Sequence[Run]) -> tuple[float, list[Run]]:
    """
    Return the :func:`moving_share` of runs read without a reference rate, and the runs.

    0 for runs with a reference rate; the runs returned have each constant gyro axis at its
    reference (:func:`gyro_tdc.identify.axes.neutral_runs`) when the share was measured.
    """
    if not unreferenced(runs):
        return 0.0, list(runs)
    fitted = neutral_runs(runs, constant_gyro_axes(runs))
    return moving_share(fitted), fitted


def rows_of(run: Run, m: NDArray[np.bool_]) -> Run:
    """Return the samples ``m`` of a run as a run (with gaps)."""
    return Run(run.t[m], run.temp[m], run.omega[m], run.omega_ref[m], run.name,
               dict(run.info), None if run.accel is None else run.accel[m])


def still_only_runs(runs: Sequence[Run], task: tuple[str, str] = ('discover', 'discovering')
                    ) -> tuple[list[Run], str | None]:
    """
    Return what discovery may fit of runs without a reference: the still samples only.

    Runs with no reference rate (a flight log) moving longer than :data:`MAX_MOVING_SHARE`
    keep their still stretches (``train``'s still test, one noise floor, a constant axis at
    its reference), one offset per session; a session without still time is left out.
    Returns the runs and a line saying what was kept (None when every sample is kept); ``task``
    words what is fitted in it. FitError when no session holds a still stretch (motion is
    never fitted as drift).
    """
    share, fitted = unreferenced_motion(runs)
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


def still_report(runs: Sequence[Run], rows: Sequence[NDArray[np.bool_]],
                 stretches: list, *, bin_c: float, motion_topic: str = '',
                 rejected: dict | None = None) -> StillReport:
    """
    Measure the still time kept (``rows`` of ``runs``) and say what to record next.

    ``stretches`` are every stretch found, ``bin_c`` the coverage bins, degC; the report carries
    the motion veto's topic and the windows refused per test.
    """
    subs = [rows_of(r, m) for r, m in zip(runs, rows) if np.count_nonzero(m) >= 2]
    cov = coverage(subs, bin_c=bin_c)
    # The direction from the temperature over the whole bag (the drives in between count).
    minutes, rate = [], []
    for r, m in zip(runs, rows):
        dt = np.diff(r.t)
        per = np.append(np.minimum(dt, 10.0 * float(np.median(dt))), float(np.median(dt)))
        minutes.append(per[m] / 60.0)
        rate.append(temperature_rate(r.t, r.temp)[m])
    mins, rate_c = np.concatenate(minutes), np.concatenate(rate)
    thr = RATE_THRESHOLD_C_PER_MIN
    cov = replace(cov, heating_min=float(mins[rate_c > thr].sum()),
                  cooling_min=float(mins[rate_c < -thr].sum()),
                  steady_min=float(mins[np.abs(rate_c) <= thr].sum()))
    still_s = float(sum(s.t1_s - s.t0_s for s in stretches if s.kept))
    return StillReport(float(sum(r.duration_s for r in runs)), still_s, list(stretches), cov,
                       motion_topic, dict(rejected or {}), _advice(cov))


def _advice(cov: Coverage) -> list[str]:
    """Return what to record next, from the still time's coverage."""
    lo, hi = cov.temp_range_c
    park = f'park for {ADVICE_PARK_MIN} min'
    out = []
    a, b = OPERATING_RANGE_C
    if lo > a:
        out.append(f'{park} at temperatures below {math.floor(lo):g} degC (a cold morning, '
                   f'down to {a:g} degC): the still time starts at {lo:.1f} degC')
    if hi < b:
        out.append(f'{park} at temperatures above {math.ceil(hi):g} degC (right after a long '
                   f'drive on a warm day, up to {b:g} degC): the still time ends at '
                   f'{hi:.1f} degC')
    out += [f'{park} at {cov.edges[i]:g} .. {cov.edges[i + 1]:g} degC: only '
            f'{cov.minutes[i]:.0f} min of still time there' for i in cov.sparse]
    return out + [f'no {way} still time ({minutes:.0f} min): {when}' for way, minutes, when in (
        ('cooling', cov.cooling_min, 'park right after a drive, while the IMU cools'),
        ('heating', cov.heating_min, 'park while the day warms up (morning sun), or power the '
         'IMU on and leave it still')) if minutes < _FEW_MIN]


def fit_without_outliers(runs: Sequence[Run], rows: Sequence[NDArray[np.bool_]],
                         spans: list[tuple[int, int, int]], labels: list[int], options: FitOptions
                         ) -> tuple[CompensationModel, NDArray[np.float64], NDArray[np.bool_]]:
    """
    Fit, then refit without the outlying stretches unless all or none are outliers.

    A run whose every stretch looks outlying keeps them (its own offset takes them): dropped,
    the run would have no still time and no offset.

    Clears the outlying stretches in ``rows`` (in place); returns the model, the mean
    compensated rate per stretch (S, 3) and which stretches were dropped. FitError, saying
    what to record, when the stretches left span too few degrees to fit.
    """
    model = fit_model(runs, options, rows=rows, sessions=labels)
    means = _stretch_means(model, runs, spans, labels)
    if means.shape[0] < 4:          # too few stretches to tell one that departs
        return model, means, np.zeros(means.shape[0], dtype=bool)
    # An outlier departs from the others' mean (robust), by OUTLIER_SIGMAS and the floor.
    dev = np.abs(means - np.median(means, axis=0))
    bad = np.any(dev > np.maximum(OUTLIER_SIGMAS * mad_sigma(means), OUTLIER_FLOOR_RAD_S), axis=1)
    run_of = np.array([i for i, _, _ in spans], dtype=np.int64)
    for i in np.unique(run_of[bad]):    # a run keeps its stops when all look like turns
        if bad[run_of == i].all():
            bad[run_of == i] = False
    if not bad.any() or bad.all():
        return model, means, np.zeros_like(bad)
    for (i, a, b), drop in zip(spans, bad):
        if drop:
            rows[i][a:b] = False
    lo, hi = span([r.temp[m] for r, m in zip(runs, rows)])
    if hi - lo < MIN_SPAN_C:
        raise FitError(f'still-only training: {int(bad.sum())} of the {bad.size} still '
                       "stretches look like slow turns (their mean rate off the others'); "
                       f'the rest span {hi - lo:.2f} degC only ({lo:.1f} .. {hi:.1f} degC; '
                       f'need at least {MIN_SPAN_C:g} degC): record stops at other '
                       'temperatures, or veto the turns with --motion-topic.')
    model = fit_model(runs, options, rows=rows, sessions=labels)
    return model, _stretch_means(model, runs, spans, labels), bad


def _stretch_means(model: CompensationModel, runs: Sequence[Run],
                   spans: list[tuple[int, int, int]], labels: Sequence[int]
                   ) -> NDArray[np.float64]:
    """
    Return the mean compensated rate (rad/s) of every still stretch (S, 3).

    Each run's compensated rate has its session's offset from the model's removed (the
    fit's ``metrics['sessions']``): a turn-on offset is no slow turn.
    """
    info = model.metrics.get('sessions')
    shift = (np.zeros((max(labels, default=0) + 1, 3)) if info is None
             else np.asarray(info['offset_dps']) / DEG_PER_RAD)
    comp = [compensate(model, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE)
            - shift[g] for r, g in zip(runs, labels)]
    return np.array([comp[i][a:b].mean(axis=0) for i, a, b in spans]).reshape(-1, 3)
