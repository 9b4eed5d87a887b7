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
A model is validated by what it computes: crafted files with matching ids are refused.

The ``model_id`` is a public content hash, so every crafted file here carries the id its
content hashes to (:func:`forge`, the attacker's step); what refuses it is the check of its
parameters and of the drift it computes. A hypothesis property test perturbs valid models:
each either loads and computes a finite, plausible drift, or is refused with a
ModelFileError.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path
import re

from gyro_tdc.base import config_dir, MAX_ACCEL_DRIFT_MPS2, MAX_DRIFT_RAD_S
from gyro_tdc.errors import ModelFileError
from gyro_tdc.model.compensation import (compensate, CompensationModel, drift,
                                         StreamingCompensator)
from gyro_tdc.model.modelfile import load_model, model_from_dict, model_to_dict, save_model
from gyro_tdc.model.out_of_range import MAX_EXTRAPOLATION_C
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.model.validate import drift_grid
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
import yaml

SUPPORT = Path(__file__).resolve().parents[1] / 'support' / 'files'
_ID = re.compile(r"(field `accel`: )?field `model_id` '[^']*' does not match the "
                 r'parameters \((\w+)\)')


def handmade() -> CompensationModel:
    """Return a format-2 model with dTdt, warmup, a scale term and an accelerometer part."""
    rng = np.random.default_rng(7)
    norm = (np.array([10.0, 300.0]), np.array([20.0, 400.0]), rng.normal(size=(3, 2)),
            rng.uniform(0.3, 1.0, 3))
    weights = rng.normal(scale=1e-2, size=(3, 3))
    coef = np.vstack([[0.01, 0.0, -0.02], rng.normal(scale=1e-2, size=(2, 3)), weights])
    accel = CompensationModel.network('rbf', ('dT', 'dT2'), {}, 20.0, norm, coef,
                                      temp_range_c=(-10.0, 50.0),
                                      residual_var=np.full(3, 1e-4), sensor_id='unit-7',
                                      thermal=ThermalState())
    norm = (np.array([10.0, 300.0, 0.0, 0.3]), np.array([20.0, 400.0, 0.01, 0.3]),
            rng.normal(size=(4, 4)), rng.uniform(0.3, 1.0, 4))
    weights = rng.normal(scale=1e-3, size=(4, 3))
    coef = np.vstack([[1e-3, -2e-3, 5e-4], rng.normal(scale=1e-4, size=(4, 3)), weights])
    return CompensationModel.network(
        'rbf', ('dT', 'dT2', 'dTdt', 'scale', 'warmup'),
        {'dTdt': {'tau_s': 60.0}, 'warmup': {'tau_s': 300.0}}, 20.0, norm, coef,
        scale=np.array([2e-4, -1e-4, 0.0]), temp_range_c=(-10.0, 50.0),
        residual_var=np.full(3, 1e-8), sensor_id='unit-7', thermal=ThermalState(), accel=accel)


_MAKERS = {
    'handmade': lambda: model_to_dict(handmade()),
    'shipped': lambda: yaml.safe_load((config_dir() / 'models' /
                                       'l3gd20_modified.yaml').read_text()),
}


@functools.cache
def _base(name: str) -> dict:
    return _MAKERS[name]()


def base_dict(name: str) -> dict:
    """Return a fresh copy of a valid model dict (parsed once: YAML is slow)."""
    return copy.deepcopy(_base(name))


def forge(d: dict) -> dict:
    """Give a crafted model dict the ids its content hashes to (public, like any hash)."""
    for _ in range(3):
        try:
            model_from_dict(d)
        except ModelFileError as exc:
            hit = _ID.search(str(exc))
            if hit is None:
                return d                   # refused for what it holds, not for its id
            (d['accel'] if hit.group(1) else d)['model_id'] = hit.group(2)
        else:
            return d
    return d


def _set(d: dict, path: tuple, value) -> None:
    for key in path[:-1]:
        d = d[key]
    d[path[-1]] = value


def crafted(base: str, *edits) -> dict:
    d = base_dict(base)
    for path, value in edits:
        _set(d, path, value)
    return forge(d)


# The crafted files of the hardening review (and a few more): every one carries a matching
# id and used to load.
CRAFTED = {
    't0_c 1e308': ([(('t0_c',), 1e308)],
                   'field `t0_c` must lie within the plausible temperatures -100 .. 200 degC'),
    'range 1e300': ([(('temp_range_c',), [-1e300, 1e300])], 'field `temp_range_c` must lie'),
    'std 1e-320': ([(('normalization', 'std', 0), 1e-320)],
                   'field `normalization.std` must be at least 1e-09'),
    'scale -1/25': ([(('scale', 0), -1 / 25)], 'field `scale` (-0.04 1/degC, axis x) makes '
                                               'the gain 1 + scale*dT'),
    'weights 1e300': ([(('weights', 1, 2), 1e300)], 'field `weights` must be within +-1e+09 '
                                                    'rad/s, got 1e+300 at [1, 2]'),
    'intercept 1e300': ([(('intercept', 0), -1e300)], 'field `intercept` must be within'),
    'slopes 1e300': ([(('linear', 0, 1), 1e300)], 'field `linear` must be within'),
    'widths 1e-200': ([(('widths', 2), 1e-200)], 'field `widths` must be at least 1e-06'),
    'accel weights 1e300': ([(('accel', 'weights', 0, 0), 1e300)],
                            'field `accel`: field `weights` must be within +-1e+09 m/s^2'),
    'mean 1e300': ([(('normalization', 'mean', 1), 1e300)], 'field `normalization.mean`'),
    'centre 1e300': ([(('centers', 0, 0), 1e300)], 'field `centers` must be within'),
    'residual 1e300': ([(('residual_var_rad2_s2', 0), 1e300)],
                       'field `residual_var_rad2_s2` must be within +-25 (rad/s)^2'),
    'dTdt tau 1e-300': ([(('effect_params', 'dTdt', 'tau_s'), 1e-300)],
                        'field `effect_params.dTdt.tau_s` must lie within'),
    # Bounded parameters, implausible drift: found by evaluating the model.
    'intercept 100 rad/s': ([(('intercept', 1), 100.0)],
                            'the drift it computes is 100 rad/s (axis y)'),
    'dTdt slope': ([(('linear', 2, 0), 0.1)], 'the drift it computes is'),
    'accel 100 m/s^2': ([(('accel', 'intercept', 2), 100.0)],
                        'field `accel`: the drift it computes is 100 m/s^2 (axis z)'),
}


@pytest.mark.parametrize('case', CRAFTED)
def test_crafted_model_with_a_matching_id_is_refused(tmp_path, case):
    edits, needle = CRAFTED[case]
    path = tmp_path / 'forged.yaml'
    path.write_text(yaml.safe_dump(crafted('handmade', *edits), sort_keys=False))
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    text = str(info.value)
    assert '\n' not in text and str(path) in text and 'does not match' not in text
    assert needle in text, text


def test_the_dTdt_slope_is_refused_at_a_plausible_temperature_rate():
    with pytest.raises(ModelFileError, match=r'rad/s \(axis x\) at .* dTdt -?2[,) ]'):
        model_from_dict(crafted('handmade', *CRAFTED['dTdt slope'][0]))


def test_a_narrow_peak_between_grid_points_is_seen_at_its_centre():
    # One centre placed off the temperature grid, made narrow and tall: its own point is
    # evaluated, where the peak is.
    m = handmade()
    grid = np.linspace(-10.0 - MAX_EXTRAPOLATION_C, 50.0 + MAX_EXTRAPOLATION_C, 257)
    t_peak = grid[120] + 0.37 * (grid[1] - grid[0])          # between two grid temperatures
    x, s = drift_grid(m)
    assert np.abs(np.unique(s[:-3 * m.n_centers]) - t_peak).min() > 0.1
    c = m.centers.copy()
    c[0] = (np.array([t_peak - 20.0, (t_peak - 20.0) ** 2, 0.0, 0.5]) - m.input_mean) \
        / m.input_std
    w = m.widths.copy()
    w[0] = 1e-5
    wt = m.weights.copy()
    wt[0] = [50.0, 0.0, 0.0]
    peaked = m.replace(centers=c, widths=w, weights=wt)
    with pytest.raises(ModelFileError, match=r'the drift it computes is 50 rad/s \(axis x\)'):
        model_from_dict(model_to_dict(peaked))


@pytest.mark.parametrize('path', sorted((config_dir() / 'models').glob('*.yaml')),
                         ids=lambda p: p.name)
def test_shipped_models_load(path):
    assert load_model(path).model_id


def test_a_plausible_model_loads_and_round_trips(tmp_path):
    m = handmade()
    assert load_model(save_model(m, tmp_path / 'm.yaml')) == m


# ------------------------------------------------------------------------------------------
# Property: perturbed models load and compute a plausible drift, or are refused
# ------------------------------------------------------------------------------------------

def _paths(d: dict, prefix: tuple = ()) -> list[tuple]:
    """Return the path of every number in the numeric fields of a model dict."""
    out = []
    for key in ('t0_c', 'temp_range_c', 'normalization', 'centers', 'widths', 'weights',
                'intercept', 'linear', 'scale', 'residual_var_rad2_s2', 'residual_var_m2_s4',
                'effect_params', 'accel', 'mean', 'std', 'dTdt', 'warmup', 'lag', 'tau_s'):
        if key in d:
            out += _numbers(d[key], prefix + (key,))
    return out


def _numbers(v, path: tuple) -> list[tuple]:
    if isinstance(v, dict):
        return _paths(v, path)
    if isinstance(v, list):
        return [p for i, x in enumerate(v) for p in _numbers(x, path + (i,))]
    return [path] if isinstance(v, (int, float)) and not isinstance(v, bool) else []


PATHS = {name: _paths(base_dict(name)) for name in _MAKERS}
HOSTILE = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e300, -1e300, 1e-320, -1e-320, 5e-324, 1e-200, 0.0,
                     -0.0, -1 / 25, 1 / 25, 1e6, -1e6, 1e5, 100.0, -100.0, 1e-9, 1e-7]),
    st.floats(min_value=-1e3, max_value=1e3))


def _ramp(lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Return a heating-then-cooling run over the range plus the extrapolation limit."""
    temp = np.concatenate([np.linspace(lo, hi, 400), np.linspace(hi, lo, 400)])
    span = max(hi - lo, 1e-6)
    step = span / 399 / 0.5                       # 0.5 degC/s
    return np.arange(temp.size) * step, temp


def _plausible(m: CompensationModel, bound: float) -> None:
    lo, hi = m.temp_range_c
    t, temp = _ramp(lo - MAX_EXTRAPOLATION_C, hi + MAX_EXTRAPOLATION_C)
    for policy in ('linear', 'clamp', 'extrapolate'):
        b = drift(m, t, temp, out_of_range=policy)
        assert np.all(np.isfinite(b)) and np.abs(b).max() <= bound, (policy, np.abs(b).max())


@settings(max_examples=200, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
@pytest.mark.parametrize('base', _MAKERS)
def test_perturbed_models_load_plausible_or_are_refused(base, data):
    d = base_dict(base)
    edits = data.draw(st.lists(st.tuples(st.sampled_from(PATHS[base]), HOSTILE),
                               min_size=1, max_size=3))
    for path, value in edits:
        _set(d, path, value)
    d = forge(d)
    try:
        m = model_from_dict(d)
    except ModelFileError as exc:
        assert '\n' not in str(exc)
        return
    _plausible(m, MAX_DRIFT_RAD_S)
    if m.accel is not None:
        _plausible(m.accel, MAX_ACCEL_DRIFT_MPS2)
    lo, hi = m.temp_range_c
    t, temp = _ramp(lo - MAX_EXTRAPOLATION_C, hi + MAX_EXTRAPOLATION_C)
    omega = np.full((t.size, 3), 0.5)
    out = compensate(m, t, temp, omega, out_of_range='linear')
    assert np.all(np.isfinite(out)) and np.abs(out).max() <= 2 * (0.5 + MAX_DRIFT_RAD_S)
    stream = StreamingCompensator(m, out_of_range='linear')
    for k in range(0, t.size, 40):
        assert np.all(np.isfinite(stream.step(t[k], temp[k], omega[k])))
