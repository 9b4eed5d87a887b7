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


"""Tests of gyro_tdc.identify.train: chamber, still-only, flight logs, frames, constant axes."""

from __future__ import annotations

from dataclasses import replace
import json
import math
from pathlib import Path
import shutil
import tempfile
import warnings

from bags import bag_from_run
from constant_axes import axis_sets, quanta, values, with_constant as _with
from flightlogs import flight_day, flight_logs, still_drift, write_dataflash
from gyro_tdc.base.limits import MAX_CENTERS
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data.bag.writer import write_bag
from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.options import BagOptions
from gyro_tdc.errors import DatasetError, FeatureError, FitError, LimitError
from gyro_tdc.evaluate.report import format_training
from gyro_tdc.evaluate.score import evaluate_run, NamedModel
from gyro_tdc.identify import constant_gyro_axes, estimate_t0, fit_model
from gyro_tdc.identify.fit import FitOptions
from gyro_tdc.identify.still_only import moving_share
from gyro_tdc.identify.train import (choose_features, features_for_fit, proxy_lag, train,
                                     train_still_only, TrainOptions, TrainResult)
from gyro_tdc.model import compensate, DEFAULT_OUT_OF_RANGE
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
from gyro_tdc.sim import load_scenario, simulate_run
from gyro_tdc.sim.simulator import to_run
from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest
from real_logs import ARDUPILOT_CUBEBLACK
from synth import synth_run


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp('train') / 'runs'
    folder.mkdir()
    runs = [synth_run(seed=21, hours=1.0, cooling=True), synth_run(seed=22, hours=1.0)]
    for k, run in enumerate(runs, start=1):
        bag_from_run(run, folder / f'run{k}')
    return folder, runs


def test_train_saves_the_model_it_returns(bags, tmp_path):
    folder, runs = bags
    lines = []
    result = train([folder], tmp_path / 'm.yaml', TrainOptions(features='dT,dT2', kind='poly'),
                   command='python -m gyro_tdc train ...', log=lines.append)
    assert result.path == tmp_path / 'm.yaml'
    assert load_model(result.path) == result.model
    assert result.bags == [str(folder / 'run1'), str(folder / 'run2')]
    total = sum(len(r) for r in runs)
    assert total - 10 <= result.samples < total   # the IMU tail after the last thermometer
    assert [line.split(':')[0] for line in lines] == [f'read {b}' for b in result.bags]
    assert result.model.created['command'] == 'python -m gyro_tdc train ...'
    assert result.model.kind == 'poly' and result.model.features == ('dT', 'dT2')
    # The model removes the drift of a held-out run to the white-noise floor.
    held = synth_run(seed=23, hours=1.0)
    bs = bias_stability(compensate(result.model, held.t, held.temp, held.omega),
                        held.omega_ref)
    assert np.all(bs < 1.5 * held.info['noise_dps'] ** 2)
    # Coverage of both runs: heating on both, cooling on the first.
    c = result.coverage
    assert c.heating_min > 0 and c.cooling_min > 0 and int(c.samples.sum()) == result.samples
    text, warns = format_training(result)
    assert text.startswith('model: poly f(dT, dT2), T0 = ')
    assert 'training data: 2 bag(s)' in text and warns == []


def test_the_options_reach_the_model(bags, tmp_path):
    folder, _ = bags
    options = TrainOptions(features='dT', kind='rbf', n_centers=5, t0=31.5, seed=4,
                           sensor_id='imu-7', accel=False)
    result = train([folder / 'run2'], tmp_path / 'm.yaml', options)
    m = result.model
    assert (m.kind, m.features, m.n_centers, m.t0_c, m.sensor_id) == ('rbf', ('dT',), 5, 31.5,
                                                                      'imu-7')
    assert result.accel is None and result.choice is None
    # The bag options say how to read: a topic the bag lacks is refused by name.
    with pytest.raises(DatasetError, match='/other/temperature'):
        train([folder / 'run2'], tmp_path / 'n.yaml', options,
              BagOptions(temperature_topic='/other/temperature'))
    assert not (tmp_path / 'n.yaml').exists()


@pytest.fixture(scope='module')
def board(tmp_path_factory):
    """Return eight power cycles of one IMU at 25 Hz, flights between 10-60 s stops."""
    return flight_logs(tmp_path_factory.mktemp('board'), 8, legs=6)


def _held_out_ratio(model, days, paths):
    """Return the within-log drift of still stretches, compensated over raw, per axis."""
    comp = []
    for path in paths:
        r = load_run(path)
        comp.append(compensate(model, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE))
    return still_drift(days, comp) / still_drift(days)


def test_default_train_on_logs_with_flights_fits_only_the_still_stretches(board, tmp_path):
    days, paths = board
    lines = []
    result = train(paths[:4], tmp_path / 'm.yaml', TrainOptions(), log=lines.append)
    assert any('no reference rate and the IMU moves' in line
               and 'training on the still stretches only' in line for line in lines)
    assert result.still is not None
    still_s = result.still.still_s
    truly = sum(d.still.sum() for d in days[:4]) / 25.0
    assert 0.6 * truly < still_s <= truly * 1.01     # the 10-60 s stretches are found
    assert 0.0 < still_s / result.still.total_s < 1.0
    ratio = _held_out_ratio(result.model, days[4:], paths[4:])
    assert np.all(ratio <= 1.1), ratio              # no harm held out on any axis
    assert np.all(ratio < 0.5), ratio               # and the drift is learnt
    # The same model as --still-only with its defaults.
    same = train_still_only(paths[:4], tmp_path / 's.yaml', TrainOptions())
    np.testing.assert_allclose(_held_out_ratio(same.model, days[4:], paths[4:]), ratio)


def test_still_only_carries_the_start_up_shift_gate_of_its_still_rows(board, tmp_path, capsys):
    days, paths = board
    out, js = tmp_path / 'm.yaml', tmp_path / 'm.json'
    assert train_main([*map(str, paths[:4]), '--still-only', '--out', str(out),
                       '--json', str(js), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'start-up anchors taken throughout the training data err by' in text
    assert 'held out on 4 power cycles' in text
    rec = json.loads(js.read_text())['reanchor']
    assert rec == load_model(out).metrics['reanchor']
    assert (rec['sessions'], rec['held_out']) == (4, 4)
    gate = 2.0 * np.array(rec['anchor_error_dps'])
    # The flights are no anchors: still stretches of one board err by millidegrees per s.
    assert np.all((gate > 0.0) & (gate < 0.05)), rec
    np.testing.assert_allclose(rec['min_shift_dps'], np.where(
        np.array(rec['gated_dps']) < np.array(rec['always_dps']), gate, 0.0))
    for a in 'xyz':
        assert sum(line.startswith(f'axis {a}: the node re-anchors')
                   for line in text.splitlines()) == 1


def test_still_only_with_a_log_without_still_time_among_three_or_more(board, tmp_path):
    days, paths = board
    flying = flight_day(99, legs=2, still_s=(0.5, 1.0), flight_s=(300.0, 300.0))
    moving = write_dataflash(tmp_path / 'flying.bin', [flying.imu])
    result = train_still_only([paths[0], moving, paths[1], paths[2]], tmp_path / 'm.yaml',
                              TrainOptions(min_still_s=20.0))
    assert len(result.model.metrics['sessions']['offset_dps']) == 3
    assert result.still.total_s > sum(d.imu.t[-1] - d.imu.t[0] for d in days[:3])
    ratio = _held_out_ratio(result.model, days[4:], paths[4:])
    assert np.all(ratio <= 1.1), ratio


def test_moving_share_tells_a_flight_log_from_a_still_one(board):
    days, paths = board
    run = load_run(paths[0])
    share = moving_share([run])
    assert 0.3 < share < 1.0 - days[0].still.mean() + 0.05
    still = flight_day(5, legs=1, still_s=(300.0, 300.0))
    assert moving_share([load_run(write_dataflash(paths[0].parent / 'still.bin',
                                                  [still.imu]))]) == 0.0


def _one_log(tmp_path, day, options):
    """Train ``--still-only`` on one simulated flight log; return its path, result, lines said."""
    path = write_dataflash(tmp_path / 'one.bin', [day.imu])
    said = []
    return path, train_still_only([path], tmp_path / 'm.yaml', options, log=said.append), said


def test_one_power_cycle_of_stops_keeps_the_offset_only_and_says_why(tmp_path):
    # One flight log: stops of 15-45 s while the board warms from 20 degC. Nothing holds a
    # power cycle out to tell whether its curve carries to the next: the offset only, said.
    path, result, said = _one_log(tmp_path, flight_day(3, legs=8, still_s=(15.0, 45.0),
                                                       tau_s=900.0), TrainOptions())
    assert result.model.features == ()
    assert np.all(result.model.linear == 0.0)
    line = [ln for ln in said if ln.startswith('one power cycle only, and no still stretch')]
    assert len(line) == 1 and line[0].endswith(
        'the model keeps the offset only on every axis (re-anchoring still applies)'), said
    assert 'of 5 min or more spans 2 degC of its own (the widest 0.' in line[0]
    assert result.choice.lines()[-1].endswith('; not kept: one power cycle of stops cannot '
                                              'judge its curve, the model keeps the offset only')
    # Default train on the flight log (it moves: its stops only) does the same.
    assert train([path], tmp_path / 'd.yaml', TrainOptions()).model.features == ()


def test_one_power_cycle_warming_still_over_a_span_keeps_its_curve(tmp_path):
    # Still 10 min while warming 20 -> 35 degC, then a flight, then a stop: the long stretch
    # tells the curve on its own, as a parked day does; kept.
    day = flight_day(4, legs=2, still_s=(600.0, 600.0), flight_s=(60.0, 60.0), t_end=35.0,
                     tau_s=300.0)
    _, result, said = _one_log(tmp_path, day, TrainOptions(features='dT,dT2'))
    assert result.model.features == ('dT', 'dT2')
    assert not any(ln.startswith('one power cycle only') for ln in said), said


def test_one_power_cycle_warming_fast_after_power_on_keeps_the_offset_only(tmp_path):
    # Still 90 s right after power-on while the board self-heats 20 -> 27 degC, then flights
    # and short stops: the span is told in the power-on minutes only, which on real boards
    # did not carry to the next power cycle. The offset only, and the line says why.
    day = flight_day(5, legs=4, still_s=(90.0, 90.0), flight_s=(60.0, 60.0), t_end=35.0,
                     tau_s=150.0)
    _, result, said = _one_log(tmp_path, day, TrainOptions(features='dT,dT2'))
    assert result.model.features == ()
    line = [ln for ln in said if ln.startswith('one power cycle only')]
    assert len(line) == 1 and ' min): no held-out power cycle' in line[0], said
    widest = float(line[0].split('(the widest ')[1].split(' degC')[0])
    assert widest >= 2.0, line


def test_no_still_time_counts_the_bags_not_their_sessions(tmp_path):
    # One log that only flies, its stamps jumping 20 min on (a logging pause): two sessions
    # of one bag. The refusal counts the bag the user gave.
    day = flight_day(6, legs=2, still_s=(0.5, 1.0), flight_s=(120.0, 120.0))
    run = load_run(write_dataflash(tmp_path / 'flying.bin', [day.imu]))
    t = run.t + np.where(np.arange(len(run)) >= len(run) // 2, 1200.0, 0.0)
    with pytest.raises(FitError, match=r'no still stretch long enough in 1 bag\(s\)'):
        train_still_only(['flying'], tmp_path / 'm.yaml', TrainOptions(),
                         runs=[replace(run, t=t)])


def test_a_real_flight_log_with_too_little_still_time_is_refused_in_one_line(tmp_path):
    with pytest.raises(FitError,
                       match=r'still-only training: the still time spans 0\.\d+ degC only'):
        train([ARDUPILOT_CUBEBLACK], tmp_path / 'm.yaml', TrainOptions())


def test_a_proxy_thermometer_turns_the_thermal_state_on_with_auto_features(board):
    days, paths = board
    run = load_run(paths[0])
    proxied = type(run)(run.t, run.temp, run.omega, run.omega_ref, run.name,
                        {**run.info, 'temperature_proxy': True}, run.accel)
    said = []
    assert proxy_lag([proxied], ('dT', 'dT2'), TrainOptions(), said.append) == (
        'dT', 'dT2', 'lag')
    assert said and 'proxy' in said[0]
    assert proxy_lag([run], ('dT', 'dT2'), TrainOptions()) == ('dT', 'dT2')
    assert proxy_lag([proxied], ('dT',), TrainOptions(features='dT')) == ('dT',)


OPTIONS = TrainOptions(features='dT,dT2', kind='poly')


def bag(path, frame_id, seed=21):
    run = synth_run(seed=seed, hours=1.0, cooling=True)
    write_bag(path, imu_t=run.t + 100.0, gyro=run.omega, accel=np.zeros((len(run), 3)),
              temp_t=run.t[::2] + 100.0, temp_c=run.temp[::2], frame_id=frame_id)
    return path


@pytest.mark.parametrize('frame_id', ['base_link', 'imu_link'])
def test_the_model_takes_the_frame_of_the_bag(tmp_path, frame_id):
    result = train([bag(tmp_path / 'run', frame_id)], tmp_path / 'm.yaml', OPTIONS)
    assert result.model.frame_id == frame_id
    assert load_model(result.path).frame_id == frame_id          # written to the file


def test_data_without_a_frame_make_a_model_that_claims_none(tmp_path):
    result = train([bag(tmp_path / 'run', '')], tmp_path / 'm.yaml', OPTIONS)
    assert result.model.frame_id == '' and load_model(result.path).frame_id == ''


def test_bags_in_two_frames_are_refused(tmp_path):
    bags = [bag(tmp_path / 'a', 'imu_link'), bag(tmp_path / 'b', 'base_link', seed=22)]
    with pytest.raises(DatasetError, match="2 frames .*'imu_link'.*'base_link'"):
        train(bags, tmp_path / 'm.yaml', OPTIONS)
    assert not (tmp_path / 'm.yaml').exists()
    # A frame-less bag beside a framed one is no conflict: the model takes the one frame.
    ok = train([tmp_path / 'a', bag(tmp_path / 'c', '', seed=23)], tmp_path / 'n.yaml', OPTIONS)
    assert ok.model.frame_id == 'imu_link'


AXES = 'xyz'
STILL_OPTIONS = TrainOptions(features='dT,dT2', n_centers=6)


@pytest.fixture(scope='module')
def runs():
    """Return a still training run and a still held-out run, a known drift on every axis."""
    return (synth_run(seed=41, hours=0.5, rate_hz=2.0, noise_dps=0.02),
            synth_run(seed=42, hours=0.5, rate_hz=2.0, noise_dps=0.02, name='held'))


def _still_only(run, options=STILL_OPTIONS):
    """Train --still-only on ``run`` in a temporary folder; return the result."""
    folder = Path(tempfile.mkdtemp())
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            return train_still_only([run.name], folder / 'm.yaml', options, runs=[run])
    finally:
        shutil.rmtree(folder)


def _columns(model, keep):
    """Return the coefficients of the axes ``keep`` and what every axis shares."""
    return (model.intercept[keep], model.linear[:, keep], model.weights[:, keep],
            model.scale[keep], model.residual_var[keep], model.centers, model.widths,
            model.input_mean, model.input_std, model.temp_range_c, model.t0_c)


@given(axes=axis_sets, value=values, quantum=quanta, seed=st.integers(0, 1000))
@example(axes=[0], value=5.0, quantum=0.0078125, seed=0)     # mean square above 25 (rad/s)^2
@settings(max_examples=12)
def test_still_only_passes_a_constant_axis_through(runs, axes, value, quantum, seed):
    """Zero columns on the constant axes, the others as with them at their reference."""
    run, held = runs
    res = _still_only(_with(run, axes, value, quantum, seed))
    ref = _still_only(_with(run, axes, 0.0, 0.0))
    m = res.model
    names = [AXES[i] for i in axes]
    others = [i for i in range(3) if i not in axes]
    assert list(res.constant) == names and m.metrics['constant_axes'] == names
    assert res.constant[names[0]] == pytest.approx(value, abs=quantum + 1e-12)
    assert 'not fitted' in res.constant_line() and res.still is not None
    assert not np.any(m.intercept[axes]) and not np.any(m.linear[:, axes])
    assert not np.any(m.weights[:, axes]) and not np.any(m.scale[axes])
    for a, b in zip(_columns(m, others), _columns(ref.model, others)):
        np.testing.assert_array_equal(a, b)
    stuck = _with(held, axes, value, quantum, seed)
    comp = compensate(m, stuck.t, stuck.temp, stuck.omega)
    assert np.array_equal(comp[:, axes], stuck.omega[:, axes])        # bit for bit
    # Its training figures: the raw ones (the reference is 0 while still).
    raw = np.degrees(_with(run, axes, value, quantum, seed).omega[:, axes]) ** 2
    for k, i in enumerate(axes):
        want = raw[:, k].mean()
        assert m.metrics['train_bs_dps2'][i] == pytest.approx(want, rel=1e-9, abs=1e-300)
        assert m.metrics['raw_bs_dps2'][i] == m.metrics['train_bs_dps2'][i]
    assert all(np.isfinite(m.metrics[k]).all() for k in ('train_bs_dps2', 'train_rms_dps'))


def test_the_other_axes_are_as_accurate_as_with_the_real_signal(runs):
    """Held out, x and y compensate within 2 % of a still-only training on z's signal."""
    run, held = runs
    real = _still_only(run).model
    stuck = _still_only(_with(run, [2], 0.25, 1e-4)).model
    named = [NamedModel('real', 'real', real), NamedModel('stuck', 'stuck', stuck)]
    b = evaluate_run(held, named)
    np.testing.assert_allclose(b.models[1].bs[:2], b.models[0].bs[:2], rtol=0.02)
    assert np.all(b.models[1].bs[:2] < 0.05 * b.raw.bs[:2])


def test_auto_features_keep_the_identity(runs):
    """Choose features on the other axes only; the constant axis stays zero."""
    run, _ = runs
    res = _still_only(_with(run, [1], -0.3, 1e-5), replace(STILL_OPTIONS, features='auto'))
    assert res.choice is not None and res.model.metrics['constant_axes'] == ['y']
    assert not np.any(res.model.linear[:, 1]) and not np.any(res.model.weights[:, 1])


def test_a_gyro_constant_on_every_axis_is_refused_with_trains_line(runs, tmp_path):
    """Refuse in one line, the line train gives on the same bag; write nothing."""
    dead = _with(runs[0], [0, 1, 2], 0.01, 1e-4)
    bag = bag_from_run(dead, tmp_path / 'dead')
    with pytest.raises(DatasetError) as still:
        train_still_only([bag], tmp_path / 'a.yaml', STILL_OPTIONS)
    with pytest.raises(DatasetError) as chamber:
        train([bag], tmp_path / 'b.yaml', STILL_OPTIONS)
    assert str(still.value) == str(chamber.value)
    assert '\n' not in str(still.value) and 'every axis' in str(still.value)
    assert not (tmp_path / 'a.yaml').exists()
    with pytest.raises(DatasetError):
        constant_gyro_axes([dead])


def test_options_are_checked_when_built():
    assert TrainOptions().auto and TrainOptions(features=' auto ').features == 'auto'
    assert TrainOptions(features='dT2, dT').features == ('dT', 'dT2')     # catalog order
    assert TrainOptions(features=['lag', 'dT']).features == ('dT', 'lag')
    with pytest.raises(FeatureError, match='bogus'):
        TrainOptions(features='dT,bogus')
    with pytest.raises(FitError, match="Expected `kind` to be one of rbf, poly, got 'spline'"):
        TrainOptions(kind='spline')
    with pytest.raises(FitError, match='ridge'):
        TrainOptions(ridge=-1.0)
    with pytest.raises(FitError, match="Expected `thermal` to be one of none, .*'third_order'"):
        TrainOptions(thermal='third_order')
    with pytest.raises(LimitError, match='centres'):
        TrainOptions(n_centers=MAX_CENTERS + 1)
    with pytest.raises(LimitError, match='bin'):
        TrainOptions(bin_c=0.0)


def test_fit_options_are_the_training_choices_fit_model_shares():
    o = TrainOptions(kind='poly', n_centers=5, refine=True, ridge=1e-3, seed=4,
                     thermal='first_order', sensor_id=7, bin_c=2.0, accel=False)
    fo = o.fit_options(t0=20.0)
    assert fo == FitOptions(kind='poly', n_centers=5, refine=True, ridge=1e-3, seed=4,
                            thermal='first_order', sensor_id='7', t0=20.0)


@pytest.mark.parametrize('constant, line', [
    ({}, ''),
    ({'z': 0.0}, 'gyro axis z: constant at 0 rad/s'),
    ({'x': 0.5, 'z': -1e-3}, 'gyro axes x, z: constant at 0.5, -0.001 rad/s')])
def test_the_constant_line_names_each_constant_axis(constant, line):
    res = TrainResult(model=None, path=None, coverage=None, bags=[], samples=0,
                      constant=constant)
    assert res.constant_line().startswith(line)
    if constant:
        assert ('passes them through' if len(constant) > 1 else 'passes it through') in \
            res.constant_line()


# ``--features auto`` (choose_features, features_for_fit) on a lagging die, one ramp direction.
#
# Power cycles of the simulator's L3GD20 (cubic drift in the die temperature, the die 90 s
# behind the package thermometer unless said), each a 5 min soak, a 1 degC/min ramp and a
# 5 min soak; a third cycle, ramped the other way, is held out. The soaks at the ends of the
# ramps show the die catching up, so the lag is identifiable from heating (or cooling) alone:
# the choice must name ``lag`` with tau near the die's, not ``warmup`` (a decay since power-on
# that the other direction does not follow) nor ``dTdt`` (a rate input the other direction
# drives out of its trained range), and the held-out cycle must come within 1.2 x the floor on
# every axis. The third case is the one where a slow ``dTdt`` stood in for the static
# curvature the base polynomial lacks.

DEG = math.pi / 180.0
TAU_DIE_S = 90.0


def _cycle(lo: float, hi: float, heating: bool, seed: int, *, rate_hz: float = 2.0,
           res: float = 0.004, tau: float = TAU_DIE_S, offset: float = 0.2):
    """Simulate one power cycle: soak, ramp at 60 degC/h, soak; the die lags by ``tau``."""
    a, b = (lo, hi) if heating else (hi, lo)
    sc = {'format_version': 1, 'name': f'cycle{seed}', 'sensor': 'l3gd20',
          'imu_rate_hz': rate_hz,
          'profile': {'start_c': a, 'segments': [
              {'kind': 'hold', 'duration_s': 300.0},
              {'kind': 'ramp', 'to_c': b, 'rate_c_per_h': 60.0},
              {'kind': 'hold', 'duration_s': 300.0}]},
          'thermal': {'tau_package_s': 30.0, 'tau_die_s': tau},
          'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': res},
          'gyro': {'effects': ['bias', 'dT', 'dT2', 'dT3', 'lag'],
                   'dT2_dps_per_c2': [8.0e-4, 6.0e-4, -2.5e-4],
                   'dT3_dps_per_c3': [4.0e-6, -3.0e-6, 2.0e-6]},
          'runs': {'count': 1, 'bias_offset_dps_std': offset}}
    sim = simulate_run(load_scenario(sc), seed=seed)
    return to_run(sim), sim.truth.noise_std


def test_heating_only_names_lag_and_holds_on_cooling():
    """Name lag (not warmup) from heating-only cycles with soaks; hold on a cooling cycle."""
    train = [_cycle(7.0, 33.0, True, 1001)[0], _cycle(20.0, 55.0, True, 1002)[0]]
    held, noise = _cycle(11.0, 46.0, False, 1003)
    t0 = estimate_t0(train[0])
    choice = choose_features(train, t0=t0)
    verdict = {d.effect: d.verdict for d in choice.decisions}
    assert 'lag' in choice.features and 'warmup' not in choice.features, choice.lines()
    assert verdict['lag'] == 'added'
    tau = choice.discovery.thermal.tau_s[0]
    assert 0.8 * TAU_DIE_S < tau < 1.2 * TAU_DIE_S
    # The report says what heating-only data cannot test.
    assert any('only heat' in line and 'hysteresis' in line for line in choice.lines())
    ids, params, _ = features_for_fit(train, 'auto', t0=t0)
    model = fit_model(train, features=ids, params=params or None, t0=t0, sessions=[0, 1])
    err = compensate(model, held.t, held.temp, held.omega) - held.omega_ref
    err -= err.mean(axis=0)                     # re-anchored: its own turn-on offset
    ratio = np.mean(err ** 2, axis=0) / noise ** 2
    assert np.all(ratio <= 1.2), ratio


def _auto_held_out_ratio(train: list, held, noise) -> tuple:
    """Train as ``train`` does by default; return the features and held-out BS / floor."""
    t0 = estimate_t0(train[0])
    ids, params, choice = features_for_fit(train, 'auto', t0=t0)
    model = fit_model(train, features=ids, params=params or None, t0=t0, sessions=[0, 1])
    err = compensate(model, held.t, held.temp, held.omega) - held.omega_ref
    err -= err.mean(axis=0)
    return ids, model, np.mean(err ** 2, axis=0) / noise ** 2


def test_cooling_only_names_lag_and_holds_on_heating():
    """Name lag from cooling-only cycles at 1 Hz; a held-out heating cycle stays at the floor."""
    kw = {'rate_hz': 1.0}
    train = [_cycle(9.0, 37.0, False, 3000, **kw)[0], _cycle(30.0, 61.0, False, 3001, **kw)[0]]
    held, noise = _cycle(14.0, 49.0, True, 3002, **kw)
    ids, model, ratio = _auto_held_out_ratio(train, held, noise)
    assert 'lag' in ids and not {'warmup', 'dTdt'} & set(ids), ids
    assert 0.8 * TAU_DIE_S < model.thermal.tau_s[0] < 1.2 * TAU_DIE_S
    assert np.all(ratio <= 1.2), ratio


def test_slow_rate_term_is_not_taken_for_missing_curvature():
    """Keep a slow dT/dt out when the static curve (dT3) holds what it would explain."""
    # The 1 Hz, 0.25 degC, 300 s lag case of bench_sessions (seed 27): heating -14..26 and
    # cooling 41..13 degC, a heating cycle 9..34 degC held out; without the static curve
    # beside it, a dT/dt of tau ~1300 s passed the guard after lag and the held-out cycle
    # came out at 1.67 / 1.38 / 1.23 x the floor.
    kw = {'rate_hz': 1.0, 'res': 0.25, 'tau': 300.0, 'offset': 0.0}
    train = [_cycle(-14.21, 25.75, True, 9000, **kw)[0],
             _cycle(13.35, 40.98, False, 9001, **kw)[0]]
    held, noise = _cycle(9.38, 33.60, True, 9002, **kw)
    ids, model, ratio = _auto_held_out_ratio(train, held, noise)
    assert 'lag' in ids and 'dTdt' not in ids, ids
    assert 240.0 < model.thermal.tau_s[0] < 360.0
    assert np.all(ratio <= 1.2), ratio


def test_lag_ranked_above_warmup_by_what_the_curve_cannot_hold():
    """Name lag, not a warm-up that held missing curvature, on cooling-only cycles."""
    # The 1 Hz, 90 s lag case of bench_sessions (seed 11): cooling 32..-6 and 46..19 degC,
    # a heating cycle -6..18 degC held out. Both pass; warmup's held-out gain was the larger
    # (0.0018 against 0.0014 (deg/s)^2) until the gains were taken beside dT3 (0.0066
    # against 0.027): the held-out cycle then came out at 34 / 11 / 4.7 x the floor.
    kw = {'rate_hz': 1.0, 'offset': 0.0}
    train = [_cycle(-5.93, 32.19, False, 4000, **kw)[0],
             _cycle(18.80, 45.58, False, 4001, **kw)[0]]
    held, noise = _cycle(-5.52, 17.68, True, 4002, **kw)
    ids, model, ratio = _auto_held_out_ratio(train, held, noise)
    assert 'lag' in ids and 'warmup' not in ids, ids
    assert 0.8 * TAU_DIE_S < model.thermal.tau_s[0] < 1.2 * TAU_DIE_S
    assert np.all(ratio <= 1.2), ratio


def _ramp_only(run, start_s: float):
    """Return ``run`` from ``start_s`` after power-on to the start of its final soak."""
    from gyro_tdc.data import Run

    keep = (run.t >= run.t[0] + start_s) & (run.t <= run.t[-1] - 300.0)
    return Run(run.t[keep], run.temp[keep], run.omega[keep], run.omega_ref[keep], run.name)


def test_ramp_without_soaks_names_lag_only_where_it_shows():
    """Name lag from a ramp that starts at a settled die; name nothing from one mid-ramp."""
    # From the start of the ramp (the die settled in the soak before it): tau shows. With
    # a 90 s lag the imprint is marginal (found on 6 of 8 seeds, effect ~0.6 x the floor),
    # with 300 s it is not (8 of 8).
    raw = [_cycle(0.0, 40.0, True, 1101, tau=300.0)[0],
           _cycle(15.0, 60.0, True, 1102, tau=300.0)[0]]
    held, noise = _cycle(11.0, 46.0, False, 1103, tau=300.0)
    ids, model, ratio = _auto_held_out_ratio([_ramp_only(r, 300.0) for r in raw], held, noise)
    assert 'lag' in ids and not {'warmup', 'dTdt'} & set(ids), ids
    assert 240.0 < model.thermal.tau_s[0] < 360.0
    assert np.all(ratio <= 1.2), ratio
    # From 10 min into the ramp of a 90 s lag (the die at its steady lag): nothing shows
    # tau, so neither lag nor a stand-in for it is named, and the report says why.
    raw = [_cycle(0.0, 40.0, True, 1201)[0], _cycle(15.0, 60.0, True, 1202)[0]]
    train = [_ramp_only(r, 900.0) for r in raw]
    choice = choose_features(train, t0=estimate_t0(train[0]))
    assert not {'lag', 'dTdt', 'warmup'} & set(choice.features), choice.lines()
    assert any('mid-ramp it is not identifiable' in line for line in choice.lines())
