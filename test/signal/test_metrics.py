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

"""Metrics: BS, P ratios, RMS, Allan deviation read-outs."""

import math

from gyro_tdc.signal.metrics import (allan_deviation, bias_stability, mad_sigma, noise_readouts,
                                     p_ratios, rms_dps)
import numpy as np
import pytest

DEG = math.pi / 180


def test_bias_stability_is_mse_in_dps_squared():
    omega = np.array([[1.0, 2.0, 0.0], [3.0, 2.0, 0.0]]) * DEG
    np.testing.assert_allclose(bias_stability(omega, np.zeros(3)), [5.0, 4.0, 0.0])
    np.testing.assert_allclose(rms_dps(omega), [np.sqrt(5.0), 2.0, 0.0])


def test_mad_sigma_is_the_scaled_median_absolute_deviation_per_column():
    # Medians 3 and 30; absolute deviations 2 1 0 1 97 and 20 10 0 10 20: MADs 1 and 10.
    v = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0], [100.0, 50.0]])
    np.testing.assert_allclose(mad_sigma(v), [1.4826, 14.826])
    # Normal data: the standard deviation, which one wild value barely moves.
    x = np.random.default_rng(1).normal(0.0, 2.0, 100_001)
    x[0] = 1e9
    assert mad_sigma(x) == pytest.approx(2.0, rel=0.02)


def test_p_ratios_match_paper_table_3():
    # Table 3, x axis: BS1 15.3711, BS2 0.0055, BS3 3.885e-4 -> P1 3.594e-4 (rounded BS2),
    # P2 2.528e-5, P3 7.03 %.
    p = p_ratios([15.3711] * 3, [0.0055] * 3, [3.885e-4] * 3)
    assert p['P1'][0] == pytest.approx(3.578e-4, rel=1e-3)
    assert p['P2'][0] == pytest.approx(2.528e-5, rel=1e-3)
    assert p['P3'][0] == pytest.approx(0.0706, rel=1e-2)


def test_allan_deviation_of_white_noise_gives_its_arw():
    rng = np.random.default_rng(0)
    rate, density = 100.0, 0.01  # deg/s/sqrt(Hz)
    omega = rng.normal(0, density * math.sqrt(rate), (200_000, 3)) * DEG
    taus, adev = allan_deviation(omega, rate)
    assert adev.shape == (taus.size, 3)
    # White rate noise: sigma(tau) = N / sqrt(tau), N = density in deg/s/sqrt(Hz) = deg/sqrt(s).
    np.testing.assert_allclose(adev[3] * np.sqrt(taus[3]), density, rtol=0.05)
    out = noise_readouts(taus, adev)
    np.testing.assert_allclose(out['arw_deg_sqrt_h'], density * 60, rtol=0.05)
    assert np.all(out['bias_instability_deg_h'] > 0)
