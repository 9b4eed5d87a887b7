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

"""The simulated back-end: the ImuSource protocol, pacing, stamps, implausible readings."""

from __future__ import annotations

from fake_iio import l3gd20_files, make_device
from gyro_tdc.sim import SimStream
from gyro_tdc.sources import IioSource, ImuSample, ImuSource, SimSource, SourceExhausted
from manual_clock import Wall
import numpy as np
import pytest

ORIGIN_NS = 1_700_000_000_123_456_789


def sim(wall: Wall, **kwargs) -> SimSource:
    calls = []

    def clock_ns() -> int:
        calls.append(1)
        return ORIGIN_NS

    src = SimSource('rate_steps', seed=0, rate_hz=2.0, clock_ns=clock_ns, wall=wall, **kwargs)
    src.clock_calls = calls
    return src


@pytest.fixture(scope='module')
def run():
    return SimStream('rate_steps', seed=0, rate_hz=2.0).run


def test_sources_satisfy_the_protocol(tmp_path):
    wall = Wall()
    src = sim(wall)
    assert isinstance(src, ImuSource) and src.has_accel and src.name.startswith('sim:rate_steps')
    iio = IioSource(make_device(tmp_path, l3gd20_files()), clock=lambda: 12.5)
    assert isinstance(iio, ImuSource) and not iio.has_accel


def test_sim_paces_itself_on_the_scaled_clock(run):
    wall = Wall()
    src = sim(wall, time_scale=10.0)
    t0 = run.imu_t[0]
    first = [s.t for s in src.pending()]
    assert first == [t0]  # only the first sample is due at the start
    assert [s.t for s in src.pending()] == []  # no wall time passed: nothing more
    wall.t += 1.5  # 15 simulated seconds
    due = [s.t for s in src.pending()]
    expect = run.imu_t[(run.imu_t > t0) & (run.imu_t <= t0 + 15.0)]
    np.testing.assert_array_equal(due, expect)
    assert len(src.clock_calls) == 1  # tied to the node clock once


def test_sim_stamps_are_shifted_not_scaled(run):
    wall = Wall()
    src = sim(wall, time_scale=50.0)
    wall.t += 2.0  # before the first call: the run starts when first asked, not when opened
    samples = list(src.pending())
    assert len(samples) == 1
    wall.t += 2.0
    samples += src.pending()
    assert len(samples) > 100
    stamps = np.array([src.stamp_ns(s.t) for s in samples])
    assert stamps[0] == ORIGIN_NS
    np.testing.assert_array_equal(stamps - ORIGIN_NS,
                                  np.round((run.imu_t[:stamps.size] - run.imu_t[0]) * 1e9))


def test_sim_flat_out_in_batches_then_exhausted(run):
    wall = Wall()
    src = sim(wall, time_scale=0.0, max_batch=1000)
    got: list[ImuSample] = []
    batches = []
    with pytest.raises(SourceExhausted, match='finished'):
        while True:
            batch = []
            for sample in src.pending():
                batch.append(sample)
                got.append(sample)
            batches.append(len(batch))
    assert len(got) == len(run) and batches == [1000] * (len(run) // 1000)
    np.testing.assert_array_equal([s.t for s in got], run.imu_t)
    np.testing.assert_array_equal([s.omega for s in got], run.gyro)
    temps = [s for s in got if s.temp_c is not None]
    np.testing.assert_array_equal([s.temp_t for s in temps], run.temp_t[:len(temps)])
    refs = [s.ref for s in got if s.ref is not None]
    np.testing.assert_array_equal(refs, run.ref)


def test_sim_refuses_bad_pacing():
    with pytest.raises(ValueError, match='time_scale'):
        SimSource('rate_steps', rate_hz=2.0, time_scale=-1.0)
    with pytest.raises(ValueError, match='max_batch'):
        SimSource('rate_steps', rate_hz=2.0, max_batch=0)


def test_sim_source_never_hands_out_an_implausible_reading():
    src = sim(Wall())
    src._fill()                                   # the first chunk of the scenario
    t0, c0 = src._temps[0]
    src._temps.insert(1, (t0 + 1e-3, 1e30))       # a glitch slotted into the stream
    temps = []
    while src._temps:
        sample = src.read()
        if sample.temp_c is not None:
            temps.append(sample.temp_c)
    assert temps and max(abs(c - c0) for c in temps) < 5.0
    assert src.temperatures_rejected == 1
