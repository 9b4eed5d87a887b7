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

"""Scenario files: every shipped one loads, files and names resolve, overrides work."""

from __future__ import annotations

import math
import re

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.errors import ScenarioError
from gyro_tdc.sim import load_scenario, Scenario, scenario_dir, simulate_run, simulate_scenario
import numpy as np
import pytest
import yaml

DEG = math.pi / 180.0
SHIPPED = ('demo_fast', 'i3g4250d_paper', 'l3gd20_heat_cool', 'l3gd20_paper', 'lag_heat_cool',
           'rate_steps', 'warmup')
MINIMAL = {'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 10.0}]}}


def test_the_expected_scenarios_are_shipped():
    assert set(SHIPPED) <= set(scenario_names())
    assert (scenario_dir() / 'l3gd20_paper.yaml').is_file()


@pytest.mark.parametrize('name', sorted(set(SHIPPED) | set(scenario_names())))
def test_every_shipped_scenario_loads_and_simulates(name):
    sc = load_scenario(name)
    assert sc.name == name and sc.description
    assert sc.source == f'{name}.yaml'
    run = simulate_run(sc.with_overrides({'duration_s': 120.0}), seed=0, rate_hz=2.0)
    assert run.gyro.shape == (240, 3) and np.all(np.isfinite(run.gyro))
    assert run.temp_t.size >= 120 and run.ref.shape == (run.ref_t.size, 3)
    # The normalised mapping round-trips through YAML.
    again = Scenario.from_dict(yaml.safe_load(yaml.safe_dump(sc.to_dict())))
    assert again.gyro == sc.gyro and again.runs == sc.runs
    np.testing.assert_array_equal(again.profile.t, sc.profile.t)


def test_l3gd20_paper_scenario():
    sc = load_scenario('l3gd20_paper')
    assert sc.runs.count == 5 and sc.sensor == 'l3gd20'
    assert sc.gyro.effects == ('bias', 'dT', 'dT2')
    assert sc.thermometer.location == 'package' and sc.thermometer.rate_hz == 1.0
    assert sc.thermometer.resolution_c == 0.03 and sc.imu_rate_hz == 10.0
    assert sc.gyro.sensitivity_mdps_per_digit == 8.75 and sc.gyro.t_ref_c == 25.0
    assert not sc.rate_table.moving
    # The raw output over -40..85 degC has a large BS (paper table 2: ~30 (deg/s)^2).
    run = simulate_run(sc, seed=0, rate_hz=1.0)
    bs = np.mean((np.degrees(run.gyro - run.ref_at(run.imu_t))) ** 2, axis=0)
    assert 25.0 < bs[0] < 35.0 and bs[1] > 5.0 and bs[2] > 0.5
    assert run.truth.die_c.min() == pytest.approx(-40.0) and run.temp_c.max() >= 84.9


def test_five_paper_runs_differ_by_small_bias_offsets():
    runs = simulate_scenario('l3gd20_paper', seed=0, rate_hz=0.05)
    assert len(runs) == 5 and len({r.name for r in runs}) == 5
    offsets = np.degrees([r.truth.bias_offset for r in runs])
    assert np.all(np.abs(offsets) < 0.15) and np.std(offsets) > 0.0


def test_i3g4250d_paper_reference_rates():
    sc = load_scenario('i3g4250d_paper')
    assert sc.rate_table.moving and 'scale' in sc.gyro.effects and sc.runs.count == 5
    t, rate = sc.rate_table.arrays()
    np.testing.assert_allclose(t, [0.0])
    np.testing.assert_allclose(rate, [[10.0 * DEG, 5.0 * DEG, 20.0 * DEG]])
    run = simulate_run(sc, seed=0, rate_hz=1.0)
    bs = np.mean((np.degrees(run.gyro - run.ref_at(run.imu_t))) ** 2, axis=0)
    assert 10.0 < bs[0] < 20.0 and 20.0 < bs[1] < 35.0 and 0.5 < bs[2] < 3.0


@pytest.mark.parametrize('name, effect', [('l3gd20_heat_cool', 'dTdt'),
                                          ('lag_heat_cool', 'lag'), ('rate_steps', 'scale'),
                                          ('warmup', 'warmup')])
def test_each_dynamic_scenario_holds_its_effect(name, effect):
    sc = load_scenario(name)
    assert effect in sc.gyro.effects and sc.runs.count >= 2
    if effect == 'lag':
        assert sc.thermal.tau_die_s > 0.0 and sc.thermometer.location == 'package'
    if effect == 'scale':
        assert len(sc.rate_table.t_s) > 5
    if effect == 'dTdt':
        lo, hi = sc.profile.span_c
        assert sc.profile.temp_c[-1] == lo and hi > lo      # heated, then cooled back


def test_demo_fast_is_short_and_fast():
    sc = load_scenario('demo_fast')
    assert 20 * 60 <= sc.duration_s <= 40 * 60 and sc.imu_rate_hz == 50.0
    assert sc.runs.count == 1


def test_load_scenario_from_file_names_the_file(tmp_path):
    path = tmp_path / 'my_run.yaml'
    path.write_text(yaml.safe_dump(MINIMAL))
    sc = load_scenario(path)
    assert sc.name == 'my_run' and sc.source == 'my_run.yaml'
    path.write_text('profile: {start_c: 20.0\n  segments: [\n')
    with pytest.raises(ScenarioError, match=r'my_run\.yaml: malformed YAML at line'):
        load_scenario(str(path))
    path.write_text(yaml.safe_dump(dict(MINIMAL, gyro={'bias_dps': 'x'})))
    with pytest.raises(ScenarioError, match=r'my_run\.yaml: `gyro\.bias_dps`'):
        load_scenario(path)


def test_unknown_scenario_name_lists_the_shipped_ones():
    with pytest.raises(ScenarioError, match='l3gd20_paper'):
        load_scenario('no_such_scenario')


def test_overrides_set_dotted_paths_and_revalidate():
    sc = load_scenario('l3gd20_paper')
    changed = sc.with_overrides({'gyro.effects.dT3': True, 'noise.enabled': False,
                                 'gyro.dT2_dps_per_c2': [1e-3, 0.0, 0.0],
                                 'runs': {'count': 2}, 'imu_rate_hz': 20.0})
    assert changed.gyro.effects == ('bias', 'dT', 'dT2', 'dT3')
    assert changed.gyro.dT2_dps_per_c2 == (1e-3, 0.0, 0.0)
    assert changed.runs.count == 2
    assert changed.runs.bias_offset_dps_std == sc.runs.bias_offset_dps_std
    assert not changed.noise.enabled and changed.imu_rate_hz == 20.0
    assert sc.gyro.effects == ('bias', 'dT', 'dT2') and sc.noise.enabled    # original unchanged
    with pytest.raises(ScenarioError, match=re.escape('`gyro.dT2_dps_per_c2`')):
        sc.with_overrides({'gyro.dT2_dps_per_c2': 'lots'})
    with pytest.raises(ScenarioError, match='dotted path'):
        sc.with_overrides({'gyro..dT2': 1.0})
