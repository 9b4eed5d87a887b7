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
Discovery on bags in which an effect is hidden: the workflow sees only the bag.

Each case simulates a chamber run with :mod:`gyro_tdc.sim` (the L3GD20 preset's noise: white,
bias instability and rate random walk, 8.75 mdps quantisation; a package thermometer at 1 Hz,
0.03 degC resolution), with one effect switched on and scaled so that the part of it the base
model (bias, dT) cannot absorb has a chosen RMS, ``k`` times the per-sample noise standard
deviation, over the whole recording. The run is written to a bag, read back with
:func:`gyro_tdc.data.dataset.load_runs` and handed to :func:`gyro_tdc.identify.discover.discover`,
which
must name the effect (or an alias it reports), bring the gap within 1.3 times the noise floor
it estimates and shrink the held-out gap; and must name nothing when nothing is hidden, also
with session-to-session offsets and a non-thermal bias excursion.
"""

from __future__ import annotations

import json
import math

from gyro_tdc.cli.discover import main
from gyro_tdc.data import write_bag
from gyro_tdc.data.dataset import load_runs
from gyro_tdc.identify.discover import build_model, discover
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import load_model, save_model
from gyro_tdc.sim.simulator import simulate_run
import numpy as np
import pytest

DEG = math.pi / 180.0

HEAT_COOL = [{'kind': 'hold', 'duration_s': 900.0},
             {'kind': 'ramp', 'to_c': 40.0, 'rate_c_per_h': 40.0},
             {'kind': 'hold', 'duration_s': 600.0},
             {'kind': 'ramp', 'to_c': 10.0, 'rate_c_per_h': 60.0},
             {'kind': 'hold', 'duration_s': 600.0}]
HEAT = [{'kind': 'hold', 'duration_s': 900.0},
        {'kind': 'ramp', 'to_c': 45.0, 'rate_c_per_h': 30.0}]
RATES = [[0.0, 0.0, 0.0], [30.0, -20.0, 60.0], [-60.0, 45.0, -30.0], [100.0, -90.0, 120.0],
         [-100.0, 60.0, -120.0], [45.0, 100.0, -60.0]]

# Per-effect coefficient keys of the simulator's `gyro` section (scaled by the calibration).
COEF_KEY = {'dT2': 'dT2_dps_per_c2', 'dTdt': 'dTdt_dps_per_c_per_s', 'scale': 'scale_ppm_per_c',
            'warmup': 'warmup_dps', 'lag': 'dT_dps_per_c'}


def scenario(effects, *, segments=HEAT_COOL, start_c=0.0, rate_hz=4.0, runs=1,
             offset_dps=0.0, rate_period_s=0.0, tau_die_s=150.0, gyro=None) -> dict:
    """Build a simulator scenario dict with the given effects switched on."""
    sc = {
        'format_version': 1, 'name': 'hidden', 'sensor': 'l3gd20', 'imu_rate_hz': rate_hz,
        'profile': {'start_c': start_c, 'segments': segments},
        'thermal': {'tau_package_s': 60.0, 'tau_die_s': tau_die_s},
        'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.03,
                        'noise_c': 0.01},
        'gyro': {'effects': list(effects), 'warmup_tau_s': 240.0, **(gyro or {})},
        'runs': {'count': runs, 'bias_offset_dps_std': offset_dps},
    }
    if rate_period_s:
        total = 900.0 + 45.0 / 30.0 * 3600.0 + 3600.0
        sc['rate_table'] = [{'t_s': i * rate_period_s, 'rate_dps': RATES[i % len(RATES)]}
                            for i in range(int(total // rate_period_s) + 1)]
    return sc


def unexplained_rms(sims_on, sims_off) -> float:
    """RMS of the effect's drift that bias + dT (of the measured temperature) cannot absorb."""
    sq, n = 0.0, 0
    for on, off in zip(sims_on, sims_off):
        d = on.truth.drift - off.truth.drift
        temp = np.interp(on.imu_t, on.temp_t, on.temp_c)
        x = np.column_stack([np.ones_like(temp), temp - temp[0]])
        r = d - x @ np.linalg.lstsq(x, d, rcond=None)[0]
        sq += float((r * r).sum())
        n += r.size
    return math.sqrt(sq / n)


def calibrate(sc: dict, effect: str, k: float, seed: int) -> dict:
    """Scale the coefficient of ``effect`` so its unexplained RMS is ``k`` noise std."""
    from gyro_tdc.sim.presets import preset

    base = [e for e in sc['gyro']['effects'] if e != effect]
    key = COEF_KEY[effect]
    ref = np.asarray(sc['gyro'].get(key, preset('l3gd20')['gyro'][key]), dtype=float)
    count = sc['runs']['count']
    on = [simulate_run(sc, seed=seed, run_index=i) for i in range(count)]
    off = [simulate_run(dict(sc, gyro=dict(sc['gyro'], effects=base)), seed=seed, run_index=i)
           for i in range(count)]
    sigma = float(np.mean(on[0].truth.noise_std))
    factor = k * sigma / unexplained_rms(on, off)
    return dict(sc, gyro=dict(sc['gyro'], **{key: (ref * factor).tolist()}))


def write_runs(tmp_path, sc: dict, seed: int, *, excursion_dps: float = 0.0) -> list:
    """Simulate every run of ``sc``, write one bag each and return the bag paths."""
    rng = np.random.default_rng(seed + 1000)
    bags = []
    for i in range(sc['runs']['count']):
        run = simulate_run(sc, seed=seed, run_index=i)
        gyro = run.gyro.copy()
        if excursion_dps and i == 0:
            # A non-thermal bias excursion: a smooth bump of ~12 min somewhere in the run.
            centre = rng.uniform(0.3, 0.7) * run.imu_t[-1]
            bump = np.exp(-0.5 * ((run.imu_t - centre) / 360.0) ** 2)
            gyro += bump[:, None] * excursion_dps * DEG * np.array([1.0, -0.7, 0.5])
        path = tmp_path / f'run{i + 1}'
        write_bag(path, imu_t=run.imu_t, gyro=gyro, accel=run.accel, temp_t=run.temp_t,
                  temp_c=run.temp_c, ref_t=run.ref_t if run.moving else None,
                  ref=run.ref if run.moving else None)
        bags.append(path)
    return bags


def check_found(res, hidden: set) -> None:
    """Assert every hidden effect is named or an alias of a named step, and nothing else."""
    named = {s.effect for s in res.steps}
    explained = named | {a for s in res.steps for a in s.aliases}
    assert hidden <= explained, f'hidden {hidden}, named {named}, explained {explained}'
    for s in res.steps:
        assert s.effect in hidden or hidden & set(s.aliases), f'false discovery {s.effect}'
    first, last = res.steps[0], res.steps[-1]
    assert last.gap_after_dps <= 1.3 * res.noise_floor_dps, (
        f'gap {last.gap_after_dps:.4g} vs floor {res.noise_floor_dps:.4g}')
    assert last.heldout_gap_after_dps < first.heldout_gap_before_dps
    for s in res.steps:
        assert s.gap_after_dps < s.gap_before_dps


CASES = [
    # (id, hidden effects, k, seed, scenario options)
    ('dT2-quarter', {'dT2'}, 0.25, 1, {}),
    ('dT2-one', {'dT2'}, 1.0, 2, {'segments': HEAT}),
    ('lag-quarter', {'lag'}, 0.25, 3, {}),
    ('lag-one', {'lag'}, 1.0, 4, {'runs': 2, 'rate_hz': 2.0}),
    ('dTdt-quarter', {'dTdt'}, 0.25, 5, {}),
    ('dTdt-one', {'dTdt'}, 1.0, 6, {}),
    ('scale-quarter', {'scale'}, 0.25, 7, {'segments': HEAT, 'rate_period_s': 300.0}),
    ('scale-one', {'scale'}, 1.0, 8, {'segments': HEAT, 'rate_period_s': 240.0}),
    ('warmup-quarter', {'warmup'}, 0.25, 9, {}),
    ('warmup-one', {'warmup'}, 1.0, 10, {'segments': HEAT}),
]


@pytest.mark.parametrize('name,hidden,k,seed,opts', CASES, ids=[c[0] for c in CASES])
def test_hidden_effect_is_named(tmp_path, name, hidden, k, seed, opts):
    (effect,) = hidden
    sc = scenario(['bias', 'dT', effect], **opts)
    sc = calibrate(sc, effect, k, seed)
    runs = load_runs(write_runs(tmp_path, sc, seed))
    res = discover(runs, allan=False)
    check_found(res, hidden)
    step = res.steps[0]
    if effect == 'lag':     # on ramps a lagging die looks like a dT/dt term: reported as aliases
        assert {'lag', 'dTdt'} == {step.effect, *step.aliases}
    if effect == 'dTdt':    # the lagged state cannot take a hysteresis of either sign
        assert step.effect == 'dTdt' and step.params['tau_s'] > 0


def test_two_hidden_effects_dT2_and_lag(tmp_path):
    sc = scenario(['bias', 'dT', 'lag'], rate_hz=2.0, runs=2)
    sc = calibrate(sc, 'lag', 0.5, 11)
    sc['gyro']['effects'] = ['bias', 'dT', 'dT2', 'lag']
    sc = calibrate(sc, 'dT2', 0.5, 11)
    runs = load_runs(write_runs(tmp_path, sc, 11))
    res = discover(runs, allan=False)
    check_found(res, {'dT2', 'lag'})
    lag = next(s for s in res.steps if 'lag' in (s.effect, *s.aliases))
    if lag.effect == 'lag':
        assert 100.0 < lag.params['tau_s'] < 250.0     # simulated die lag: 150 s
    # The model file holds it: a format-2 poly of the thermal state, tau with its interval.
    path = save_model(build_model(res, runs), tmp_path / 'm.yaml')
    model = load_model(path)
    assert model.kind == 'poly' and model.features == res.final_effects
    assert model.format_version == 2 and model.thermal == res.thermal
    assert res.thermal.identifiable
    lo, hi = res.thermal.tau_interval_s[0]
    assert lo < res.params['lag']['tau_s'] < hi
    for run in runs:
        err = compensate(model, run.t, run.temp, run.omega) - run.omega_ref
        err -= err.mean(axis=0)                       # the node re-anchors its offset
        n = len(err) // 20 * 20
        block = err[:n].reshape(-1, 20, 3).mean(axis=1)   # 10-s means at 2 Hz
        assert np.sqrt((block ** 2).mean()) / DEG < 1.3 * res.noise_floor_dps


NULLS = [('heat-cool', 21, {}), ('heat-cool', 22, {'rate_hz': 2.0}),
         ('heat-only', 23, {'segments': HEAT})]


@pytest.mark.parametrize('name,seed,opts', NULLS, ids=[f'{n}-{s}' for n, s, _o in NULLS])
def test_null_names_nothing(tmp_path, name, seed, opts):
    sc = scenario(['bias', 'dT'], **opts)
    res = discover(load_runs(write_runs(tmp_path, sc, seed)), allan=False)
    assert res.steps == (), [s.effect for s in res.steps]
    assert res.final_effects == ('bias', 'dT')
    assert res.gap_dps <= 1.3 * res.noise_floor_dps
    why = {u.effect: u for u in res.unidentifiable}
    assert 'scale' in why and 'zero' in why['scale'].reason
    assert why['scale'].experiment.startswith('Rate-table steps')
    if name == 'heat-only':
        # One heating rate after a soak: the start of the ramp is a change of rate, so the
        # rate effects are scored (and rejected: nothing is hidden), and a note says what
        # the data cannot test.
        assert not {'dTdt', 'lag'} & set(why)
        assert any('only heat and at one rate' in n and 'hysteresis' in n for n in res.notes)


def test_null_with_session_offsets_and_bias_excursion(tmp_path):
    # Three sessions with offsets of 0.05 deg/s std and a smooth non-thermal bump of
    # 0.03 deg/s (about three noise floors) in the first: neither is thermal.
    sc = scenario(['bias', 'dT'], rate_hz=2.0, runs=3, offset_dps=0.05)
    runs = load_runs(write_runs(tmp_path, sc, 31, excursion_dps=0.03))
    res = discover(runs, allan=False)
    assert res.steps == (), [(s.effect, s.best.heldout_gain_dps2) for s in res.steps]
    assert res.settings['folds'] == 'leave-one-run-out'
    offsets = np.asarray(res.coef['offsets']) / DEG
    assert np.ptp(offsets, axis=0).max() > 0.02      # the offsets were seen, as offsets


def test_unidentifiable_without_soak_or_rate_steps():
    from gyro_tdc.data.runs import Run

    # Constant non-zero rate, a ramp from the first sample (no soak): scale and warm-up
    # cannot be excited; the reason and the experiment name what is missing.
    n = 2 * 3600 * 2
    t = np.arange(n) / 2.0
    temp = 10.0 + 30.0 * t / t[-1]
    ref = np.tile([0.1, 0.0, 0.0], (n, 1))
    omega = ref + (0.01 + 0.002 * (temp - 10.0))[:, None] * DEG
    omega = omega + np.random.default_rng(0).normal(0.0, 0.05 * DEG, (n, 3))
    res = discover([Run(t, temp, omega, ref)], allan=False)
    why = {u.effect: u for u in res.unidentifiable}
    assert 'constant' in why['scale'].reason
    assert 'soak' in why['warmup'].reason and 'soak' in why['warmup'].experiment
    # One rate, no soak: the rate effects are scored (only the ramp's start could show
    # them), nothing is named, and a note says what the data cannot test.
    assert not {'dTdt', 'lag'} & set(why)
    assert any('one rate' in n and 'no soak' in n and 'mid-ramp' in n for n in res.notes)
    assert res.steps == ()


def test_cli_json_shape_model_file_and_report(tmp_path, capsys):
    sc = scenario(['bias', 'dT', 'dT2'], rate_hz=2.0, segments=HEAT[:1] + [
        {'kind': 'ramp', 'to_c': 30.0, 'rate_c_per_h': 40.0}])
    sc = calibrate(sc, 'dT2', 1.0, 41)
    (bag,) = write_runs(tmp_path, sc, 41)
    out = tmp_path / 'out'
    rc = main([str(bag), '--json', str(out / 'r.json'), '--out', str(out / 'm.yaml'),
               '--report', str(out / 'report'), '--no-progress'])
    assert rc == 0
    stdout = capsys.readouterr().out
    assert 'step 1: add dT2' in stdout and 'noise floor' in stdout
    doc = json.loads((out / 'r.json').read_text())
    assert list(doc) == ['base_effects', 'noise_floor_dps', 'steps', 'final_effects',
                         'unidentifiable', 'model_file']
    assert doc['base_effects'] == ['bias', 'dT']
    assert doc['final_effects'] == ['bias', 'dT', 'dT2']
    assert doc['model_file'] == str(out / 'm.yaml')
    assert isinstance(doc['noise_floor_dps'], float) and doc['noise_floor_dps'] > 0
    (step,) = doc['steps']
    required = ['effect', 'aliases', 'description', 'gap_before_dps', 'gap_after_dps',
                'heldout_gap_before_dps', 'heldout_gap_after_dps']
    assert list(step)[:len(required)] == required
    assert step['effect'] == 'dT2' and isinstance(step['aliases'], list)
    assert step['description'].startswith('Comb gap')
    assert all(isinstance(step[k], float) for k in required[3:])
    assert step['gap_after_dps'] < step['gap_before_dps']
    for u in doc['unidentifiable']:
        assert list(u) == ['effect', 'reason', 'experiment']
    model = load_model(out / 'm.yaml')
    assert model.features == ('bias', 'dT', 'dT2') and model.kind == 'poly'
    report = (out / 'report' / 'report.md').read_text()
    assert 'step1_maps.png' in report and (out / 'report' / 'step1_maps.png').stat().st_size
    assert (out / 'report' / 'allan.png').is_file()


def test_cli_null_json_has_empty_steps(tmp_path):
    (bag,) = write_runs(tmp_path, scenario(['bias', 'dT'], rate_hz=2.0, segments=HEAT), 51)
    assert main([str(bag), '--json', str(tmp_path / 'r.json'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'r.json').read_text())
    assert doc['steps'] == [] and doc['model_file'] is None
    assert doc['final_effects'] == doc['base_effects'] == ['bias', 'dT']


@pytest.mark.parametrize('args,needle', [
    (['{missing}'], 'does not exist'),
    (['{bag}', '--base', 'bias,dT,humidity'], 'humidity'),
    (['{bag}', '--block-s', '0'], '--block-s'),
    (['{bag}', '--temperature-topic', '/nope'], '/nope'),
    (['{bag}', '--json', '{dir}'], '--json'),
])
def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys, args, needle):
    bag = tmp_path / 'bag'
    n = 400
    write_bag(bag, imu_t=np.arange(n) * 0.5, gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)),
              temp_t=np.arange(n // 2) * 1.0, temp_c=np.linspace(20.0, 30.0, n // 2))
    argv = [a.format(bag=bag, missing=tmp_path / 'nobag', dir=tmp_path) for a in args]
    assert main(argv + ['--no-progress']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err


def test_api_rejects_bad_runs():
    from gyro_tdc.errors import FitError
    from gyro_tdc.data.runs import Run

    with pytest.raises(FitError, match='No runs'):
        discover([])
    t = np.arange(100) * 0.1
    bad = Run(t, np.full(100, 20.0), np.full((100, 3), np.nan), np.zeros((100, 3)), 'bad')
    with pytest.raises(FitError, match="'bad' has non-finite values in `omega`"):
        discover([bad])
    ok = Run(t, np.linspace(20, 30, 100), np.zeros((100, 3)), np.zeros((100, 3)), 'short')
    with pytest.raises(FitError, match='Too few blocks'):
        discover([ok])
    with pytest.raises(FitError, match='block_s'):
        discover([ok], block_s=-1.0)


def test_base_that_holds_the_effect_leaves_nothing_to_add():
    from synth import synth_run

    run = synth_run(seed=3, a2=(0.0, 0.0, 0.0), tau_die=300.0, cooling=True)
    res = discover([run], base='bias,dT,lag', allan=False)
    assert res.base_effects == ('bias', 'dT', 'lag') and res.steps == ()
    assert abs(res.params['lag']['tau_s'] - 300.0) < 30.0


def test_progress_is_called_for_every_candidate_scored():
    from synth import synth_run

    run = synth_run(seed=3, a2=(0.0, 0.0, 0.0), tau_die=300.0, cooling=True)
    calls = []
    res = discover([run], base='bias,dT,lag', allan=False,
                   progress=lambda step, eid: calls.append((step, eid)))
    plain = discover([run], base='bias,dT,lag', allan=False)
    # One call per candidate scored in the one round (nothing named), none for the base.
    assert calls and {step for step, _ in calls} == {0}
    called = [eid for _, eid in calls]
    assert len(called) == len(set(called))
    assert {sc.effect for sc in res.candidates} <= set(called)
    assert not {'bias', 'dT', 'lag'} & {eid for _, eid in calls}
    assert res.to_json() == plain.to_json()


def test_warmup_at_fixed_ambient_gives_a_warmup_only_model():
    from gyro_tdc.data.runs import Run

    # Power-on at a fixed 25 degC (no temperature span): bias + warm-up (tau 240 s) whose
    # RMS over the hour is about a quarter of the noise std.
    n = 3600 * 2
    t = np.arange(n) / 2.0
    rng = np.random.default_rng(5)
    omega = (0.1 + 0.1 * np.exp(-t / 240.0))[:, None] * DEG * np.array([1.0, -0.6, 0.4])
    omega = omega + rng.normal(0.0, 0.05 * DEG, (n, 3))
    run = Run(t, np.full(n, 25.0), omega, np.zeros((n, 3)), 'flat')
    res = discover([run], allan=False)
    assert res.named == ('warmup',)
    assert abs(res.params['warmup']['tau_s'] - 240.0) < 60.0
    why = {u.effect: u.reason for u in res.unidentifiable}
    assert {'dT2', 'dT3', 'dTdt', 'lag', 'scale'} <= set(why)
    assert 'spans only' in why['dT2']
    model = build_model(res, [run])
    assert model.features == ('bias', 'warmup') and model.kind == 'poly'
