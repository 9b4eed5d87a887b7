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
The online learner's model temperature: held thermometer, streamed thermal state.

Pure (numpy only). :func:`hold_readings` holds the thermometer by stamp (the one hold,
:class:`gyro_tdc.signal.TemperatureHold`), :func:`stream_state`
runs the prior's thermal front end over batches of any size, :func:`same_thermal` compares
two front ends and :func:`at_state` makes a lagged model take the state as its input.
See ``doc/internals/learn.md``.
"""

from __future__ import annotations

from dataclasses import replace
import math

from gyro_tdc.model import CompensationModel, first_order_lag, THERMAL_EFFECTS, ThermalState
from gyro_tdc.signal import hold_readings
import numpy as np
from numpy.typing import NDArray

__all__ = ['ThermalCarry', 'at_state', 'hold_readings', 'same_thermal', 'stream_state']

#: The state carried between batches: the last stamp and one value per node.
ThermalCarry = tuple[float, list[float]]


def stream_state(thermal: ThermalState | None, carry: ThermalCarry | None,
                 t: NDArray[np.float64], temp: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], ThermalCarry | None]:
    """
    Return the model temperature of a batch of samples and the state to carry on.

    Parameters
    ----------
    thermal : ThermalState or None
        The front end (None or kind ``none``: the model temperature is ``temp``).
    carry : ThermalCarry or None
        The state after the previous batch; None starts settled at the first finite
        ``temp`` (steady state).
    t : NDArray[np.float64], shape (N,), s
        Stamps.
    temp : NDArray[np.float64], shape (N,), degC
        Held measured temperature; NaN samples give NaN and do not advance the state.

    Returns
    -------
    state : NDArray[np.float64], shape (N,), degC
        The model temperature (``temp`` itself without a lag).
    carry : ThermalCarry or None
        The state after the last finite sample.

    """
    ok = np.isfinite(temp)
    if thermal is None or thermal.kind == 'none' or not ok.any():
        return temp, carry
    tt, x = t[ok], temp[ok]
    t_prev, ys = carry or (float(tt[0]), [float(x[0])] * len(thermal.tau_s))
    new = []
    for tau, y0 in zip(thermal.tau_s, ys):        # cascaded nodes, from the carried state on
        x = first_order_lag(np.r_[t_prev, tt], np.r_[y0, x], tau, y0=y0)[1:]
        new.append(float(x[-1]))
    out = np.full(t.size, math.nan)
    out[ok] = x
    return out, (max(float(tt[-1]), t_prev), new)


def same_thermal(a: ThermalState | None, b: ThermalState | None) -> bool:
    """Return whether two thermal sections give the same model temperature (None = none)."""
    ka = 'none' if a is None else a.kind
    kb = 'none' if b is None else b.kind
    return ka == kb and (ka == 'none' or a.tau_s == b.tau_s)


def at_state(model: CompensationModel) -> CompensationModel:
    """Return ``model`` taking the model temperature as its input (its lag switched off)."""
    if model.thermal is None or model.thermal.kind == 'none':
        return model
    return replace(model, features=tuple(f for f in model.features if f not in THERMAL_EFFECTS),
                   effect_params={k: v for k, v in model.effect_params.items()
                                  if k not in THERMAL_EFFECTS},
                   thermal=ThermalState('none'), accel=None)
