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
The learner's ``learn_file``: its state as plain types, read and written as JSON (pure).

:func:`encode_state` turns a learner (any :class:`LearnerState`, such as
:class:`gyro_tdc.learn.learner.Learner`, which this module does not import) into the dict its
``save`` writes (tagged :data:`FORMAT`); :func:`decode_state` checks such a dict and gives back
the attribute values it restores; :func:`write_state` and :func:`read_state` move it to and
from a file (atomically; a missing file is no state).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Protocol

from gyro_tdc.base import atomic_write
from gyro_tdc.errors import FeatureError
from gyro_tdc.model import ThermalState
import numpy as np
from numpy.typing import NDArray

__all__ = ['FORMAT', 'LearnerState', 'decode_state', 'encode_state', 'read_state',
           'write_state']

FORMAT = 'gyro_tdc learn 1'


class LearnerState(Protocol):
    """What :func:`encode_state` reads of a learner: the attributes a ``learn_file`` keeps."""

    bins: dict[int, list[list]]
    session: int
    gyro_floor: NDArray[np.float64]
    accel_floor: NDArray[np.float64]
    t_first: float | None
    still_s: float
    stretches: int
    windows: int
    recent: list[list]
    fit: dict | None
    last_update_t: float | None
    last_t: float | None
    check: dict | None
    swaps: int
    motion: list[tuple[float, bool]]
    thermal: ThermalState | None
    thermal_state: tuple[float, list[float]] | None
    config: Any


def encode_state(learner: LearnerState) -> dict[str, Any]:
    """Return the persistent state of ``learner`` as plain types (what ``save`` writes)."""
    ts = learner.thermal_state
    return {
        'format': FORMAT,
        'bins': {str(k): [list(map(float, e[:3])) + [list(map(float, e[3])), e[4], e[5]]
                          for e in v] for k, v in sorted(learner.bins.items())},
        'session': learner.session,
        'gyro_floor': [float(v) for v in learner.gyro_floor],
        'accel_floor': [float(v) for v in learner.accel_floor],
        't_first': learner.t_first, 'still_s': learner.still_s,
        'stretches': learner.stretches, 'windows': learner.windows, 'recent': learner.recent,
        'fit': learner.fit, 'last_update_t': learner.last_update_t, 'last_t': learner.last_t,
        'check': learner.check, 'swaps': learner.swaps,
        'motion': [[float(m[0]), bool(m[1])] for m in learner.motion],
        'thermal': None if learner.thermal is None else learner.thermal.to_dict(),
        'thermal_state': None if ts is None else [float(ts[0]), [float(v) for v in ts[1]]],
        'config': {k: getattr(learner.config, k) for k in (
            'bin_c', 'half_life_s', 'window_s', 'min_still_s')},
    }


def decode_state(state: dict[str, Any]
                 ) -> tuple[dict[str, Any], ThermalState | None]:
    """
    Check a state :func:`encode_state` made; return what it restores.

    Parameters
    ----------
    state : dict
        The state, as read from a ``learn_file``.

    Returns
    -------
    values : dict
        The learner's attribute values by name (``last_save_t`` is the saved ``last_t``).
    thermal : ThermalState or None
        The thermal section the points were binned with (None: the thermometer).

    Raises
    ------
    ValueError
        The state is not one a learner wrote.

    """
    if not isinstance(state, dict) or state.get('format') != FORMAT:
        raise ValueError(f'not a learner state ({FORMAT!r} expected)')
    ts = state.get('thermal_state')
    values = {
        'bins': {int(k): [[float(e[0]), float(e[1]), float(e[2]),
                           tuple(float(x) for x in e[3]), int(e[4]), int(e[5])]
                          for e in v]
                 for k, v in state['bins'].items()},
        'gyro_floor': np.asarray(state['gyro_floor'], dtype=np.float64),
        'accel_floor': np.asarray(state['accel_floor'], dtype=np.float64),
        't_first': state['t_first'],
        'session': int(state['session']),
        'still_s': float(state['still_s']),
        'stretches': int(state['stretches']),
        'windows': int(state['windows']),
        'recent': [list(r) for r in state['recent']],
        'fit': state['fit'],
        'last_update_t': state['last_update_t'],
        'last_t': state['last_t'],
        'last_save_t': state['last_t'],
        'check': state['check'],
        'swaps': int(state['swaps']),
        'motion': [(float(m[0]), bool(m[1])) for m in state.get('motion', [])],
        'thermal_state': None if ts is None else (float(ts[0]), [float(v) for v in ts[1]]),
    }
    try:
        saved = state.get('thermal')
        thermal = None if saved is None else ThermalState.from_dict(saved)
    except FeatureError as exc:
        raise ValueError(f'learner state: `thermal` {exc}') from None
    return values, thermal


def write_state(path: str | Path, state: dict[str, Any]) -> None:
    """Write ``state`` to ``path`` atomically (JSON)."""
    atomic_write(path, json.dumps(state, indent=1) + '\n')


def read_state(path: str | Path) -> dict[str, Any] | None:
    """
    Return the state in ``path``, or None when there is no such file.

    Raises
    ------
    ValueError
        The file is not JSON.

    """
    p = Path(path)
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding='utf-8'))
    except json.JSONDecodeError as exc:
        raise ValueError(f'{p}: not JSON ({exc})') from None
