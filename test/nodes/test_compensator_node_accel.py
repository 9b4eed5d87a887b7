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
compensator_node corrects the specific force with the model's accelerometer part.

The live done-criterion: a short, low-rate ``accel_chamber`` run streamed through a real
compensator_node (fresh Context) gives, sample for sample, the offline batch compensation
(:func:`gyro_tdc.identify.compensate_accel`) in both input paths, with the covariance widened by
the accelerometer residual variance (and the out-of-range policy); a model without an
accelerometer part leaves ``linear_acceleration`` as it came.
"""

from __future__ import annotations

from compensator_rig import Rig, stamp_s, to_ns
from gyro_tdc.identify import compensate_accel, fit_accel, fit_model
from gyro_tdc.model.compensation import compensate, StreamingCompensator
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.model.out_of_range import variance_growth
from gyro_tdc.runtime.core import CompensatorCore
from gyro_tdc.runtime.flags import OUT_OF_RANGE
from gyro_tdc.runtime.health import accel_state
from gyro_tdc.runtime.policy import Policy
from gyro_tdc.sim import load_scenario, simulate_scenario, to_run
import numpy as np
import pytest
from sensor_msgs.msg import Imu

T_START = 1_700_000_000.0
STEP = 5          # every 5th sample of the 0.5 Hz run: one per 10 s
N = 1320          # the whole held-out run at 0.1 Hz
HOT_FROM = 1100   # from here the thermometer reads 50 degC more: beyond the range (50 degC)
ACOV = (2e-4, 1e-9, 0.0, 1e-9, 3e-4, 0.0, 0.0, 0.0, 5e-4)


@pytest.fixture(scope='module')
def chamber(tmp_path_factory):
    """Fit chamber run 1 with and without an accelerometer part; slice run 2 to stream."""
    root = tmp_path_factory.mktemp('accel_models')
    sims = simulate_scenario(load_scenario('accel_chamber'), seed=3, rate_hz=0.5)
    runs = [to_run(s) for s in sims]
    gyro = fit_model(runs[:1], features='dT,dT2,lag')
    model = gyro.replace(accel=fit_accel(runs[:1], gyro).part)
    static = fit_model(runs[:1], features='dT,dT2')
    static = static.replace(accel=fit_accel(runs[:1], static).part)
    run = runs[1]
    k = np.arange(N) * STEP
    temp = run.temp[k].copy()
    temp[HOT_FROM:] += 50.0
    ns = np.array([to_ns(T_START + v) for v in run.t[k]])
    return {'model': (save_model(model, root / 'accel.yaml'), model), 'static': static,
            'gyro': (save_model(gyro, root / 'gyro.yaml'), gyro),
            'ns': ns, 't': np.array([stamp_s(v) for v in ns]), 'temp': temp,
            'omega': run.omega[k], 'accel': run.accel[k]}


@pytest.fixture
def rig(ros_context):
    made = []

    def make(**params):
        made.append(Rig(ros_context, **params))
        return made[-1]

    yield make
    for r in made:
        r.close()


def _stream(r: Rig, c: dict, chunk: int = 5) -> list[Imu]:
    """
    Publish each sample's temperature (same stamp) then the Imu; wait for every output.

    A chunk's readings lead its Imu by at most 50 s: the node refuses readings stamped over
    a minute ahead of the last IMU stamp.
    """
    start = len(r.out)
    temps = r.node.core.temps.received
    for lo in range(0, N, chunk):
        hi = min(lo + chunk, N)
        for k in range(lo, hi):
            r.temperature(c['ns'][k], c['temp'][k])
        r.spin_until(lambda: r.node.core.temps.received >= temps + hi, what='temperatures in')
        for k in range(lo, hi):
            r.imu(c['ns'][k], c['omega'][k], accel=c['accel'][k], accel_cov=ACOV)
        r.spin_until(lambda: len(r.out) >= start + hi, what=f'{hi} outputs')
    return r.out[start:]


def _fields(out: list[Imu]):
    acc = np.array([(m.linear_acceleration.x, m.linear_acceleration.y,
                     m.linear_acceleration.z) for m in out])
    acov = np.array([list(m.linear_acceleration_covariance) for m in out])
    rate = np.array([(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)
                     for m in out])
    return acc, acov, rate


@pytest.mark.parametrize('raw_cdr', [True, False], ids=['raw_cdr', 'deserialised'])
def test_live_specific_force_equals_offline_compensation(chamber, rig, raw_cdr):
    path, model = chamber['model']
    r = rig(model_file=str(path), raw_cdr=raw_cdr, reanchor_on_start=False)  # the model alone
    out = _stream(r, chamber)
    assert len(out) == N
    acc, acov, rate = _fields(out)
    t, temp = chamber['t'], chamber['temp']
    policy = Policy()
    batch = compensate_accel(model, t, temp, chamber['accel'], out_of_range=policy.out_of_range,
                             max_extrapolation_c=policy.max_extrapolation_c)
    np.testing.assert_allclose(acc, batch, rtol=0, atol=1e-9)
    assert np.abs(acc - chamber['accel']).max() > 1e-3      # a real correction (mg)
    gyro = compensate(model, t, temp, chamber['omega'], out_of_range=policy.out_of_range,
                      max_extrapolation_c=policy.max_extrapolation_c)
    np.testing.assert_allclose(rate, gyro, rtol=0, atol=1e-9)
    # Covariance: the residual variance in range; beyond it the out-of-range variance
    # growing with the distance (linear), the distance from the model's own streaming part.
    ref = StreamingCompensator(model, out_of_range=policy.out_of_range,
                               max_extrapolation_c=policy.max_extrapolation_c).accel
    added = np.empty((N, 3))
    for k in range(N):
        ref.step(t[k], temp[k], chamber['accel'][k])
        extra = 0.0
        if not ref.in_range:
            extra = policy.out_of_range_variance + variance_growth(
                policy.out_of_range_variance, ref.range_distance_c, policy.out_of_range)
        added[k] = np.asarray(model.accel.residual_var) + extra
    assert not ref.in_range and np.all(added[-1] > 2 * added[0])     # the state got there
    expect = np.tile(ACOV, (N, 1))
    expect[:, [0, 4, 8]] += added
    np.testing.assert_allclose(acov, expect, rtol=1e-12, atol=0)
    values = {kv.key: kv.value for kv in r.node.diagnostic_status().values}
    assert values['accelerometer'] == 'compensated'
    assert values['accelerometer compensated'] == str(N)


@pytest.mark.parametrize('raw_cdr', [True, False], ids=['raw_cdr', 'deserialised'])
def test_a_model_without_accel_leaves_the_specific_force_unchanged(chamber, rig, raw_cdr):
    path, _ = chamber['gyro']
    r = rig(model_file=str(path), raw_cdr=raw_cdr)
    out = _stream(r, chamber)
    acc, acov, _ = _fields(out)
    assert acc.tobytes() == np.asarray(chamber['accel'], dtype=np.float64).tobytes()
    assert acov.tobytes() == np.tile(ACOV, (N, 1)).tobytes()
    values = {kv.key: kv.value for kv in r.node.diagnostic_status().values}
    assert values['accelerometer'] == 'not in model'


def test_passthrough_widens_the_accel_covariance_and_keeps_the_values(chamber):
    _, model = chamber['model']
    policy = Policy(stale_policy='passthrough', temperature_timeout=1.0)
    core = CompensatorCore(policy, model)
    a = (0.1, -0.2, 9.8)
    *_, aout, avar = core.process(1.0, 0.0, 0.0, 0.0, a)      # no temperature yet
    assert aout is None and avar == (policy.passthrough_variance,) * 3
    core.add_temperature(1.0, 20.0)
    *_, aout, avar = core.process(1.5, 0.0, 0.0, 0.0, a)
    assert aout is not None and avar == tuple(model.accel.residual_var)
    *_, aout, avar = core.process(3.0, 0.0, 0.0, 0.0, a)      # stale: passed through
    assert aout is None and avar == (policy.passthrough_variance,) * 3
    assert accel_state(core) == 'passthrough (temperature stale)'
    *_, aout, avar = core.process(3.0, 0.0, 0.0, 0.0, None)   # an Imu without accelerometer
    assert aout is None and avar is None
    assert accel_state(core) == 'passthrough (no accelerometer data in the Imu)'
    hold = CompensatorCore(Policy(temperature_timeout=1.0), model)
    hold.add_temperature(1.0, 20.0)
    hold.process(1.5, 0.0, 0.0, 0.0, a)
    *_, aout, avar = hold.process(3.0, 0.0, 0.0, 0.0, a)      # stale, held: widened
    assert aout is not None
    np.testing.assert_allclose(avar, np.asarray(model.accel.residual_var)
                               + Policy().stale_variance, rtol=1e-15)
    assert accel_state(hold) == 'compensated'
    gyro_only = CompensatorCore(policy, model.replace(accel=None))
    gyro_only.add_temperature(1.0, 20.0)
    *_, aout, avar = gyro_only.process(1.5, 0.0, 0.0, 0.0, a)
    assert not gyro_only.accel_on and accel_state(gyro_only) == 'not in model'
    assert aout is None and avar is None


def test_a_static_part_is_cached_per_temperature_and_equals_batch(chamber):
    model = chamber['static']
    core = CompensatorCore(Policy(), model)
    assert core.slot.accel.static             # dT, dT2 without a lag: the cached path
    t, temp, acc = chamber['t'], chamber['temp'], chamber['accel']
    out = []
    for k in range(N):
        core.add_temperature(t[k], temp[k])
        *_, aout, avar = core.process(t[k], *chamber['omega'][k], acc[k])
        out.append(aout)
    batch = compensate_accel(model, t, temp, acc, out_of_range=Policy().out_of_range)
    np.testing.assert_allclose(np.array(out), batch, rtol=0, atol=1e-9)
    # Beyond the range: residual + out_of_range_variance + the linear growth.
    assert core.accel_flags & OUT_OF_RANGE
    assert avar[0] > model.accel.residual_var[0] + Policy().out_of_range_variance
