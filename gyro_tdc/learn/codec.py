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
The learner's state as plain types and back: :func:`encode_state`, :func:`decode_state` (pure).

:func:`encode_state` turns a :class:`~gyro_tdc.learn.learner.Learner` into the dict its ``save``
writes (tagged :data:`FORMAT`); :func:`decode_state` checks every field of such a dict
(:class:`gyro_tdc.base.FieldChecker`) and gives back the attribute values it restores. The
rules: ``doc/internals/learn.md``.
"""

from __future__ import annotations

from functools import partial
import math
import re
from typing import Any, Callable

from gyro_tdc.base import FieldChecker, MAX_COUNT, MAX_RATE_RAD_S, shown, TEMP_PLAUSIBLE_C
from gyro_tdc.errors import FeatureError, LearnFileError, ModelFileError
from gyro_tdc.learn.fit import AXES, model_of, same_thermal
from gyro_tdc.learn.records import Entry, POWER_UPS, RecentStretch
from gyro_tdc.model import (CompensationModel, MAX_PARAM, model_from_dict, model_to_dict,
                            ThermalState)
import numpy as np
from numpy.typing import NDArray

__all__ = ['decode_state', 'encode_state', 'FORMAT', 'MAX_COUNT', 'MAX_STAMP_S', 'RECENT_ROWS']

FORMAT = 'gyro_tdc learn 1'
#: Windows of one recent stretch kept in the file (its newest): a day of 10 s windows.
RECENT_ROWS = 8640
#: Largest stamp magnitude, s (an unsigned 32-bit second count).
MAX_STAMP_S = 2.0 ** 32
_FEATURES = ((), ('dT',), ('dT', 'dT2'), ('dT', 'dT2', 'dT3'))
_KEYS = ('format', 'bins', 'session', 'gyro_floor', 'accel_floor', 't_first', 'still_s',
         'stretches', 'windows', 'recent', 'fit', 'last_update_t', 'last_t', 'check', 'swaps',
         'motion', 'thermal', 'thermal_state', 'config', 'segment', 'power_ups')
_FIT_KEYS = ('features', 't0_c', 'coef', 'range_c', 'resid_var', 'points', 'held_out')
_GATE_HELD = ('always_dps', 'gated_dps', 'never_dps')
_HELD_KEYS = ('sessions', 'folds', 'points', 'curve_ms_dps2', 'offset_ms_dps2', 'offset_only')
_CONFIG_KEYS = ('bin_c', 'half_life_s', 'window_s', 'min_still_s')
_RATE = (-MAX_RATE_RAD_S, MAX_RATE_RAD_S, 'a rate in rad/s')
_TEMP = (*TEMP_PLAUSIBLE_C, 'a plausible temperature in degC')


def encode_state(learner: Any) -> dict[str, Any]:
    """
    Return the persistent state of ``learner`` as plain types (what ``save`` writes).

    A noise floor not known yet (infinite) is ``None``; a recent stretch keeps its newest
    :data:`RECENT_ROWS` windows.
    """
    ts = learner.thermal_state
    return {
        'format': FORMAT,
        'bins': {str(k): [[float(e.t_end), float(e.samples), float(e.temp_c),
                           [float(b) for b in e.bias], e.group, e.session]
                          for e in v] for k, v in sorted(learner.bins.items())},
        'session': learner.session,
        **{k: [float(v) if math.isfinite(v) else None for v in getattr(learner.still, k)]
           for k in ('gyro_floor', 'accel_floor')},
        't_first': learner.still.t_first, 'still_s': learner.still_s,
        'stretches': learner.stretches, 'windows': learner.windows,
        'recent': [[stretch, session, rows[-RECENT_ROWS:]]
                   for stretch, session, rows in learner.recent],
        'fit': learner.fit, 'last_update_t': learner.last_update_t, 'last_t': learner.last_t,
        'check': learner.check, 'swaps': learner.swaps,
        'motion': [[float(m[0]), bool(m[1])] for m in learner.motion],
        'thermal': None if learner.thermal is None else learner.thermal.to_dict(),
        'thermal_state': None if ts is None else [float(ts[0]), [float(v) for v in ts[1]]],
        'config': {k: getattr(learner.config, k) for k in _CONFIG_KEYS},
        'segment': [learner.segment, learner.segment_t0],
        'power_ups': [[int(u[0]), int(u[1]), *(float(v) for v in u[2:])]
                      for u in learner.power_ups],
        # A correction fit: the model it corrects, so the file alone gives the learned model.
        **({'prior': model_to_dict(learner.prior)}
           if learner.fit is not None and learner.fit.get('prior') else {}),
    }


# -- decoding: every field checked, by name ------------------------------------------------


def _bad(name: str, what: str) -> LearnFileError:
    """Return the error for field ``name``."""
    return LearnFileError(f'learner state: field `{name}` {what}')


#: The shared field checks (gyro_tdc.base.fields), worded for a learn_file.
_CHK = FieldChecker(lambda name, expected, got: _bad(name,
                                                     f'must be {expected}, got {shown(got)}'))
_number, _count, _list, _dict = _CHK.number, _CHK.count, _CHK.items, _CHK.keys


def _maybe(check: Callable[..., Any]) -> Callable[..., Any]:
    """Return ``check`` that takes null too (None)."""
    return lambda v, *args: None if v is None else check(v, *args)


def _fields(v: Any, name: str, checks: dict, optional: tuple = ()) -> dict:
    """Return the mapping ``v`` of the keys of ``checks`` (``optional`` ones may lack), checked."""
    v = _dict(v, name, [k for k in checks if k not in optional], optional=optional)
    return {k: check(v[k], f'{name}.{k}') for k, check in checks.items() if k in v}


#: A stamp (s), a plausible temperature (degC) and a sample count.
_stamp = partial(_number, lo=-MAX_STAMP_S, hi=MAX_STAMP_S, what='a stamp in s')
_temp = partial(_number, lo=TEMP_PLAUSIBLE_C[0], hi=TEMP_PLAUSIBLE_C[1], what=_TEMP[2])
_samples = partial(_number, lo=1.0, hi=MAX_COUNT, what='a sample count')
#: The items of a point-table entry (:class:`Entry`) and of a recent window: (label, check).
_ENTRY = ((' (t_end)', _stamp), (' (samples)', _samples), (' (temperature)', _temp),
          ('', lambda v, name: tuple(_CHK.numbers(v, name, 3, *_RATE))), (' (stretch)', _count),
          (' (session)', _count))
_WINDOW = ((' (samples)', _samples), (' (temperature)', _temp),
           *[(' (mean rate)', partial(_number, lo=_RATE[0], hi=_RATE[1], what=_RATE[2]))] * 3,
           (' (t_end)', _stamp))
_POWER_UP = ((' (session)', _count), (' (windows)', _count), *_WINDOW[:-1])


def _row(v: Any, name: str, items: tuple) -> list:
    """Return the list ``v``, each item checked by its ``(label, check)`` of ``items``."""
    return [check(x, f'{name}[{i}]{label}')
            for i, (x, (label, check)) in enumerate(zip(_list(v, name, len(items)), items))]


def _floor_in(v: Any, name: str) -> NDArray[np.float64]:
    """Return a noise floor: positive, or infinite (null: not known yet)."""
    floor = _list(v, name, 3)
    for i, f in enumerate(floor):
        if f is not None and not _number(f, f'{name}[{i}]', 0.0, 1e6,
                                         'a noise floor (positive or null)') > 0.0:
            raise _bad(f'{name}[{i}]', f'must be positive or null, got {f!r}')
    return np.array([math.inf if f is None else float(f) for f in floor])


def _bins(v: Any, bin_c: float | None, most: int | None) -> dict[int, list[Entry]]:
    """Return the point table: bin -> entries ``[t_end, samples, temp, b, stretch, session]``."""
    if not isinstance(v, dict):
        raise _bad('bins', f'must be an object (bin -> entries), got {shown(v)}')
    # The bins of the plausible temperatures, one either side.
    lo, hi = (-math.inf, math.inf) if bin_c is None else (
        math.floor(c / bin_c) + d for c, d in zip(TEMP_PLAUSIBLE_C, (-1, 1)))
    out: dict[int, list[Entry]] = {}
    for key, entries in v.items():
        name = f'bins[{key!r:.20}]'
        if not (isinstance(key, str) and re.fullmatch(r'-?[0-9]{1,9}', key)):
            raise _bad(name, 'must be keyed by a bin number')
        k = int(key)
        if not lo <= k <= hi:
            raise _bad(name, f'must be a bin of a plausible temperature ({lo} .. {hi})')
        out[k] = [Entry(*_row(e, f'{name}[{j}]', _ENTRY))
                  for j, e in enumerate(_list(entries, name, most=most))]
        if not out[k]:
            raise _bad(name, 'must hold at least one entry')
    return out


def _recent(v: Any, most: int | None) -> list[RecentStretch]:
    """Return the recent stretches: ``[stretch, session, windows]``."""
    items = ((' (stretch)', _count), (' (session)', _count), ('', lambda w, name: [
        _row(r, f'{name}[{j}]', _WINDOW) for j, r in enumerate(_list(w, name, most=RECENT_ROWS))]))
    return [RecentStretch(*_row(s, f'recent[{i}]', items))
            for i, s in enumerate(_list(v, 'recent', most=most))]


def _fit(v: Any, thermal: ThermalState | None, prior: CompensationModel | None) -> dict | None:
    """
    Return the fit record, its model checked like a model file's (null: :func:`_maybe`).

    A correction fit (``prior``, a ``model_id``) must be one to the state's ``prior``.
    """
    v = _dict(v, 'fit', _FIT_KEYS, optional=('reanchor', 'prior'))
    feats = _list(v['features'], 'fit.features')
    if tuple(feats) not in _FEATURES:
        raise _bad('fit.features', f'must be one of {", ".join(map(str, _FEATURES))}, '
                   f'got {feats!r:.60}')
    coef = [_CHK.numbers(row, f'fit.coef[{i}]', 3, -MAX_PARAM, MAX_PARAM, 'a coefficient')
            for i, row in enumerate(_list(v['coef'], 'fit.coef', 1 + len(feats)))]
    rng = _CHK.numbers(v['range_c'], 'fit.range_c', 2, *_TEMP)
    if not rng[0] <= rng[1]:
        raise _bad('fit.range_c', f'must be [low, high], got {rng}')
    fit = {'features': list(feats), 't0_c': _temp(v['t0_c'], 'fit.t0_c'), 'coef': coef,
           'range_c': rng,
           'resid_var': _CHK.numbers(v['resid_var'], 'fit.resid_var', 3, 0.0,
                                     MAX_RATE_RAD_S ** 2, 'a variance in (rad/s)^2'),
           'points': _count(v['points'], 'fit.points', 1),
           'held_out': _held_out(v['held_out'], bool(feats))}
    if v.get('reanchor') is not None:
        fit['reanchor'] = _gate(v['reanchor'])
    if (mid := v.get('prior')) is not None:
        if prior is None or mid != prior.model_id:
            raise _bad('fit.prior', "must be the model_id of the state's `prior`, got "
                       f'{shown(mid)}')
        fit['prior'] = mid
    try:
        model_of(fit, thermal, prior)
    except ModelFileError as exc:
        raise _bad('fit', f'gives a model refused as a model file would be: {exc}') from None
    return fit


def _gate(v: Any) -> dict:
    """Return the fit's start-up shift gate (:func:`gyro_tdc.learn.gate.learned_gate`)."""
    dps = partial(_CHK.numbers, n=3, lo=0.0, hi=MAX_PARAM, what='a rate in deg/s')
    rates = dict.fromkeys(('anchor_error_dps', 'min_shift_dps') + _GATE_HELD, dps)
    return _fields(v, 'fit.reanchor', {'sessions': _count, 'held_out': _count, **rates},
                   optional=_GATE_HELD)


def _held_out(v: Any, curve: bool) -> dict | None:
    """Return the fit's held-out record (None: the fit has no curve)."""
    if v is None and not curve:
        return None
    v = _dict(v, 'fit.held_out', _HELD_KEYS)
    out = {k: _count(v[k], f'fit.held_out.{k}') for k in _HELD_KEYS[:3]}
    for k in _HELD_KEYS[3:5]:
        out[k] = None if v[k] is None and not out['folds'] else _CHK.numbers(
            v[k], f'fit.held_out.{k}', 3, 0.0, MAX_PARAM, 'a mean square in (deg/s)^2')
    axes = _list(v['offset_only'], 'fit.held_out.offset_only', most=3)
    if not all(a in AXES for a in axes) or len(set(axes)) < len(axes):
        raise _bad('fit.held_out.offset_only', f'must be distinct axis names, got {axes!r:.40}')
    out['offset_only'] = axes
    return out


def _prior(v: Any, thermal: ThermalState | None) -> CompensationModel | None:
    """Return the model a correction fit was learned over, as a model file's."""
    try:
        prior = model_from_dict(v)
    except ModelFileError as exc:
        raise _bad('prior', f'is not a model: {exc}') from None
    if not same_thermal(prior.thermal, thermal):
        raise _bad('prior', 'must have the thermal section the points were binned with')
    return prior


def _check(v: Any) -> dict | None:
    """Return the last prediction check."""
    mse = partial(_number, lo=0.0, hi=MAX_RATE_RAD_S ** 2 * 3, what='a squared error in (rad/s)^2')
    return _fields(v, 'check', {'t': _stamp, 'candidate_mse': mse, 'current_mse': _maybe(mse),
                                'swapped': _CHK.boolean})


def _thermal(v: Any) -> ThermalState | None:
    """Return the thermal section the points were binned with."""
    if not isinstance(v, dict) or not isinstance(v.get('kind'), str):
        raise _bad('thermal', f'must be a thermal section with a `kind`, got {shown(v)}')
    try:
        thermal = ThermalState.from_dict(v)
    except (FeatureError, TypeError, ValueError) as exc:
        raise _bad('thermal', str(exc)) from None
    for i, tau in enumerate(thermal.tau_s):
        _number(tau, f'thermal.tau_s[{i}]', 1e-3, 1e8, 'a time constant in s')
    return thermal


def _thermal_state(v: Any, thermal: ThermalState | None) -> tuple[float, list[float]] | None:
    """Return the carried thermal state: (stamp, one value per node of ``thermal``)."""
    nodes = 0 if thermal is None else len(thermal.tau_s)
    if not nodes:
        raise _bad('thermal_state', 'must be null without a thermal section with a lag')
    temps = partial(_CHK.numbers, n=nodes, lo=_TEMP[0], hi=_TEMP[1], what=_TEMP[2])
    return tuple(_row(v, 'thermal_state', (('', _stamp), ('', temps))))


def _motion(v: Any) -> list[tuple[float, bool]]:
    """Return the motion reports (stamp, moving), in stamp order."""
    return sorted((tuple(_row(m, f'motion[{i}]', (('', _stamp), ('', _CHK.boolean))))
                   for i, m in enumerate(_list(v, 'motion'))), key=lambda r: r[0])


def decode_state(state: Any, *, bin_c: float | None = None, bin_entries: int | None = None,
                 stretches: int | None = None) -> tuple[dict[str, Any], ThermalState | None]:
    """
    Check every field of a state :func:`encode_state` made; return what it restores.

    Returns the learner's attribute values by name (``last_save_t`` is the saved
    ``last_t``; ``prior`` the model a correction fit was learned over, None without one)
    and the thermal section the points were binned with (None: the thermometer).
    ``bin_c`` (degC), ``bin_entries`` and ``stretches`` are the learner's bin width, entries
    per bin and recent stretches kept, checked against when given.

    Raises
    ------
    LearnFileError
        Not a state a learner wrote: one line naming the field, what it must be and holds.

    """
    if not isinstance(state, dict) or state.get('format') != FORMAT:
        raise LearnFileError(f'not a learner state ({FORMAT!r} expected)')
    _dict(state, 'state', _KEYS, optional=('prior',))
    for k, x in _dict(state['config'], 'config', _CONFIG_KEYS).items():
        if x is not None or k != 'min_still_s':          # None: the auto rule
            _number(x, f'config.{k}', 0.0)
    thermal = _maybe(_thermal)(state['thermal'])
    prior = _maybe(_prior)(state.get('prior'), thermal)
    values = {
        'bins': _bins(state['bins'], bin_c, bin_entries),
        'gyro_floor': _floor_in(state['gyro_floor'], 'gyro_floor'),
        'accel_floor': _floor_in(state['accel_floor'], 'accel_floor'),
        'still_s': _number(state['still_s'], 'still_s', 0.0, MAX_COUNT, 'a duration in s'),
        'recent': _recent(state['recent'], stretches),
        'power_ups': [_row(u, f'power_ups[{i}]', _POWER_UP) for i, u in enumerate(
            _list(state['power_ups'], 'power_ups', most=POWER_UPS))],
        'fit': _maybe(_fit)(state['fit'], thermal, prior),
        'prior': prior,
        'check': _maybe(_check)(state['check']),
        'motion': _motion(state['motion']),
        'thermal_state': _maybe(_thermal_state)(state['thermal_state'], thermal),
    }
    values.update({k: _count(state[k], k) for k in ('session', 'stretches', 'windows', 'swaps')})
    values.update({k: _maybe(_stamp)(state[k], k) for k in ('t_first', 'last_update_t', 'last_t')})
    values['segment'], values['segment_t0'] = _row(state['segment'], 'segment', (
        (' (entry group)', _count), (' (its first stamp)', _maybe(_stamp))))
    values['last_save_t'] = values['last_t']
    return values, thermal
