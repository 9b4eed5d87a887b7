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
The model in use and its drift at a temperature: the gyro's and the accelerometer part's.

:class:`ModelSlot` holds the installed model's streaming compensator, its variance table and,
for a static model, the drift per temperature (:class:`DriftEntry`, made by
:meth:`ModelSlot.refresh` as each thermometer reading arrives); :class:`AccelSlot` does the
same for the accelerometer part and corrects one specific force (:meth:`AccelSlot.correct`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

from gyro_tdc.base import (MAX_ACCEL_DRIFT_MPS2 as _MAX_ACCEL_DRIFT,
                           MAX_DRIFT_RAD_S as _MAX_DRIFT, MAX_RATE_RAD_S as _MAX_RATE)
from gyro_tdc.model import CompensationModel, STATIC_EFFECTS, StreamingCompensator, variance_growth
from gyro_tdc.runtime.blockstats import Vec3
from gyro_tdc.runtime.flags import IMPLAUSIBLE_OUTPUT, NON_FINITE, OUT_OF_RANGE, STALE
from gyro_tdc.runtime.policy import Policy
import numpy as np
from numpy.typing import NDArray

__all__ = ['accel_slot', 'AccelEntry', 'AccelSlot', 'correction_is_safe', 'DriftEntry',
           'ModelSlot', 'timeless', 'variance_table', 'widen']

#: A static model's cache holds the drift at this many temperatures at most.
CACHE_SIZE = 64


@dataclass(frozen=True, slots=True)
class DriftEntry:
    """
    A static model's drift at one temperature, as the message path uses it.

    The output rate is ``(w - b) / d`` per axis, the operations ``StreamingCompensator.step``
    does, so the same bits.
    """

    bx: float
    by: float
    bz: float
    #: ``1 + dT * scale`` per axis.
    dx: float
    dy: float
    dz: float
    #: ``OUT_OF_RANGE`` outside the model's temperature range, else 0.
    oor: int
    distance_c: float
    #: Variance to add, fresh and stale temperature.
    var: Vec3
    var_stale: Vec3
    #: Every input the input check lets through (finite, within ``MAX_RATE_RAD_S``) is
    #: corrected by at most half ``MAX_DRIFT_RAD_S``: the per-sample output check can be skipped.
    safe: bool = False


def correction_is_safe(b: Vec3, d: Vec3) -> bool:
    """
    Say whether ``(w - b) / d`` moves every ``|w| <= MAX_RATE_RAD_S`` by under half the limit.

    The correction is ``w (1/d - 1) - b/d``, at most ``MAX_RATE |1/d - 1| + |b/d|`` in size;
    the half is a margin far above the rounding of either side. NaN or Inf gives False.
    """
    return all(di and _MAX_RATE * abs(1.0 / di - 1.0) + abs(bi / di) <= 0.5 * _MAX_DRIFT
               for bi, di in zip(b, d))     # NaN fails the compare


def timeless(model: CompensationModel) -> bool:
    """
    Return whether ``model``'s output depends on the current temperature alone.

    No time terms (warm-up, rates of change, ...: only ``STATIC_EFFECTS``) and no lagged
    thermal state, in the gyro part and the accelerometer part: such a model has no filter
    to replay, so installing it reads no thermometer history.
    """
    return all(set(part.features) <= STATIC_EFFECTS and part.thermal.kind == 'none'
               for part in (model, getattr(model, 'accel', None)) if part is not None)


def growth(dist: float, policy: Policy) -> float:
    """Return the variance added ``dist`` degC out of the model's range (``linear`` grows)."""
    return (variance_growth(policy.out_of_range_variance, dist, policy.out_of_range)
            if dist else 0.0)


def widen(var: Vec3, more: float) -> Vec3:
    """Return ``var`` with ``more`` added on each axis (the out-of-range growth)."""
    return (var[0] + more, var[1] + more, var[2] + more) if more else var


@dataclass(frozen=True, slots=True)
class AccelEntry:
    """A static accelerometer part's drift at one temperature: ``a - b``, and its flag."""

    bx: float
    by: float
    bz: float
    oor: int
    #: Variance growth outside the range (``linear``: with the distance), (m/s^2)^2.
    growth: float


@dataclass(slots=True)
class AccelSlot:
    """The installed model's accelerometer part: its compensator, variance table and cache."""

    comp: StreamingCompensator
    var: dict[int, Vec3]
    #: Cached per temperature (only when the gyro's drift is static too).
    static: bool
    cache: dict[float, AccelEntry] = field(default_factory=dict)

    def refresh(self, t: float, temp: float, policy: Policy) -> AccelEntry:
        """Evaluate the part at one temperature; keep it when static."""
        acomp = self.comp              # no scale term: the output is a - b
        entry = AccelEntry(*acomp.drift(t, temp).tolist(), 0 if acomp.in_range else OUT_OF_RANGE,
                           growth(acomp.range_distance_c, policy))
        if self.static:
            self.cache[temp] = entry
        return entry

    def correct(self, t: float, temp: float, accel: Sequence[float], flags: int,
                policy: Policy) -> tuple[Vec3 | None, Vec3 | None, int]:
        """
        Correct one specific force (m/s^2) at ``temp`` (``flags``: ``STALE`` or 0).

        Returns the corrected force, the variance to add and its flags; None, None and why
        (``NON_FINITE``, ``IMPLAUSIBLE_OUTPUT``) when it is to pass through.
        """
        ax, ay, az = accel
        if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)):
            return None, None, NON_FINITE
        e = self.cache.get(temp) or self.refresh(t, temp, policy)   # the cache: static only
        out = (ax - e.bx, ay - e.by, az - e.bz)
        flags |= e.oor
        var = widen(self.var[flags], e.growth)
        if not (abs(out[0] - ax) <= _MAX_ACCEL_DRIFT and abs(out[1] - ay) <= _MAX_ACCEL_DRIFT
                and abs(out[2] - az) <= _MAX_ACCEL_DRIFT and math.isfinite(sum(var))):
            return None, None, IMPLAUSIBLE_OUTPUT
        return out, var, flags


def accel_slot(model: CompensationModel, comp: StreamingCompensator, static: bool,
               policy: Policy) -> AccelSlot | None:
    """Return the slot of ``model``'s accelerometer part (None: it has none)."""
    part = model.accel
    return None if part is None else AccelSlot(
        comp.accel, variance_table(part.residual_var, policy),
        static and set(part.features) <= STATIC_EFFECTS)


def variance_table(residual_var: Sequence[float], policy: Policy) -> dict[int, Vec3]:
    """Return the variance to add per flags (0, ``STALE``, ``OUT_OF_RANGE``, both)."""
    resid = np.asarray(residual_var, dtype=np.float64).tolist()
    stale, oor = policy.stale_variance, policy.out_of_range_variance
    return {f: tuple(v + (stale if f & STALE else 0.0) + (oor if f & OUT_OF_RANGE else 0.0)
                     for v in resid) for f in (0, STALE, OUT_OF_RANGE, STALE | OUT_OF_RANGE)}


@dataclass(slots=True)
class ModelSlot:
    """The model in use, its streaming compensator, variance table and per-temperature cache."""

    model: CompensationModel | None = None
    model_id: str = ''
    comp: StreamingCompensator | None = None
    var: dict[int, Vec3] = field(default_factory=dict)
    scale: np.ndarray | None = None
    #: Made of ``STATIC_EFFECTS``: its drift changes only when the temperature does.
    static: bool = False
    cache: dict[float, DriftEntry] = field(default_factory=dict)
    accel: AccelSlot | None = None
    #: The attached learner's model (:meth:`CompensatorCore.schedule`).
    learned: bool = False
    #: The model's ``offset_only``, read once (no curve: its range is no limit on
    #: re-anchoring).
    flat: bool = False

    def clear(self) -> None:
        """Forget the drift cached per temperature (the model's offset moved)."""
        self.cache.clear()
        if self.accel is not None:
            self.accel.cache.clear()

    def refresh(self, t: float, temp: float, policy: Policy) -> DriftEntry:
        """
        Evaluate the drift of a static model at one temperature and keep it.

        The thermometer callback calls this as each reading arrives, so the IMU callback only
        looks the result up.
        """
        comp = self.comp
        bx, by, bz = comp.drift(t, temp).tolist()
        dx, dy, dz = (1.0 + comp.dt_c * self.scale).tolist()
        dist = comp.range_distance_c
        more = growth(dist, policy)
        oor = 0 if comp.in_range else OUT_OF_RANGE
        var, var_stale = widen(self.var[oor], more), widen(self.var[oor | STALE], more)
        if not math.isfinite(sum(var) + sum(var_stale)):
            bx = math.nan              # process's output check refuses the entry
        entry = DriftEntry(bx, by, bz, dx, dy, dz, oor, dist, var, var_stale,
                           correction_is_safe((bx, by, bz), (dx, dy, dz)))
        if len(self.cache) >= CACHE_SIZE:
            self.clear()
        self.cache[temp] = entry
        if self.accel is not None and self.accel.static:
            self.accel.refresh(t, temp, policy)
        return entry

    def scale_at(self, temp: float) -> NDArray[np.float64]:
        """Return ``1 + s dT`` per axis at ``temp`` (the divisor of the compensated rate)."""
        if self.static:
            e = self.cache[temp]
            return np.asarray((e.dx, e.dy, e.dz))
        return 1.0 + self.comp.dt_c * self.scale
