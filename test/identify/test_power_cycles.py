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

"""Across power cycles: the start-up shift rule, and a curve no power cycle can judge."""

from __future__ import annotations

from dataclasses import replace
import json

from bags import bag_from_run
from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import Run
from gyro_tdc.identify import (fit_model, FitOptions, offset_check_lines, reanchor_lines,
                               reanchor_rule, session_check_lines)
from gyro_tdc.identify.power_cycles import MIN_FOLDS
from gyro_tdc.identify.still_only import rows_of
from gyro_tdc.model import load_model
from gyro_tdc.signal import check_offsets, MIN_SESSION_SPAN_C
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run


def _bursts(seed: int, jitter_dps: float, offset_dps=(0.0, 0.0, 0.0), hours: float = 2.0,
            **kw) -> Run:
    """Return a 10 Hz run kept in 5 s bursts every 300 s, each burst its own jitter."""
    r = synth_run(seed=seed, hours=hours, rate_hz=10.0, t_lo=15.0, t_hi=30.0, noise_dps=0.02,
                  offset_dps=offset_dps, **kw)
    rng = np.random.default_rng(seed)
    burst = (r.t // 300.0).astype(int)
    omega = r.omega + np.radians(rng.normal(0.0, jitter_dps, (burst.max() + 1, 3)))[burst]
    keep = r.t % 300.0 < 5.0
    return Run(r.t[keep], r.temp[keep], omega[keep], r.omega_ref[keep], f'b{seed}')


def _rule(runs, labels):
    """Fit a poly dT, dT2 with one offset per session and apply the rule (refit alike)."""
    def fit(rr, gg):
        return fit_model(rr, kind='poly', features='dT,dT2', t0=20.0, sessions=gg)
    return reanchor_rule(fit(runs, labels), runs, labels, fit)


def test_one_session_of_jittering_bursts_gates_at_twice_its_anchors_error():
    model = _rule([_bursts(1, 0.006)], [0])
    rec = model.metrics['reanchor']
    assert (rec['sessions'], rec['held_out']) == (1, 0) and 'always_dps' not in rec
    err = np.array(rec['anchor_error_dps'])
    # An anchor (a burst's mean, or two) errs by the jitter and the noise's SE.
    assert np.all((err > 0.003) & (err < 0.01)), err
    np.testing.assert_allclose(rec['min_shift_dps'], 2.0 * err)
    lines = reanchor_lines(rec)
    assert lines[0].startswith('start-up anchors taken throughout the training data err by')
    assert all(x.startswith(f'axis {a}: the node re-anchors only beyond')
               for a, x in zip('xyz', lines[1:]))
    # Without jitter the anchors err by the noise alone: a smaller gate.
    quiet = np.array(_rule([_bursts(1, 0.0)], [0]).metrics['reanchor']['anchor_error_dps'])
    assert np.all(quiet < 0.75 * err), (quiet, err)


def test_turn_on_offsets_held_out_keep_any_shift():
    rng = np.random.default_rng(3)
    runs = [synth_run(seed=20 + i, hours=0.5, rate_hz=2.0, t_lo=0.0, t_hi=40.0,
                      noise_dps=0.02, offset_dps=tuple(rng.normal(0.0, 0.3, 3)),
                      cooling=bool(i % 2)) for i in range(4)]
    rec = _rule(runs, [0, 1, 2, 3]).metrics['reanchor']
    assert (rec['sessions'], rec['held_out']) == (4, 4)
    always, never = np.array(rec['always_dps']), np.array(rec['never_dps'])
    assert np.all(always < never / 20.0), (always, never)
    assert rec['min_shift_dps'] == [0.0, 0.0, 0.0]
    lines = reanchor_lines(rec)
    assert lines[1].startswith('held out on 4 power cycles')
    assert [x.split()[0] for x in lines[2:5]] == ['always', 'gated', 'never']
    assert lines[-1] == 'axis z: the node re-anchors any start-up shift'


def test_without_turn_on_offsets_the_gate_is_kept_where_it_did_better():
    runs = [_bursts(30 + i, 0.004, hours=1.5, cooling=bool(i % 2)) for i in range(4)]
    rec = _rule(runs, [0, 1, 2, 3]).metrics['reanchor']
    assert rec['held_out'] == 4
    always, gated = np.array(rec['always_dps']), np.array(rec['gated_dps'])
    gate = 2.0 * np.array(rec['anchor_error_dps'])
    np.testing.assert_allclose(rec['min_shift_dps'], np.where(gated < always, gate, 0.0))
    # Re-anchoring on one jittering burst does worse than the model's offset held out.
    assert np.all(np.array(rec['never_dps']) < always), rec
    assert any(v > 0 for v in rec['min_shift_dps'])


def test_the_still_rows_alone_decide_the_gate():
    """Motion between the still rows (``rows``) is neither an anchor nor in the refits."""
    rng = np.random.default_rng(4)
    runs, moved, rows = [], [], []
    for i in range(3):
        r = synth_run(seed=40 + i, hours=0.5, rate_hz=2.0, t_lo=0.0, t_hi=40.0,
                      noise_dps=0.02, cooling=bool(i % 2))
        m = r.t % 600.0 < 300.0
        omega = r.omega.copy()
        omega[~m] += np.radians(rng.normal(0.0, 30.0, (np.count_nonzero(~m), 3)))
        runs.append(r)
        moved.append(replace(r, omega=omega))
        rows.append(m)

    def fit(rr, gg, rows=None):
        return fit_model(rr, kind='poly', features='dT,dT2', t0=20.0, sessions=gg, rows=rows)

    labels = [0, 1, 2]
    gated = reanchor_rule(fit(moved, labels, rows), moved, labels, fit, rows)
    rec = gated.metrics['reanchor']
    still = [rows_of(r, m) for r, m in zip(runs, rows)]
    ref = reanchor_rule(fit(still, labels), still, labels, fit).metrics['reanchor']
    assert rec['held_out'] == ref['held_out'] == 3
    for key in ('anchor_error_dps', 'min_shift_dps', 'always_dps', 'gated_dps', 'never_dps'):
        np.testing.assert_allclose(rec[key], ref[key], rtol=1e-6, atol=1e-12, err_msg=key)
    # Without the rows the motion is taken for the anchors' error.
    wild = reanchor_rule(fit(moved, labels, rows), moved, labels, fit).metrics['reanchor']
    assert np.all(np.array(wild['anchor_error_dps'])
                  > 10.0 * np.array(rec['anchor_error_dps'])), (wild, rec)


def test_train_reports_the_rule_in_text_and_json(tmp_path, capsys):
    bag = bag_from_run(_bursts(5, 0.004), tmp_path / 'bursts')
    out, js = tmp_path / 'm.yaml', tmp_path / 'm.json'
    assert train_main([str(bag), '--out', str(out), '--features', 'dT,dT2', '--kind', 'poly',
                       '--json', str(js), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'start-up anchors taken throughout the training data err by' in text
    assert 'axis y: the node re-anchors only beyond' in text
    rec = json.loads(js.read_text())['reanchor']
    assert rec == load_model(out).metrics['reanchor']
    assert rec['min_shift_dps'] == pytest.approx(2.0 * np.array(rec['anchor_error_dps']))


def test_a_curve_no_power_cycle_can_judge_is_kept_and_the_report_says_so():
    # Two power cycles 5 degC apart: none lies inside the other's temperatures, no fold.
    cycles = ((10.0, 20.0, (0.4, -0.3, 0.1)), (25.0, 35.0, (-0.5, 0.2, 0.45)))
    runs = [synth_run(seed=i, hours=1.0, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=0.02,
                      offset_dps=off, name=f'run{i}') for i, (lo, hi, off) in enumerate(cycles)]
    m = fit_model(runs, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1])
    check = m.metrics['sessions']['heldout']
    assert check == {'folds': 0, 'sessions': 2, 'offset_only': []}
    assert np.all(m.linear != 0.0)                      # the curve is kept on every axis
    assert session_check_lines(check) == [
        'the curve is not judged on a held-out power cycle: none of the 2 sessions with data '
        "has two blocks inside the others' temperatures; the model keeps it on every axis "
        "unchecked (a power cycle over the others' temperatures would judge it)"]


def test_a_curve_no_power_cycle_shows_over_two_degrees_keeps_the_offset_only():
    # Two power cycles of under a degree each, 10 degC apart: no fold, and each offset free,
    # the curve rests on less than a degree of either (the short stops of flight logs).
    cycles = ((20.0, 20.8, (0.0, 0.0, 0.1)), (30.0, 30.6, (0.4, -0.3, 0.1)))
    runs = [synth_run(seed=60 + i, hours=0.25, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=0.05,
                      offset_dps=off, name=f'stop{i}') for i, (lo, hi, off) in enumerate(cycles)]
    m = fit_model(runs, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1])
    check = m.metrics['sessions']['heldout']
    assert check['folds'] == 0 and check['sessions'] == 2
    assert check['offset_only'] == ['x', 'y', 'z']
    assert 0.4 < check['widest_span_c'] < MIN_SESSION_SPAN_C
    assert np.all(m.linear == 0.0)                      # no curve: the offsets only
    means = np.degrees([r.omega.mean(axis=0) for r in runs])   # each power cycle's offset
    # Each against the model's: their mean, or none where it does not predict the other.
    none = np.isin(['x', 'y', 'z'], m.metrics['sessions']['turn_on']['no_offset'])
    level = np.where(none, 0.0, means.mean(axis=0))
    np.testing.assert_allclose(np.degrees(m.intercept), level, atol=2e-3)
    np.testing.assert_allclose(m.metrics['sessions']['offset_dps'], means - level, atol=2e-3)
    line, = session_check_lines(check)
    assert line.startswith('the curve is not judged on a held-out power cycle: none of the 2 '
                           'sessions with data has two blocks inside the others')
    assert (f'none spans {MIN_SESSION_SPAN_C:g} degC of its own (widest '
            f"{check['widest_span_c']:.2f} degC)") in line
    assert line.endswith('the model keeps the offset only on every axis (re-anchoring still '
                         'applies)')
    # A power cycle over 2 degC shows the curve: kept unchecked, as before.
    wide = [runs[0], synth_run(seed=61, hours=0.25, rate_hz=2.0, t_lo=30.0, t_hi=33.0,
                               noise_dps=0.05, offset_dps=cycles[1][2], name='stop1')]
    kept = fit_model(wide, kind='poly', features='dT,dT2', t0=20.0, sessions=[0, 1])
    assert kept.metrics['sessions']['heldout'] == {'folds': 0, 'sessions': 2, 'offset_only': []}
    assert np.all(kept.linear != 0.0)


def test_a_curve_of_stops_needs_two_power_cycles_to_judge_it():
    # Still-only training asks two folds (MIN_FOLDS): none, or one, keeps the offset only.
    cycles = ((10.0, 20.0, (0.4, -0.3, 0.1)), (25.0, 35.0, (-0.5, 0.2, 0.45)))
    runs = [synth_run(seed=i, hours=1.0, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=0.02,
                      offset_dps=off, name=f'run{i}') for i, (lo, hi, off) in enumerate(cycles)]
    opts = FitOptions(kind='poly', features='dT,dT2', t0=20.0, min_folds=MIN_FOLDS)
    none = fit_model(runs, opts, sessions=[0, 1])
    check = none.metrics['sessions']['heldout']
    assert check == {'folds': 0, 'sessions': 2, 'offset_only': ['x', 'y', 'z'],
                     'min_folds': 2}
    assert np.all(none.linear == 0.0)
    assert session_check_lines(check)[0].endswith(
        'fewer than 2 cannot tell whether a curve of stops carries to the next power cycle: '
        'the model keeps the offset only on every axis (re-anchoring still applies)')
    # A third power cycle between them lies inside the others' temperatures: one fold.
    third = synth_run(seed=5, hours=1.0, rate_hz=2.0, t_lo=21.0, t_hi=24.0, noise_dps=0.02,
                      offset_dps=(0.1, 0.1, -0.2), name='run2')
    one = fit_model([*runs, third], opts, sessions=[0, 1, 2])
    check = one.metrics['sessions']['heldout']
    assert check['folds'] == 1 and check['offset_only'] == ['x', 'y', 'z']
    assert session_check_lines(check)[0].startswith(
        'the curve is judged on 1 held-out power cycle only (of the 3 sessions with data)')
    # The default (one fold judges; none keeps the curve unchecked) is unchanged.
    judged = fit_model([*runs, third], kind='poly', features='dT,dT2', t0=20.0,
                       sessions=[0, 1, 2]).metrics['sessions']['heldout']
    assert judged['folds'] == 1 and 'worse_folds' in judged


def _offsets(*rows):
    """Return session offsets given in deg/s, rad/s (S, 3)."""
    return np.radians(np.array(rows, dtype=np.float64))


_FLAT = np.zeros((3, 3))          # coefficients of three offset-only axes (intercept, two terms)


def test_an_offset_that_repeats_across_power_cycles_is_kept():
    off = _offsets((0.40, -0.30, 0.10), (0.45, -0.32, 0.12), (0.38, -0.29, 0.09))
    level, rec = check_offsets(off, _FLAT, np.zeros(3))
    np.testing.assert_array_equal(level, off.mean(axis=0))
    assert rec['no_offset'] == [] and rec['axes'] == ['x', 'y', 'z']
    assert all(m < n for m, n in zip(rec['mean_ms_dps2'], rec['none_ms_dps2']))
    assert len(offset_check_lines(rec)) == 3               # the figures, no axis dropped


def test_offsets_of_a_board_that_zeroes_its_gyro_at_power_on_give_no_offset():
    # x: a boot calibration on every power cycle (near 0); y: two of four failed (0.25,
    # 0.3 deg/s): the others' mean wins in mean square, not in mean absolute error;
    # z: a real turn-on offset that repeats.
    off = _offsets((0.010, 0.01, 0.50), (-0.02, 0.02, 0.52), (0.015, 0.25, 0.49),
                   (-0.01, 0.30, 0.51))
    level, rec = check_offsets(off, _FLAT, np.zeros(3))
    assert rec['no_offset'] == ['x', 'y']
    assert rec['mean_ms_dps2'][1] < rec['none_ms_dps2'][1]             # mean square: mean
    assert rec['mean_mae_dps'][1] > rec['none_mae_dps'][1]             # absolute: none
    np.testing.assert_array_equal(level[:2], 0.0)
    assert level[2] == pytest.approx(off[:, 2].mean())
    assert offset_check_lines(rec)[-1].startswith(
        "axes x, y: the other power cycles' mean does not predict a held-out one's offset "
        'better than none on both figures')


def test_an_offset_of_one_sign_but_a_wide_spread_is_kept():
    # A gyro not zeroed at power-on whose offset moves by 0.9 deg/s between power cycles
    # (a real Pixhawk 6C: -0.72, -1.14, -0.20 deg/s on y): the others' mean still beats none.
    off = _offsets((0.0, -0.72, 0.0), (0.0, -1.14, 0.0), (0.0, -0.20, 0.0))
    level, rec = check_offsets(off, _FLAT, np.zeros(3))
    assert 'y' not in rec['no_offset'] and level[1] == pytest.approx(off[:, 1].mean())


def test_an_axis_with_a_curve_or_one_session_keeps_its_level_unjudged():
    off = _offsets((0.01, 0.01, 0.01), (-0.01, -0.02, -0.02))
    coef = _FLAT.copy()
    coef[1, 0] = 1e-4                                     # x has a curve
    level, rec = check_offsets(off, coef, np.array([0.0, 1e-3, 0.0]))    # y a scale term
    assert rec['axes'] == ['z'] and rec['no_offset'] == ['z']
    np.testing.assert_array_equal(level[:2], off[:, :2].mean(axis=0))
    level, rec = check_offsets(off[:1], _FLAT, np.zeros(3))
    assert rec is None and offset_check_lines(rec) == []
    np.testing.assert_array_equal(level, off[0])


def test_train_gives_no_offset_where_boot_calibrated_power_cycles_show_none(tmp_path, capsys):
    # Three power cycles whose offsets scatter around zero (a board that calibrates at power-on),
    # no curve: the model adds no offset; the node still re-anchors.
    runs = [synth_run(seed=i, hours=0.5, rate_hz=5.0, t_lo=20.0, t_hi=30.0, noise_dps=0.01,
                      a1=(0.0, 0.0, 0.0), a2=(0.0, 0.0, 0.0), b0=(0.0, 0.0, 0.0),
                      offset_dps=off, name=f'boot{i}')
            for i, off in enumerate(((0.01, -0.02, 0.015), (-0.015, 0.01, -0.02),
                                     (0.005, 0.015, 0.01)))]
    bags = [str(bag_from_run(r, tmp_path / r.name)) for r in runs]
    out = tmp_path / 'm.yaml'
    assert train_main([*bags, '--out', str(out), '--features', 'bias', '--kind', 'poly',
                       '--no-progress']) == 0
    text = capsys.readouterr().out
    m = load_model(out)
    assert m.metrics['sessions']['turn_on']['no_offset'] == ['x', 'y', 'z']
    np.testing.assert_array_equal(m.intercept, 0.0)
    assert "against the model's (their mean; none on x, y, z)" in text
    assert 'the model adds no offset there (re-anchoring still applies)' in text


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(*[st.floats(-1.0, 1.0, allow_subnormal=False)] * 3), min_size=2,
                max_size=12),
       st.tuples(*[st.booleans()] * 3))
def test_the_level_is_the_mean_or_none_and_a_curve_axis_is_never_judged(rows, curve):
    off = _offsets(*rows)
    coef = _FLAT.copy()
    coef[1] = np.where(curve, 1e-4, 0.0)
    level, rec = check_offsets(off, coef, np.zeros(3))
    mean = off.mean(axis=0)
    assert np.all(np.isfinite(level))
    for a, name in enumerate('xyz'):
        dropped = rec is not None and name in rec['no_offset']
        assert level[a] == (0.0 if dropped else mean[a])
        assert not (curve[a] and dropped)
    if rec is not None:
        assert rec['axes'] == [n for n, c in zip('xyz', curve) if not c]
    else:
        assert all(curve)
    # A turn-on offset that repeats (the same in every power cycle, away from zero) is kept.
    same = np.repeat(off[:1] + np.radians(0.5) * np.sign(off[:1] + 1e-12), len(rows), axis=0)
    assert check_offsets(same, _FLAT, np.zeros(3))[1]['no_offset'] == []
