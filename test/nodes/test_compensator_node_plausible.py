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

"""One thermometer glitch through a real compensator_node (rclpy): held back, said so."""

from __future__ import annotations

from compensator_rig import rates, stamp_s, to_ns
from gyro_tdc.identify import fit_model
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.runtime import CompensatorCore, Policy
import numpy as np
from synth import synth_run


def test_a_1e30_reading_leaves_the_output_as_without_it(rig_factory, tmp_path):
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    model = fit_model([run], features=('dT', 'dT2', 'dTdt'), n_centers=10, fit_params=False)
    path = save_model(model, tmp_path / 'dtdt.yaml')
    rig = rig_factory(model_file=str(path))
    t0 = 1_700_000_000.0
    imu_ns = [to_ns(t0 + k / 100.0) for k in range(1500)]
    omega = np.tile((0.01, -0.02, 0.005), (1500, 1))
    temp_ns = [to_ns(t0 - 0.05 + k / 10.0) for k in range(151)]
    temp_c = [20.0 + 0.05 * k / 10.0 for k in range(151)]
    glitch = 40                     # one extra reading of 1e30 degC, 20 ms after reading 40
    rig.feed(imu_ns, omega, temp_ns[:glitch + 1] + [temp_ns[glitch] + 20_000_000]
             + temp_ns[glitch + 1:], temp_c[:glitch + 1] + [1e30] + temp_c[glitch + 1:])
    assert len(rig.out) == 1500 and rig.node.core.temps.implausible == 1
    clean = CompensatorCore(Policy(), model)       # the same stream without the glitch
    expect, j = [], 0
    for ns, w in zip(imu_ns, omega):
        while j < len(temp_ns) and temp_ns[j] <= ns:
            clean.add_temperature(stamp_s(temp_ns[j]), temp_c[j])
            j += 1
        expect.append(clean.process(stamp_s(ns), *w)[:3])
    out = rates(rig.out)
    np.testing.assert_array_equal(out, np.array(expect))
    assert np.abs(out - omega).max() < 0.1
    assert rig.node.core.counts['compensated'] == 1500
    rig.spin_until(lambda: any('temperatures rejected (implausible): 1 ' in s.message
                               for s in rig.diag), what='the glitch on /diagnostics')
    status = next(s for s in rig.diag if 'temperatures rejected (implausible)' in s.message)
    assert status.level == status.WARN
    assert {kv.key: kv.value for kv in status.values}[
        'temperatures rejected (implausible)'] == '1'
