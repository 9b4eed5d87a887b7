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


"""The start-up shift rule on runs of single means (the learner's points), refits refused."""

from __future__ import annotations

from gyro_tdc.data import Run
from gyro_tdc.identify import fit_model
from gyro_tdc.runtime.startup_gate import reanchor_rule
import numpy as np


def _points(seed: int, jitter_dps: float) -> Run:
    """Return 60 still means 10 min apart, each its own jitter around a linear drift."""
    rng = np.random.default_rng(seed)
    t = 600.0 * np.arange(60.0)
    temp = 15.0 + 0.25 * np.arange(60.0)
    omega = np.radians(0.01 * (temp - 20.0)[:, None] + rng.normal(0.0, jitter_dps, (60, 3)))
    return Run(t, temp, omega, np.zeros_like(omega), f'p{seed}')


def _fit(runs, labels):
    return fit_model(runs, kind='poly', features='dT', t0=20.0, sessions=labels)


def test_every_point_is_an_anchor_and_its_jitter_the_gate():
    runs = [_points(1, 0.004)]
    rec = reanchor_rule(_fit(runs, [0]), runs, [0], _fit).metrics['reanchor']
    err = np.array(rec['anchor_error_dps'])
    assert np.all((err > 0.002) & (err < 0.006)), err        # the points' jitter
    np.testing.assert_allclose(rec['min_shift_dps'], 2.0 * err)


def test_a_refit_refused_leaves_its_power_cycle_unjudged():
    runs = [_points(k, 0.004) for k in range(3)]
    rec = reanchor_rule(_fit(runs, [0, 1, 2]), runs, [0, 1, 2],
                        lambda rr, gg: None).metrics['reanchor']
    assert (rec['sessions'], rec['held_out']) == (3, 0) and 'always_dps' not in rec
    np.testing.assert_allclose(rec['min_shift_dps'], 2.0 * np.array(rec['anchor_error_dps']))
