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
Discovery on runs in which an effect is hidden: the search sees only the bag.

The cases (``discover_cases``) hide one effect at ``k`` times the per-sample noise; the search
must name the effect (or an alias it reports), bring the gap within 1.3 times the noise floor
it estimates and shrink the held-out gap; and must name nothing when nothing is hidden, also
with session-to-session offsets and a non-thermal bias excursion.
"""

from __future__ import annotations

from discover_cases import calibrate, CASES, check_found, DEG, NULLS, scenario, write_runs
from gyro_tdc.data.dataset import load_runs
from gyro_tdc.identify.discover import build_model, discover, DiscoverOptions
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import load_model, save_model
import numpy as np
import pytest
from synth import synth_run


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
    run = synth_run(seed=3, a2=(0.0, 0.0, 0.0), tau_die=300.0, cooling=True)
    res = discover([run], base='bias,dT,lag', allan=False)
    assert res.base_effects == ('bias', 'dT', 'lag') and res.steps == ()
    assert abs(res.params['lag']['tau_s'] - 300.0) < 30.0


def test_progress_is_called_for_every_candidate_scored():
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


def test_discover_options_are_the_keywords_and_a_keyword_overrides_them():
    run = synth_run(seed=4, hours=0.5, rate_hz=2.0)
    opts = DiscoverOptions(candidates='dT2,dT3', allan=False, max_steps=1)
    res = discover([run], opts)
    same = discover([run], candidates=('dT2', 'dT3'), allan=False, max_steps=1)
    assert res.final_effects == same.final_effects == ('bias', 'dT', 'dT2')
    assert res.gap_dps == same.gap_dps and res.heldout_gap_dps == same.heldout_gap_dps
    none = discover([run], opts, max_steps=0)
    assert none.final_effects == ('bias', 'dT') and not none.steps
    assert none.candidates[0].effect == 'dT2' and none.candidates[0].passed
