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
The installed ``gyro-tdc discover`` on a sensor constant on every axis: one line, exit 2.

A gyro whose every axis reads a fixed value, and (``--sensor accel``) an accelerometer read
as exactly ``(0, 0, g)``, leave discovery nothing to find: the command refuses in one line
before the search, in train's words (it raised ZeroDivisionError in the summary before),
writes no output file, with every warning an error. A gyro with one stuck axis is
discovered with that axis passed through.
"""

from __future__ import annotations


from gyro_tdc.data import write_bag
from gyro_tdc.identify.accel import G0
from gyro_tdc.sim import simulate_scenario
import numpy as np
import pytest
from strict_cli import strict_cli as _cli


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Write a dead gyro (every axis fixed) and a gyro with a constant accelerometer."""
    root = tmp_path_factory.mktemp('const_discover')
    sim = simulate_scenario('demo_fast', seed=3, rate_hz=2.0)[0]
    accel = np.zeros_like(sim.accel)
    accel[:, 2] = G0
    dead = np.zeros_like(sim.gyro)
    dead[:, 0] = 0.25                                # a stuck axis, off the reference
    dead[:, 1] = 0.01
    write_bag(root / 'dead', imu_t=sim.imu_t, gyro=dead, accel=sim.accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    write_bag(root / 'flat_accel', imu_t=sim.imu_t, gyro=sim.gyro, accel=accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    return root


@pytest.mark.parametrize('bag, extra', [('dead', ('--out', 'm.yaml', '--json', 'd.json')),
                                        ('flat_accel', ('--sensor', 'accel', '--json', 'd.json'))])
def test_discover_refuses_a_sensor_constant_on_every_axis(bags, tmp_path, bag, extra):
    """Exit 2 with one line naming the constant readings; no traceback, no file written."""
    argv = [a if not a.endswith(('.yaml', '.json')) else tmp_path / a for a in extra]
    res = _cli('discover', bags / bag, *argv)
    assert res.returncode == 2, (res.returncode, res.stderr)
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('gyro-tdc discover: error: '), res.stderr
    assert 'constant' in err[0] and ('every axis' in err[0] or bag == 'flat_accel'), err[0]
    assert 'Traceback' not in res.stderr and 'Warning' not in res.stderr
    assert not (tmp_path / 'm.yaml').exists() and not (tmp_path / 'd.json').exists()


def test_discover_out_passes_a_stuck_axis_through(tmp_path):
    """``discover --out`` on a gyro with z stuck at 0.25 rad/s: z not fitted, x and y as train."""
    import yaml
    sim = simulate_scenario('demo_fast', seed=4, rate_hz=2.0)[0]
    gyro = sim.gyro.copy()
    gyro[:, 2] = 0.25
    write_bag(tmp_path / 'z1', imu_t=sim.imu_t, gyro=gyro, accel=sim.accel,
              temp_t=sim.temp_t, temp_c=sim.temp_c)
    res = _cli('discover', tmp_path / 'z1', '--out', tmp_path / 'm.yaml')
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr and 'Warning' not in res.stderr
    doc = yaml.safe_load((tmp_path / 'm.yaml').read_text())
    assert doc['training']['constant_axes'] == ['z'], doc['training']
    from gyro_tdc.model import compensate, load_model
    model = load_model(tmp_path / 'm.yaml')
    out = compensate(model, sim.imu_t, np.interp(sim.imu_t, sim.temp_t, sim.temp_c), gyro)
    assert np.array_equal(out[:, 2], gyro[:, 2])          # passed through, bit for bit
    assert np.std(out[:, 0] - gyro[:, 0]) > 0             # x is corrected
