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
Stamp-scheduled swaps: the learner's step cadence changes nothing within the swap delay.

Vehicle day 1 then day 2 at 2 Hz (as test_field_live) stream through a CompensatorCore with
a learner, stepped (:meth:`CompensatorCore.learn_step`, the node's timer) every 1, 10 or 100
seconds of stamps with ``swap_delay_s`` = 120 s: every accepted candidate is ready before its
effective stamp, so the output is bit for bit the same, as are the accepted candidates and
their stamps and the learner's state (learn_file). Stepped every 600 s (beyond the delay) the
learned state and the accepted sequence are still the same; the swaps come late, counted.
"""

from __future__ import annotations

import json

from gyro_tdc.learn.learner import LearnConfig, Learner
from gyro_tdc.runtime import CompensatorCore, Policy
from gyro_tdc.sim import simulate_run
from learning_days import GAP_S, stream
import numpy as np
import pytest

RATE_HZ = 2.0
DELAY_S = 120.0


@pytest.fixture(scope='module')
def days():
    """Vehicle day 1 (seed 1) and day 2 (seed 2, hotter) at 2 Hz."""
    d1 = simulate_run('vehicle_day1', seed=1, rate_hz=RATE_HZ)
    d2 = simulate_run('vehicle_day2', seed=2, rate_hz=RATE_HZ)
    return d1, d2, d1.imu_t[-1] + GAP_S - d2.imu_t[0]


def run(days, every_s, delay_s=DELAY_S):
    """Stream both days, stepping every ``every_s`` of stamps; outputs, swaps, learner, core."""
    d1, d2, off = days
    core = CompensatorCore(Policy())
    learner = Learner(LearnConfig(swap_delay_s=delay_s))
    core.learner = learner
    every = int(round(every_s * RATE_HZ))
    accepted = []
    outs = [stream(core, learner, d, shift, poll=every, accepted=accepted)
            for d, shift in ((d1, 0.0), (d2, off))]
    accepted += [(due, model.model_id) for due, model in core.learn_step()]
    learner.flush()
    return outs, accepted, learner, core


@pytest.fixture(scope='module')
def runs(days):
    """Run the stream stepped every 1, 10, 100 and 600 s of stamps."""
    return {s: run(days, s) for s in (1.0, 10.0, 100.0, 600.0)}


def _state(learner):
    return json.dumps(learner.state(), sort_keys=True)


def test_step_cadence_within_the_delay_gives_the_same_output_bit_for_bit(runs):
    ref_outs, ref_acc, ref_l, ref_core = runs[1.0]
    assert len(ref_acc) > 10 and ref_l.late_swaps == 0
    assert ref_core.learned_installs == len([a for a in ref_acc if a[0] is not None])
    assert ref_outs[1][1].all()                # learned on day 1: day 2 compensated throughout
    for s in (10.0, 100.0):
        outs, acc, learner, core = runs[s]
        assert learner.late_swaps == 0, s
        assert acc == ref_acc, s                 # the same candidates, the same stamps
        for (out, ok), (ref, ref_ok) in zip(outs, ref_outs):
            assert np.array_equal(ok, ref_ok) and np.array_equal(out, ref), s
        assert _state(learner) == _state(ref_l), s
        assert core.learned_installs == ref_core.learned_installs


def test_step_cadence_beyond_the_delay_learns_the_same_and_counts_late_swaps(runs):
    ref_outs, ref_acc, ref_l, _ = runs[1.0]
    outs, acc, learner, core = runs[600.0]
    assert acc == ref_acc and _state(learner) == _state(ref_l)
    assert learner.late_swaps > 0
    assert learner.diagnostic_values()['learn late swaps'] == str(learner.late_swaps)
    assert not np.array_equal(outs[1][0], ref_outs[1][0])   # late: the output moved


def test_effective_stamp_is_the_trigger_plus_the_delay(days, runs):
    """Each swap takes effect swap_delay_s after the sample that let it be computed."""
    _, acc5, _, _ = run(days, 1.0, delay_s=5.0)
    acc120 = runs[1.0][1]
    assert [a[1] for a in acc5] == [a[1] for a in acc120]
    assert np.allclose([a[0] + 115.0 for a in acc5], [a[0] for a in acc120])
