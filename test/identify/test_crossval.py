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

"""validate_curve: leave one session out, curve or offset only and re-anchoring per axis."""

from __future__ import annotations

import math

from gyro_tdc.identify import fit_model
from gyro_tdc.identify.crossval import validate_curve
from gyro_tdc.model import compensate
import numpy as np
from synth import synth_run

DEG = math.pi / 180.0
OFFSETS = ((0.4, -0.3, 0.1), (-0.5, 0.2, 0.45), (0.05, 0.5, -0.35))
RANGES = ((-10.0, 30.0), (0.0, 40.0), (5.0, 35.0))


def _runs(a1s, noise=0.01):
    return [synth_run(seed=i, hours=0.5, rate_hz=2.0, t_lo=lo, t_hi=hi, noise_dps=noise,
                      offset_dps=off, a1=a1, a2=(0.0, 0.0, 0.0), name=f'run{i}')
            for i, (off, (lo, hi), a1) in enumerate(zip(OFFSETS, RANGES, a1s))]


def _fit(runs):
    labels = list(range(len(runs)))
    return fit_model(runs, kind='poly', features='dT', t0=25.0, sessions=labels), labels


def test_a_curve_that_carries_is_kept_on_every_axis():
    runs = _runs([(0.02, -0.015, 0.01)] * 3)
    model, labels = _fit(runs)
    out, held = validate_curve(model, runs, labels)
    assert held.validated and held.held_out == 3 and held.curve == (True, True, True)
    assert all(c < 0.05 * o for c, o in zip(held.curve_ms, held.offset_ms))
    # The turn-on offsets differ by 0.2..0.9 deg/s: re-anchoring wins held out.
    assert held.reanchor == (True, True, True)
    np.testing.assert_array_equal(out.linear, model.linear)
    assert out.metrics['held_out']['curve'] == [True, True, True]
    assert any('curve kept' in line for line in held.lines())


def test_a_curve_that_changes_per_power_cycle_keeps_the_offset_only():
    # x: the slope flips sign from one power cycle to the next (no curve carries); y, z carry.
    runs = _runs([(0.02, -0.015, 0.01), (-0.02, -0.015, 0.01), (0.02, -0.015, 0.01)])
    model, labels = _fit(runs)
    out, held = validate_curve(model, runs, labels)
    assert held.curve == (False, True, True)
    assert held.curve_ms[0] >= held.offset_ms[0] and held.curve_ms[1] < held.offset_ms[1]
    assert np.all(out.linear[:, 0] == 0.0) and np.all(out.linear[:, 1:] == model.linear[:, 1:])
    # The x axis compensates a constant now: the mean of the sessions' raw levels.
    levels = [np.mean(r.omega[:, 0] - r.omega_ref[:, 0]) for r in runs]
    c = compensate(out, runs[0].t, runs[0].temp, runs[0].omega)
    np.testing.assert_allclose(runs[0].omega[:, 0] - c[:, 0], np.mean(levels), rtol=1e-9)
    rec = out.metrics['held_out']
    assert rec['curve'] == [False, True, True] and rec['validated'] is True
    text = '\n'.join(held.lines())
    assert 'axis x: OFFSET ONLY' in text and 'axis y: curve kept' in text
    # The report shows the figures (RMS of the held-out block means) it decided on.
    row = next(line for line in held.lines() if line.strip().startswith('offset only'))
    assert float(row.split()[2]) == float(f'{math.sqrt(held.offset_ms[0]):.4g}')
    # The training figures of x are those of the offset: its scatter about the session levels.
    assert out.metrics['train_rms_dps'][0] > 10 * model.metrics['train_rms_dps'][1]


def test_one_session_is_not_validated_and_gates_reanchoring():
    runs = _runs([(0.02, -0.015, 0.01)], noise=0.05)
    model, labels = _fit(runs)
    out, held = validate_curve(model, runs, labels)
    assert not held.validated and held.sessions == 1 and held.curve == (True, True, True)
    np.testing.assert_array_equal(out.linear, model.linear)
    assert all(v > 0 for v in held.reanchor_min_dps)
    np.testing.assert_allclose(held.reanchor_min_dps, 2.0 * np.array(held.anchor_error_dps))
    assert 'NOT validated across power cycles' in held.lines()[0]
    assert out.metrics['held_out']['validated'] is False


def test_constant_axes_are_not_judged():
    runs = _runs([(0.02, -0.015, 0.01), (-0.02, -0.015, 0.0), (0.02, -0.015, 0.01)])
    for r in runs:
        r.omega[:, 2] = r.omega_ref[:, 2]
    model, labels = _fit(runs)
    _, held = validate_curve(model, runs, labels, constant=(False, False, True))
    assert held.curve[2] and held.reanchor[2]
    assert not any(line.startswith('axis z') for line in held.lines())


def test_still_rows_only_count():
    runs = _runs([(0.02, -0.015, 0.01)] * 2)
    # A flight in the second half of every run: its rows do not count.
    rows = []
    for r in runs:
        m = r.t < r.t[-1] / 2
        r.omega[~m] += 0.3
        rows.append(m)
    labels = [0, 1]
    model = fit_model(runs, kind='poly', features='dT', t0=25.0, sessions=labels, rows=rows)
    _, held = validate_curve(model, runs, labels, rows=rows)
    assert held.validated and held.curve == (True, True, True)
    assert max(held.curve_ms) < 1e-3
