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

"""What the core hands its learner: block means at most max_rate_hz, never across a pause."""

from __future__ import annotations

from array import array
import math
from types import SimpleNamespace

from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.policy import Policy
import numpy as np


class _Sink:
    """The learner's face the core uses: a buffer, a thermometer, motion, a config."""

    def __init__(self, rate_hz=100.0):
        self.config = SimpleNamespace(max_rate_hz=rate_hz)
        self.buf = array('d')

    def add_temperature(self, t, temp_c):
        pass

    def observe_motion(self, t, moving):
        pass

    def rows(self):
        return np.asarray(self.buf).reshape(-1, 7)


def _feed(core, t, w, a=None):
    for k in range(t.size):
        core.process(float(t[k]), *w[k], None if a is None else a[k])


def test_a_fast_stream_is_handed_as_block_means():
    rng = np.random.default_rng(0)
    t = 10.0 + np.arange(2000) / 1000.0                 # 1 kHz, 2 s
    w = rng.normal(0.0, 1e-2, (t.size, 3))
    a = rng.normal(9.8, 1e-2, (t.size, 3))
    core, sink = CompensatorCore(Policy()), _Sink(100.0)
    core.learner = sink
    _feed(core, t, w, a)
    rows = sink.rows()
    # The first sample alone, then means of 10 samples each (one per 10 ms of stamps).
    assert rows.shape[0] == 200
    np.testing.assert_allclose(rows[0], np.r_[t[0], w[0], a[0]])
    blocks = np.hstack([t[1:1991, None], w[1:1991], a[1:1991]]).reshape(199, 10, 7).mean(axis=1)
    np.testing.assert_allclose(rows[1:], blocks, rtol=0, atol=1e-9)
    # A mean is quieter than one sample: about a tenth of its variance.
    assert np.var(rows[1:, 1:4]) < 0.2 * np.var(w)


def test_a_pause_closes_the_block_and_slow_streams_go_sample_by_sample():
    core, sink = CompensatorCore(Policy()), _Sink(100.0)
    core.learner = sink
    burst = np.arange(25) / 2000.0                      # 2 kHz bursts of 25 samples
    t = np.r_[burst, 120.0 + burst]
    w = np.tile(np.arange(t.size, dtype=float)[:, None], 3)
    _feed(core, t, w)
    rows = sink.rows()
    stamps = rows[:, 0]
    assert not np.any((stamps > burst[-1]) & (stamps < 120.0))   # no mean spans the pause
    assert math.isnan(rows[0, 4])                       # no accelerometer: NaN
    # The first burst: its first sample, a 10 ms block (samples 1-20), and its tail
    # (21-24) handed at the second burst's first sample, which starts a block.
    np.testing.assert_allclose(rows[stamps < 120.0, 1], [0.0, 10.5, 22.5])
    assert rows[stamps >= 120.0, 0].min() > 120.0
    slow, sink1 = CompensatorCore(Policy()), _Sink(100.0)
    slow.learner = sink1
    ts = np.arange(30.0)                                 # 1 Hz: every sample, at once
    _feed(slow, ts, np.ones((30, 3)))
    np.testing.assert_array_equal(sink1.rows()[:, 0], ts)


def test_stamps_that_step_back_are_handed_over_at_once():
    """
    A restart of the IMU's clock closes the old clock's block and opens the hand-off at once.

    1 kHz for 2 s, then the stamps start again at 0.5 s: the old block is handed alone, the
    new stamps from their first sample on (before: every sample held in the block until the
    stamps passed the old clock's hand-off stamp), and a learned model queued for an
    old-clock stamp is installed at the restart, as not carrying the new session's offset.
    """
    from gyro_tdc.learn.fit import learned_model
    core, sink = CompensatorCore(Policy()), _Sink(100.0)
    core.learner = sink
    core.add_temperature(9.0, 20.0)
    t1 = 10.0 + np.arange(2000) / 1000.0
    _feed(core, t1, np.zeros((t1.size, 3)))
    m = learned_model(np.array([[1e-3] * 3, [0.0] * 3]), ('dT',), 20.0, (0.0, 40.0),
                      np.full(3, 1e-6))
    m.created['offset_until'] = 11.5             # in the old clock: after the new start
    core.schedule(m, 13.0)                       # due by the old clock: waiting
    assert core.model is None or core.model_id != m.model_id
    t2 = 0.5 + np.arange(500) / 1000.0
    _feed(core, t2, np.ones((t2.size, 3)))
    rows = sink.rows()
    new = rows[rows[:, 0] < 5.0]
    assert new.shape[0] == 50 and new[0, 0] == 0.5          # from the first sample, 100 Hz
    np.testing.assert_array_equal(new[:, 1], 1.0)           # no old sample mixed in
    assert len(core.learning.block) < 7 * 20
    assert core.model_id == m.model_id and core.reanchoring.sessions.session == 2
    assert not core.reanchoring.learned and core.reanchoring.waiting
