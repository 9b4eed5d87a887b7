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
``python -m gyro_tdc train``: bags in, a model file out, a coverage report, exit 2 on bad input.

Bags are written in ``tmp_path`` with :func:`gyro_tdc.data.write_bag` from the exact synthetic
runs of ``synth.py`` or from the simulator. The helpers here are shared with
``test_evaluate.py``.
"""

from __future__ import annotations

from bags import assert_bad_input, bag_from_run, DEG, sim_bags
from flightlogs import sd_card
from gyro_tdc.cli.train import main
from gyro_tdc.data.runs import Run
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import load_model
from gyro_tdc.signal.metrics import bias_stability
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def synth_bag(tmp_path_factory):
    """Return a 2 h, 5 Hz synthetic heating run as a sqlite3 bag, and the run."""
    run = synth_run(seed=11)
    return bag_from_run(run, tmp_path_factory.mktemp('bags') / 'heat'), run


def test_train_writes_a_model_that_loads_and_compensates(synth_bag, tmp_path, capsys):
    bag, run = synth_bag
    out = tmp_path / 'models' / 'mod.yaml'
    assert main([str(bag), '--out', str(out), '--kind', 'poly', '--no-progress']) == 0
    text = capsys.readouterr().out
    model = load_model(out)
    assert model.features == ('dT', 'dT2') and model.kind == 'poly'
    assert model.created['bags'] == [str(bag)]
    assert model.created['command'].startswith('gyro-tdc train ')
    assert '--kind poly' in model.created['command']
    held_out = synth_run(seed=12)
    floor = held_out.info['noise_dps'] ** 2
    bs = bias_stability(compensate(model, held_out.t, held_out.temp, held_out.omega),
                        held_out.omega_ref)
    assert np.all(bs < 1.1 * floor), bs
    # The report: training BS raw and compensated, range, bins, heating/cooling minutes.
    for needle in ('training bias stability BS, (deg/s)^2', 'raw', 'compensated',
                   'temperature range covered: -10.00 .. 49.99 degC',
                   'coverage per 5 degC bin:', '[45, 50) degC', 'heating (dT/dt > +0.05',
                   'warning: no cooling data', f'wrote {out}'):
        assert needle in text, (needle, text)
    bs_line = next(line for line in text.splitlines() if line.strip().startswith('compensated'))
    assert np.allclose([float(v) for v in bs_line.split()[1:]],
                       model.metrics['train_bs_dps2'], rtol=1e-3)


def test_conventional_and_rbf_options_reach_the_model(synth_bag, tmp_path, capsys):
    bag, _ = synth_bag
    out = tmp_path / 'conv.yaml'
    assert main([bag, '--out', out, '--features', 'dT', '--centers', '5', '--seed', '3',
                 '--t0', '25']) == 0
    model = load_model(out)
    assert model.features == ('dT',) and model.kind == 'rbf' and model.n_centers <= 5
    assert model.t0_c == 25.0
    assert 'model: rbf f(dT), ' in capsys.readouterr().out


def test_folder_of_mcap_bags_expands_to_its_runs_and_counts_heating_and_cooling(
        tmp_path, capsys):
    folder = tmp_path / 'multi'
    folder.mkdir()
    for k in (1, 2):
        bag_from_run(synth_run(seed=20 + k, cooling=True, hours=1.0), folder / f'run{k}',
                     storage='mcap')
    out = tmp_path / 'm.yaml'
    assert main([folder, '--out', out]) == 0
    text = capsys.readouterr().out
    model = load_model(out)
    assert model.metrics['runs'] == [str(folder / 'run1'), str(folder / 'run2')]
    assert model.created['bags'] == model.metrics['runs']
    assert 'training data: 2 bag(s)' in text
    heat = text.split('heating (dT/dt > +0.05 degC/min): ')[1]
    heating_min = float(heat.split(' min')[0])
    cooling_min = float(heat.split('cooling (< -0.05): ')[1].split(' min')[0])
    assert heating_min > 40 and cooling_min > 40, text
    assert 'no cooling data' not in text


def test_coverage_warning_names_bins_crossed_too_fast(tmp_path, capsys):
    # Soak at 0 degC, a jump through 0..20 degC in 2 minutes, then a slow ramp to 40 degC.
    rate = 2.0
    t = np.arange(int(3 * 3600 * rate)) / rate
    temp = np.interp(t, [0, 1800, 1920, t[-1]], [0.0, 0.0, 20.0, 40.0])
    rng = np.random.default_rng(5)
    omega = (0.01 * temp[:, None] * DEG * np.ones(3)
             + rng.normal(0, 0.05 * DEG, (len(t), 3)))
    run = Run(t, temp, omega, np.zeros((len(t), 3)), 'jump')
    out = tmp_path / 'j.yaml'
    assert main([bag_from_run(run, tmp_path / 'jump'), '--out', out, '--kind', 'poly']) == 0
    text = capsys.readouterr().out
    warning = next(line for line in text.splitlines() if 'little data' in line
                   and line.startswith('warning:'))
    for name in ('[5, 10) degC', '[10, 15) degC'):
        assert name in warning
    for name in ('[25, 30) degC', '[30, 35) degC'):
        assert name not in warning


def test_lag_feature_recovers_the_die_lag_of_a_simulated_heat_cool_run(tmp_path, capsys):
    # The die lags the package thermometer by tau_die = 180 s; heating and cooling legs.
    folder, sims = sim_bags(tmp_path, 'lag_heat_cool', rate_hz=2.0)
    out = tmp_path / 'lag.yaml'
    assert main([folder / 'run1', '--out', out, '--features', 'lag']) == 0
    model = load_model(out)
    assert model.effect_params['lag']['tau_s'] == pytest.approx(180.0, rel=0.05)
    assert 'lag.tau_s = ' in capsys.readouterr().out


# --------------------------------------------------------------------------------------------
# Bad input: exit 2, one line on stderr, no traceback
# --------------------------------------------------------------------------------------------

def test_missing_bag_path(tmp_path, capsys):
    assert_bad_input(capsys, [tmp_path / 'nope', '--out', tmp_path / 'm.yaml'],
                     'gyro-tdc train: error:', 'does not exist')


def test_not_a_bag(tmp_path, capsys):
    (tmp_path / 'empty').mkdir()
    assert_bad_input(capsys, [tmp_path / 'empty', '--out', tmp_path / 'm.yaml'],
                     'not a rosbag2 directory')
    (tmp_path / 'notes.txt').write_text('hello')
    assert_bad_input(capsys, [tmp_path / 'notes.txt', '--out', tmp_path / 'm.yaml'],
                     'is a file, not a rosbag2 directory')


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_a_bag_without_metadata_yaml_trains_the_same_model_with_a_warning(
        synth_bag, tmp_path, capsys, storage):
    # The power went during `ros2 bag record`: rosbag2 wrote no metadata.yaml.
    _, run = synth_bag
    bag = bag_from_run(run, tmp_path / 'rec', storage=storage)
    args = ['--kind', 'poly', '--no-progress']
    assert main([str(bag), '--out', str(tmp_path / 'a.yaml'), *args]) == 0
    (data,) = [p for p in bag.iterdir() if p.suffix in ('.db3', '.mcap')]
    data.rename(bag / f'rec_0{data.suffix}')
    (bag / 'metadata.yaml').unlink()
    capsys.readouterr()
    assert main([str(bag), '--out', str(tmp_path / 'b.yaml'), *args]) == 0
    out = capsys.readouterr()
    assert (f'warning: {bag}: no metadata.yaml (the recording did not close: rosbag2 writes '
            f'it then): read from rec_0{data.suffix} as `ros2 bag reindex` would list it'
            in out.out + out.err)
    a, b = load_model(tmp_path / 'a.yaml'), load_model(tmp_path / 'b.yaml')
    assert a.model_id == b.model_id
    assert sorted(p.name for p in bag.iterdir()) == [f'rec_0{data.suffix}']


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_corrupt_bag(tmp_path, capsys, storage):
    bag = bag_from_run(synth_run(seed=1, hours=0.2), tmp_path / 'bad', storage=storage)
    data = next(p for p in bag.iterdir() if p.suffix in ('.db3', '.mcap'))
    data.write_bytes(b'\x00garbage' * 100)
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml'], 'unreadable or corrupt')
    assert not (tmp_path / 'm.yaml').exists()


def test_missing_topic_lists_the_topics_of_the_bag(synth_bag, tmp_path, capsys):
    bag, _ = synth_bag
    line = assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml', '--imu-topic', '/x'],
                            "no topic '/x'", 'topics present:', '/imu/data_raw',
                            '/imu/temperature')
    assert 'sensor_msgs/msg/Imu' in line


def test_temperature_span_too_small(tmp_path, capsys):
    run = synth_run(seed=2, hours=0.3, t_lo=25.0, t_hi=25.2)
    assert_bad_input(capsys, [bag_from_run(run, tmp_path / 'flat'), '--out',
                              tmp_path / 'm.yaml'], 'Temperature span too small')


def test_one_short_still_power_cycle_keeps_the_offset_only(tmp_path, capsys):
    """Still, no reference, 3 min over 1.5 degC: its curve cannot be judged, as --still-only."""
    run = synth_run(seed=2, hours=0.05, t_lo=25.0, t_hi=26.5)
    out = tmp_path / 'm.yaml'
    assert main([str(bag_from_run(run, tmp_path / 'short')), '--out', str(out),
                 '--no-progress']) == 0
    said = capsys.readouterr().out
    assert 'one power cycle only, and no still stretch of 5 min or more spans 2 degC' in said
    assert load_model(out).offset_only
    wide = synth_run(seed=2, hours=0.2, t_lo=25.0, t_hi=35.0)        # 12 min over 10 degC
    assert main([str(bag_from_run(wide, tmp_path / 'wide')), '--out', str(out),
                 '--no-progress']) == 0
    assert 'one power cycle only' not in capsys.readouterr().out
    assert not load_model(out).offset_only


def test_too_few_samples(tmp_path, capsys):
    run = synth_run(seed=2, hours=0.002)  # 36 samples at 5 Hz
    assert_bad_input(capsys, [bag_from_run(run, tmp_path / 'short', temp_hz=5.0), '--out',
                              tmp_path / 'm.yaml'], 'Too few samples')


def test_bad_feature_id_fails_before_reading(tmp_path, capsys):
    assert_bad_input(capsys, [tmp_path / 'nope', '--out', tmp_path / 'm.yaml', '--features',
                              'dT,dT4'], "Unknown effect id(s) 'dT4'")


@pytest.mark.parametrize('value', ['1,2', 'a,b,c', '1,2,nan', '1,2,3 furlongs'])
def test_bad_reference(synth_bag, tmp_path, capsys, value):
    bag, _ = synth_bag
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml', f'--reference={value}'],
                     '--reference', 'three finite rates')


def test_usage_errors_are_one_line(synth_bag, tmp_path, capsys):
    bag, _ = synth_bag
    assert main([str(bag), '-o', str(tmp_path / 'o.yaml'), '--no-progress']) == 0
    assert load_model(tmp_path / 'o.yaml').features
    assert_bad_input(capsys, [bag], 'the following arguments are required: -o/--out')
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml', '--kind', 'spline'],
                     "invalid choice: 'spline'")
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml', '--centers', '0'],
                     'expected an integer >= 1')
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'm.yaml', '--reference', '0,0,0',
                              '--reference-topic', '/r'], 'not allowed with')


def test_unwritable_output_is_bad_input(synth_bag, tmp_path, capsys):
    bag, _ = synth_bag
    (tmp_path / 'dir.yaml').mkdir()
    assert_bad_input(capsys, [bag, '--out', tmp_path / 'dir.yaml'], 'cannot access')


def test_help_exits_zero(capsys):
    assert main(['--help']) == 0
    assert '--features' in capsys.readouterr().out


@pytest.fixture(scope='module')
def card(tmp_path_factory):
    """Write an SD card's folder: two readable logs (one in ``log/DATE/``), two not."""
    root = tmp_path_factory.mktemp('card')
    return (root, *sd_card(root))


def test_a_folder_skips_the_logs_it_cannot_read_and_trains_on_the_rest(card, tmp_path, capsys):
    root, good, bad = card
    out = tmp_path / 'card.yaml'
    args = ['--out', out, '--features', 'dT,dT2', '--no-progress']
    assert main([root, *args]) == 0
    said = capsys.readouterr()
    lines = said.out.splitlines()
    for path, why in zip(bad, ('damaged bytes inside the log', 'empty')):
        mine = [ln for ln in lines if str(path) in ln]
        assert len(mine) == 1 and mine[0].startswith(f'warning: skipped {path}: '), lines
        assert why in mine[0], mine[0]
    assert 'read 2 of the 4 bags and logs, skipped 2 that cannot be read' in said.out
    assert 'Traceback' not in said.err and said.err.strip() == ''
    assert load_model(out).created['bags'] == [str(p) for p in good]
    # Named on the command line, an unreadable log is refused in one line.
    assert_bad_input(capsys, [bad[1], *args], str(bad[1]))
    assert_bad_input(capsys, [good[1], bad[0], *args], 'damaged bytes inside the log')
    # A folder of which nothing can be read: one line.
    only_bad = tmp_path / 'bad'
    only_bad.mkdir()
    for path in bad:
        (only_bad / path.name).write_bytes(path.read_bytes())
    assert_bad_input(capsys, [only_bad, *args], 'None of the 2 bags and logs found can be read',
                     'empty.BIN')
