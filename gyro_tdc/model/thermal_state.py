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
The thermal front end of a model: the model temperature as a state of the measured one.

A :class:`ThermalState` (``none``, ``first_order`` or ``two_node``) estimates the die
temperature from the thermometer's; :class:`StreamingThermalState` computes the same one
sample at a time and says when its start-up assumption has settled.
See ``doc/internals/model.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping

from gyro_tdc.base import is_number
from gyro_tdc.errors import FeatureError
from gyro_tdc.model.lag import first_order_lag, lag_step
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['NODES', 'SETTLE_TAUS', 'StreamingThermalState', 'THERMAL_KINDS', 'ThermalState']

#: Kinds of thermal front end, and the number of time constants (nodes) of each.
NODES: Mapping[str, int] = {'none': 0, 'first_order': 1, 'two_node': 2}
THERMAL_KINDS: tuple[str, ...] = tuple(NODES)
#: Time constants after the first sample at which the state counts as settled.
SETTLE_TAUS = 3.0


def _positive(value: Any, name: str) -> float:
    """Return ``value`` as a positive finite float, or raise naming ``name``."""
    if not (is_number(value) and float(value) > 0.0):
        raise FeatureError(f'`{name}` must be a positive finite number, got {value!r:.60}')
    return float(value)


@dataclass(frozen=True)
class ThermalState:
    """
    The thermal front end of a model (immutable data): kind, time constants, their interval.

    Parameters
    ----------
    kind : str
        ``'none'``, ``'first_order'`` or ``'two_node'`` (:data:`THERMAL_KINDS`).
    tau_s : tuple of float, s
        One time constant per node (none, one, or two: package then die).
    tau_interval_s : tuple of (float, float), s, optional
        Per time constant, its 95 % profile-likelihood interval ``(lo, hi)``; None when the
        time constants were given, not fitted.
    identifiable : bool, optional
        False when the data cannot pin the time constants (an interval reaches a search
        bound or spans more than a factor 3); None when not assessed.

    """

    kind: str = 'none'
    tau_s: tuple[float, ...] = ()
    tau_interval_s: tuple[tuple[float, float], ...] | None = None
    identifiable: bool | None = None

    def __post_init__(self) -> None:
        """Check the fields and store them as tuples of floats."""
        if not isinstance(self.kind, str) or self.kind not in NODES:
            raise FeatureError(f'`kind` must be one of {", ".join(THERMAL_KINDS)}, '
                               f'got {self.kind!r}')
        taus = self.tau_s
        if isinstance(taus, (int, float)) and not isinstance(taus, bool):
            taus = (taus,)
        if not isinstance(taus, (list, tuple, np.ndarray)) or len(taus) != NODES[self.kind]:
            raise FeatureError(f'`tau_s` must hold {NODES[self.kind]} time constant(s) for '
                               f'kind {self.kind!r}, got {self.tau_s!r:.60}')
        taus = tuple(_positive(v, 'tau_s') for v in taus)
        object.__setattr__(self, 'tau_s', taus)
        iv = self.tau_interval_s
        if iv is not None:
            if not isinstance(iv, (list, tuple)) or len(iv) != len(taus) or not all(
                    isinstance(p, (list, tuple)) and len(p) == 2 for p in iv):
                raise FeatureError(f'`tau_interval_s` must hold one [lo, hi] per time '
                                   f'constant ({len(taus)}), got {iv!r:.60}')
            iv = tuple((_positive(lo, 'tau_interval_s'), _positive(hi, 'tau_interval_s'))
                       for lo, hi in iv)
            for (lo, hi), tau in zip(iv, taus):
                if not lo <= tau <= hi:
                    raise FeatureError(f'`tau_interval_s` [{lo!r}, {hi!r}] must contain its '
                                       f'time constant {tau!r}')
            object.__setattr__(self, 'tau_interval_s', iv)
        if self.identifiable is not None and not isinstance(self.identifiable, bool):
            raise FeatureError(f'`identifiable` must be true, false or null, '
                               f'got {self.identifiable!r:.40}')

    @property
    def tau_total_s(self) -> float:
        """Return the state's mean delay behind a ramp: the sum of the time constants, s."""
        return float(sum(self.tau_s))

    def temperature(self, t: ArrayLike, temp: ArrayLike) -> NDArray[np.float64]:
        """
        Return the state (the model temperature, degC) over one continuous run.

        Starts at ``temp[0]``; a copy of ``temp`` for kind ``none``. ``t`` (s) non-decreasing.
        """
        s = np.array(temp, dtype=np.float64)
        t = np.asarray(t, dtype=np.float64)
        for tau in self.tau_s:
            s = first_order_lag(t, s, tau)
        return s

    def stream(self) -> StreamingThermalState:
        """Return a fresh streaming filter of this front end."""
        return StreamingThermalState(self)

    def describe(self) -> str:
        """Return one line: the kind, the time constants and their interval."""
        if self.kind == 'none':
            return 'thermal state: the measured temperature (no lag)'
        taus = ' + '.join(f'{v:.4g}' for v in self.tau_s)
        what = 'first-order lag' if self.kind == 'first_order' else 'two-node lag (package + die)'
        if self.tau_interval_s is None:
            return f'thermal state: {what}, tau = {taus} s (given, not fitted)'
        if self.identifiable is False:
            lo, hi = min(p[0] for p in self.tau_interval_s), max(p[1] for p in self.tau_interval_s)
            return (f'thermal state: {what}; tau not identifiable from these data: profile '
                    f'flat over {lo:.4g}..{hi:.4g} s (best {taus} s)')
        ivs = ', '.join(f'{lo:.4g}..{hi:.4g}' for lo, hi in self.tau_interval_s)
        return f'thermal state: {what}, tau = {taus} s (95 % interval {ivs} s)'

    def to_dict(self) -> dict:
        """Return the front end as plain types (the model file's ``thermal`` section)."""
        return {'kind': self.kind, 'tau_s': [float(v) for v in self.tau_s],
                'tau_interval_s': None if self.tau_interval_s is None
                else [[float(lo), float(hi)] for lo, hi in self.tau_interval_s],
                'identifiable': self.identifiable}

    @classmethod
    def from_dict(cls, d: Any) -> ThermalState:
        """
        Build a front end from :meth:`to_dict` output (a model file's ``thermal`` section).

        Raises
        ------
        FeatureError
            Naming the field (``kind``, ``tau_s``...) that is missing or wrong.

        """
        if not isinstance(d, Mapping):
            raise FeatureError(f'must be a mapping, got {type(d).__name__}')
        extra = sorted(set(d) - {'kind', 'tau_s', 'tau_interval_s', 'identifiable'})
        if extra:
            raise FeatureError(f'unknown field(s) {extra}; expected kind, tau_s, '
                               'tau_interval_s, identifiable')
        for key in ('kind', 'tau_s'):
            if key not in d:
                raise FeatureError(f'missing field `{key}`')
        taus = d['tau_s']
        if not isinstance(taus, list):
            raise FeatureError(f'`tau_s` must be a list of time constants, got {taus!r:.60}')
        return cls(kind=d['kind'], tau_s=tuple(taus), tau_interval_s=d.get('tau_interval_s'),
                   identifiable=d.get('identifiable'))


class StreamingThermalState:
    """
    The state of a :class:`ThermalState`, one sample at a time (equal to the batch form).

    Parameters
    ----------
    thermal : ThermalState
        The front end.

    """

    def __init__(self, thermal: ThermalState) -> None:
        self.thermal = thermal
        self.reset()

    def reset(self) -> None:
        """Forget the state (a new run starts, settled, at the next sample)."""
        self._y: list[float] = []         # per node; stamps of the first and latest sample
        self._t_first = self._t_prev = self.value = None

    def update(self, t: float, temp: float) -> float:
        """
        Advance to stamp ``t`` (s) with measured temperature ``temp`` (degC); return the state.

        A stamp not after the previous one leaves the state unchanged.
        """
        if self._t_prev is None:
            self._t_first = self._t_prev = t
            self._y = [temp] * len(self.thermal.tau_s)
            self.value = temp
            return temp
        dt_s = max(t - self._t_prev, 0.0)
        self._t_prev = max(t, self._t_prev)
        u = temp
        for i, tau in enumerate(self.thermal.tau_s):      # cascaded nodes
            u = self._y[i] = lag_step(self._y[i], u, dt_s, tau)
        self.value = u
        return u

    @property
    def progress(self) -> float:
        """Return the stamp time since the first sample in time constants (``inf``: no lag)."""
        total = self.thermal.tau_total_s
        if total == 0.0:
            return math.inf
        return 0.0 if self._t_first is None else (self._t_prev - self._t_first) / total

    @property
    def settled(self) -> bool:
        """Return True once :data:`SETTLE_TAUS` time constants have passed (by stamps)."""
        return self._t_first is not None and self.progress >= SETTLE_TAUS
