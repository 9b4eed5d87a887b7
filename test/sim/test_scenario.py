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

"""Scenarios: the schema names bad fields, every shipped one loads, overrides work."""

from __future__ import annotations

import copy
import math
import re

from gyro_tdc.base import check_sim_samples
from gyro_tdc.base.resources import config_dir, scenario_names
from gyro_tdc.errors import LimitError, ScenarioError
from gyro_tdc.sim import load_scenario, Scenario, simulate_run, simulate_scenario
from gyro_tdc.sim.scenario import DEFAULTS
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from scenarios import table_moving
import yaml

DEG = math.pi / 180.0
SHIPPED = ('demo_fast', 'i3g4250d_paper', 'l3gd20_heat_cool', 'l3gd20_paper', 'lag_heat_cool',
           'rate_steps', 'warmup')
MINIMAL = {'profile': {'start_c': 20.0, 'segments': [{'kind': 'hold', 'duration_s': 10.0}]}}


def test_the_expected_scenarios_are_shipped():
    assert set(SHIPPED) <= set(scenario_names())
    assert (config_dir() / 'scenarios' / 'l3gd20_paper.yaml').is_file()


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
    assert not table_moving(sc.rate_table)
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
    assert table_moving(sc.rate_table) and 'scale' in sc.gyro.effects and sc.runs.count == 5
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
        lo, hi = sc.profile.temp_c.min(), sc.profile.temp_c.max()
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


def _bad(**changes):
    data = copy.deepcopy(MINIMAL)
    for path, value in changes.items():
        node = data
        parts = path.split('__')
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return data


@pytest.mark.parametrize('data, field', [
    (_bad(gyro__dT2_dps_per_c2='abc'), 'gyro.dT2_dps_per_c2'),
    (_bad(gyro__dT_dps_per_c=[1.0, 2.0]), 'gyro.dT_dps_per_c'),
    (_bad(gyro__dt2_dps_per_c2=1e-3), 'gyro.dt2_dps_per_c2'),
    (_bad(gyro__effects=['bias', 'dT4']), 'gyro.effects'),
    (_bad(gyro__quantise='yes'), 'gyro.quantise'),
    (_bad(thermometer__location='probe'), 'thermometer.location'),
    (_bad(thermometer__rate_hz=0.0), 'thermometer.rate_hz'),
    (_bad(noise__arw_dps_per_rt_hz=-0.1), 'noise.arw_dps_per_rt_hz'),
    (_bad(noise__bias_instability_tau_s=[]), 'noise.bias_instability_tau_s'),
    (_bad(thermal__tau_die_s=float('nan')), 'thermal.tau_die_s'),
    (_bad(runs__count=0), 'runs.count'),
    (_bad(runs__count=1001), 'runs.count'),         # simulate would name them all first
    (_bad(runs__count=2 ** 63), 'runs.count'),
    (_bad(thermometer__rate_hz=1e30), 'thermometer.rate_hz'),    # not a 1e30-element arange
    (_bad(vehicle__cmd_vel_rate_hz=1e30), 'vehicle.cmd_vel_rate_hz'),
    (_bad(sensor=['l3gd20']), 'sensor'), (_bad(sensor={'a': 1}), 'sensor'),
    (_bad(profile={'start_c': 20.0, 'segments': [{'kind': {}}]}), 'profile.segments[0].kind'),
    (_bad(profile__start_c=1e19), 'profile.start_c'),       # a chamber's, -100 .. 200 degC
    (_bad(profile={'start_c': 20.0, 'segments': [{'kind': 'ramp', 'to_c': 2 ** 63,
                                                  'rate_c_per_h': 1.0}]}),
     'profile.segments[0].to_c'),
    (_bad(profile={'start_c': 20.0, 'segments': [{'kind': 'points', 't_s': [0.0, 1.0],
                                                  'temp_c': [20.0, -300.0]}]}),
     'profile.segments[0].temp_c'),
    (_bad(profile={'start_c': 20.0, 'segments': [{'kind': 'staircase', 'to_c': 30.0,
                                                  'step_c': 1e-300, 'hold_s': 1.0}]}),
     'profile.segments'),                           # 1e301 steps: not one array of them
    (_bad(thermometer__noise_c=1e300), 'thermometer.noise_c'),   # its square overflowed
    (_bad(gyro__bias_dps=[0.0, 1e300, 0.0]), 'gyro.bias_dps'),
    (_bad(gyro__bias_dps=1e300), 'gyro.bias_dps'),    # one number for the three axes
    (_bad(sensor='bmi088'), 'sensor'),
    (_bad(imu_rate_hz=-5), 'imu_rate_hz'),
    (_bad(format_version=2), 'format_version'),
    (_bad(colour='red'), 'colour'),
    (_bad(profile={'start_c': 0.0, 'segments': []}), 'profile.segments'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'hold', 'duration_s': 5.0},
                                                {'kind': 'ramp', 'to_c': 5.0,
                                                 'rate_c_per_h': -1.0}]}),
     'profile.segments[1].rate_c_per_h'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'wobble'}]}),
     'profile.segments[0].kind'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'staircase', 'to_c': 5.0,
                                                 'step_c': 0.1}]}),
     'profile.segments[0].hold_s'),
    (_bad(profile={'start_c': 0.0, 'segments': [{'kind': 'points', 't_s': [1.0, 2.0],
                                                 'temp_c': [0.0, 1.0]}]}),
     'profile.segments[0].t_s'),
    (_bad(rate_table=[{'t_s': 0.0, 'rate_dps': 1.0}, {'t_s': 0.0, 'rate_dps': 2.0}]),
     'rate_table[1].t_s'),
    (_bad(rate_table=[{'t_s': 0.0, 'rate_dps': 1.0, 'rate_rad_s': 1.0}]), 'rate_table[0]'),
    (_bad(duration_s=0.01), 'duration_s'),
])
def test_validation_error_names_the_field(data, field):
    with pytest.raises(ScenarioError, match=re.escape(f'`{field}`')) as info:
        Scenario.from_dict(data, source='bad.yaml')
    message = str(info.value)
    assert message.startswith('bad.yaml: ') and 'expected' in message and '\n' not in message


def test_scenario_must_be_a_mapping():
    with pytest.raises(ScenarioError, match='mapping'):
        Scenario.from_dict([1, 2, 3])


def test_effects_as_list_means_exactly_those():
    sc = Scenario.from_dict(dict(MINIMAL, sensor='l3gd20', gyro={'effects': ['dT3']}))
    assert sc.gyro.effects == ('dT3',)
    default = Scenario.from_dict(MINIMAL)
    assert default.gyro.effects == ('bias', 'dT', 'dT2')


def test_defaults_fill_every_section_and_the_preset_overrides_them():
    sc = Scenario.from_dict(MINIMAL)
    assert sc.thermal.internal_step_s == DEFAULTS['thermal']['internal_step_s'] == 0.1
    assert sc.thermometer.location == 'package' and sc.thermometer.rate_hz == 1.0
    assert sc.gyro.warmup_tau_s == DEFAULTS['gyro']['warmup_tau_s'] == 300.0
    assert sc.gyro.quantise and sc.gyro.bias_dps == (0.0, 0.0, 0.0)
    assert sc.noise.bias_instability_tau_s == (10.0, 100.0, 1000.0)
    assert sc.accel.gravity_mps2 == 9.80665 and sc.accel.tilt_deg == (0.0, 0.0)
    assert sc.runs.count == 1 and sc.runs.bias_offset_dps_std == (0.0, 0.0, 0.0)
    assert list(sc.data) == list(DEFAULTS)       # the normalised mapping keeps the order
    l3 = Scenario.from_dict(dict(MINIMAL, sensor='l3gd20'))
    assert l3.gyro.warmup_tau_s == 240.0 and l3.gyro.range_dps == 250.0
    assert l3.noise.bias_instability_dps == (0.004, 0.005, 0.004)


#: What a hostile or careless scenario file puts where a number, list or name belongs.
_HOSTILE = st.sampled_from([0, -1, 1e-300, 1e300, math.nan, math.inf, -math.inf, '', 'x', None,
                            True, [], {}, [1, 2], {'a': 1}, 10 ** 30, -10 ** 30, 2 ** 63,
                            86400 * 365, '1e400', 3, 1e-3, 1e9])


def _paths(d, pre=()):
    """Yield the path of every entry of a nested mapping / list."""
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        yield pre + (k,)
        yield from _paths(v, pre + (k,))


@given(data=st.data())
@settings(max_examples=60, deadline=None)
def test_mutated_shipped_scenarios_simulate_or_are_refused_in_one_line(data):
    name = data.draw(st.sampled_from(sorted(scenario_names())))
    doc = yaml.safe_load((config_dir() / 'scenarios' / f'{name}.yaml').read_text())
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(list(_paths(doc))))
        node = doc
        for k in path[:-1]:
            node = node[k]
        if data.draw(st.integers(0, 4)) == 0 and isinstance(node, dict):
            del node[path[-1]]
        else:
            # A copy: sampled_from hands out its own objects, which would be mutated later
            # (carried into the next example) or put inside themselves (a cycle).
            node[path[-1]] = copy.deepcopy(data.draw(_HOSTILE))
    try:
        sc = Scenario.from_dict(doc, source='mutated.yaml')
    except ScenarioError as exc:
        assert '\n' not in str(exc) and str(exc).startswith('mutated.yaml: ')
        return
    try:
        n = check_sim_samples(sc.duration_s, 1.0)
    except LimitError as exc:           # simulate's refusal, before any array is made
        assert '\n' not in str(exc)
        return
    if n > 400_000:                     # legal, but too long to simulate here
        return
    # What loads simulates (at 1 Hz, a run of a day in a fraction of a second).
    runs = simulate_scenario(sc, seed=0, rate_hz=1.0, runs=[0])
    assert np.all(np.isfinite(runs[0].imu_t)) and len(runs[0].temp_t) >= 1
