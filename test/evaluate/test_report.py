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

"""Tests of gyro_tdc.evaluate.report: tables, JSON and CSV from hand-made results; coverage."""

from __future__ import annotations

import json
import math

from gyro_tdc.data.coverage import Coverage
from gyro_tdc.evaluate.report import (csv_columns, evaluation_json, format_allan, format_bag,
                                      format_coverage, format_means, format_paper_table,
                                      format_still, format_summary, is_coverage_line, write_csv,
                                      write_json)
from gyro_tdc.evaluate.score import BagEval
from handmade_bag import handmade_bag, model_eval as _ev
import numpy as np
import pytest

DEG = math.pi / 180.0


@pytest.fixture
def bag():
    return handmade_bag()


def test_summary_table(bag):
    lines = format_summary(bag).splitlines()
    assert lines[0] == ('bag bags/run3: 50 samples over 24.50 h, temperature 20.00 .. 40.00 '
                        'degC, reference rate zero (no reference topic)')
    assert lines[1].startswith('  BS in (deg/s)^2 (paper eq. 30)')
    assert lines[2].split() == ['BS', 'x', 'BS', 'y', 'BS', 'z', 'RMS', 'x', 'RMS', 'y', 'RMS',
                                'z', 'BS/BS1', 'x', 'BS/BS1', 'y', 'BS/BS1', 'z']
    assert lines[3].split() == ['raw', '100', '100', '100', '10', '10', '10', '1', '1', '1']
    assert lines[4].split() == ['conv', '4', '2', '1', '2', '1.414', '1', '0.04', '0.02', '0.01']
    assert lines[6] == ('  note: 25 % of the samples lie outside the trained range of mod '
                        '[-10.00, 30.00] degC: the correction is held at the range end '
                        '(out-of-range policy clamp)')
    assert len(lines) == 7
    bag.duration_s = 6.0                    # a short bag in s, not "0.00 h"
    assert format_summary(bag).startswith('bag bags/run3: 50 samples over 6 s, temperature')


def test_paper_table_ratios(bag):
    lines = format_paper_table(bag, 0, 1).splitlines()
    assert lines[0] == ('  paper table (eq. 31-32), run3: BS1 raw, BS2 conv (conventional), '
                        'BS3 mod (modified); BS in (deg/s)^2')
    assert lines[1].split() == ['BS1', 'BS2', 'BS3', 'P1', 'P2', 'P3']
    # P1 = BS2/BS1, P2 = BS3/BS1, P3 = BS3/BS2 in %.
    assert lines[2].split() == ['x-axis', '100', '4', '1', '0.04', '0.01', '25.00%']
    assert lines[3].split() == ['y-axis', '100', '2', '1', '0.02', '0.01', '50.00%']
    assert lines[4].split() == ['z-axis', '100', '1', '0.5', '0.01', '0.005', '50.00%']


def test_allan_table_and_non_finite_numbers(bag):
    bag.models[0].bias_instability_deg_h = np.array([np.nan, 20.0, np.inf])
    lines = format_allan(bag).splitlines()
    assert 'ARW in deg/sqrt(h)' in lines[0] and 'BI in deg/h' in lines[0]
    assert lines[2].split() == ['raw', '1.5', '1.6', '1.7', '10', '20', '30']
    assert lines[3].split() == ['conv', '1.5', '1.6', '1.7', '-', '20', '-']


def test_bag_text_holds_a_paper_table_per_modified_model(bag):
    assert format_bag(bag) == format_summary(bag) + '\n' + format_allan(bag)
    assert format_bag(bag, 1) == '\n'.join([format_summary(bag), format_paper_table(bag, 1, 0),
                                            format_allan(bag)])
    bag.models.append(_ev('third', [2.0, 2.0, 2.0], [0.02] * 3))
    assert format_bag(bag, 0).count('paper table') == 2


def test_means_over_bags(bag):
    models = [_ev('conv', [2.0] * 3, [0.02] * 3), _ev('mod', [3.0] * 3, [0.03] * 3)]
    other = BagEval(bag='b2', label='b2', samples=1, temperature_c=(0.0, 1.0), duration_s=1.0,
                    reference='zero', raw=_ev('raw', [300.0] * 3, [1.0] * 3), models=models)
    lines = format_means([bag, other]).splitlines()
    assert lines[0] == 'mean over 2 bags: BS in (deg/s)^2 and BS/BS1'
    assert lines[2].split() == ['raw', '200', '200', '200', '1', '1', '1']
    assert lines[3].split() == ['conv', '3', '2', '1.5', '0.03', '0.02', '0.015']
    assert lines[4].split() == ['mod', '2', '2', '1.75', '0.02', '0.02', '0.0175']


def test_json_shape_and_nulls(bag, tmp_path):
    bag.models[1].bs = np.array([1.0, np.nan, np.inf])
    doc = evaluation_json([bag])
    assert list(doc) == ['bags', 'out_of_range'] and doc['out_of_range'] == 'clamp'
    b = doc['bags'][0]
    assert list(b) == ['bag', 'samples', 'temperature_c', 'raw', 'models']
    assert b['raw'] == {'bs': [100.0] * 3, 'accel_bs': None, 'rms_dps': [10.0] * 3}
    m = b['models'][1]
    assert list(m) == ['model', 'features', 'bs', 'accel_bs', 'rms_dps', 'p_vs_raw', 'adev']
    assert m['accel_bs'] is None
    assert m['bs'] == [1.0, None, None]
    assert m['adev'] == {'tau_s': [0.1, 1.0], 'dps': [[0.2, 0.3, 0.4], [0.02, 0.03, 0.04]]}
    path = write_json([bag], tmp_path / 'deep' / 'scores.json')
    assert json.loads(path.read_text()) == doc


def test_floor_columns_and_json_keys(bag, tmp_path):
    # A known white-noise floor per axis: every BS also as a multiple of it.
    bag.raw.accel_bs = np.array([4e-4, 8e-4, 2e-4])
    bag.models[0].accel_bs = np.array([2e-5, 4e-5, 1e-5])
    lines = format_summary(bag, floor=(0.5, 0.5, 0.5), accel_floor=(1e-5, 2e-5, 1e-5))
    lines = lines.splitlines()
    assert lines[1].endswith(', BS/fl against the floor 0.5 (deg/s)^2 (--floor)')
    assert lines[2].split()[-6:] == ['BS/fl', 'x', 'BS/fl', 'y', 'BS/fl', 'z']
    assert lines[3].split()[-3:] == ['200', '200', '200']
    assert lines[4].split()[-3:] == ['8', '4', '2']      # conv BS 4, 2, 1 over 0.5
    assert 'aBS/fl against the floor 1e-05, 2e-05, 1e-05 (m/s^2)^2' in lines[7]
    assert lines[8].split()[-6:] == ['aBS/fl', 'x', 'aBS/fl', 'y', 'aBS/fl', 'z']
    assert lines[9].split()[-3:] == ['40', '40', '20']
    assert lines[10].split()[-3:] == ['2', '2', '1']
    assert lines[11].split()[-3:] == ['-', '-', '-']     # no accelerometer part
    assert 'BS/fl' not in format_summary(bag)
    means = format_means([bag, bag], floor=(2.0, 2.0, 4.0)).splitlines()
    assert means[0].endswith(', BS/fl against the floor 2, 2, 4')
    assert means[3].split() == ['conv', '4', '2', '1', '0.04', '0.02', '0.01', '2', '1', '0.25']
    doc = evaluation_json([bag], floor=(0.5, 0.5, 0.5), accel_floor=(1e-5, 2e-5, 1e-5))
    assert list(doc) == ['bags', 'out_of_range', 'floor', 'accel_floor']
    assert doc['floor'] == [0.5] * 3 and doc['accel_floor'] == [1e-5, 2e-5, 1e-5]
    raw, conv, mod = doc['bags'][0]['raw'], *doc['bags'][0]['models']
    assert list(raw) == ['bs', 'bs_over_floor', 'accel_bs', 'accel_bs_over_floor', 'rms_dps']
    assert raw['bs_over_floor'] == [200.0] * 3
    assert raw['accel_bs_over_floor'] == pytest.approx([40.0, 40.0, 20.0])
    assert conv['bs_over_floor'] == [8.0, 4.0, 2.0]
    assert conv['accel_bs_over_floor'] == pytest.approx([2.0, 2.0, 1.0])
    assert mod['accel_bs'] is None and mod['accel_bs_over_floor'] is None
    path = write_json([bag], tmp_path / 'f.json', floor=(0.5, 0.5, 0.5))
    assert 'accel_floor' not in json.loads(path.read_text())


def test_csv_holds_every_sample(bag, tmp_path):
    path = write_csv(bag, tmp_path / 'csv', chunk=7)
    assert path == tmp_path / 'csv' / 'run3.csv'
    head, *rows = path.read_text().splitlines()
    assert head.split(',') == csv_columns(bag)
    assert csv_columns(bag)[:5] == ['t_s', 'temp_c', 'raw_x_rad_s', 'raw_y_rad_s',
                                    'raw_z_rad_s']
    assert csv_columns(bag)[-3:] == ['mod_x_rad_s', 'mod_y_rad_s', 'mod_z_rad_s']
    data = np.loadtxt(path, delimiter=',', skiprows=1)
    run = bag.run
    want = np.column_stack([run.t, run.temp, run.omega, run.omega_ref,
                            bag.models[0].omega, bag.models[1].omega])
    np.testing.assert_allclose(data[:, 0], want[:, 0], atol=1e-6)     # t: %.6f
    np.testing.assert_allclose(data[:, 1], want[:, 1], rtol=1e-5)     # temperature: %.6g
    np.testing.assert_allclose(data[:, 2:], want[:, 2:], rtol=1e-8)   # rates: %.9g
    bag.release()
    with pytest.raises(ValueError, match='released'):
        write_csv(bag, tmp_path)


def test_a_bag_scored_still_only_says_whose_every_figure_is(bag):
    # A hand-made still-only record: 20 of the 50 samples, 30 of 90 s, 25-30 of 20-40 degC.
    part = {'samples': 20, 'stretches': 2, 'still_s': 30.0, 'temperature_c': [25.0, 30.0],
            'total_samples': 50, 'total_s': 90.0, 'total_temperature_c': [20.0, 40.0],
            'share': 1.0 / 3.0}
    bag.still = {**part, 'sessions': 1, 'per_session': [part]}
    bag.samples, bag.temperature_c, bag.duration_s = 20, (25.0, 30.0), 30.0
    bag.raw.accel_bs = np.array([4e-4, 8e-4, 2e-4])
    lines = format_summary(bag).splitlines()
    assert lines[0] == ('bag bags/run3: scored 20 still samples over 30 s of still time at '
                        '25.00 .. 30.00 degC (the whole bag: 50 samples over 90 s at 20.00 .. '
                        '40.00 degC), reference rate zero (no reference topic)')
    assert lines[6] == ('  note: 25 % of the still samples scored lie outside the trained '
                        'range of mod [-10.00, 30.00] degC: the correction is held at the range '
                        'end (out-of-range policy clamp)')
    assert ("over the still samples of the whole bag by the accelerometer's still test"
            in lines[7])
    assert format_still(bag) == [
        'run3: no reference rate and the IMU moves: scored the still stretches only, 20 '
        'samples in 2 stretch(es), 30 s of 90 s (33.3 %), at 25.00 .. 30.00 degC; the whole '
        'bag: 50 samples at 20.00 .. 40.00 degC; raw and models re-anchored on the first '
        'still stretch of each of the 1 session(s), as the compensator does at start-up']
    assert format_allan(bag).splitlines()[-1] == (
        '  note: no Allan deviation on still stretches (the gaps between them break the time '
        'series)')
    bag.still['total_s'] = part['total_s'] = 3 * 3600.0     # long logs in min, then h
    assert 'the whole bag: 50 samples over 3.00 h at' in format_summary(bag)
    bag.duration_s = 600.0
    assert 'scored 20 still samples over 10.0 min of still time' in format_summary(bag)
    doc = evaluation_json([bag])['bags'][0]
    assert doc['samples'] == 20 and doc['temperature_c'] == [25.0, 30.0]
    assert doc['still']['total_temperature_c'] == [20.0, 40.0]
    assert doc['still']['sessions'] == [{k: part[k] for k in doc['still']['sessions'][0]}]
    assert list(doc['still']['sessions'][0]) == list(part)
    # A bag scored whole says none of it.
    bag.still = None
    assert 'note' not in format_allan(bag)
    assert 'still samples' not in format_summary(bag) and format_still(bag) == []


# The coverage table of the training report and its warnings.

def _coverage(**kw):
    c = dict(bin_c=5.0, edges=np.array([15.0, 20.0, 25.0, 30.0]),
             samples=np.array([100, 5, 300]), minutes=np.array([10.0, 0.5, 30.0]), sparse=[1],
             temp_range_c=(17.5, 29.0), heating_min=30.0, cooling_min=0.0, steady_min=10.5,
             threshold_c_per_min=0.05)
    c.update(kw)
    return Coverage(**c)


def test_coverage_table_and_warnings():
    table, warns = format_coverage(_coverage())
    lines = table.splitlines()
    assert lines[0] == 'temperature range covered: 17.50 .. 29.00 degC (span 11.50 degC)'
    # The bins in one line: count, least and most minutes (named), median, thin ones counted.
    assert lines[1] == ('coverage per 5 degC bin: 3 bins 15 .. 30 degC; minutes per bin 0.5 '
                        '([20, 25) degC) .. 30.0 ([25, 30) degC), median 10.0; 1 thin (named '
                        'in the warning below)')
    assert lines[2] == ('heating (dT/dt > +0.05 degC/min): 30.0 min; cooling (< -0.05): '
                        '0.0 min; steady: 10.5 min')
    assert len(lines) == 3 and all(is_coverage_line(line) for line in lines)
    assert len(warns) == 2
    assert warns[0].startswith('little data in temperature bin(s) [20, 25) degC')
    assert warns[1].startswith('no cooling data:')
    assert all(is_coverage_line(f'warning: {w}') for w in warns)
    assert not is_coverage_line('training bias stability BS, (deg/s)^2:')
    table, warns = format_coverage(_coverage(sparse=[], cooling_min=12.0))
    assert warns == [] and table.splitlines()[1].endswith('median 10.0; none thin')
    _, warns = format_coverage(_coverage(sparse=[], heating_min=0.0, cooling_min=30.0))
    assert warns[0].startswith('no heating data:')
    _, warns = format_coverage(_coverage(sparse=[], heating_min=0.0, cooling_min=0.0))
    assert warns == []                 # all steady: nothing to tell apart
