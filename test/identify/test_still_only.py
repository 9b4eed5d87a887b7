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

"""Calibrate without a chamber: vehicle days, train --still-only, day 2 within 1.1x floor."""

from __future__ import annotations

from dataclasses import replace
import importlib.util
import math
from pathlib import Path

from flightlogs import flight_day, flight_logs, write_dataflash
from gyro_tdc.cli.evaluate import main as evaluate_main
from gyro_tdc.cli.simulate import simulate
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import BagOptions, load_runs
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import FitError
from gyro_tdc.evaluate.score import evaluate_run, NamedModel
from gyro_tdc.identify import fit_model
from gyro_tdc.identify.discover import discover
from gyro_tdc.identify.still_only import still_only_runs
from gyro_tdc.identify.train import train, train_still_only, TrainOptions
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal import motion_veto
from gyro_tdc.sim import load_scenario, simulate_run, to_run
from gyro_tdc.sim.vehicle import CMD_VEL_TOPIC, gravity_in_sensor, TRUTH_TOPIC
import numpy as np
import pytest
from scenarios import gravity_vector, table_moving
import yaml

ROOT = Path(__file__).resolve().parents[2]
DEG = math.pi / 180.0
BOUND = 1.1


def _script(path: Path):
    """Return the module of a script of the repository (a tool or a bench)."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _tool():
    return _script(ROOT / 'tools' / 'field_day.py')


@pytest.fixture(scope='module')
def days():
    """Vehicle day 1 (seed 1) and day 2 (seed 2, hotter), compressed to 6 h at 10 Hz."""
    return simulate_run('vehicle_day1', seed=1), simulate_run('vehicle_day2', seed=2)


# ------------------------------------------------------------------------- the simulator

def test_vehicle_day_physics(days):
    d1, d2 = days
    v = d1.vehicle
    kinds = [leg.kind for leg in v.legs]
    assert kinds[0] == 'park' and 'drive' in kinds and v.legs[0].t1_s == 2400.0
    assert 0.45 < v.parked.mean() < 0.75
    # Parked: no rotation, gravity at the parking slope; driving: turns and vibration.
    assert np.all(v.rate[v.parked] == 0.0)
    np.testing.assert_allclose(v.force[v.parked],
                               gravity_in_sensor(9.80665, v.roll_deg, v.pitch_deg)[v.parked])
    slopes = {(round(leg.roll_deg, 6), round(leg.pitch_deg, 6)) for leg in v.legs
              if leg.kind == 'park'}
    assert len(slopes) >= 4
    assert np.degrees(np.abs(v.rate[~v.parked, 2]).max()) > 10.0
    np.testing.assert_allclose(d1.ref, v.rate)               # the truth, never a rate table
    assert not d1.moving                 # so a sim driver publishes no rate_table/reference
    assert not table_moving(load_scenario('vehicle_day1').rate_table)
    # The accelerometer reads the specific force plus its offset and noise.
    off = d1.truth.accel_offset
    assert np.abs(d1.accel - off - v.force)[v.parked].max() < 0.05
    # cmd_vel: zero while parked, the commanded speed while driving.
    park = np.zeros(v.cmd_t.size, dtype=bool)
    for leg in v.legs:
        if leg.kind == 'park':
            park |= (v.cmd_t >= leg.t0_s) & (v.cmd_t <= leg.t1_s)
    assert np.all(v.cmd[park] == 0.0) and v.cmd[:, 0].max() == pytest.approx(10.0)
    assert np.all(v.cmd[~park, 0] > 0.0) and np.any(v.cmd[~park, 5] != 0.0)
    # Self-heating: the die is warmer than the ambient after drives; day 2 runs hotter.
    assert v.heating_c.max() > 5.0 and np.all(v.heating_c >= -1e-12)
    assert d1.truth.die_c.max() > 24.0 + 5.0
    assert d2.truth.die_c.min() > d1.truth.die_c.min() + 3.0
    assert d2.truth.die_c.max() > d1.truth.die_c.max()
    # Same convention as the chamber's gravity.
    r, p = np.array([3.0, -7.0]), np.array([-2.0, 5.0])
    np.testing.assert_allclose(gravity_in_sensor(9.8, r, p),
                               [gravity_vector(9.8, a, b) for a, b in zip(r, p)])


def test_a_chamber_scenario_is_unchanged_by_the_vehicle_stream():
    a = simulate_run(load_scenario('die_lag').with_overrides({'duration_s': 600.0}), seed=3,
                     rate_hz=5.0)
    assert a.vehicle is None and not a.moving
    sc = load_scenario('vehicle_day1')
    assert sc.with_overrides({'vehicle.cmd_vel_rate_hz': 0.0}).vehicle.cmd_vel_rate_hz == 0.0
    with pytest.raises(Exception, match='vehicle.drive_s'):
        sc.with_overrides({'vehicle.drive_s': [10.0, 5.0]})
    with pytest.raises(Exception, match='vehicle.speed'):
        sc.with_overrides({'vehicle.speed': 3.0})


# ------------------------------------------------------------------------ the done-criterion

def test_still_only_day1_compensates_day2_within_the_noise_floor(days, tmp_path):
    """Train --still-only on day 1; day 2, driving included, is within 1.1x the floor."""
    d1, d2 = days
    res = train_still_only(['vehicle_day1'], tmp_path / 'm.yaml', runs=[to_run(d1)])
    m = res.model
    assert 'lag' in m.features and m.thermal.kind == 'first_order'
    assert 100.0 < m.thermal.tau_s[0] < 150.0          # the die lags the probe by 120 s
    rep = res.still
    assert 0.45 < rep.still_s / rep.total_s < 0.65 and len(rep.stretches) >= 6
    assert rep.coverage.heating_min > 10.0 and rep.coverage.cooling_min > 60.0
    assert res.samples < len(d1)
    floor = d2.truth.noise_std ** 2 * (180.0 / math.pi) ** 2
    r2 = to_run(d2)                                     # omega_ref: the true rate
    ev = evaluate_run(r2, [NamedModel('m', 'm', m)], reanchor_s='auto')
    ratio = ev.models[0].bs / floor
    assert np.all(ratio <= BOUND), ratio
    assert np.all(ev.raw.bs > 100.0 * floor)
    assert ev.models[0].outside_fraction > 0.05        # day 2 is hotter than the still time
    # The node's logic, streamed message by message with defaults plus re-anchoring.
    out, ok, core = _tool().stream(m, d2.imu_t, d2.gyro, d2.accel, d2.temp_t, d2.temp_c)
    assert core.anchor is not None and core.anchor.t < 2400.0
    bs = ((out[ok] - d2.ref[ok]) ** 2).mean(axis=0) * (180.0 / math.pi) ** 2
    assert np.all(bs / floor <= BOUND), bs / floor
    assert np.count_nonzero(ok) > 0.999 * ok.size


def test_fit_rows_all_true_is_the_plain_fit_and_rows_exclude_motion(days):
    d1, _ = days
    run = to_run(d1)
    run = Run(run.t[::20], run.temp[::20], run.omega[::20], np.zeros((run.t[::20].size, 3)),
              'd1', {})
    parked = d1.vehicle.parked[::20]
    kw = {'features': ('dT', 'dT2'), 'kind': 'poly', 't0': 10.0}
    plain = fit_model([run], **kw)
    every = fit_model([run], rows=[np.ones(len(run), dtype=bool)], **kw)
    np.testing.assert_allclose(every.linear, plain.linear, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(every.residual_var, plain.residual_var, rtol=1e-9)
    # Only the parked rows: the driving (a non-zero rate with omega_ref = 0) does not count.
    still = fit_model([run], rows=[parked], **kw)
    assert still.metrics['samples'] == int(parked.sum())
    assert np.all(still.residual_var < 0.2 * plain.residual_var)


def test_a_slow_turn_that_looks_still_is_dropped_or_vetoed(days, tmp_path):
    d1, _ = days
    full = to_run(d1)
    run = Run(full.t[::2], full.temp[::2], full.omega[::2], full.omega_ref[::2], 'd1', {},
              full.accel[::2])                                        # 5 Hz: quicker
    # A perfectly smooth 2 deg/s yaw during the longest stop: no scatter, so it passes the
    # still test; the fit finds its mean off the others' and drops it.
    legs = [leg for leg in d1.vehicle.legs if leg.kind == 'park'][1:]
    stop = max(legs, key=lambda leg: leg.t1_s - leg.t0_s)
    turn = (run.t >= stop.t0_s + 300.0) & (run.t < stop.t0_s + 900.0)
    omega = run.omega.copy()
    omega[turn, 2] += 2.0 * DEG
    turning = Run(run.t, run.temp, omega, np.zeros_like(omega), 'turning', {}, run.accel)
    paper = TrainOptions(features='dT,dT2', kind='poly')
    res = train_still_only(['turning'], tmp_path / 't.yaml', paper, runs=[turning])
    dropped = [s for s in res.still.stretches if not s.kept]
    assert len(dropped) == 1 and dropped[0].offset_dps[2] == pytest.approx(2.0, abs=0.05)
    assert stop.t0_s + 290.0 < dropped[0].t0_s < stop.t0_s + 320.0
    assert any('dropped still stretch' in line for line in res.still.lines())
    # The motion veto (cmd_vel reporting the turn) keeps it out from the start.
    cmd_t = np.arange(0.0, run.t[-1], 0.2)
    cmd = np.zeros((cmd_t.size, 6))
    cmd[:, 5] = np.where((cmd_t >= stop.t0_s + 299.0) & (cmd_t < stop.t0_s + 900.0),
                         2.0 * DEG, 0.0)                      # the command leads the turn
    held = np.searchsorted(d1.vehicle.cmd_t, cmd_t, side='right') - 1
    cmd[:, 0] = d1.vehicle.cmd[held, 0]
    veto = motion_veto(run.t, cmd_t, cmd)
    vetoed = train_still_only(['turning'], tmp_path / 'v.yaml', paper, runs=[turning],
                              moving=[veto])
    assert all(s.kept for s in vetoed.still.stretches)
    assert not np.any(turn & ~veto)
    np.testing.assert_allclose(vetoed.model.residual_var, res.model.residual_var, rtol=0.05)


def _stops(levels, rate_hz=10.0, seed=5):
    """Return a run of 120 s still stretches (degC, z offset deg/s each), 30 s moving between."""
    rng = np.random.default_rng(seed)
    t, temp, omega, t0 = [], [], [], 0.0
    for k, (deg_c, off) in enumerate(levels):
        for n, still in ((int(120 * rate_hz), True), (int(30 * rate_hz), False)):
            if not still and k == len(levels) - 1:
                break
            g = np.radians(rng.normal(0.0, 0.02 if still else 20.0, (n, 3)))
            g[:, 2] += math.radians(off) if still else 0.0
            t.append(t0 + np.arange(n) / rate_hz)
            temp.append(np.full(n, deg_c))
            omega.append(g)
            t0 = t[-1][-1] + 1.0 / rate_hz
    omega = np.concatenate(omega)
    return Run(np.concatenate(t), np.concatenate(temp), omega, np.zeros_like(omega), 'stops')


def test_slow_turns_dropped_leaving_too_few_degrees_say_so_in_still_terms(tmp_path):
    # Four stops within 0.15 degC; three warmer ones whose mean rate zigzags (slow turns).
    run = _stops([(20.0, 0.0), (20.05, 0.0), (20.1, 0.0), (20.15, 0.0), (24.0, 1.0),
                  (27.0, -1.0), (30.0, 1.0)])
    with pytest.raises(FitError) as err:
        train_still_only(['stops'], tmp_path / 's.yaml',
                         TrainOptions(features='dT', kind='poly'), runs=[run])
    msg = str(err.value)
    assert msg.startswith('still-only training: 3 of the 7 still stretches look like slow turns')
    assert 'the rest span 0.15 degC only' in msg and 'record stops at other temperatures' in msg
    assert '--motion-topic' in msg and '\n' not in msg


# ------------------------------------------------------------------------- command line

def _scenario(tmp_path, name, overrides):
    sc = load_scenario('vehicle_day1').with_overrides(overrides)
    data = sc.to_dict()
    data['name'] = name
    path = tmp_path / f'{name}.yaml'
    path.write_text(yaml.safe_dump(data), encoding='utf-8')
    return str(path)


def test_cli_still_only_with_motion_topic_and_evaluate_on_the_truth(tmp_path, capsys):
    sc = _scenario(tmp_path, 'short',
                   {'imu_rate_hz': 5.0, 'duration_s': 9000.0, 'vehicle.cmd_vel_rate_hz': 2.0})
    bag = tmp_path / 'day'
    simulate(sc, str(bag), seed=1, log=lambda line: None)
    model = tmp_path / 'm.yaml'
    assert train_main([str(bag), '--still-only', '--motion-topic', CMD_VEL_TOPIC,
                       '--features', 'dT,dT2,lag', '--no-accel', '--out', str(model)]) == 0
    out = capsys.readouterr().out
    assert 'no reference read (still: zero rate)' in out
    assert f'; motion veto {CMD_VEL_TOPIC}' in out and 'still time heating' in out
    assert 'still time per 5 degC (min): ' in out and 'record next: park for 20 min' in out
    assert load_model(model).metrics['still']['motion_topic'] == CMD_VEL_TOPIC
    # train() on the same bag falls back to the still stretches with the same veto (the
    # runs it loaded handed over, the motion topic read for them).
    said = []
    train([str(bag)], tmp_path / 'api.yaml', TrainOptions(features='dT,dT2,lag', accel=False),
          BagOptions(motion_topic=CMD_VEL_TOPIC), log=said.append)
    assert any('training on the still stretches only' in line for line in said)
    cli, api = (load_model(p).metrics['still'] for p in (model, tmp_path / 'api.yaml'))
    assert api == cli
    assert evaluate_main([str(bag), '--model', str(model), '--reference-topic', TRUTH_TOPIC,
                          '--reanchor', 'auto']) == 0
    assert f'reference rate from {TRUTH_TOPIC}' in capsys.readouterr().out
    # Bad input: one line, exit 2.
    for argv, words in (
            ([str(bag), '--still-only', '--motion-topic', '/odom'], 'no motion topic'),
            ([str(bag), '--still-only', '--motion-topic', '/imu/temperature'], 'has type'),
            ([str(bag), '--motion-topic', CMD_VEL_TOPIC], 'only with --still-only'),
            ([str(bag), '--still-only', '--min-still', '20000'], 'no still stretch')):
        assert train_main(argv + ['--out', str(tmp_path / 'bad.yaml')]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (argv, err)
    assert not (tmp_path / 'bad.yaml').exists()


def test_cli_still_time_with_too_small_a_span_says_what_to_record(tmp_path, capsys):
    sc = _scenario(tmp_path, 'flat', {
        'imu_rate_hz': 5.0, 'profile': {'start_c': 20.0, 'segments': [
            {'kind': 'hold', 'duration_s': 3600.0}]},
        'vehicle.self_heating_c': 0.0})
    bag = tmp_path / 'flat'
    simulate(sc, str(bag), seed=1, log=lambda line: None)
    assert train_main([str(bag), '--still-only', '--out', str(tmp_path / 'f.yaml')]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'the still time spans' in err[0] and 'record stops' in err[0]


# ------------------------------------------------------------------ logs of one board (issue 34)

def _board_bench():
    return _script(ROOT / 'bench' / 'bench_board_logs.py')


def test_the_real_board_bench_can_hold_out_eight_logs_on_every_draw():
    """--held-first: eight held out with two stops each, four trained among the rest."""
    bench = _script(ROOT / 'bench' / 'bench_real_boards.py')
    logs = [{'name': k, 'stretches': s} for k, s in enumerate([2] * 10 + [1] * 6 + [0])]
    for draw in range(20):
        rng = np.random.default_rng([0, draw])
        train, held = bench.draw_logs(logs, rng, 4, 8, held_first=True)
        assert len(held) == 8 and all(lg['stretches'] >= 2 for lg in held)
        assert len(train) == 4 and all(lg['stretches'] >= 1 for lg in train)
        assert not {lg['name'] for lg in train} & {lg['name'] for lg in held}
        train, held = bench.draw_logs(logs, np.random.default_rng([0, draw]), 4, 8, False)
        assert len(train) == 4 and not {lg['name'] for lg in train} & {lg['name'] for lg in held}
    few = logs[:9] + logs[10:13]                # 9 with two stops, 3 with one
    train, held = bench.draw_logs(few, np.random.default_rng(0), 4, 8, held_first=True)
    assert (len(train), len(held)) == (4, 8)    # one with two stops is trained on


@pytest.mark.parametrize('case', [0])
def test_cli_still_only_on_four_logs_of_a_board_does_no_harm_on_eight_more(case, tmp_path):
    """Four 25 Hz DataFlash logs trained as a user does; <= 1.05x raw on eight held out."""
    bench = _board_bench()
    c = bench.draw_case(0, case)
    assert c['board'] and c['rate_hz'] == 25.0
    days, paths = bench.write_case(c, tmp_path)
    model = tmp_path / 'still.yaml'
    code, err = bench.cli_train(paths[:4], model, '--still-only')
    assert code == 0, err
    ratio = bench.held_out_ratio(model, days[4:], paths[4:])
    assert np.all(ratio <= bench.BOUND_STILL), ratio
    assert np.min(ratio) < 0.99, ratio                  # and a curve that carries is learnt
    check = load_model(model).metrics['sessions']['heldout']
    assert 'x' in check['offset_only'], check           # the x curve does not carry
    assert ratio[0] == pytest.approx(1.0, abs=1e-9)
    code, err = bench.cli_train(paths[:4], tmp_path / 'train.yaml')
    if code:
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and 'still' in lines[0], err
    else:
        ratio = bench.held_out_ratio(tmp_path / 'train.yaml', days[4:], paths[4:])
        assert np.all(ratio <= bench.BOUND_TRAIN), ratio


@pytest.fixture(scope='module')
def flights(tmp_path_factory):
    """Three power cycles of one board at 25 Hz: flights between 10-60 s stops."""
    return flight_logs(tmp_path_factory.mktemp('flights'), 3, legs=8)


def test_flight_logs_keep_their_still_stretches_only(flights):
    days, paths = flights
    runs = load_runs(paths)
    kept, line = still_only_runs(runs)
    assert line is not None and 'still stretches only' in line
    assert len(kept) == len(runs)
    for day, run, k in zip(days, runs, kept):
        idx = np.searchsorted(run.t, k.t)
        np.testing.assert_array_equal(run.t[idx], k.t)
        assert np.all(day.still[idx])                 # nothing of a flight is kept
        assert len(k) > 0.6 * day.still.sum()
        assert np.all(k.omega_ref == 0.0)
    pct = float(line.split(' %;')[0].rsplit(', ', 1)[1])
    assert 0.0 < pct <= 100.0


def test_discovery_on_flights_fits_the_drift_not_the_motion(flights):
    days, paths = flights
    runs = load_runs(paths)
    kept, _line = still_only_runs(runs)
    still = discover(kept, allan=False, max_steps=2)
    # The still stretches' noise: 0.05 deg/s per sample, a few mdeg/s on 10 s means; the
    # flights would put tens of deg/s of manoeuvres into the same gaps.
    assert still.white_noise_dps < 0.1
    assert still.noise_floor_dps < 0.01
    assert still.gap_dps < 2.0 * still.noise_floor_dps
    moving = discover(runs, allan=False, max_steps=0)
    assert moving.gap_dps > 20.0 * still.gap_dps
    # The drift slope found is the board's (0.004 deg/s per degC on x near 35 degC, the
    # curvature pulling it lower near the cold T0).
    slope = np.degrees(still.coef['dT'])
    assert 0.001 < slope[0] < 0.006


def test_data_with_a_reference_or_without_motion_are_kept_whole(flights, tmp_path):
    days, paths = flights
    runs = load_runs(paths)
    ref = [type(r)(r.t, r.temp, r.omega, r.omega_ref, r.name, {**r.info, 'reference': 'topic'})
           for r in runs]
    assert still_only_runs(ref) == (ref, None)
    quiet = flight_day(7, legs=1, still_s=(300.0, 300.0))
    run = load_runs([write_dataflash(tmp_path / 'quiet.bin', [quiet.imu])])
    assert still_only_runs(run) == (run, None)
    flying = flight_day(8, legs=2, still_s=(0.2, 0.3), flight_s=(300.0, 300.0))
    run = load_runs([write_dataflash(tmp_path / 'flying.bin', [flying.imu])])
    with pytest.raises(FitError, match='no still stretch to discover on'):
        still_only_runs(run)


def test_a_power_cycle_whose_every_stop_is_a_slow_turn_is_no_crash(tmp_path):
    # Two clean power cycles over 20 .. 30 degC; a third whose two stops zigzag (slow turns):
    # dropping both would leave it no still time, so it keeps them (its offset takes them).
    clean = [_stops([(20.0 + 2.0 * k + j, 0.0) for k in range(5)], seed=10 + j)
             for j in range(2)]
    turns = _stops([(22.0, 1.0), (28.0, -1.0)], seed=12)
    runs = [replace(r, name=f'cycle{j}') for j, r in enumerate([*clean, turns])]
    res = train_still_only(['a', 'b', 'c'], tmp_path / 's.yaml',
                           TrainOptions(features='dT', kind='poly'), runs=runs)
    assert res.model.metrics['sessions']['count'] == 3
    assert (tmp_path / 's.yaml').exists()


def test_a_curve_of_stops_loading_would_refuse_keeps_the_offset_only(tmp_path):
    # Three power cycles of stops whose z rate climbs 0 -> 270 deg/s over 35 .. 38 degC: the
    # curve carries from one to the next (the held-out check keeps it), but continued 15 degC
    # beyond the range it is beyond any gyro. Offset only, said.
    runs = [replace(_stops([(35.0 + k, 30.0 * k * k) for k in range(4)], seed=5 + j),
                    name=f'cycle{j}') for j in range(3)]
    said = []
    res = train_still_only(['a', 'b', 'c'], tmp_path / 's.yaml',
                           TrainOptions(features='dT,dT2', kind='poly'), runs=runs,
                           log=said.append)
    assert any(line.startswith('the curve of the stops would be refused on loading (the '
                               'drift it computes is') and line.endswith(
        'the model keeps the offset only on every axis (re-anchoring still applies)')
        for line in said), said
    assert res.model.features == () and (tmp_path / 's.yaml').exists()
    # features auto: the report's last word on the features is what the model keeps.
    res = train_still_only(['a', 'b', 'c'], tmp_path / 'a.yaml', TrainOptions(kind='poly'),
                           runs=runs)
    assert res.model.features == ()
    assert res.choice.lines()[-1].endswith('; not kept: its curve would be refused on '
                                           'loading, the model keeps the offset only')
    assert res.model.metrics['features']['dropped'].startswith('its curve would be refused')
