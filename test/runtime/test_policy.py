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

"""A new Policy swapped into a running core applies from the next sample, as if built so."""

from __future__ import annotations

from dataclasses import replace

from gyro_tdc.identify import fit_model
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.flags import PASSTHROUGH, STALE
from gyro_tdc.runtime.policy import PARAMS, Policy
from gyro_tdc.runtime.priming import prepare, prepared_for
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def model():
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3)
    return fit_model([run], features=('dT', 'dT2', 'dTdt', 'lag', 'warmup'), n_centers=10,
                     fit_params=False)


def feed(core, t0=10.0, n=50):
    """Feed one thermometer reading and ``n`` fresh samples, 0.1 s apart; return the last."""
    core.add_temperature(t0, 20.0)
    for k in range(n):
        out = core.process(t0 + 0.1 * (k + 1), 0.1, 0.2, 0.3)
    return out


def test_every_policy_row_is_settable_and_every_other_says_why_not():
    for spec in PARAMS:
        if spec.policy:
            assert not spec.read_only, spec.name
        elif spec.read_only:
            assert 'read at start' in spec.description.lower(), spec.name


def test_stale_policy_passthrough_applies_from_the_next_sample(model):
    core = CompensatorCore(Policy(temperature_timeout=2.0), model)
    feed(core)
    held = core.process(13.0, 0.1, 0.2, 0.3)                  # 3 s after the reading
    assert held[4] == STALE and held[:3] != (0.1, 0.2, 0.3)
    core.set_policy(replace(core.policy, stale_policy='passthrough',
                            passthrough_variance=0.5))
    assert core.process(13.1, 0.1, 0.2, 0.3) == (
        0.1, 0.2, 0.3, (0.5, 0.5, 0.5), STALE | PASSTHROUGH, None, None)


def test_variances_swapped_in_equal_a_core_built_with_them(model):
    new = Policy(temperature_timeout=2.0, stale_variance=0.25, out_of_range_variance=0.125)
    swapped = CompensatorCore(Policy(temperature_timeout=2.0), model)
    built = CompensatorCore(new, model)
    feed(swapped)
    feed(built)
    swapped.set_policy(new)
    a = swapped.process(13.0, 0.1, 0.2, 0.3)
    b = built.process(13.0, 0.1, 0.2, 0.3)
    assert a[4] == b[4] == STALE
    assert a[:3] == pytest.approx(b[:3], abs=1e-15)
    assert a[3] == pytest.approx(b[3])
    assert a[3] == pytest.approx(tuple(v + 0.25 for v in model.residual_var))


def test_a_model_prepared_before_a_change_is_prepared_again_at_install(model):
    core = CompensatorCore(Policy(temperature_timeout=2.0), model)
    feed(core)
    early = prepare(model, core.policy, core.priming())       # a background load
    new = replace(core.policy, stale_variance=0.25)
    core.set_policy(new)
    assert not prepared_for(early, new)
    core.install(early)
    assert core.process(13.0, 0.1, 0.2, 0.3)[3] == pytest.approx(
        tuple(v + 0.25 for v in model.residual_var))


def test_a_changed_stillness_threshold_makes_a_new_detector_until_anchored(model):
    core = CompensatorCore(Policy(reanchor_on_start=True), model)
    before = core.reanchoring.detector
    core.set_policy(replace(core.policy, motion_threshold=0.5))   # not a stillness row
    assert core.reanchoring.detector is before and core.policy.motion_threshold == 0.5
    core.set_policy(replace(core.policy, still_window=2.0, still_max_rate=0.01))
    detector = core.reanchoring.detector
    assert detector is not before
    assert (detector.window, detector.still.max_rate) == (2.0, 0.01)


def test_upstream_passthrough_can_be_turned_on_and_off(model):
    core = CompensatorCore(Policy(), model)
    assert not core.upstream_pass
    core.set_policy(replace(core.policy, upstream_correction='px4'))
    assert core.upstream_pass
    core.set_policy(replace(core.policy, upstream_policy='compensate'))
    assert not core.upstream_pass


def test_an_invalid_policy_is_refused_before_any_swap():
    with pytest.raises(ValueError, match='stale_policy'):
        replace(Policy(), stale_policy='sometimes')
