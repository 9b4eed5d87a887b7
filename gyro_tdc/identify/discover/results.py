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
What discovery found: steps, candidate scores, residual maps, and their JSON and text forms.

:class:`DiscoveryResult` holds the outcome of :func:`gyro_tdc.identify.discover.discover`;
:meth:`DiscoveryResult.to_json` is the ``discover --json`` document and
:func:`format_summary` the text the command prints.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from functools import partial

from gyro_tdc.base import plain
from gyro_tdc.errors import DatasetError
from gyro_tdc.model import ThermalState
import numpy as np
from numpy.typing import NDArray

__all__ = ['BinMap', 'CandidateScore', 'DiscoveryResult', 'format_summary', 'Step',
           'Unidentifiable']


@dataclass(frozen=True)
class BinMap:
    """The residual binned by one quantity, per axis, with the bins noise cannot explain marked."""

    #: ``temperature``, ``dTdt``, ``reference`` or ``time``.
    name: str
    #: What the bins are, with unit (x axis of a plot).
    label: str
    #: Bin centres (B, 3) per axis (the reference map bins each axis by its own rate); NaN
    #: where a bin is empty on that axis.
    centers: NDArray[np.float64]
    #: Weighted mean residual (B, 3) per bin and axis, deg/s.
    mean_dps: NDArray[np.float64]
    #: Its standard error (B, 3) from the noise floor, inflated for autocorrelated noise, deg/s.
    se_dps: NDArray[np.float64]
    #: Blocks (B, 3) per bin and axis.
    count: NDArray[np.int64]
    #: ``|mean| > 3 se`` (B, 3): a disagreement noise does not explain.
    flagged: NDArray[np.bool_]
    #: Bin labels (e.g. ``cooling fast``), one per bin.
    labels: tuple[str, ...] = ()

    @property
    def n_flagged(self) -> int:
        """Return the number of flagged (bin, axis) cells."""
        return int(np.count_nonzero(self.flagged))


@dataclass(frozen=True)
class CandidateScore:
    """How well one candidate effect explains what the current model misses."""

    #: Effect id.
    effect: str
    #: Fitted effect parameters (e.g. ``{'tau_s': 180.0}``).
    params: dict
    #: HAC Wald test of the added columns, smallest over axes times 3 (Bonferroni over axes).
    p_value: float
    #: Held-out mean squared gap of the model minus that with the candidate, (deg/s)^2.
    heldout_gain_dps2: float
    #: RMS of the in-sample improvement (what the candidate explains), over blocks and axes,
    #: deg/s.
    effect_rms_dps: float
    #: In-sample and held-out gap with the candidate added, deg/s.
    gap_dps: float
    heldout_gap_dps: float
    #: Significant, held-out gain and effect size all above their thresholds.
    passed: bool
    #: Which test failed (empty when passed).
    why_not: str
    #: Fitted coefficients (q, 3) of the candidate's columns (SI units of the feature).
    coef: NDArray[np.float64] = field(repr=False)


@dataclass(frozen=True)
class Unidentifiable:
    """
    An effect this data cannot excite or cannot tell apart from the model's effects.

    Parameters
    ----------
    effect : str
        Effect id.
    reason : str
        Why, in terms of this data.
    experiment : str
        The experiment that would excite or separate it.

    """

    effect: str
    reason: str
    experiment: str


@dataclass(frozen=True)
class Step:
    """One discovery step: the effect named, the evidence and the gap before and after."""

    #: The effect added.
    effect: str
    #: Candidates this data cannot tell apart from it.
    aliases: tuple[str, ...]
    #: Its physics (``EFFECTS[effect].description``).
    description: str
    #: Its fitted parameters (time constants, s).
    params: dict
    #: Its coefficients (q, 3) per axis in deg/s per feature unit (after the refit).
    coef_dps: NDArray[np.float64]
    #: In-sample gap before and after, deg/s.
    gap_before_dps: float
    gap_after_dps: float
    #: Held-out gap before and after, deg/s.
    heldout_gap_before_dps: float
    heldout_gap_after_dps: float
    #: Every candidate scored at this step, best first.
    candidates: tuple[CandidateScore, ...] = field(repr=False)
    #: Residual maps before and after.
    maps_before: tuple[BinMap, ...] = field(repr=False)
    maps_after: tuple[BinMap, ...] = field(repr=False)
    #: Allan deviation averaging times (M,) (longest run, full rate), s.
    adev_tau_s: NDArray[np.float64] = field(repr=False)
    #: Allan deviation (M,) of the residual before and after (RMS over axes), deg/s.
    adev_before_dps: NDArray[np.float64] = field(repr=False)
    adev_after_dps: NDArray[np.float64] = field(repr=False)
    #: The score of the effect added.
    best: CandidateScore | None = field(default=None, repr=False)
    #: The thermal state of the model after the step, tau with its profile interval (None
    #: without ``lag``).
    thermal: ThermalState | None = None


@dataclass(frozen=True)
class DiscoveryResult:
    """
    Everything :func:`discover` found; :meth:`to_json` gives the ``discover --json`` document.

    Parameters
    ----------
    base_effects : tuple of str
        Effects of the starting model (``bias`` always included).
    final_effects : tuple of str
        Effects of the final model, catalog order.
    params : dict
        Fitted effect parameters of the final model, ``{effect: {param: value}}``.
    noise_floor_dps : float, deg/s
        Noise floor on the scale of the gap (block means), RMS over axes.
    noise_floor_axes_dps : NDArray[np.float64], shape (3,), deg/s
        The same per axis.
    white_noise_dps : float, deg/s
        Per-sample white-noise standard deviation (first differences), RMS over axes.
    block_s : float, s
        Nominal block length.
    t0_c : float, degC
        Reference temperature of the features.
    steps : tuple of Step
        Discovery steps, in order.
    unidentifiable : tuple of Unidentifiable
        Effects this data cannot excite.
    candidates : tuple of CandidateScore
        Candidates scored against the final model (none passed).
    maps : tuple of BinMap
        Residual maps of the final model.
    gap_dps, heldout_gap_dps : float, deg/s
        Gaps of the final model.
    coef : dict
        Final coefficients: ``offsets`` (R, 3) rad/s per run, ``gain`` (3,) constant
        scale-factor error, ``scale`` (3,) 1/degC, and per input effect (3,) in rad/s per
        feature unit.
    runs : tuple of str
        Run names.
    blocks : int
        Number of blocks analysed.
    notes : tuple of str
        Caveats about this data (confounded candidates, untestable hysteresis...).
    settings : dict
        Thresholds used.
    adev_tau_s : NDArray[np.float64], shape (M,), s
        Allan deviation averaging times of the final residual (empty without ``allan``).
    adev_dps : NDArray[np.float64], shape (M,), deg/s
        Allan deviation of the final residual (longest run, full rate, RMS over axes).
    thermal : ThermalState, optional
        The final model's thermal state: tau, its 95 % profile interval and whether the data
        pin it (None without ``lag``).

    """

    base_effects: tuple[str, ...]
    final_effects: tuple[str, ...]
    params: dict
    noise_floor_dps: float
    noise_floor_axes_dps: NDArray[np.float64]
    white_noise_dps: float
    block_s: float
    t0_c: float
    steps: tuple[Step, ...]
    unidentifiable: tuple[Unidentifiable, ...]
    candidates: tuple[CandidateScore, ...]
    maps: tuple[BinMap, ...]
    gap_dps: float
    heldout_gap_dps: float
    coef: dict
    runs: tuple[str, ...]
    blocks: int
    notes: tuple[str, ...]
    settings: dict
    adev_tau_s: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)
    adev_dps: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)
    thermal: ThermalState | None = None

    def __post_init__(self) -> None:
        """Refuse a discovery without noise: every axis constant, nothing was measured."""
        if not self.noise_floor_dps > 0:
            raise DatasetError('Expected readings to discover effects on: every axis reads '
                               'the same value from one sample to the next in every run (noise '
                               'floor 0: a constant sensor, e.g. a driver filling a fixed '
                               'value); check that the driver publishes the sensor.')

    @property
    def named(self) -> tuple[str, ...]:
        """Return the effects named, in step order."""
        return tuple(s.effect for s in self.steps)

    def to_json(self, model_file: str | None = None) -> dict:
        """
        Return the ``discover --json`` document (plain types).

        Parameters
        ----------
        model_file : str, optional
            Path of the model file written, or None.

        Returns
        -------
        dict
            ``base_effects``, ``noise_floor_dps``, ``steps``, ``final_effects``,
            ``unidentifiable``, ``model_file``; and ``thermal`` (kind, ``tau_s``,
            ``tau_interval_s``, ``identifiable``) when the final model has a thermal state.

        """
        pl = partial(plain, nan_to_none=True)
        steps = [{
            'effect': s.effect, 'aliases': list(s.aliases), 'description': s.description,
            'gap_before_dps': float(s.gap_before_dps), 'gap_after_dps': float(s.gap_after_dps),
            'heldout_gap_before_dps': float(s.heldout_gap_before_dps),
            'heldout_gap_after_dps': float(s.heldout_gap_after_dps),
            'params': pl(s.params), 'coef_dps': pl(s.coef_dps),
            **{k: None if s.best is None else float(getattr(s.best, k))
               for k in ('p_value', 'heldout_gain_dps2', 'effect_rms_dps')},
            'flagged_bins_before': int(sum(m.n_flagged for m in s.maps_before)),
            'flagged_bins_after': int(sum(m.n_flagged for m in s.maps_after)),
            'adev': {'tau_s': pl(s.adev_tau_s), 'before_dps': pl(s.adev_before_dps),
                     'after_dps': pl(s.adev_after_dps)},
            'thermal': None if s.thermal is None else s.thermal.to_dict(),
        } for s in self.steps]
        return {'base_effects': list(self.base_effects),
                'noise_floor_dps': float(self.noise_floor_dps), 'steps': steps,
                'final_effects': list(self.final_effects),
                'unidentifiable': [asdict(u) for u in self.unidentifiable],
                'model_file': None if model_file is None else str(model_file),
                **({} if self.thermal is None else {'thermal': self.thermal.to_dict()})}


def format_summary(result: DiscoveryResult) -> str:
    """
    Return a readable multi-line summary of a discovery.

    Parameters
    ----------
    result : DiscoveryResult
        A discovery.

    Returns
    -------
    str
        The summary, ending with a newline.

    """
    held = result.settings['block_mean_s']    # seconds of data a block holds, on average
    grid = (f'{result.blocks} blocks of {result.block_s:g} s' if held >= 0.9 * result.block_s
            else f'{result.blocks} blocks on a {result.block_s:g} s grid holding {held:.3g} s '
                 'of data each on average (gaps in the recording)')
    lines = [f'discover: {len(result.runs)} run(s), {grid}, T0 = {result.t0_c:.2f} degC',
             f'base model: {", ".join(result.base_effects)}  '
             f'(one offset per run; cross-validation: {result.settings["folds"]})',
             f'noise floor: {result.noise_floor_dps:.3g} deg/s on those block means (white '
             f'noise {result.white_noise_dps:.3g} deg/s per sample); gaps are RMS of block means']
    if not result.steps:
        lines.append('no missing effect found: no candidate is significant, gains on held-out '
                     'data and exceeds the noise')
    for i, s in enumerate(result.steps, 1):
        par = ', '.join(f'{k} = {v:.4g}' for k, v in s.params.items())
        b = s.best
        lines += [f'step {i}: add {s.effect}' + (f' ({par})' if par else '')
                  + (f'; aliases: {", ".join(s.aliases)}' if s.aliases else ''),
                  f'  {s.description}']
        if b is not None:
            lines.append(f'  evidence: HAC p = {b.p_value:.2g}, held-out gain '
                         f'{b.heldout_gain_dps2:.3g} (deg/s)^2, effect RMS '
                         f'{b.effect_rms_dps:.3g} deg/s')
        lines.append(f'  gap {s.gap_before_dps:.4g} -> {s.gap_after_dps:.4g} deg/s, held-out '
                     f'{s.heldout_gap_before_dps:.4g} -> {s.heldout_gap_after_dps:.4g} deg/s')
        if s.thermal is not None:
            lines.append(f'  {s.thermal.describe()}')
    lines.append(f'final model: {", ".join(result.final_effects)}; gap {result.gap_dps:.4g} '
                 f'deg/s = {result.gap_dps / result.noise_floor_dps:.2f} x noise floor '
                 f'(held-out {result.heldout_gap_dps:.4g})')
    if result.thermal is not None:
        lines.append(f'final {result.thermal.describe()}')
    lines += ['remaining candidates (none passed):'] if result.candidates else []
    lines += [f'  {c.effect:7s} p = {c.p_value:.2g}, held-out gain {c.heldout_gain_dps2:+.2g} '
              f'(deg/s)^2, effect {c.effect_rms_dps:.2g} deg/s: {c.why_not}'
              for c in result.candidates]
    lines += [f'unidentifiable: {u.effect}: {u.reason}. Experiment: {u.experiment}'
              for u in result.unidentifiable] + [f'note: {n}' for n in result.notes]
    gain = np.asarray(result.coef.get('gain', np.zeros(3)))
    if np.any(gain != 0):
        lines.append('constant scale-factor error vs the reference (not thermal, not in the '
                     'model file): ' + ', '.join(f'{g * 1e6:+.0f} ppm' for g in gain))
    return '\n'.join(lines) + '\n'
