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

"""Tests of gyro_tdc.data.dataset (alignment, load_run)."""

from __future__ import annotations

import re

from gyro_tdc.data import IMU_TYPE, TEMPERATURE_TYPE, write_bag
from gyro_tdc.data.dataset import align_temperature, load_run, load_runs
from gyro_tdc.data.options import BagOptions
from gyro_tdc.data.runs import Run
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest
from rosbags.rosbag2 import Writer
from rosbags.typesys import get_typestore, Stores

TS = get_typestore(Stores.ROS2_JAZZY)


def _ramp(t):
    """Return a piecewise-linear temperature, exact under linear interpolation at knots."""
    return 20.0 + 0.01 * (t - 100.0)


# ------------------------------------------------------------------------------------------
# align_temperature
# ------------------------------------------------------------------------------------------

def test_align_different_rates_is_linear_interpolation():
    imu_t = 100.0 + np.arange(0, 60_000) * 1e-3      # 1 kHz for 60 s
    temp_t = 100.0 + np.arange(0, 61) * 1.0          # 1 Hz
    temp, valid = align_temperature(imu_t, temp_t, _ramp(temp_t))
    assert valid.all()
    np.testing.assert_allclose(temp, _ramp(imu_t), rtol=0, atol=1e-12)


def test_align_outside_span_and_gaps_are_invalid():
    imu_t = np.arange(0.0, 60.0, 0.01)
    temp_t = np.concatenate([np.arange(5.0, 20.0, 1.0), np.arange(40.0, 51.0, 1.0)])
    temp, valid = align_temperature(imu_t, temp_t, _ramp(temp_t), max_gap_s=5.0)
    near = (imu_t <= 24.0) | (imu_t >= 35.0)           # within 5 s of 19 s or of 40 s
    expected = (imu_t >= 5.0) & (imu_t <= 50.0) & near
    np.testing.assert_array_equal(valid, expected)
    assert np.isnan(temp[~valid]).all()
    np.testing.assert_allclose(temp[valid], _ramp(imu_t[valid]), atol=1e-12)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_align_sorted_fast_path_equals_general_path(seed):
    # Sorted IMU stamps take the per-knot path; the same stamps shuffled take the
    # per-sample path. Irregular thermometer with long gaps, stamps on the knots and on
    # the gap boundaries, samples before and after the span.
    rng = np.random.default_rng(seed)
    temp_t = np.cumsum(rng.choice([0.5, 1.0, 3.0, 12.0, 40.0], size=200))
    temp_c = 20.0 + np.cumsum(rng.normal(0.0, 0.1, temp_t.size))
    imu_t = np.sort(np.concatenate([
        rng.uniform(temp_t[0] - 20.0, temp_t[-1] + 20.0, 20_000), temp_t[::3],
        temp_t[:-1] + 5.0, temp_t[1:] - 5.0]))
    temp, valid = align_temperature(imu_t, temp_t, temp_c, max_gap_s=5.0)
    shuffle = rng.permutation(imu_t.size)
    temp2, valid2 = align_temperature(imu_t[shuffle], temp_t, temp_c, max_gap_s=5.0)
    back = np.empty_like(shuffle)
    back[shuffle] = np.arange(shuffle.size)
    np.testing.assert_array_equal(valid, valid2[back])
    assert 0 < np.count_nonzero(~valid) < valid.size
    np.testing.assert_allclose(temp, temp2[back], rtol=0, atol=1e-12, equal_nan=True)
    on_knot = np.isin(imu_t, temp_t)
    knot = np.searchsorted(temp_t, imu_t[on_knot])
    np.testing.assert_array_equal(temp[on_knot], temp_c[knot])


def test_align_sorts_out_of_order_and_keeps_the_last_duplicate():
    rng = np.random.default_rng(4)
    temp_t = np.arange(0.0, 30.0, 1.0)
    temp_c = _ramp(temp_t)
    order = rng.permutation(len(temp_t))
    imu_t = np.sort(rng.uniform(0.0, 29.0, 500))
    ref, _ = align_temperature(imu_t, temp_t, temp_c)
    temp_t2 = np.concatenate([temp_t[order], [10.0]])
    temp_c2 = np.concatenate([temp_c[order], [temp_c[10] + 2.0]])   # duplicate stamp
    temp, valid, counts = align_temperature(imu_t, temp_t2, temp_c2, return_counts=True)
    assert valid.all()
    assert counts['duplicates'] == 1 and counts['out_of_order'] > 0
    assert counts['conflicting'] == 1
    fixed = temp_c.copy()
    fixed[10] += 2.0                                  # the last reading given at 10 s
    np.testing.assert_allclose(temp, np.interp(imu_t, temp_t, fixed), atol=1e-12)
    assert not np.allclose(temp, ref)


def test_align_rejects_and_counts_nonfinite():
    temp_t = np.arange(0.0, 10.0, 1.0)
    temp_c = _ramp(temp_t)
    temp_c[3] = np.nan
    temp_c[6] = np.inf
    temp_t = temp_t.copy()
    temp_t[8] = np.nan
    imu_t = np.arange(0.0, 9.0, 0.1)
    temp, valid, counts = align_temperature(imu_t, temp_t, temp_c, return_counts=True)
    assert counts == {'nonfinite': 3, 'out_of_order': 0, 'duplicates': 0, 'conflicting': 0}
    assert valid.all() and np.isfinite(temp).all()
    np.testing.assert_allclose(temp, _ramp(imu_t), atol=1e-12)   # a ramp survives the holes


def test_align_with_no_thermometer_sample():
    temp, valid = align_temperature([1.0, 2.0], [np.nan], [20.0])
    assert not valid.any() and np.isnan(temp).all()
    temp, valid = align_temperature([1.0, 2.0], [], [])
    assert not valid.any()


def test_align_bad_arguments():
    with pytest.raises(DatasetError, match=r'`temp_c` to have shape \(3,\)'):
        align_temperature([0.0], [0.0, 1.0, 2.0], [1.0, 2.0])
    with pytest.raises(DatasetError, match=r'`imu_t` to have shape \(N,\)'):
        align_temperature(np.zeros((2, 2)), [0.0], [1.0])
    with pytest.raises(DatasetError, match='`max_gap_s` to be a positive number'):
        align_temperature([0.0], [0.0], [1.0], max_gap_s=0.0)


# ------------------------------------------------------------------------------------------
# load_run
# ------------------------------------------------------------------------------------------

def _bag(path, *, storage='sqlite3', n=5000, rate=1000.0, seed=2, **kw):
    rng = np.random.default_rng(seed)
    imu_t = 100.0 + np.arange(n) / rate
    temp_t = np.arange(100.0, imu_t[-1] + 1.0, 1.0)
    args = dict(imu_t=imu_t, gyro=1e-3 * rng.normal(size=(n, 3)), accel=rng.normal(size=(n, 3)),
                temp_t=temp_t, temp_c=_ramp(temp_t))
    args.update(kw)
    write_bag(path, storage=storage, **args)
    return args


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_load_run_reference_sources(tmp_path, storage):
    ref_t = np.array([99.0, 102.0, 103.5])
    ref = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5], [0.1, 0.0, -0.5]])
    args = _bag(tmp_path / 'bag', storage=storage, ref_t=ref_t, ref=ref)
    run = load_run(tmp_path / 'bag')
    assert isinstance(run, Run) and run.name == str(tmp_path / 'bag')
    assert len(run) == 5000 and run.info['reference'] == 'topic'
    assert set(run.info['rejected'].values()) == {0}
    np.testing.assert_array_equal(run.omega, args['gyro'])
    np.testing.assert_allclose(run.temp, _ramp(args['imu_t']), atol=1e-9)
    held = ref[np.searchsorted(ref_t, run.t, side='right') - 1]
    np.testing.assert_array_equal(run.omega_ref, held)
    assert run.omega_ref[2000].tolist() == [0.0, 0.0, 0.5]   # t = 102.0 s exactly

    const = load_run(tmp_path / 'bag', BagOptions(reference=(0.0, 0.0, 0.25)))
    assert const.info['reference'] == 'constant'
    np.testing.assert_array_equal(const.omega_ref, np.tile([0.0, 0.0, 0.25], (5000, 1)))

    _bag(tmp_path / 'noref', storage=storage)
    zero = load_run(tmp_path / 'noref')
    assert zero.info['reference'] == 'zero' and not zero.omega_ref.any()
    lines = []
    runs = load_runs([tmp_path / 'bag', tmp_path / 'noref'], BagOptions(reference=(0, 0, 0)),
                     log=lines.append)
    assert [r.name for r in runs] == [str(tmp_path / 'bag'), str(tmp_path / 'noref')]
    assert [r.info['reference'] for r in runs] == ['constant', 'constant']
    assert all('constant reference rate' in line for line in lines) and len(lines) == 2
    # The reference topic the options name is the one read (and named when missing).
    other = load_runs(tmp_path / 'bag', BagOptions(reference_topic='/other'), log=lines.append)
    assert other[0].info['reference'] == 'zero' and lines[-1].endswith('(no /other in the bag)')


def test_load_run_drops_and_counts_bad_samples(tmp_path):
    n = 3000
    rng = np.random.default_rng(8)
    imu_t = 100.0 + np.arange(n) * 1e-2
    imu_t[1000] = imu_t[999]                         # duplicate stamp
    gyro = rng.normal(size=(n, 3))
    gyro[[10, 20, 30], [0, 1, 2]] = [np.nan, np.inf, -np.inf]
    temp_t = np.arange(105.0, 131.0, 1.0)            # starts 5 s after the IMU
    temp_c = _ramp(temp_t)
    temp_c[4] = np.nan
    ref_t, ref = np.array([101.0]), np.array([[0.0, 0.0, 1.0]])
    write_bag(tmp_path / 'bag', imu_t=imu_t, gyro=gyro, accel=np.zeros((n, 3)), temp_t=temp_t,
              temp_c=temp_c, ref_t=ref_t, ref=ref)
    run = load_run(tmp_path / 'bag')
    rej = run.info['rejected']
    assert rej['imu_nonfinite'] == 3 and rej['temp_nonfinite'] == 1
    assert rej['duplicate_stamps'] == 1
    # IMU before 105 s (500 samples, three of them non-finite and dropped earlier) have no
    # temperature; the samples after the last thermometer sample (130 s) neither.
    assert rej['no_temperature'] == 500 - 3 + int(np.sum(imu_t > 130.0))
    assert rej['no_reference'] == 0                  # all before 101 s already lack temperature
    assert np.all(np.diff(run.t) > 0) and np.isfinite(run.omega).all()
    assert run.t[0] == pytest.approx(105.0) and run.t[-1] <= 130.0
    assert len(run) == n - 3 - 1 - rej['no_temperature']
    np.testing.assert_allclose(run.temp, _ramp(run.t), atol=1e-9)
    assert run.info['samples_read'] == n


def test_load_run_sorts_out_of_order_header_stamps(tmp_path):
    """Header stamps out of order (log times in order) are sorted; duplicates keep the first."""
    rng = np.random.default_rng(6)
    header_t = 10.0 + np.arange(200) * 0.01
    header_t[[50, 51]] = header_t[[51, 50]]          # swapped pair
    header_t[120] = header_t[119]                    # duplicate; the first one wins
    gyro = rng.normal(size=(200, 3))
    types = TS.types
    with Writer(tmp_path / 'bag', version=9) as writer:
        imu = writer.add_connection('/imu/data_raw', IMU_TYPE, typestore=TS)
        temp = writer.add_connection('/imu/temperature', TEMPERATURE_TYPE, typestore=TS)
        for k, t in enumerate([9.0, 13.0]):
            writer.write(temp, int(t * 1e9), bytes(TS.serialize_cdr(types[TEMPERATURE_TYPE](
                types['std_msgs/msg/Header'](types['builtin_interfaces/msg/Time'](int(t), 0),
                                             'imu'), 20.0 + k, 0.0), TEMPERATURE_TYPE)))
        vec = types['geometry_msgs/msg/Vector3']
        for i in range(200):
            sec = int(np.floor(header_t[i]))
            nsec = int(round((header_t[i] - sec) * 1e9))
            msg = types[IMU_TYPE](
                types['std_msgs/msg/Header'](types['builtin_interfaces/msg/Time'](sec, nsec),
                                             'imu'),
                types['geometry_msgs/msg/Quaternion'](0.0, 0.0, 0.0, 1.0), np.zeros(9),
                vec(*gyro[i]), np.zeros(9), vec(0.0, 0.0, 0.0), np.zeros(9))
            writer.write(imu, int(9.5e9) + i * 10**7, bytes(TS.serialize_cdr(msg, IMU_TYPE)))
    run = load_run(tmp_path / 'bag')
    assert run.info['rejected']['out_of_order'] == 1
    assert run.info['rejected']['duplicate_stamps'] == 1
    assert len(run) == 199 and np.all(np.diff(run.t) > 0)
    expected = np.delete(gyro[np.argsort(header_t, kind='stable')],
                         np.argsort(header_t, kind='stable').tolist().index(120), axis=0)
    np.testing.assert_array_equal(run.omega, expected)


def test_load_run_errors(tmp_path):
    with pytest.raises(DatasetError, match='does not exist'):
        load_run(tmp_path / 'missing')
    _bag(tmp_path / 'bag', n=100)
    with pytest.raises(DatasetError, match=r'`reference` to be three finite rates'):
        BagOptions(reference=(0.0, 1.0))
    with pytest.raises(DatasetError, match=r'`reference` to be three finite rates'):
        BagOptions(reference=(0.0, 1.0, float('nan')))
    with pytest.raises(DatasetError, match="no topic '/temp'.*/imu/temperature"):
        load_run(tmp_path / 'bag', BagOptions(temperature_topic='/temp'))
    write_bag(tmp_path / 'apart', imu_t=[0.0, 0.1], gyro=np.zeros((2, 3)),
              accel=np.zeros((2, 3)), temp_t=[50.0, 51.0], temp_c=[20.0, 20.0])
    with pytest.raises(DatasetError, match='no usable sample') as err:
        load_run(tmp_path / 'apart')
    # What was rejected, by name and count; no reason that rejected nothing.
    assert re.search(r'rejected: (\d+ \w+, )*\d+ no_temperature', str(err.value))
    assert ': 0' not in str(err.value) and ' 0 ' not in str(err.value)


def test_load_run_drops_a_thermometer_jump_as_the_node_does(tmp_path):
    """The trainer's gate is the node's: in range but 80 degC in 1 s is dropped and counted."""
    temp_t = np.arange(100.0, 106.0, 1.0)
    temp_c = _ramp(temp_t)
    temp_c[2] = 100.0                   # 80 degC above its neighbours, 1 s after the last
    _bag(tmp_path / 'bag', temp_t=temp_t, temp_c=temp_c)
    run = load_run(tmp_path / 'bag', BagOptions(reference=(0.0, 0.0, 0.0)))
    assert run.info['rejected']['temp_implausible'] == 1
    assert np.abs(run.temp - 20.0).max() < 0.1


def test_a_kept_run_of_rows_is_a_slice_and_a_gapped_one_stays_an_index():
    """load_run keeps one contiguous run of samples as views; the values are the same."""
    from gyro_tdc.data.dataset import _as_slice
    x = np.arange(20.0)
    mask = np.zeros(20, dtype=bool)
    mask[3:17] = True
    kept = _as_slice(mask)
    assert kept == slice(3, 17)
    assert np.shares_memory(x[kept], x) and np.array_equal(x[kept], x[mask])
    mask[8] = False
    assert _as_slice(mask) is mask
    assert _as_slice(np.array([2, 3, 4])) == slice(2, 5)
    rows = np.array([2, 4, 3])          # the same span, out of order: not a slice
    assert _as_slice(rows) is rows
    assert _as_slice(np.zeros(4, dtype=bool)).dtype == bool


def test_a_folder_is_walked_and_what_it_holds_that_cannot_be_read_is_skipped(tmp_path):
    from flightlogs import sd_card
    from gyro_tdc.data.dataset import find_bags, iter_runs
    good, bad = sd_card(tmp_path / 'card')
    (tmp_path / 'card' / 'run10.bin').write_bytes(good[1].read_bytes())
    day = tmp_path / 'card' / 'log' / '2024-05-01'
    assert find_bags([tmp_path / 'card']) == [
        (tmp_path / 'card' / 'empty.BIN', True), (day / 'run0.ulg', True),
        (day / 'run2.ulg', True), (tmp_path / 'card' / 'run1.bin', True),
        (tmp_path / 'card' / 'run10.bin', True)]
    assert find_bags([good[0]]) == [(good[0], False)]
    said = []
    runs = load_runs(tmp_path / 'card', log=said.append)
    assert [r.name for r in runs] == [str(day / 'run0.ulg'), str(good[1]),
                                      str(tmp_path / 'card' / 'run10.bin')]
    skips = [ln for ln in said if ln.startswith('warning: skipped')]
    assert len(skips) == 2 and skips[0].startswith(f'warning: skipped {bad[1]}: ')
    assert skips[1].startswith(f'warning: skipped {bad[0]}: ')
    assert 'damaged bytes inside the log' in skips[1]
    assert said[-1] == ('read 3 of the 5 bags and logs, skipped 2 that cannot be read '
                        '(each named above)')
    assert len(load_runs(tmp_path / 'card')) == 3        # no log: skipped all the same
    with pytest.raises(DatasetError, match='damaged bytes inside the log'):
        load_runs([good[0], bad[0]])                       # named: refused
    runs = iter_runs([bad[1].parent / 'log'])            # one at a time: the good one first
    assert next(runs).name == str(day / 'run0.ulg')
    with pytest.raises(StopIteration):
        next(runs)
    only_bad = tmp_path / 'bad'
    only_bad.mkdir()
    (only_bad / 'empty.BIN').write_bytes(b'')
    with pytest.raises(DatasetError, match=r'None of the 1 bags and logs found can be read '
                                           r'\(the first: .*empty\.BIN'):
        load_runs(only_bad)


@pytest.mark.parametrize('storage, meta', [('sqlite3', 'no'), ('mcap', 'no'),
                                           ('mcap', 'an empty')])
def test_a_walk_reads_a_bag_that_lost_its_metadata_yaml(tmp_path, storage, meta):
    # A robot's bag folder after a power loss: one bag closed, one without metadata.yaml
    # or with an empty one (the power went as rosbag2 wrote it at close; its storage file
    # as rosbag2 names it), and a folder of notes that is no bag.
    from gyro_tdc.data.dataset import find_bags
    ext = '.db3' if storage == 'sqlite3' else '.mcap'
    root = tmp_path / 'bags'
    _bag(root / 'closed', storage=storage, n=2000)
    _bag(root / 'cut', storage=storage, n=3000, seed=5)
    (root / 'cut' / f'cut{ext}').rename(root / 'cut' / f'cut_0{ext}')
    (root / 'cut' / 'metadata.yaml').unlink()
    if meta == 'an empty':
        (root / 'cut' / 'metadata.yaml').write_bytes(b'')
    (root / 'notes').mkdir()
    (root / 'notes' / 'trip_1.mcap').write_bytes(b'not a bag')
    (root / 'notes' / 'readme.txt').write_text('flight notes')
    assert find_bags([root]) == [(root / 'closed', True), (root / 'cut', True)]
    said = []
    runs = load_runs(root, log=said.append)
    assert [len(r.t) for r in runs] == [2000, 3000]
    assert runs[1].info['warnings'][0].startswith(f'{meta} metadata.yaml (the recording did '
                                                  'not close: rosbag2 writes it then): read '
                                                  f'from cut_0{ext}')
    assert any(ln.startswith(f'warning: {root / "cut"}: {meta} metadata.yaml') for ln in said)
    assert sorted(p.name for p in (root / 'cut').iterdir()) == [f'cut_0{ext}'] + (
        ['metadata.yaml'] if meta == 'an empty' else [])
    with pytest.raises(DatasetError, match=r'no metadata\.yaml, and not only storage files '
                                           r'named NAME_N\.db3 or NAME_N\.mcap \(found '
                                           r"\['readme\.txt', 'trip_1\.mcap'\]\)"):
        load_runs(root / 'notes')
