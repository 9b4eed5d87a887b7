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

"""The core's plausibility gates: thermometer glitches, stamps, rates and its own outputs."""

from __future__ import annotations

from dataclasses import replace
import math

from gyro_tdc.base.limits import MAX_DRIFT_RAD_S, MAX_RATE_RAD_S, MAX_TEMP_LEAD_S
from gyro_tdc.identify import fit_model
from gyro_tdc.learn.learner import Learner
from gyro_tdc.runtime import flags as F
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.drift import correction_is_safe
from gyro_tdc.runtime.health import health, OK, WARN
from gyro_tdc.runtime.policy import Policy
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from synth import synth_run

#: The bounds the core promises for what it marks compensated (base.limits).
MAX_DRIFT = 5.0
FEATURES = {'static': ('dT', 'dT2'), 'dTdt': ('dT', 'dT2', 'dTdt'), 'lag': ('dT', 'dT2', 'lag')}


@pytest.fixture(scope='module')
def models():
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=3, tau_die=60.0)
    return {name: fit_model([run], features=feats, n_centers=10, fit_params=False)
            for name, feats in FEATURES.items()}


def feed(core, n=6000, rate_hz=100.0, temp_every=10, glitch=None):
    """
    Feed a minute at 100 Hz warming by 0.06 degC/s, the thermometer at 10 Hz.

    ``glitch`` is ``(when, stamp, degC)`` of one extra reading, fed before the first sample
    stamped at or after ``when``. Return the outputs (N, 3), variances (N, 3) and flags (N,).
    """
    out, var, flags = [], [], []
    extra = glitch
    for k in range(n):
        t = 1000.0 + k / rate_hz
        if extra is not None and extra[0] <= t:
            core.add_temperature(*extra[1:])
            extra = None
        if k % temp_every == 0:
            core.add_temperature(t, 25.0 + 0.06 * k / rate_hz)
        ox, oy, oz, v, f, _, _ = core.process(t, 0.01, -0.02, 0.005)
        out.append((ox, oy, oz))
        var.append(v)
        flags.append(f)
    return np.array(out), np.array(var), np.array(flags)


@pytest.mark.parametrize('kind', ['static', 'dTdt', 'lag'])
@pytest.mark.parametrize('reading', [1e30, 1000.0, -1e30, 190.0])
def test_one_thermometer_glitch_changes_nothing_but_a_count(models, kind, reading):
    """One implausible reading (out of range, or 165 degC in 5 ms) is never held or filtered."""
    clean = CompensatorCore(Policy(), models[kind])
    ref = feed(clean)
    core = CompensatorCore(Policy(), models[kind])
    got = feed(core, glitch=(1010.005, 1010.005, reading))
    for a, b in zip(got, ref):
        np.testing.assert_array_equal(a, b)
    assert np.abs(got[0] - (0.01, -0.02, 0.005)).max() < MAX_DRIFT and got[1].max() < 1e-3
    assert core.temps.implausible == 1 and core.counts == clean.counts
    h = health(core)
    assert h.level == WARN and 'temperatures rejected (implausible): 1 ' in h.message
    assert h.values['temperatures rejected (implausible)'] == '1'
    assert health(core, h.mark).level == OK           # nothing new since


def test_a_reading_stamped_a_day_ahead_is_rejected(models):
    """It would stop the thermometer history a later model is primed over, and the age."""
    clean = CompensatorCore(Policy(), models['static'])
    feed(clean)
    core = CompensatorCore(Policy(), models['static'])
    feed(core, glitch=(1010.0, 1010.0 + 86400.0, 30.0))
    assert core.temps.implausible == 1
    assert list(core.stream.history) == list(clean.stream.history)
    assert core.temperature_age() == clean.temperature_age() == pytest.approx(0.09)
    for c in (clean, core):          # a lag model loaded now is primed over the history
        c.set_model(models['lag'])
    np.testing.assert_array_equal(feed(core)[0], feed(clean)[0])


def test_a_reading_ahead_by_up_to_a_night_or_the_timeout_is_held():
    lead = MAX_TEMP_LEAD_S
    core = CompensatorCore(Policy(temperature_timeout=5.0))
    core.process(100.0, 0.0, 0.0, 0.0)     # the IMU pauses: the next run starts up to a night on
    assert core.add_temperature(100.0 + lead - 0.1, 25.0)
    assert not core.add_temperature(100.0 + lead + 0.2, 25.0) and core.temps.implausible == 1
    core = CompensatorCore(Policy(temperature_timeout=2.0 * lead))
    core.process(100.0, 0.0, 0.0, 0.0)
    assert core.add_temperature(99.0 + 2.0 * lead, 25.0)
    assert not core.add_temperature(101.0 + 2.0 * lead, 25.0)


def test_the_learner_sees_only_plausible_readings(models):
    core = CompensatorCore(Policy(), models['static'])
    core.learner = learner = Learner()
    core.add_temperature(1.0, 25.0)
    assert not core.add_temperature(1.5, 1e30) and not core.add_temperature(1.6, 90.0)
    assert core.add_temperature(2.0, 25.5)
    assert learner.temps == [(1.0, 25.0), (2.0, 25.5)]


@pytest.mark.parametrize('w', [1e6, -1e6, 100.5, 1e300])
def test_a_rate_beyond_any_gyro_passes_through_flagged(models, w):
    core = CompensatorCore(Policy(), models['static'])
    core.add_temperature(0.0, 25.0)
    ox, oy, oz, var, flags, _, _ = core.process(0.5, w, 0.0, 0.0)
    assert flags & F.PASSTHROUGH, 'an impossible rate must not be marked compensated'
    assert flags == F.PASSTHROUGH | F.IMPLAUSIBLE_INPUT
    assert (ox, oy, oz) == (w, 0.0, 0.0) and var == (Policy().passthrough_variance,) * 3
    assert core.counts['compensated'] == 0
    h = health(core)
    assert h.level == WARN and 'input rate beyond any gyro range (1 samples)' in h.message
    assert core.process(1.0, 100.0, 0.0, 0.0)[4] == 0       # the bound itself is compensated
    assert core.process(1.5, math.nan, 0.0, 0.0)[4] == F.PASSTHROUGH | F.NON_FINITE


def forged(model, **fields):
    """Return ``model`` with fields replaced (what a crafted file would carry past the id)."""
    return replace(model, **{k: np.asarray(v, dtype=np.float64) for k, v in fields.items()})


@pytest.mark.parametrize('kind', ['static', 'dTdt'])
@pytest.mark.parametrize('change', [
    {'intercept': [1e300, 0.0, 0.0]}, {'intercept': [math.nan, 0.0, 0.0]},
    {'intercept': [0.0, 0.0, 6.0]}, {'residual_var': [math.inf, 0.0, 0.0]},
    {'scale': 'gain 1e-6 at 45 degC'},
])
def test_an_output_not_finite_or_implausible_passes_through_flagged(models, kind, change):
    if change.get('scale'):           # the gain 1 + scale * dT all but zero: ~1e4 rad/s out
        change = {'scale': [-(1.0 - 1e-6) / (45.0 - models[kind].t0_c), 0.0, 0.0]}
    model = forged(models[kind], **change)
    core = CompensatorCore(Policy(), model)
    core.add_temperature(0.0, 45.0)
    out = core.process(0.5, 0.01, 0.0, 0.0)
    assert out[4] & F.PASSTHROUGH, f'{out[:4]} marked compensated'
    assert out[4] & F.IMPLAUSIBLE_OUTPUT and out[:3] == (0.01, 0.0, 0.0)
    assert core.counts['compensated'] == 0
    h = health(core)
    assert h.level == WARN
    assert 'compensated output not finite or implausible (1 samples)' in h.message
    assert h.values['implausible output'] == '1'


def test_an_accelerometer_output_not_plausible_passes_it_through(models):
    base = models['static']
    part = replace(base, intercept=np.array([0.0, 0.0, 1e300]), accel=None)
    core = CompensatorCore(Policy(), replace(base, accel=part))
    core.add_temperature(0.0, 25.0)
    ox, oy, oz, var, flags, aout, avar = core.process(0.5, 0.01, 0.0, 0.0, (0.0, 0.0, 9.81))
    assert not flags & F.PASSTHROUGH                 # the gyro is compensated
    assert aout is None and avar == (Policy().passthrough_variance,) * 3
    assert core.accel_flags == F.PASSTHROUGH | F.IMPLAUSIBLE_OUTPUT


readings = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.floats(-120.0, 220.0), st.sampled_from([1e30, -1e30, 1000.0, 25.0]))
stamps = st.one_of(st.floats(-10.0, 200.0), st.sampled_from([math.nan, math.inf, 86400.0]))


@pytest.mark.parametrize('kind', ['static', 'lag'])
@settings(derandomize=True, max_examples=200, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.lists(st.tuples(stamps, readings), max_size=40),
       rate=st.floats(-2.0, 2.0))
def test_temperature_path_property(models, kind, data, rate):
    """Any readings and stamps: nothing raises; what is not passed through is plausible."""
    core = CompensatorCore(Policy(), models[kind])
    for k, (t_temp, c) in enumerate(data):
        core.add_temperature(t_temp, c)
        t = 0.5 * k
        ox, oy, oz, var, flags, _, _ = core.process(t, rate, 0.0, -rate)
        if flags & F.PASSTHROUGH:
            assert (ox, oy, oz) == (rate, 0.0, -rate)
        else:
            assert abs(ox - rate) <= MAX_DRIFT and abs(oy) <= MAX_DRIFT
            assert abs(oz + rate) <= MAX_DRIFT
            assert all(math.isfinite(v) and 0.0 <= v < 1e3 for v in var)
            held = core.temps.at(t)
            assert held is not None and -100.0 <= held[0] <= 200.0
    h = health(core)
    assert h.level in (OK, WARN)


@settings(derandomize=True, max_examples=300, deadline=None)
@given(b=st.floats(allow_nan=True, allow_infinity=True), d=st.floats(allow_nan=True,
       allow_infinity=True), w=st.floats(-MAX_RATE_RAD_S, MAX_RATE_RAD_S))
def test_a_safe_cache_entry_never_fails_the_output_check(b, d, w):
    """The static path skips the output check for a safe entry: it would always pass."""
    if correction_is_safe((b, 0.0, 0.0), (d, 1.0, 1.0)):
        for x in (w, MAX_RATE_RAD_S, -MAX_RATE_RAD_S):
            assert abs((x - b) / d - x) <= MAX_DRIFT_RAD_S
    else:
        assert not (math.isfinite(b) and d == 1.0 and abs(b) <= MAX_DRIFT_RAD_S / 2)
