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
The features of ``train --features auto``: the paper's f(dT, dT2) plus what the data support.

:func:`choose_features` runs discovery on the training runs and records every effect added
or rejected with its reason (:class:`FeatureChoice`); ``doc/internals/identify.md`` tells how.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Sequence

from gyro_tdc.data import Run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.discover.results import DiscoveryResult
from gyro_tdc.identify.discover.search import discover
from gyro_tdc.identify.fit import estimate_t0
from gyro_tdc.model import EFFECTS, normalise_ids
from gyro_tdc.signal import block_mean
import numpy as np

__all__ = ['AUTO', 'AUTO_BASE', 'Decision', 'FeatureChoice', 'SEARCH_RATE_HZ', 'choose_features',
           'features_for_fit']

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
    ``discovery`` the search behind it (None when the data were too short, ``note`` says why).
    """

    base: tuple[str, ...]
    features: tuple[str, ...]
    decisions: tuple[Decision, ...]
    discovery: DiscoveryResult | None = field(default=None, repr=False)
    note: str = ''

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
                + [f'features chosen: {", ".join(self.features)}'])

    def to_dict(self) -> dict:
        """Return the choice as plain types (the model's ``training`` metrics)."""
        d = self.discovery
        out = {'mode': AUTO, 'base': list(self.base), 'chosen': list(self.features),
               'decisions': [asdict(x) for x in self.decisions]}
        if d is not None:
            out['discovery'] = {
                'noise_floor_dps': float(d.noise_floor_dps), 'gap_dps': float(d.gap_dps),
                'heldout_gap_dps': float(d.heldout_gap_dps), 'folds': d.settings['folds'],
                'block_s': float(d.block_s),
                'thermal': None if d.thermal is None else d.thermal.to_dict()}
        else:
            out['note'] = self.note
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
    ref = (block_mean(run.omega_ref, m, partial=False) if np.any(run.omega_ref)
           else np.zeros((len(run) // m, 3)))         # no reference: its means are zeros
    return Run(block_mean(run.t, m, partial=False), block_mean(run.temp, m, partial=False),
               block_mean(run.omega, m, partial=False), ref, run.name, dict(run.info))


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
