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

"""The learner's records (``learn.records``): the open stretch and the held-out line."""

from __future__ import annotations

import math

from gyro_tdc.learn.records import held_out_line, OpenStretch
from gyro_tdc.signal import Window


def _win(t0, t1, n):
    return Window(t0, t1, n, (0.0,) * 3, (0.0,) * 3, None, None, 20.0, False, '', ((), ()),
                  None, None)


def test_the_open_stretch_spans_its_windows_and_keeps_the_newest():
    st = OpenStretch()
    assert st.span() == 0.0 and math.isnan(st.t0)
    for k in range(3):
        st.add(_win(10.0 * k, 10.0 * k + 9.9, 100))
    assert st.t0 == 0.0 and st.n == 300
    assert st.span() == (29.9 + 29.9 / 299)           # one sample period included
    st.keep_from(1)
    assert st.t0 == 10.0 and st.n == 200 and len(st.rows) == 2
    st.learned = True
    st.rows = []
    st.add(_win(30.0, 39.9, 100))                     # learned in part: the first stamp stays
    assert st.t0 == 10.0


def test_the_held_out_line_says_what_was_judged_and_what_was_chosen():
    assert held_out_line(None) == 'no learned model yet'
    assert held_out_line({'held_out': None}) == 'no curve'
    rec = {'sessions': 1, 'folds': 0, 'points': 0, 'curve_ms_dps2': None,
           'offset_ms_dps2': None, 'offset_only': []}
    line = held_out_line({'held_out': rec})
    assert line.startswith('not judged (1 session(s)') and 'the curve is kept' in line
    rec = {**rec, 'sessions': 3, 'folds': 3, 'points': 40, 'curve_ms_dps2': [2e-4, 1e-5, 3e-6],
           'offset_ms_dps2': [1e-4, 4e-5, 3e-6], 'offset_only': ['x', 'z']}
    line = held_out_line({'held_out': rec})
    assert 'held out on 3 of 3 power cycles (40 points)' in line
    assert 'x 0.0002 vs 0.0001' in line and 'offset only on x, z' in line
    assert '\n' not in line
    line = held_out_line({'held_out': {**rec, 'offset_only': []}})
    assert line.endswith('the curve is kept on every axis')


def test_the_held_out_line_says_when_short_power_cycles_left_the_offset_only():
    rec = {'sessions': 2, 'folds': 0, 'points': 0, 'curve_ms_dps2': None,
           'offset_ms_dps2': None, 'offset_only': ['x', 'y', 'z']}
    line = held_out_line({'held_out': rec})
    assert line == ('not judged (2 session(s), no other power cycle over the same '
                    'temperatures), and none spans 2 degC of its own: offset only on every '
                    'axis, each power-up re-anchored')
