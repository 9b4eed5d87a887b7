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
The accelerometer part: still data, orientation changes, the fit, zero at T0, the model file.

Runs come from the ``accel_chamber`` scenario (the die lags the probe by 300 s, the offset is
curved in the die temperature) at a low rate; the gyro model is ``dT, dT2, lag`` so its
thermal state is the one the accelerometer part shares.
"""

from __future__ import annotations

from dataclasses import replace
import math

from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FeatureError, FitError, ModelFileError
from gyro_tdc.identify import (accel_features, accel_scores, compensate_accel, discovery_runs,
                               fit_accel, fit_linear, fit_model, fit_px4_cubic, MG, PX4_FEATURES,
                               static_bs, static_data)
from gyro_tdc.identify.power_cycles import MIN_FOLDS, SLOW_CURVE_S
from gyro_tdc.model import static_slope
from gyro_tdc.model.compensation import drift, StreamingCompensator
from gyro_tdc.model.modelfile import load_model, model_from_dict, model_to_dict, save_model
from gyro_tdc.model.thermal_state import ThermalState
from gyro_tdc.signal import has_accelerometer
from gyro_tdc.sim import load_scenario, simulate_scenario, to_run
import numpy as np
import pytest

RATE_HZ = 2.0


def _runs(overrides: dict | None = None, *, rate: float = RATE_HZ, seed: int = 0):
    sc = load_scenario('accel_chamber')
    if overrides:
        sc = sc.with_overrides(overrides)
    sims = simulate_scenario(sc, seed=seed, rate_hz=rate)
    return sims, [to_run(s) for s in sims]


@pytest.fixture(scope='module')
def chamber():
    """Two chamber runs, the gyro model of run 1, its accelerometer fit, and the PX4 pair."""
    sims, runs = _runs()
    gyro = fit_model(runs[:1], features='dT,dT2,lag')
    fit = fit_accel(runs[:1], gyro)
    px4 = fit_px4_cubic(runs[:1])
    px4_fit = fit_accel(runs[:1], px4, kind='poly', features=PX4_FEATURES)
    return {'sims': sims, 'runs': runs, 'gyro': gyro, 'fit': fit,
            'model': gyro.replace(accel=fit.part), 'px4': px4.replace(accel=px4_fit.part)}


def test_held_out_variance_reaches_the_noise_floor_and_beats_px4(chamber):
    floor = chamber['sims'][1].truth.accel_noise_std ** 2
    raw, (ours, px4) = accel_scores(chamber['runs'][1], [chamber['model'], chamber['px4']])
    assert np.all(raw > 50.0 * floor)                   # a real thermal effect to remove
    assert np.all(ours <= 1.05 * floor), ours / floor
    assert np.all(ours <= px4), (ours, px4)
    # The die lags the probe: a cubic in the measured temperature cannot follow it.
    assert np.all(px4 > 2.0 * floor)


def test_part_shares_the_thermal_state_and_t0(chamber):
    part, gyro = chamber['fit'].part, chamber['gyro']
    assert part.thermal == gyro.thermal and part.t0_c == gyro.t0_c
    assert part.features == ('dT', 'dT2', 'lag') and np.all(part.scale == 0)
    assert part.frame_id == gyro.frame_id
    assert part.effect_params['lag']['tau_s'] == gyro.thermal.tau_total_s


def test_correction_is_zero_at_t0(chamber):
    # A long soak at T0: the thermal state settles at T0 and the correction vanishes, so
    # the compensated specific force equals the raw one (the static offset is not touched).
    model = chamber['model']
    t = np.arange(0.0, 7200.0, 1.0)
    temp = np.full(t.size, model.t0_c)
    acc = np.tile([0.1, -0.2, 9.8], (t.size, 1))
    np.testing.assert_allclose(drift(model.accel, t, temp), 0.0, atol=1e-12)
    np.testing.assert_allclose(compensate_accel(model, t, temp, acc), acc, rtol=0, atol=1e-12)
    # Away from T0 it is the learnt change, close to the truth's change relative to T0.
    sim = chamber['sims'][1]
    truth = sim.truth.accel_thermal
    k0 = int(np.argmin(np.abs(sim.truth.die_c - model.t0_c)))
    run = chamber['runs'][1]
    corr = drift(model.accel, run.t, run.temp)
    err = corr - (truth - truth[k0])
    assert np.sqrt(np.mean(err ** 2, axis=0)).max() < 0.2 * MG


def test_streaming_equals_batch(chamber):
    # Temperatures beyond the trained range exercise the linear tangent too.
    model, run = chamber['model'], chamber['runs'][1]
    temp = np.concatenate([run.temp[:3000], run.temp[3000:6000] + 30.0])
    t, acc = run.t[:6000], run.accel[:6000]
    for policy in ('linear', 'clamp', 'extrapolate'):
        batch = compensate_accel(model, t, temp, acc, out_of_range=policy)
        comp = StreamingCompensator(model, out_of_range=policy)
        stream = np.array([comp.accel.step(a, b, c) for a, b, c in zip(t, temp, acc)])
        np.testing.assert_allclose(stream, batch, rtol=0, atol=1e-9)
    comp.reset()
    assert comp.accel.model_temp is None


def test_gyro_only_model_keeps_its_id_and_accel_is_covered(chamber):
    model = chamber['model']
    assert model.replace(accel=None).model_id == chamber['gyro'].model_id
    assert model.model_id != chamber['gyro'].model_id
    other = model.replace(accel=model.accel.replace(intercept=model.accel.intercept + 1e-9))
    assert other.model_id != model.model_id


def test_model_file_round_trip(chamber, tmp_path):
    model = chamber['model']
    path = save_model(model, tmp_path / 'm.yaml')
    back = load_model(path)
    assert back == model and back.model_id == model.model_id
    assert back.accel.model_id == model.accel.model_id
    text = path.read_text()
    assert 'accel:' in text and 'residual_var_m2_s4' in text
    # Gyro-only files have no section.
    assert 'accel' not in model_to_dict(chamber['gyro'])


@pytest.mark.parametrize('edit, match', [
    (lambda d: d['accel']['weights'][0].__setitem__(0, 1.0), 'model_id'),
    (lambda d: d['accel'].__setitem__('thermal', d['thermal']), 'belong to the model'),
    (lambda d: d['accel'].pop('residual_var_m2_s4'), 'residual_var_m2_s4'),
    (lambda d: d['accel'].__setitem__('features', ['dT']), 'accel'),
    (lambda d: d.__setitem__('accel', 3), 'accel'),
])
def test_bad_accel_sections_are_named(chamber, edit, match):
    d = model_to_dict(chamber['model'])
    edit(d)
    with pytest.raises(ModelFileError, match=match):
        model_from_dict(d)


def test_an_accel_section_needs_the_thermal_section(chamber):
    d = model_to_dict(chamber['px4'])
    d.pop('thermal')
    with pytest.raises(ModelFileError, match='missing field `thermal`'):
        model_from_dict(d)


def test_orientation_change_is_detected_split_and_not_fitted_as_drift(chamber):
    sims, runs = _runs({'accel.reorient_at_s': 5003.0, 'accel.reorient_tilt_deg': [8.0, 0.0]})
    data = static_data(runs[0])
    assert data.n_segments == 2 and len(data.changes) == 1
    change = data.changes[0]
    assert 5003.0 <= change.t_s <= 5020.0 and 6.0 < change.angle_deg < 10.0
    assert 'orientation changed' in change.line() and 'split' in change.line()
    # The window holding the jump is not still; each side keeps its own offset.
    assert not data.mask[np.searchsorted(runs[0].t, 5003.0)]
    fit = fit_accel(runs[:1], chamber['gyro'])
    assert fit.part.metrics['segments'] == 2 and len(fit.changes) == 1
    model = chamber['gyro'].replace(accel=fit.part)
    floor = chamber['sims'][1].truth.accel_noise_std ** 2
    _, (bs,) = accel_scores(chamber['runs'][1], [model])
    assert np.all(bs <= 1.05 * floor)
    # Fitted as drift (one offset for the whole run) the jump would wreck the model.
    whole = fit_linear(runs[0].temp[:, None] - 0.0, runs[0].accel, kind='poly')
    assert np.max(np.mean(whole.resid ** 2, axis=0) / floor) > 100.0


def test_no_false_orientation_change_on_chamber_runs(chamber):
    for run in chamber['runs']:
        data = static_data(run, model=chamber['gyro'])
        assert data.changes == () and data.n_segments == 1 and data.fraction > 0.99


def test_motion_is_not_static_and_splits_the_segments():
    _, runs = _runs(rate=RATE_HZ)
    run = runs[0]
    rng = np.random.default_rng(4)
    moving = (run.t > 3000.0) & (run.t < 3200.0)
    omega, acc = run.omega.copy(), run.accel.copy()
    omega[moving] += rng.standard_normal((int(moving.sum()), 3)) * 0.5
    acc[moving] += rng.standard_normal((int(moving.sum()), 3)) * 2.0
    data = static_data(Run(run.t, run.temp, omega, run.omega_ref, 'moved', accel=acc))
    assert not data.mask[moving].any()
    assert data.changes == () and data.n_segments == 2     # a long motion: a new offset
    assert data.fraction > 0.95


def test_a_turning_rate_table_is_not_static(chamber):
    run = chamber['runs'][0]
    ref = np.tile([0.0, 0.0, math.radians(10.0)], (len(run), 1))
    turning = Run(run.t, run.temp, run.omega + ref, ref, 'table', accel=run.accel)
    fit = fit_accel([turning], chamber['gyro'])
    assert fit.part is None and 'reference rate is not zero' in fit.note
    assert fit.lines()[0].startswith('accelerometer: not fitted:')


def test_no_accelerometer_data(chamber):
    run = chamber['runs'][0]
    zeros = Run(run.t, run.temp, run.omega, run.omega_ref, 'z', accel=np.zeros((len(run), 3)))
    assert not has_accelerometer(zeros.accel) and not has_accelerometer(None)
    assert static_data(zeros) is None
    unread = Run(run.t, run.temp, run.omega, run.omega_ref, 'not read')
    fit = fit_accel([zeros, unread], chamber['gyro'])
    assert fit.part is None and 'no accelerometer data' in fit.note
    assert accel_scores(zeros, [chamber['model']]) == (None, [None])


def test_static_bs_is_the_variance_around_the_mean(chamber):
    run = chamber['runs'][1]
    data = static_data(run)
    np.testing.assert_allclose(static_bs(run.accel, data), run.accel[data.mask].var(axis=0),
                               rtol=1e-12)


def test_scores_are_none_for_models_without_a_part_and_runs_that_move(chamber):
    run = chamber['runs'][1]
    raw, (a, b) = accel_scores(run, [chamber['gyro'], chamber['model']])
    assert raw is not None and a is None and b is not None
    rng = np.random.default_rng(1)
    moving = (np.floor(run.t / 100.0) % 3 != 0)[:, None]     # two thirds of the run move
    shaken = Run(run.t, run.temp, run.omega + moving * rng.standard_normal(run.omega.shape),
                 run.omega_ref, 's', accel=run.accel + moving * rng.standard_normal((len(run), 3)))
    assert static_data(shaken).fraction < 0.5
    assert accel_scores(shaken, [chamber['model']]) == (None, [None])


def test_accel_features(chamber):
    gyro = chamber['gyro']
    assert accel_features(gyro) == ('dT', 'dT2', 'lag')
    assert accel_features(gyro, 'dT3') == ('dT3', 'lag')
    assert accel_features(gyro, 'dT,dTdt') == ('dT', 'dTdt', 'lag')
    with pytest.raises(FeatureError, match='holds only'):
        accel_features(gyro, 'dT,scale')
    unlagged = fit_px4_cubic(chamber['runs'][:1])
    assert accel_features(unlagged, PX4_FEATURES) == PX4_FEATURES
    with pytest.raises(FeatureError, match='lag'):
        accel_features(unlagged, 'dT,lag')
    assert unlagged.thermal == ThermalState()
    with pytest.raises(FitError, match="Expected `kind` to be one of rbf, poly, got 'mlp'"):
        fit_accel(chamber['runs'][:1], gyro, kind='mlp')


def test_discovery_runs_are_the_still_segments_in_mg(chamber):
    runs = discovery_runs(chamber['runs'])
    assert len(runs) == 2 and np.all(runs[0].omega_ref == 0)
    np.testing.assert_allclose(np.degrees(runs[0].omega), chamber['runs'][0].accel / MG)
    run = chamber['runs'][0]
    with pytest.raises(FitError, match='no still accelerometer data.*x: no accelerometer'):
        discovery_runs([Run(run.t, run.temp, run.omega, run.omega_ref, 'x')])


def test_discovery_runs_leave_out_an_empty_segment(chamber, monkeypatch):
    # Segments 0 and 2 hold the still samples, segment 1 none: no run of zero samples.
    import gyro_tdc.identify.accel as accel_module

    run = chamber['runs'][0]
    d = static_data(run)
    still = np.flatnonzero(d.segment == 0)
    segment = d.segment.copy()
    segment[still[still.size // 2:]] = 2
    monkeypatch.setattr(accel_module, 'static_data',
                        lambda r: replace(d, segment=segment, n_segments=3))
    runs = discovery_runs([run])
    assert [r.name for r in runs] == [f'{run.name}#1', f'{run.name}#3']
    assert [len(r) for r in runs] == [still.size // 2, still.size - still.size // 2]


@pytest.mark.parametrize('chunk_rows', [1, 7, 1000])
@pytest.mark.parametrize('max_rows', [20_000, 10 ** 6])
def test_the_fit_is_the_same_in_passes_of_any_size(chamber, monkeypatch, chunk_rows, max_rows):
    # The force's block sums run in passes of whole blocks (of one row too: max_rows above
    # the still samples); the pass size changes no bit.
    import gyro_tdc.signal.blocks as blocks

    ref = fit_accel(chamber['runs'][:1], chamber['gyro'], max_rows=max_rows)
    monkeypatch.setattr(blocks, 'PASS_ROWS', chunk_rows)
    fit = fit_accel(chamber['runs'][:1], chamber['gyro'], max_rows=max_rows)
    assert fit.part.model_id == ref.part.model_id
    np.testing.assert_array_equal(fit.train_bs, ref.train_bs)
    np.testing.assert_array_equal(fit.raw_bs, ref.raw_bs)
    if max_rows == 20_000:
        assert fit.part.model_id == chamber['fit'].part.model_id
    else:       # one row a block: the blocked fit's residual within 1e-3
        np.testing.assert_allclose(fit.train_bs, chamber['fit'].train_bs, rtol=1e-3)


def _slice(run: Run, lo_c: float, hi_c: float, name: str) -> Run:
    """Return the first stretch of ``run`` whose temperature lies in ``lo_c .. hi_c``."""
    inside = (run.temp >= lo_c) & (run.temp <= hi_c)
    k = int(np.argmax(inside))
    end = k + int(np.argmin(inside[k:])) if not inside[k:].all() else len(run)
    return Run(run.t[k:end], run.temp[k:end], run.omega[k:end], run.omega_ref[k:end], name,
               accel=run.accel[k:end])


def test_no_part_where_no_still_segment_spans_two_degrees_of_its_own(chamber):
    """Each segment has its own constant: a curve over stops of under 2 degC is not told."""
    run = chamber['runs'][0]
    lo, hi = float(run.temp.min()), float(run.temp.max())
    parts = [_slice(run, lo + 5.0, lo + 6.0, 'a'), _slice(run, hi - 6.0, hi - 5.0, 'b')]
    assert all(len(p) >= 100 and np.ptp(p.temp) < 1.5 for p in parts)
    fit = fit_accel(parts, chamber['gyro'])
    assert fit.part is None
    assert fit.note.startswith('no still segment spans 2 degC of the model temperature of its '
                               'own (widest ')
    # One segment over the same stretch is fitted as before; so is the whole run.
    assert fit_accel([_slice(run, lo + 5.0, hi - 5.0, 'c')], chamber['gyro']).part is not None


def test_an_implausible_part_is_left_out_and_said(chamber, monkeypatch):
    """An optional part that loading would refuse never keeps the gyro model unwritten."""
    import gyro_tdc.model.validate as validate
    monkeypatch.setattr(validate, 'MAX_ACCEL_DRIFT_MPS2', 1e-6)
    fit = fit_accel(chamber['runs'][:1], chamber['gyro'])
    assert fit.part is None
    assert fit.note.startswith('the part fitted is implausible, loading would refuse it '
                               '(field `accel`: ')


def _with_z_slope(run: Run, slope: float, name: str) -> Run:
    """Return ``run`` with a z change of ``slope`` (m/s^2 per degC) of its own power cycle."""
    acc = np.array(run.accel, dtype=np.float64)
    acc[:, 2] += slope * (run.temp - run.temp.mean())
    return replace(run, accel=acc, name=name)


def test_the_change_is_judged_on_held_out_power_cycles(chamber):
    """As the gyro's curve: an axis whose change does not carry to another power cycle is off."""
    gyro, (a, b) = chamber['gyro'], chamber['runs']
    carried = fit_accel([a, b], gyro)
    check = carried.part.metrics['held_out']
    assert check['folds'] == 2 and check['offset_only'] == []
    assert np.all(np.array(check['curve_ms_mg2']) < np.array(check['offset_ms_mg2']))
    # z's change differs from one power cycle to the next (each its own slope): not carried.
    slope = 20.0 * MG
    fit = fit_accel([_with_z_slope(a, slope, 'a'), _with_z_slope(b, -slope, 'b')], gyro)
    check = fit.part.metrics['held_out']
    assert check['offset_only'] == ['z'] and check['worse_folds'][2] == 2
    # Unjudged (the PX4-style baseline, fitted as PX4 fits it): z's change is kept.
    px4 = fit_accel([_with_z_slope(a, slope, 'a'), _with_z_slope(b, -slope, 'b')], gyro,
                    judge=False).part
    assert 'held_out' not in px4.metrics and static_slope(px4)[2] != 0.0
    temp = np.linspace(-10.0, 50.0, 61)               # slowly: the thermal state follows
    change = compensate_accel(gyro.replace(accel=fit.part), 3600.0 * np.arange(61.0), temp,
                              np.zeros((61, 3)))
    assert np.all(change[:, 2] == 0.0) and np.ptp(change[:, :2], axis=0).min() > MG
    lines = fit.lines()
    assert any(line.startswith('accelerometer: the change with temperature held out on each '
                               'power cycle (2 sessions') for line in lines)
    assert 'accelerometer axes z: the change with temperature does not predict every ' \
           'held-out power cycle better than none: the part removes none there' in lines
    # Every axis so: no part, said.
    acc = [np.array(r.accel) for r in (a, b)]
    for k, s in enumerate((slope, -slope)):
        acc[k] += s * (np.array((a, b)[k].temp) - (a, b)[k].temp.mean())[:, None] * [1, 1, 1]
    none = fit_accel([replace(r, accel=x) for r, x in zip((a, b), acc)], gyro)
    assert none.part is None and none.note.startswith('the change with temperature does not '
                                                      'predict every held-out power cycle')
    assert none.check['offset_only'] == ['x', 'y', 'z']


def test_one_power_cycle_of_stops_needs_a_slow_segment(chamber):
    """Still-only training (MIN_FOLDS): one power cycle's change rests on a slow segment."""
    run = chamber['runs'][0]
    lo = float(run.temp.min())
    short = _slice(run, lo + 5.0, lo + 8.0, 'short')
    assert np.ptp(short.t) < SLOW_CURVE_S and np.ptp(short.temp) > 2.5
    assert fit_accel([short], chamber['gyro']).part is not None         # default train
    fit = fit_accel([short], chamber['gyro'], min_folds=MIN_FOLDS)
    assert fit.part is None and fit.note.startswith('one power cycle of stops, and no still '
                                                    'segment of 5 min or more spans 2 degC')
    assert fit_accel([run], chamber['gyro'], min_folds=MIN_FOLDS).part is not None
    # Two power cycles at temperatures apart: none judges the other's change.
    hi = float(run.temp.max())
    apart = [_slice(run, lo, lo + 15.0, 'cold'), _slice(run, hi - 15.0, hi, 'warm')]
    assert fit_accel(apart, chamber['gyro']).part is not None         # default train
    fit = fit_accel(apart, chamber['gyro'], min_folds=MIN_FOLDS)
    assert fit.part is None and fit.note == (
        'judged on 0 held-out power cycle(s) of 2 only: fewer than 2 cannot tell whether a '
        'change of stops carries to the next power cycle')
