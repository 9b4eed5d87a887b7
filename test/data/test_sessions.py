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

"""Tests of gyro_tdc.data.sessions: gaps, bursts, restarts and the three modes."""

from __future__ import annotations

from dataclasses import replace

from gyro_tdc.data import BagOptions
from gyro_tdc.data import dataset
from gyro_tdc.data.bag.reader import BagData
from gyro_tdc.data.runs import Run
from gyro_tdc.data.sessions import (find_breaks, session_gap, SESSION_GAP_S, split_sessions)
from gyro_tdc.errors import DatasetError
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest


def _run(t, name='bag', **info):
    t = np.asarray(t, dtype=float)
    n = t.size
    return Run(t, 20.0 + 0.001 * np.arange(n), np.zeros((n, 3)), np.zeros((n, 3)), name,
               dict(info))


def test_a_continuous_run_is_one_session():
    run = _run(np.arange(0.0, 3600.0, 0.1))
    assert find_breaks(run) == []
    split = split_sessions([run])
    assert split.count == 1 and split.runs[0] is run and split.labels == [0]
    assert split.sessions[0].why == 'bag' and split.sessions[0].samples == len(run)


def test_a_long_gap_starts_a_session_and_names_the_parts():
    t = np.concatenate([np.arange(0.0, 600.0, 1.0), 2000.0 + np.arange(0.0, 600.0, 1.0)])
    run = _run(t)
    assert find_breaks(run) == [(600, 'gap of 1401 s')]
    split = split_sessions([run])
    assert [r.name for r in split.runs] == ['bag@1', 'bag@2']
    assert split.labels == [0, 1] and [len(r) for r in split.runs] == [600, 600]
    assert split.sessions[1].why == 'gap of 1401 s' and split.sessions[1].start_s == 2000.0
    assert 'bag: gap of 1401 s at t = 2000.0 s' in '\n'.join(split.lines())


def test_the_gap_threshold_follows_the_rate_and_the_option():
    slow = np.arange(0.0, 36000.0, 10.0)                     # 0.1 Hz: 100 periods = 1000 s
    assert session_gap(slow) == pytest.approx(1000.0)
    assert session_gap(np.arange(0.0, 100.0, 0.01)) == SESSION_GAP_S
    t = np.concatenate([np.arange(0.0, 100.0, 1.0), 400.0 + np.arange(0.0, 100.0, 1.0)])
    assert find_breaks(_run(t)) == []                          # 301 s: below 600 s
    assert find_breaks(_run(t), gap_s=60.0) == [(100, 'gap of 301 s')]


def test_a_bursty_log_is_not_cut_at_its_own_rhythm_but_at_a_longer_pause():
    bursts = [k * 305.0 + np.arange(0.0, 5.0, 0.02) for k in range(25)]
    run = _run(np.concatenate(bursts))                         # PAN-like: 5 s every 305 s
    assert session_gap(run.t) == pytest.approx(3 * 300.02, rel=1e-3)
    assert find_breaks(run) == []
    late = [b + (5000.0 if k >= 20 else 0.0) for k, b in enumerate(bursts)]
    assert [why for _, why in find_breaks(_run(np.concatenate(late)))] == ['gap of 5300 s']


def test_restarts_recorded_by_the_reader_start_sessions():
    run = _run(np.arange(0.0, 100.0, 1.0), restarts=[[40, 3600.0]])
    assert find_breaks(run) == [(40, 'restart (stamps back by 3600 s)')]
    split = split_sessions([run])
    assert [len(r) for r in split.runs] == [40, 60]
    assert 'restarts' not in split.runs[1].info


def test_modes_bag_and_none_keep_the_runs_whole_and_report_the_breaks():
    t = np.concatenate([np.arange(0.0, 100.0, 1.0), 5000.0 + np.arange(0.0, 100.0, 1.0)])
    a, b = _run(t, 'a'), _run(np.arange(0.0, 50.0, 1.0), 'b')
    per_bag = split_sessions([a, b], 'bag')
    assert per_bag.runs == [a, b] and per_bag.labels == [0, 1] and per_bag.count == 2
    assert any('not cut: --sessions bag' in line for line in per_bag.lines())
    one = split_sessions([a, b], 'none')
    assert one.runs == [a, b] and one.labels == [0, 0] and one.count == 1
    assert one.sessions[0].name == 'all' and one.sessions[0].samples == 250
    auto = split_sessions([a, b])
    assert auto.labels == [0, 1, 2] and [r.name for r in auto.runs] == ['a@1', 'a@2', 'b']


@pytest.mark.parametrize('kw, needle', [({'mode': 'split'}, '`sessions`'),
                                        ({'gap_s': -1.0}, '`session_gap_s`')])
def test_bad_choices_are_named(kw, needle):
    with pytest.raises(DatasetError, match=needle):
        split_sessions([_run([0.0, 1.0])], **kw)


def _data(imu_t, temp_t):
    n, m = len(imu_t), len(temp_t)
    return BagData(np.asarray(imu_t, float), np.zeros((n, 3)), None, 'imu_link',
                   np.asarray(temp_t, float), np.full(m, 20.0), np.zeros(m), None, None,
                   topics={}, rejected={'imu_nonfinite': 0, 'temp_nonfinite': 0,
                                        'ref_nonfinite': 0, 'undecodable': 0},
                   storage='sqlite3', path='fake')


def test_a_device_clock_restart_becomes_a_session(monkeypatch):
    # Stamps since boot: 100 s, then the device restarts at 0 s and runs 50 s more.
    imu = np.concatenate([np.arange(0.0, 100.0, 0.5), np.arange(0.0, 50.0, 0.5)])
    temp = np.concatenate([np.arange(0.0, 100.0, 1.0), np.arange(0.0, 50.0, 1.0)])
    monkeypatch.setattr(dataset, 'read_bag', lambda *a, **k: _data(imu, temp))
    monkeypatch.setattr(dataset, 'detect_format', lambda *a, **k: 'rosbag2')
    run = dataset.load_run('fake', replace(BagOptions(), max_loss=1.0))
    assert np.all(np.diff(run.t) > 0) and len(run) == 299     # the last: past the thermometer
    (i, back), = run.info['restarts']
    assert i == 200 and back == pytest.approx(99.5)
    assert run.t[200] - run.t[199] == pytest.approx(2 * 5.0 + 1.0)
    split = split_sessions([run])
    assert [len(r) for r in split.runs] == [200, 99]
    assert split.sessions[1].why == 'restart (stamps back by 100 s)'


def test_a_restart_the_thermometer_does_not_share_is_refused(monkeypatch):
    imu = np.concatenate([np.arange(0.0, 100.0, 0.5), np.arange(0.0, 50.0, 0.5)])
    temp = np.arange(0.0, 150.0, 1.0)                      # host-stamped: no restart
    monkeypatch.setattr(dataset, 'read_bag', lambda *a, **k: _data(imu, temp))
    monkeypatch.setattr(dataset, 'detect_format', lambda *a, **k: 'rosbag2')
    with pytest.raises(DatasetError, match='step back 1 time.*thermometer stamps 0 time'):
        dataset.load_run('fake', replace(BagOptions(), max_loss=1.0))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(steps=st.lists(st.one_of(st.floats(0.01, 2.0), st.floats(500.0, 5000.0)),
                      min_size=1, max_size=60),
       gap=st.sampled_from([0.0, 100.0, 1000.0]))
def test_cutting_keeps_every_sample_once_and_leaves_no_long_gap_inside(steps, gap):
    run = _run(np.concatenate([[0.0], np.cumsum(steps)]))
    split = split_sessions([run], gap_s=gap)
    limit = session_gap(run.t, gap)
    assert np.array_equal(np.concatenate([r.t for r in split.runs]), run.t)
    assert split.labels == list(range(split.count)) and len(split.runs) == split.count
    for piece, (j, a, b) in zip(split.runs, split.parts):
        assert j == 0 and np.array_equal(piece.t, run.t[a:b])
        assert not np.any(np.diff(piece.t) > limit)
    assert split.count == 1 + int(np.count_nonzero(np.diff(run.t) > limit))
