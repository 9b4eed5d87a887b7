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
Fleet statistics: the drift polynomial, robust z-scores, outlier flags, constant axes.

A sensor whose gyro has a constant axis (a 2-axis gyro, a dead axis) is left out of that
axis' median and MAD and gets no slope, curvature or z-score there, never a flag.
"""

from __future__ import annotations

import math

from fleet_rig import AXES, BASE_A1, constant_sensor
from gyro_tdc.fleet import drift_polynomial, fleet_statistics, robust_z, SensorResult
from gyro_tdc.identify import fit_model
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run


def test_robust_z():
    z = robust_z([1.0, 2.0, 3.0, 4.0, 100.0])
    assert z[2] == 0.0
    assert z[4] == pytest.approx(97.0 / 1.4826)
    assert np.all(np.isnan(robust_z([5.0, 5.0, 5.0, 6.0])))


def test_drift_polynomial_recovers_the_known_drift():
    run = synth_run(seed=3, hours=1.0, rate_hz=2.0, noise_dps=0.0)
    model = fit_model([run], kind='poly', features=('dT', 'dT2'), t0=25.0)
    c = drift_polynomial(model)                       # b = c0 + c1 T + c2 T^2, deg/s
    a1, a2 = np.array([0.02, -0.015, 0.01]), np.array([2e-4, 1.5e-4, -1e-4])
    np.testing.assert_allclose(c[:, 2], a2, rtol=1e-6)
    np.testing.assert_allclose(c[:, 1] + 2 * c[:, 2] * 25.0, a1, rtol=1e-6)


def test_fleet_statistics_flag_only_the_planted_outlier():
    rng = np.random.default_rng(1)
    sensors = []
    for i in range(12):
        poly = np.zeros((3, 3))
        poly[:, 1] = BASE_A1 * (1 + 0.05 * rng.standard_normal(3))
        poly[:, 2] = 1e-4 * (1 + 0.05 * rng.standard_normal(3))
        if i == 5:
            poly[1, 1] *= 2.0
        sensors.append(SensorResult(f's{i}', 'ok', drift_poly=poly.tolist(),
                                    temp_range_c=[0.0, 0.0]))
    sensors.append(SensorResult('broken', 'failed', error='x'))
    assert fleet_statistics(sensors, outlier_z=3.5) == 0.0
    flagged = {s.sensor_id: s.flags for s in sensors if s.flags}
    assert list(flagged) == ['s5']
    assert len(flagged['s5']) == 1 and flagged['s5'][0].startswith('drift slope on y ')
    assert 'σ from the fleet' in flagged['s5'][0]
    assert sensors[-1].z_slope is None


def test_fleet_statistics_need_three_sensors():
    poly = np.zeros((3, 3)).tolist()
    two = [SensorResult(f's{i}', 'ok', drift_poly=poly, temp_range_c=[0, 10]) for i in range(2)]
    assert fleet_statistics(two) == 5.0
    assert all(s.z_slope is None and not s.flags for s in two)


@given(n=st.integers(3, 12), stuck=st.lists(st.sampled_from(['x', 'y', 'z', 'xz', 'xy']),
                                            min_size=1, max_size=4),
       seed=st.integers(0, 2 ** 16))
@settings(max_examples=40)
def test_constant_axes_take_no_part_in_the_fleet_statistics(n, stuck, seed):
    """Leave them out exactly: the others' z-scores are those of the fleet without them."""
    rng = np.random.default_rng(seed)
    good = [constant_sensor(f's{i}', rng) for i in range(n)]
    odd = [constant_sensor(f'c{k}', rng, tuple(axes)) for k, axes in enumerate(stuck)]
    alone = [SensorResult(s.sensor_id, 'ok', drift_poly=s.drift_poly, temp_range_c=[0, 40])
             for s in good]
    ref = fleet_statistics(good + odd)
    fleet_statistics(alone)
    for s in odd:
        assert not [f for f in s.flags for a in s.constant_axes if f' on {a} ' in f], s.flags
        for i, a in enumerate(AXES):
            if a in s.constant_axes:
                assert s.slope[i] is None and s.curvature[i] is None
                assert s.z_slope[i] is None and s.z_curvature[i] is None
    for i, a in enumerate(AXES):
        fitted = [s for s in good + odd if a not in s.constant_axes]
        slope = [s.drift_poly[i][1] + 2.0 * s.drift_poly[i][2] * ref for s in fitted]
        want = robust_z(slope)
        assert [s.z_slope[i] for s in fitted] == [float(v) for v in want]
        if all(a in s.constant_axes for s in odd):       # the fleet on a: the good ones
            assert [s.z_slope[i] for s in good] == [r.z_slope[i] for r in alone]
            assert [s.z_curvature[i] for s in good] == [r.z_curvature[i] for r in alone]
    assert all(v is None or math.isfinite(v) for s in good + odd
               for v in (s.z_slope or []) + (s.z_curvature or []))


def test_a_zero_drift_axis_is_flagged_unless_it_is_constant():
    """The bug this guards against: a passed-through axis read as a drift slope of 0."""
    rng = np.random.default_rng(3)
    fleet = [constant_sensor(f's{i}', rng) for i in range(8)]
    flat = constant_sensor('flat', rng)
    flat.drift_poly[0] = [0.0, 0.0, 0.0]
    fleet_statistics(fleet + [flat])
    assert flat.flags and flat.flags[0].startswith('drift slope on x ')
    fleet = [constant_sensor(f's{i}', rng) for i in range(8)]
    stuck = constant_sensor('stuck', rng, ('x',))
    fleet_statistics(fleet + [stuck])
    assert not stuck.flags and stuck.z_slope[0] is None and stuck.z_slope[1] is not None
    assert not any(s.flags for s in fleet)


def test_too_few_sensors_fitted_on_an_axis_give_it_no_z_scores():
    """Two sensors fitted on z of four: no z-score on z, the other axes scored."""
    rng = np.random.default_rng(5)
    fleet = [constant_sensor('a', rng), constant_sensor('b', rng), constant_sensor('c', rng, 'z'),
             constant_sensor('d', rng, 'z')]
    fleet_statistics(fleet)
    assert all(s.z_slope[2] is None and s.z_slope[0] is not None for s in fleet)
    assert [s.slope[2] is None for s in fleet] == [False, False, True, True]
