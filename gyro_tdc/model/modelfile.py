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
The versioned YAML model file: save, load, validate.

One format, :data:`FORMAT_VERSION`. :func:`load_model` reads with the safe loader under hard
limits, checks every field, the ``model_id`` content hash and what the model computes
(:mod:`gyro_tdc.model.validate`), and names a bad field in one line. The format, field by
field: ``doc/internals/model.md``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

from gyro_tdc.base import (atomic_write, FieldChecker, MAX_CENTERS, plain, read_yaml, shown,
                           YamlLimits)
from gyro_tdc.errors import ModelFileError
from gyro_tdc.model.compensation import CompensationModel, FORMAT_VERSION, KINDS
from gyro_tdc.model.effects import input_ids, normalise_ids, resolve_params
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.model.validate import check_model, reworded
import numpy as np
import yaml

__all__ = ['FORMAT_VERSION', 'MAX_MODEL_BYTES', 'MAX_MODEL_DEPTH', 'MAX_MODEL_NODES',
           'load_model', 'model_from_dict', 'model_to_dict', 'save_model']

MAX_MODEL_BYTES = 4 * 1024 * 1024
MAX_MODEL_DEPTH = 32
MAX_MODEL_NODES = 250_000
_LIMITS = YamlLimits('model file', max_bytes=MAX_MODEL_BYTES, max_depth=MAX_MODEL_DEPTH,
                     max_nodes=MAX_MODEL_NODES, aliases=False)


def model_to_dict(model: CompensationModel) -> dict:
    """Return the model as a dict of plain types, in file order."""
    d = {
        'format_version': FORMAT_VERSION,
        'kind': model.kind,
        'model_id': model.model_id,
        'features': list(model.features),
        'effect_params': plain(model.effect_params),
        'thermal': model.thermal.to_dict(),
        't0_c': float(model.t0_c),
        'temp_range_c': [float(v) for v in model.temp_range_c],
        'normalization': {'mean': plain(model.input_mean), 'std': plain(model.input_std)},
        **{k: plain(getattr(model, k)) for k in ('centers', 'widths', 'weights', 'intercept',
                                                 'linear', 'scale')},
        'residual_var_rad2_s2': plain(model.residual_var),
        'sensor': {'frame_id': model.frame_id, 'sensor_id': model.sensor_id},
        'training': plain(model.metrics),
        'created': plain(model.created),
    }
    if model.accel is not None:     # the part's fields but those it shares, in m/s^2
        d['accel'] = {('residual_var_m2_s4' if k == 'residual_var_rad2_s2' else k): v
                      for k, v in model_to_dict(model.accel).items() if k not in _SHARED}
    return d


#: Fields of the model an ``accel`` part shares (not repeated in its section).
_SHARED = ('format_version', 'thermal', 't0_c', 'sensor', 'created', 'scale')


def _accel_from_dict(d: Mapping) -> CompensationModel | None:
    """Read the optional ``accel`` section of a model file (None when absent)."""
    if d.get('accel') is None:
        return None
    sec = _mapping(d, 'accel')
    bad = sorted(set(sec) & (set(_SHARED) | {'residual_var_rad2_s2'}))
    if bad:
        raise ModelFileError(f'field `accel`: {bad} belong to the model, not to its '
                             'accelerometer part')
    sub = dict(sec, format_version=FORMAT_VERSION, thermal=d.get('thermal'), t0_c=d.get('t0_c'),
               sensor=d.get('sensor'), scale=[0.0, 0.0, 0.0])
    with reworded('field `accel`', ModelFileError):
        sub['residual_var_rad2_s2'] = _get(sub, 'residual_var_m2_s4')
        return _model_from_dict(sub)


#: The shared field checks (gyro_tdc.base.fields), worded for a model file.
_CHK = FieldChecker(lambda key, expected, got: ModelFileError(
    f'field `{key}` must be {expected}, got {shown(got)}'))


def _get(d: Mapping, key: str) -> Any:
    """Return ``d[key]``, or refuse the missing field."""
    if key not in d:
        raise ModelFileError(f'missing field `{key}`')
    return d[key]


def _array(d: Mapping, key: str, shape: tuple, *, positive: bool = False) -> np.ndarray:
    """Read ``d[key]`` as a finite float array of ``shape`` (``-1`` matches any length)."""
    try:
        arr = np.asarray(_get(d, key), dtype=np.float64)
    except (TypeError, ValueError, OverflowError):     # OverflowError: an integer beyond float
        raise ModelFileError(f'field `{key}` must be numbers, got {d[key]!r:.60}') from None
    if len(shape) == 2 and arr.size == 0:
        arr = arr.reshape(0, shape[1] if shape[1] >= 0 else 0)
    if arr.ndim != len(shape) or any(s >= 0 and a != s for a, s in zip(arr.shape, shape)):
        want = str(tuple('N' if s < 0 else s for s in shape)).replace("'", '')
        raise ModelFileError(f'field `{key}` must have shape {want}, got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ModelFileError(f'field `{key}` has non-finite values')
    if positive and np.any(arr <= 0):
        raise ModelFileError(f'field `{key}` must be positive')
    return arr


def _mapping(d: Mapping, key: str, *, required: bool = True) -> dict:
    """Read ``d[key]`` as a mapping (empty when optional and absent or null)."""
    if not required and d.get(key) is None:
        return {}
    return _CHK.mapping(_get(d, key), key)


def model_from_dict(d: Any) -> CompensationModel:
    """
    Build and validate a model from the parsed YAML document of a model file.

    Raises
    ------
    ModelFileError
        Naming the first field that is missing or wrong.

    """
    if not isinstance(d, Mapping):
        raise ModelFileError(f'expected a mapping at the top level, got {type(d).__name__}')
    version = d.get('format_version')
    if type(version) is not int or version != FORMAT_VERSION:       # not 2.0, not true
        note = '' if type(version) is int else f' (a {type(version).__name__}, not an integer)'
        raise ModelFileError(f'field `format_version` must be {FORMAT_VERSION} (the format '
                             f'this gyro_tdc reads), got {version!r}{note}')
    with reworded(f'format_version {version} model', ModelFileError):
        model = _model_from_dict(d)
        check_model(model)
    return model


def _model_from_dict(d: Mapping) -> CompensationModel:
    """Build and validate a model of the current format (see :func:`model_from_dict`)."""
    mid = d.get('model_id')
    if 'model_id' not in d:
        raise ModelFileError('missing field `model_id` (the content hash every model file '
                             'carries; re-save the model with gyro_tdc to add it)')
    if not isinstance(mid, str):
        raise ModelFileError(f'field `model_id` must be a string, got {mid!r:.40}')
    kind = d.get('kind')
    if kind not in KINDS:
        raise ModelFileError(f'field `kind` must be one of {", ".join(KINDS)}, got {kind!r}')
    feats = d.get('features')
    if not isinstance(feats, list) or not all(isinstance(f, str) for f in feats):
        raise ModelFileError(f'field `features` must be a list of effect ids, got {feats!r}')
    with reworded('field `features`/`effect_params`'):
        ids = normalise_ids(feats)
        params = resolve_params(ids, _mapping(d, 'effect_params', required=False))
    if list(ids) != feats:
        raise ModelFileError(f'field `features` must list each id once in catalog order '
                             f'({", ".join(ids)}), got {feats!r}')
    with reworded('field `thermal`'):
        thermal = ThermalState.from_dict(_mapping(d, 'thermal'))
    f = len(input_ids(ids, state=True))
    rows = d.get('centers')
    if isinstance(rows, list) and len(rows) > MAX_CENTERS:
        raise ModelFileError(f'field `centers` has {len(rows)} rows, more than the limit of '
                             f'{MAX_CENTERS} centres')
    norm = _mapping(d, 'normalization')
    mean, std = _array(norm, 'mean', (f,)), _array(norm, 'std', (f,), positive=True)
    centers = _array(d, 'centers', (-1, f))
    k = centers.shape[0]
    if kind == 'poly' and k:
        raise ModelFileError(f'field `centers` must be empty for a poly model, got {k} rows')
    widths, weights, intercept, linear, scale, resid = (
        _array(d, key, shape, positive=key == 'widths') for key, shape in (
            ('widths', (k,)), ('weights', (k, 3)), ('intercept', (3,)), ('linear', (f, 3)),
            ('scale', (3,)), ('residual_var_rad2_s2', (3,))))
    if np.any(resid < 0):
        raise ModelFileError('field `residual_var_rad2_s2` must be non-negative')
    rng_ = _array(d, 'temp_range_c', (2,))
    if rng_[0] > rng_[1]:
        raise ModelFileError(f'field `temp_range_c` must be [min, max], got {rng_.tolist()}')
    accel = _accel_from_dict(d)
    sensor = _mapping(d, 'sensor', required=False)
    frame_id, sensor_id = sensor.get('frame_id', 'imu_link'), sensor.get('sensor_id', '')
    if not isinstance(frame_id, str) or not isinstance(sensor_id, str):
        raise ModelFileError('field `sensor` must hold string `frame_id` and `sensor_id`')
    with reworded('fields `thermal`/`features`/`effect_params`'):
        model = CompensationModel.network(
            kind, ids, params, _CHK.number(_get(d, 't0_c'), 't0_c', what='a finite number'),
            (mean, std, centers, widths), np.vstack([intercept[None, :], linear, weights]),
            scale=scale, temp_range_c=rng_, residual_var=resid, frame_id=frame_id,
            sensor_id=sensor_id, metrics=_mapping(d, 'training', required=False),
            created=_mapping(d, 'created', required=False), thermal=thermal, accel=accel)
    if mid != model.model_id:
        raise ModelFileError(f'field `model_id` {mid!r} does not match the parameters '
                             f'({model.model_id}): the file was edited or corrupted')
    return model


def save_model(model: CompensationModel, path: str | os.PathLike) -> Path:
    """
    Write a model file atomically and return its path (OutputError: nothing is left behind).

    A model that loading would refuse (:func:`check_model`: an implausible drift inside its
    range or the extrapolation beyond it) is not written: ModelFileError, one line.
    """
    try:
        check_model(model)
    except ModelFileError as exc:
        lo, hi = model.temp_range_c
        raise ModelFileError(f'{path}: not written, the fitted model would be refused on '
                             f'loading: {exc} (trained {lo:.1f} .. {hi:.1f} degC)') from None
    text = '# gyro_tdc compensation model (see README "Model file")\n' + yaml.safe_dump(
        model_to_dict(model), sort_keys=False, default_flow_style=None, width=100)
    return atomic_write(Path(path), text, what='model file')


def load_model(path: str | os.PathLike) -> CompensationModel:
    """Read and validate a model file (ModelFileError: the file and what is wrong, one line)."""
    path = Path(path)
    data = read_yaml(path, _LIMITS, error=ModelFileError)
    with reworded(str(path), ModelFileError):
        return model_from_dict(data)
