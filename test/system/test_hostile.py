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
Hostile files and faulty inputs (the parts outside the nodes).

Each case reproduces one reported failure: deep nesting and alias bombs in YAML, oversized
files, tampered model files (atomic, permission-keeping outputs: test_atomicio.py), silent
message loss in a damaged bag, absurd values in a bag, options sizing huge arrays, the same bag
twice, conflicting temperature stamps. Bags are written in ``tmp_path`` with ``write_bag``; no
rclpy.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
import stat
import tracemalloc

from gyro_tdc.base.limits import MAX_CENTERS
from gyro_tdc.errors import GyroTdcError, ModelFileError, OutputError, ScenarioError
from gyro_tdc.model.modelfile import load_model, model_from_dict, model_to_dict, save_model
from gyro_tdc.sim import load_scenario
from hostile_helpers import one_line_error, small_model
import numpy as np
import pytest
import yaml

DEEP = '[' * 600 + ']' * 600          # 1.2 KB, 600 levels: RecursionError in yaml.safe_load


def alias_bomb(levels: int = 9) -> str:
    """Return a 'billion laughs' YAML document (2-3 KB, 10**levels leaves expanded)."""
    lines = ['a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]']
    for k in range(1, levels + 1):
        refs = ', '.join([f'*a{k - 1}'] * 10)
        lines.append(f'a{k}: &a{k} [{refs}]')
    return '\n'.join(lines) + '\n'


# --------------------------------------------------------------------------------------------
# Items 1 and 3: deep nesting, alias bombs and size limits in every YAML the package reads
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('text', [DEEP, 'centers: ' + DEEP + '\n',
                                  'training: ' + '{a: ' * 400 + '1' + '}' * 400 + '\n'])
def test_deeply_nested_model_file_is_a_clear_error(tmp_path, text):
    path = tmp_path / 'deep.yaml'
    path.write_text(text)
    with pytest.raises(ModelFileError, match='nesting deeper than 32 levels') as info:
        load_model(path)
    assert str(path) in one_line_error(info)


def test_deeply_nested_scenario_file_is_a_clear_error(tmp_path):
    path = tmp_path / 'deep.yaml'
    path.write_text('profile: ' + DEEP + '\n')
    with pytest.raises(ScenarioError, match='nesting deeper than') as info:
        load_scenario(path)
    assert 'deep.yaml' in one_line_error(info)


def test_alias_bomb_model_file_is_refused_fast_in_bounded_memory(tmp_path):
    path = tmp_path / 'bomb.yaml'
    path.write_text(alias_bomb(9))
    assert path.stat().st_size < 3000
    tracemalloc.start()
    try:
        with pytest.raises(ModelFileError, match='aliases are not allowed in a model file'):
            load_model(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5e6, peak


def test_alias_bomb_scenario_file_is_refused_by_the_expanded_node_count(tmp_path):
    path = tmp_path / 'bomb.yaml'
    path.write_text(alias_bomb(9))
    tracemalloc.start()
    try:
        with pytest.raises(ScenarioError, match=r'more than \d+ YAML nodes \(aliases expanded\)'):
            load_scenario(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5e6, peak


def test_recursive_alias_is_refused(tmp_path):
    path = tmp_path / 'loop.yaml'
    path.write_text('profile: &p [1, *p]\n')
    with pytest.raises(ScenarioError, match='recursive YAML alias'):
        load_scenario(path)


def test_oversized_model_file_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / 'huge.yaml'
    with open(path, 'wb') as fh:                 # sparse: 64 MiB without writing them
        fh.truncate(64 * 1024 * 1024)
    with pytest.raises(ModelFileError, match=r'bytes, more than the 4194304-byte limit'):
        load_model(path)


def test_too_many_nodes_in_a_model_file(tmp_path):
    path = tmp_path / 'wide.yaml'
    path.write_text('training: {x: [' + '0,' * 300_000 + '0]}\n')
    with pytest.raises(ModelFileError, match='more than 250000 YAML nodes'):
        load_model(path)


def test_too_many_centres_named_with_the_limit():
    k = MAX_CENTERS + 1
    d = model_to_dict(small_model(4))
    d['centers'] = [[0.0, 0.0]] * k
    with pytest.raises(ModelFileError, match=f'`centers` has {k} rows, more than the limit '
                                             f'of {MAX_CENTERS} centres'):
        model_from_dict(d)


def test_bag_metadata_with_deep_nesting_is_a_clear_error(tmp_path):
    from gyro_tdc.data import read_bag, write_bag
    from gyro_tdc.errors import DatasetError
    bag = tmp_path / 'bag'
    t = np.arange(100) * 0.1
    write_bag(bag, imu_t=t, gyro=np.zeros((100, 3)), accel=np.zeros((100, 3)),
              temp_t=t[::10], temp_c=np.full(10, 20.0))
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: ' + DEEP + '\n')
    with pytest.raises(DatasetError, match='nesting deeper than') as info:
        read_bag(bag)
    assert 'metadata.yaml' in one_line_error(info)


# --------------------------------------------------------------------------------------------
# Item 6: the content hash covers every field but `created`; a file without it is refused
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('field, value', [
    ('temp_range_c', [-1000.0, 1000.0]),
    ('residual_var_rad2_s2', [1.0, 1.0, 1.0]),
    ('sensor', {'frame_id': 'other_link', 'sensor_id': 'unit-7'}),
    ('sensor', {'frame_id': 'imu_link', 'sensor_id': 'unit-8'}),
    ('training', {'samples': 2000, 'runs': ['/bags/run1']}),
    ('t0_c', 21.0),
])
def test_tampered_field_does_not_load_under_the_old_id(tmp_path, field, value):
    path = save_model(small_model(), tmp_path / 'm.yaml')
    d = yaml.safe_load(path.read_text())
    d[field] = value
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    with pytest.raises(ModelFileError, match='`model_id` .* does not match the parameters'):
        load_model(path)


def test_created_is_outside_the_hash(tmp_path):
    m = small_model()
    path = save_model(m, tmp_path / 'm.yaml')
    d = yaml.safe_load(path.read_text())
    d['created'] = {'utc': 'another day', 'command': 'edited'}
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    assert load_model(path).model_id == m.model_id


def test_id_survives_the_round_trip_with_numpy_values_in_the_metrics(tmp_path):
    m = small_model(metrics={'samples': np.int64(7), 'bs': np.array([1.5, 2.5]),
                             'pair': (np.float64(0.1), 3), 'nan': float('nan')})
    back = load_model(save_model(m, tmp_path / 'm.yaml'))
    assert back.model_id == m.model_id


def test_file_without_model_id_is_refused(tmp_path):
    d = model_to_dict(small_model())
    del d['model_id']
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ModelFileError, match='missing field `model_id`'):
        load_model(path)


# --------------------------------------------------------------------------------------------
# Item 15: format_version must be the integer 2
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('text', ['2.0', 'true', "'2'", '1'])
def test_format_version_must_be_the_integer_two(tmp_path, text):
    path = save_model(small_model(), tmp_path / 'm.yaml')
    body = path.read_text().replace('format_version: 2\n', f'format_version: {text}\n')
    assert body != path.read_text()
    path.write_text(body)
    with pytest.raises(ModelFileError, match='`format_version` must be 2'):
        load_model(path)


def test_errors_are_gyro_tdc_errors():
    assert issubclass(OutputError, GyroTdcError)


# --------------------------------------------------------------------------------------------
# Items 2 and 14: IIO permission errors are device errors; scale changes take effect
# --------------------------------------------------------------------------------------------

@pytest.fixture
def deny(monkeypatch):
    """
    Return a function making a path unreadable as mode 000 makes it for a normal user.

    The mode is set for real; since the tests may run as root (which ignores it), the
    file-system calls the IIO back-end makes (``os.stat``, ``os.listdir``, ``os.scandir``,
    ``open``) also raise ``PermissionError`` (EACCES) for it: a denied directory can be
    stat'ed but not listed, and nothing inside it can be stat'ed or opened; a denied file
    can be stat'ed but not opened.
    """
    import builtins
    dirs: list[str] = []
    files: list[str] = []
    changed: list[tuple[Path, int]] = []

    def blocked(path, *, use: bool) -> bool:
        if not isinstance(path, (str, os.PathLike)):
            return False
        p = os.path.abspath(os.fspath(path))
        return (any(p.startswith(d + os.sep) or (use and p == d) for d in dirs)
                or (use and p in files))

    def guard(real, use):
        def call(path, *args, **kwargs):
            if blocked(path, use=use):
                raise PermissionError(errno.EACCES, 'Permission denied', os.fspath(path))
            return real(path, *args, **kwargs)
        return call

    monkeypatch.setattr(os, 'stat', guard(os.stat, False))
    monkeypatch.setattr(os, 'listdir', guard(os.listdir, True))
    monkeypatch.setattr(os, 'scandir', guard(os.scandir, True))
    monkeypatch.setattr(builtins, 'open', guard(builtins.open, True))

    def add(path: Path) -> None:
        changed.append((path, stat.S_IMODE(path.stat().st_mode)))
        (dirs if path.is_dir() else files).append(os.path.abspath(path))
        path.chmod(0)

    yield add
    for path, mode in changed:
        path.chmod(mode)


def _l3gd20(root: Path, dirname: str = 'iio:device0') -> Path:
    from fake_iio import l3gd20_files, make_device
    return make_device(root, l3gd20_files(), dirname)


def test_unreadable_device_dir_at_start_is_a_device_error(tmp_path, deny):
    from gyro_tdc.errors import DeviceError
    from gyro_tdc.sources import IioSource
    dev = _l3gd20(tmp_path)
    deny(dev)
    with pytest.raises(DeviceError, match='Permission denied') as info:
        IioSource(dev)
    assert str(dev) in one_line_error(info)


def test_device_becoming_unreadable_at_run_time_is_a_device_error(tmp_path, deny):
    from gyro_tdc.errors import DeviceError
    from gyro_tdc.sources import IioSource
    dev = _l3gd20(tmp_path)
    src = IioSource(dev)
    src.read()
    deny(dev / 'in_anglvel_y_raw')
    with pytest.raises(DeviceError, match='in_anglvel_y_raw.*Permission denied'):
        src.read()
    deny(dev)
    with pytest.raises(DeviceError, match='Permission denied'):
        src.read()
    with pytest.raises(DeviceError, match='Permission denied'):   # the driver's reopen
        IioSource(dev)


def test_unrelated_unreadable_device_sorting_first_is_skipped(tmp_path, deny):
    from gyro_tdc.errors import DeviceError
    from gyro_tdc.sources import find_iio_device
    from fake_iio import make_device
    other = make_device(tmp_path, {'name': 'secret_adc'}, 'iio:device0')
    wanted = _l3gd20(tmp_path, 'iio:device1')
    deny(other)
    assert find_iio_device('l3gd20', root=tmp_path) == wanted
    with pytest.raises(DeviceError, match=r'found: iio:device0 unreadable \(Permission denied\)'
                                          r', l3gd20'):
        find_iio_device('bmi160', root=tmp_path)


def test_scale_change_takes_effect_without_reopening(tmp_path):
    from gyro_tdc.sources import IioSource
    dev = _l3gd20(tmp_path)
    src = IioSource(dev, rescale_every=10)
    before = src.read().omega[0]
    scale = float((dev / 'in_anglvel_scale').read_text())
    (dev / 'in_anglvel_scale').write_text(f'{4.0 * scale:.12g}\n')    # 250 -> 1000 dps range
    rates = [src.read().omega[0] for _ in range(10)]
    assert rates[0] == before                   # not yet re-read (sample 2 of 10)
    assert rates[-1] == pytest.approx(4.0 * before, rel=1e-9)
    (dev / 'in_anglvel_scale').write_text(f'{scale:.12g}\n')
    src.rescale()
    assert src.read().omega[0] == pytest.approx(before, rel=1e-9)


def test_temperature_offset_change_and_garbled_scale_at_rescale(tmp_path):
    from gyro_tdc.errors import DeviceError
    from gyro_tdc.sources import IioSource
    dev = _l3gd20(tmp_path)
    src = IioSource(dev, rescale_every=1)
    assert src.read().temp_c == pytest.approx(25.0)
    (dev / 'in_temp_offset').write_text('1\n')      # 1 degC: within the slew gate's margin
    assert src.read().temp_c == pytest.approx(26.0)
    (dev / 'in_anglvel_scale').write_text('garbage\n')
    with pytest.raises(DeviceError, match="in_anglvel_scale' holds 'garbage'"):
        src.read()


# --------------------------------------------------------------------------------------------
# Items 5, 7, 13, 15: bags that lose messages, hold absurd values, are given twice, or carry
# conflicting temperature stamps
# --------------------------------------------------------------------------------------------

def _heat_bag(path: Path, *, storage: str = 'sqlite3', edit=None) -> Path:
    """Write a 2 h, 5 Hz synthetic heating run (36,000 IMU messages) as a bag."""
    from gyro_tdc.data import write_bag
    from synth import synth_run
    run = synth_run(seed=11)
    imu = {'t': run.t + 100.0, 'gyro': run.omega.copy()}
    temp = {'t': run.t[::5] + 100.0, 'c': run.temp[::5].copy()}
    if edit is not None:
        edit(imu, temp)
    write_bag(path, imu_t=imu['t'], gyro=imu['gyro'], accel=np.zeros((len(imu['t']), 3)),
              temp_t=temp['t'], temp_c=temp['c'], storage=storage)
    return path


@pytest.fixture(scope='module')
def heat_bag(tmp_path_factory):
    return _heat_bag(tmp_path_factory.mktemp('heat') / 'heat')


def _cli(capsys, entry, argv):
    """Run a command's ``main``; return (exit code, stdout, stderr)."""
    rc = entry([str(a) for a in argv])
    captured = capsys.readouterr()
    assert 'Traceback' not in captured.err
    return rc, captured.out, captured.err


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def _delete_imu_rows(bag: Path, count: int) -> None:
    """Remove ``count`` IMU messages from a sqlite3 bag, leaving metadata.yaml as it was."""
    import sqlite3
    (db,) = bag.glob('*.db3')
    with sqlite3.connect(db) as con:
        con.execute('DELETE FROM messages WHERE id IN (SELECT m.id FROM messages m JOIN topics '
                    "t ON m.topic_id = t.id WHERE t.name = '/imu/data_raw' "
                    'ORDER BY m.id LIMIT ? OFFSET 5000)', (count,))


@pytest.mark.parametrize('fill', ['random', 'zeros'])
def test_damaged_mcap_is_refused_naming_the_loss_and_allowed_on_request(tmp_path, capsys,
                                                                        fill):
    from gyro_tdc.cli.train import main
    from gyro_tdc.data.dataset import load_run
    from gyro_tdc.data.options import BagOptions
    from gyro_tdc.errors import DatasetError
    bag = _heat_bag(tmp_path / 'bag', storage='mcap')
    (mcap,) = bag.glob('*.mcap')
    size = mcap.stat().st_size
    # 64 KB in the middle. rosbags skips the damaged chunk without a word (with other random
    # seeds its reader fails loudly instead, which load_run already reports as corrupt).
    junk = (np.random.default_rng(4).integers(0, 256, 65536, dtype=np.uint8).tobytes()
            if fill == 'random' else bytes(65536))
    with open(mcap, 'r+b') as fh:
        fh.seek(size // 2 - 32768)
        fh.write(junk)
    with pytest.raises(DatasetError, match=r'/imu/data_raw: read \d+ of 36000 messages listed '
                                           r'in the bag metadata') as info:
        load_run(bag)
    assert '--allow-loss' in one_line_error(info)
    run = load_run(bag, BagOptions(max_loss=1.0))
    read, listed = run.info['messages']['/imu/data_raw']
    assert listed == 36000 and 0 < read < listed
    assert any(f'read {read} of 36000 messages' in w for w in run.info['warnings'])

    rc, _, err = _cli(capsys, main, [bag, '--out', tmp_path / 'm.yaml', '--no-progress'])
    assert rc == 2 and f'read {read} of 36000 messages' in _one_error_line(err)
    assert not (tmp_path / 'm.yaml').exists()
    rc, out, err = _cli(capsys, main, [bag, '--out', tmp_path / 'm.yaml', '--no-progress',
                                       '--allow-loss'])
    assert rc == 0, err
    assert f'warning: {bag}: /imu/data_raw: read {read} of 36000 messages' in out


def test_small_loss_is_a_warning_and_a_large_one_refused(tmp_path, capsys):
    import shutil
    from gyro_tdc.cli.train import main
    bag = _heat_bag(tmp_path / 'small')
    big = tmp_path / 'big'
    shutil.copytree(bag, big)
    _delete_imu_rows(bag, 36)                           # 0.1 %: reported, used
    _delete_imu_rows(big, 720)                          # 2 %: refused
    rc, out, err = _cli(capsys, main, [bag, '--out', tmp_path / 'm.yaml', '--no-progress'])
    assert rc == 0, err
    assert 'warning: ' in out and '/imu/data_raw: read 35964 of 36000 messages' in out
    rc, out, err = _cli(capsys, main, [big, '--out', tmp_path / 'm2.yaml', '--no-progress'])
    assert rc == 2 and 'read 35280 of 36000 messages' in _one_error_line(err)
    assert 'more than the 1 % allowed' in err


def _outliers(imu, temp):
    temp['c'][100] = 1e30
    temp['c'][200] = 1e300
    imu['gyro'][5000, 0] = 1e300
    imu['gyro'][6000, 2] = -1e300


def test_absurd_values_are_dropped_and_counted_at_load(tmp_path):
    from gyro_tdc.data.dataset import load_run
    run = load_run(_heat_bag(tmp_path / 'bag', edit=_outliers))
    rej = run.info['rejected']
    assert rej['temp_implausible'] == 2 and rej['imu_implausible'] == 2
    assert np.all(np.abs(run.omega) < 1.0) and np.all(np.abs(run.temp) < 100.0)


def test_train_and_discover_survive_one_finite_outlier(tmp_path, capsys):
    from gyro_tdc.cli.discover import main as discover
    from gyro_tdc.cli.train import main as train
    bag = _heat_bag(tmp_path / 'bag', edit=_outliers)
    rc, out, err = _cli(capsys, train, [bag, '--out', tmp_path / 'm.yaml', '--no-progress'])
    assert rc == 0, err
    assert 'dropped 2 IMU samples above 100 rad/s; 2 temperature readings outside' in out
    model = load_model(tmp_path / 'm.yaml')
    assert np.all(np.isfinite(model.residual_var)) and np.all(model.residual_var < 1e-3)
    rc, out, err = _cli(capsys, discover, [bag, '--json', tmp_path / 'd.json', '--no-progress'])
    assert rc == 0, err


@pytest.mark.parametrize('command', ['train', 'evaluate', 'discover'])
def test_the_same_bag_twice_is_refused(tmp_path, capsys, heat_bag, command):
    import importlib
    main = importlib.import_module(f'gyro_tdc.cli.{command}').main
    extra = {'train': ['--out', tmp_path / 'm.yaml'],
             'evaluate': ['--model', 'l3gd20_modified'], 'discover': []}[command]
    folder = tmp_path / 'runs'
    folder.mkdir()
    (folder / 'run1').symlink_to(heat_bag)
    for bags in ([heat_bag, heat_bag], [folder, heat_bag], [heat_bag, heat_bag / '.']):
        rc, out, err = _cli(capsys, main, [*bags, *extra, '--no-progress'])
        assert rc == 2 and 'is given twice' in _one_error_line(err), err
        assert 'read ' not in out                        # refused before reading a bag


def test_conflicting_temperature_stamps_keep_the_last_and_warn(tmp_path):
    from gyro_tdc.data.dataset import load_run

    def dup(imu, temp):
        temp['t'] = np.insert(temp['t'], 51, temp['t'][50])
        temp['c'] = np.insert(temp['c'], 51, temp['c'][50] + 1.5)   # within the slew margin

    run = load_run(_heat_bag(tmp_path / 'bag', edit=dup))
    assert run.info['rejected']['temp_duplicate_stamps'] == 1
    (warning,) = run.info['warnings']
    assert '1 stamp(s) carry conflicting temperature readings; kept the last' in warning


# --------------------------------------------------------------------------------------------
# Item 8: options that size arrays are checked before any memory is spent
# Items 1 and 11 at the command line: one line, exit 2, nothing left behind
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('option, needle', [
    (['--bin', '1e-7'], '--bin 1e-07 degC makes up to 3e+09 coverage bins'),
    (['--centers', '1000000'], '--centers 1000000: at most 10000 RBF centres'),
])
def test_train_options_sizing_arrays_are_refused_before_reading(tmp_path, capsys, heat_bag,
                                                                option, needle):
    from gyro_tdc.cli.train import main
    rc, out, err = _cli(capsys, main, [heat_bag, '--out', tmp_path / 'm.yaml', *option,
                                       '--no-progress'])
    assert rc == 2 and needle in _one_error_line(err)
    assert 'read ' not in out and not (tmp_path / 'm.yaml').exists()


def test_simulate_rate_that_needs_terabytes_is_refused_upfront(tmp_path, capsys):
    from gyro_tdc.cli.simulate import main
    rc, _, err = _cli(capsys, main, ['--scenario', 'l3gd20_paper', '--out', tmp_path / 'b',
                                     '--rate-hz', '1e6'])
    line = _one_error_line(err)
    assert rc == 2 and '--rate-hz 1e+06: 2.92e+10 IMU samples per run' in line
    assert 'GB' in line and 'at most 2e+07 samples per run' in line
    assert list(tmp_path.iterdir()) == []


def _two_run_scenario(tmp_path: Path) -> Path:
    from gyro_tdc.base.resources import scenario_path
    text = scenario_path('demo_fast').read_text().replace('count: 1', 'count: 2')
    path = tmp_path / 'two.yaml'
    path.write_text(text)
    return path


@pytest.mark.parametrize('exc', [OSError(errno.ENOSPC, 'No space left on device'),
                                 KeyboardInterrupt()])
def test_failed_simulate_leaves_no_bag_behind(tmp_path, exc):
    from gyro_tdc.cli.simulate import simulate
    out = tmp_path / 'out' / 'bags'
    logged = []

    def log(line):                       # fails after the first of two bags is written
        logged.append(line)
        raise exc

    with pytest.raises((OutputError, KeyboardInterrupt)):
        simulate(_two_run_scenario(tmp_path), out, log=log)
    assert len(logged) == 1 and str(out / 'run1') in logged[0]
    assert list((tmp_path / 'out').iterdir()) == []
    paths = simulate(_two_run_scenario(tmp_path), out, log=lambda line: None)
    assert paths == [out / 'run1', out / 'run2']
    assert all((p / 'metadata.yaml').is_file() for p in paths)
    assert [p.name for p in (tmp_path / 'out').iterdir()] == ['bags']


def test_discover_block_longer_than_the_data_is_refused_in_bounded_memory(tmp_path, capsys,
                                                                          heat_bag):
    from gyro_tdc.cli.discover import main
    tracemalloc.start()
    try:
        rc, _, err = _cli(capsys, main, [heat_bag, '--block-s', '1e9', '--no-progress'])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rc == 2 and 'Too few blocks' in _one_error_line(err)
    assert peak < 300e6, peak               # was a 14.9 GiB np.ones(block)


def test_deep_model_and_scenario_files_at_the_command_line(tmp_path, capsys, heat_bag):
    from gyro_tdc.cli.evaluate import main as evaluate
    from gyro_tdc.cli.simulate import main as simulate
    deep = tmp_path / 'deep.yaml'
    deep.write_text(DEEP)
    rc, _, err = _cli(capsys, evaluate, [heat_bag, '--model', deep, '--no-progress'])
    assert rc == 2 and 'nesting deeper than 32 levels' in _one_error_line(err)
    rc, _, err = _cli(capsys, simulate, ['--scenario', deep, '--out', tmp_path / 'b'])
    assert rc == 2 and 'nesting deeper than 64 levels' in _one_error_line(err)
    bomb = tmp_path / 'bomb.yaml'
    bomb.write_text(alias_bomb(9))
    rc, _, err = _cli(capsys, evaluate, [heat_bag, '--model', bomb, '--no-progress'])
    assert rc == 2 and 'aliases are not allowed' in _one_error_line(err)


def test_block_sum_of_a_block_longer_than_the_data_allocates_nothing_big():
    from gyro_tdc.signal.blocks import block_sum
    a = np.arange(12.0).reshape(4, 3)
    tracemalloc.start()
    try:
        kept = block_sum(a, 10**9)
        dropped = block_sum(a, 10**9, partial=False)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1e6
    np.testing.assert_array_equal(kept, a.sum(axis=0, keepdims=True))
    assert dropped.shape == (0, 3)
    assert block_sum(np.zeros(0), 5).shape == (0,)
