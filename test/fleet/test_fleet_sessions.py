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

"""A fleet sensor with several training bags: one turn-on offset per bag, held out re-anchored."""

from __future__ import annotations

from dataclasses import replace

from bags import bag_from_run
from gyro_tdc.data import BagOptions
from gyro_tdc.fleet.manifest import SensorSpec
from gyro_tdc.fleet.run import run_sensor
from gyro_tdc.identify import TrainOptions
import numpy as np
from synth import synth_run

NOISE_DPS = 0.02
OFFSETS = ((0.4, -0.3, 0.1), (-0.5, 0.2, 0.45), (0.1, 0.5, -0.4))
RANGES = ((-10.0, 30.0), (15.0, 50.0), (0.0, 40.0))


def test_a_sensor_trained_on_bags_with_their_own_offsets(tmp_path):
    bags = [str(bag_from_run(synth_run(seed=i, hours=0.5, rate_hz=2.0, t_lo=lo, t_hi=hi,
                                       noise_dps=NOISE_DPS, offset_dps=off),
                             tmp_path / f'bag{i}'))
            for i, (off, (lo, hi)) in enumerate(zip(OFFSETS, RANGES))]
    spec = SensorSpec('imu-1', tuple(bags[:2]), (bags[2],))
    options = TrainOptions(features='dT,dT2', kind='poly', accel=False)
    out = run_sensor(spec, options)
    assert out.status == 'ok', out.error
    info = out.model.metrics['sessions']
    off = np.array(OFFSETS[:2])
    np.testing.assert_allclose(info['offset_dps'], off - off.mean(axis=0), atol=0.003)
    floor = NOISE_DPS ** 2
    assert max(out.heldout_bs) < 1.1 * floor          # re-anchored on its own power cycle
    one = run_sensor(spec, options, bag=replace(BagOptions(), sessions='none'))
    assert 'sessions' not in one.model.metrics
    assert min(one.heldout_bs) > 5 * floor             # one intercept: a bent curve
    assert one.key != out.key                          # the choice is part of the resume key
