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

"""compensator_node with real rclpy: one out per in, offline equivalence, policies, reload."""

from __future__ import annotations

import math
from pathlib import Path

from compensator_rig import rates, record_statuses, RELIABLE, reported, stamp_s, to_ns
from diagnostic_msgs.msg import DiagnosticStatus
from gyro_tdc.data.imu_cdr import ImuView, locate
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.nodes.compensator_node import PARAMS
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.runtime import CompensatorCore, Policy
from marks import mark
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message, serialize_message
from rosutil import interrupt, node_process, spin_until
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger
from synth import synth_run
import yaml

CONFIG = Path(__file__).resolve().parents[2] / 'config'


@pytest.fixture(scope='module')
def models(tmp_path_factory):
    """Two fitted models saved to files: a paper model and one with dynamic features."""
    root = tmp_path_factory.mktemp('models')
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    paper = fit_model([run], features=('dT', 'dT2'), n_centers=10)
    dynamic = fit_model([run], features=('dT', 'dT2', 'dTdt', 'lag', 'warmup'), n_centers=12,
                        fit_params=False)
    return {'paper': (save_model(paper, root / 'paper.yaml'), paper),
            'dynamic': (save_model(dynamic, root / 'dynamic.yaml'), dynamic)}


def warming_stream(n=1500, rate_hz=200.0, temp_hz=2.0, seed=0, t_lo=5.0, t_hi=30.0,
                   t0=1_700_000_000.0):
    """IMU stamps (ns), raw rates and thermometer samples (ns, degC) of a warming run."""
    rng = np.random.default_rng(seed)
    imu_ns = np.array([to_ns(t0 + k / rate_hz) for k in range(n)])
    temp_ns = np.array([to_ns(t0 - 0.2 + k / temp_hz) for k in range(int(n / rate_hz *
                                                                         temp_hz) + 1)])
    temp_c = np.linspace(t_lo, t_hi, temp_ns.size) + rng.normal(0, 0.02, temp_ns.size)
    omega = 0.02 + rng.normal(0, 2e-3, (n, 3))
    return imu_ns, omega, temp_ns, temp_c


def offline(model, imu_ns, omega, temp_ns, temp_c, clamp=True):
    """Evaluate the model offline on the same stamps and zero-order-held temperatures."""
    t = np.array([stamp_s(ns) for ns in imu_ns])
    tt = np.array([stamp_s(ns) for ns in temp_ns])
    idx = np.searchsorted(tt, t, side='right') - 1
    assert np.all(idx >= 0)
    return compensate(model, t, np.asarray(temp_c)[idx], omega, clamp=clamp)


@pytest.mark.parametrize('executor,raw_cdr', [
    ('single', False), ('events', False), ('single', True), ('events', True)])
def test_one_out_per_in_in_order_headers_unchanged(models, rig_factory, executor, raw_cdr):
    path, model = models['paper']
    rig = rig_factory(executor_kind=executor, model_file=str(path), raw_cdr=raw_cdr)
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=1200)
    sent = rig.feed(imu_ns, omega, temp_ns, temp_c)
    spin_until(rig.executor, lambda: len(rig.out) >= len(sent), 5.0)
    assert len(rig.out) == len(sent) == 1200
    assert rig.node.core.counts == {'in': 1200, 'out': 1200, 'compensated': 1200}
    for s, o in zip(sent, rig.out):
        assert o.header == s.header
        assert o.orientation == s.orientation
        assert list(o.orientation_covariance) == list(s.orientation_covariance)
        assert o.linear_acceleration == s.linear_acceleration
        assert list(o.linear_acceleration_covariance) == list(s.linear_acceleration_covariance)
        cov = np.array(s.angular_velocity_covariance)
        cov[[0, 4, 8]] += model.residual_var
        cov[[0, 4, 8]] = [mark(v) for v in cov[[0, 4, 8]]]  # the two lowest bytes of each
        np.testing.assert_array_equal(o.angular_velocity_covariance, cov)
    np.testing.assert_allclose(rates(rig.out), offline(model, imu_ns, omega, temp_ns, temp_c),
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize('raw_cdr', [True, False])
def test_output_equals_offline_evaluation_dynamic_features(models, rig_factory, raw_cdr):
    path, model = models['dynamic']
    rig = rig_factory(executor_kind='events', model_file=str(path), raw_cdr=raw_cdr)
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=2000, rate_hz=100.0, temp_hz=1.0,
                                                    seed=4)
    rig.feed(imu_ns, omega, temp_ns, temp_c)
    expect = offline(model, imu_ns, omega, temp_ns, temp_c)
    got = rates(rig.out)
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-9)
    assert np.abs(got - omega).max() > 1e-4  # the model did something


def diag_values(status):
    return {kv.key: kv.value for kv in status.values}


def test_no_temperature_yet_passes_through(models, rig_factory):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path), passthrough_variance=0.25)
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=100)
    sent = rig.feed(imu_ns, omega)
    np.testing.assert_array_equal(rates(rig.out), rates(sent))
    assert all(o.angular_velocity_covariance[0] == 1e-6 + 0.25 for o in rig.out)
    st = rig.node.diagnostic_status()
    values = diag_values(st)
    assert st.level == DiagnosticStatus.WARN and 'no temperature yet' in st.message
    assert values['compensation active'] == 'False'
    assert values['why not'] == 'no temperature yet, raw rate passed through'
    assert values['messages in'] == values['messages out'] == '100'


def same_status(a, b):
    """Return whether two statuses say the same (one judged, one received on /diagnostics)."""
    return (a.level, a.message, diag_values(a)) == (b.level, b.message, diag_values(b))


@pytest.mark.parametrize('policy,executor', [('hold', 'events'), ('passthrough', 'single')])
def test_stale_temperature(models, rig_factory, policy, executor):
    path, model = models['paper']
    rig = rig_factory(executor_kind=executor, model_file=str(path), temperature_timeout=0.5,
                      stale_policy=policy,
                      stale_variance=0.5, passthrough_variance=0.25)
    statuses = record_statuses(rig.node)
    t0 = 1_700_000_100.0
    imu_ns = [to_ns(t0 + k * 0.01) for k in range(200)]  # 2 s of IMU, one temperature
    omega = np.full((200, 3), 0.01)
    rig.feed(imu_ns, omega, [to_ns(t0)], [20.0])
    out = rates(rig.out)
    fresh = np.arange(200) * 0.01 <= 0.5 + 1e-9
    expect = offline(model, imu_ns, omega, [to_ns(t0)], [20.0])
    np.testing.assert_allclose(out[fresh], expect[fresh], rtol=0, atol=1e-9)
    cov0 = np.array([o.angular_velocity_covariance[0] for o in rig.out])
    if policy == 'hold':
        np.testing.assert_allclose(out[~fresh], expect[~fresh], rtol=0, atol=1e-9)
        np.testing.assert_allclose(cov0[~fresh], 1e-6 + model.residual_var[0] + 0.5)
    else:
        np.testing.assert_array_equal(out[~fresh], omega[~fresh])
        np.testing.assert_allclose(cov0[~fresh], 1e-6 + 0.25)
    st = rig.node.diagnostic_status()
    assert float(diag_values(st)['temperature age s']) == pytest.approx(1.99, abs=1e-6)
    # Each report names the stale samples new since the one before (WARN); under load the
    # 1 Hz timer's may fall within the feed: together they name every stale sample once.
    said = [s for s in statuses if 'temperature stale' in s.message]
    assert said and all(s.level == DiagnosticStatus.WARN for s in said), said
    assert reported(statuses, 'temperature stale') == (~fresh).sum(), statuses
    # The 1 Hz timer publishes the same status on /diagnostics: the next one, nothing new
    # since the last status, is OK.
    n = len(statuses)
    spin_until(rig.executor, lambda: len(statuses) > n and any(
        same_status(s, statuses[n]) for s in rig.diag), 30.0, what='the next /diagnostics')
    assert statuses[n].level == DiagnosticStatus.OK, statuses[n].message
    assert diag_values(statuses[n])['messages in'] == '200'


@pytest.mark.parametrize('mode', ['clamp', 'extrapolate'])
def test_out_of_range(models, rig_factory, mode):
    path, model = models['paper']
    lo, hi = model.temp_range_c
    rig = rig_factory(model_file=str(path), out_of_range=mode, out_of_range_variance=0.125)
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=600, t_lo=hi - 3.0, t_hi=hi + 6.0)
    rig.feed(imu_ns, omega, temp_ns, temp_c)
    expect = offline(model, imu_ns, omega, temp_ns, temp_c, clamp=mode == 'clamp')
    np.testing.assert_allclose(rates(rig.out), expect, rtol=0, atol=1e-9)
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN and 'out of model range' in st.message
    assert diag_values(st)['in range'] == 'False'
    assert rig.out[-1].angular_velocity_covariance[0] == pytest.approx(
        1e-6 + model.residual_var[0] + 0.125)


def test_nan_and_inf_pass_through_flagged(models, rig_factory):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path))
    statuses = record_statuses(rig.node)
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=50)
    omega[10, 0] = math.nan
    omega[20, 2] = math.inf
    omega[30, 1] = -math.inf
    rig.feed(imu_ns, omega, temp_ns, temp_c)
    out = rates(rig.out)
    assert len(rig.out) == 50
    bad = [10, 20, 30]
    np.testing.assert_array_equal(out[bad], omega[bad])
    good = np.setdiff1d(np.arange(50), bad)
    # The filters skip the bad samples; with a static model that changes nothing.
    expect = offline(model, imu_ns[good], omega[good], temp_ns, temp_c)
    np.testing.assert_allclose(out[good], expect, rtol=0, atol=1e-9)
    st = rig.node.diagnostic_status()
    # Each report names the samples new since the one before (the 1 Hz timer's may fall
    # within the feed): together exactly the three, each time WARN.
    said = [s for s in statuses if 'non-finite input' in s.message]
    assert said and all(s.level == DiagnosticStatus.WARN for s in said), said
    assert reported(statuses, 'non-finite input') == 3, statuses
    assert diag_values(st)['non-finite'] == '3'


def test_non_finite_temperature_is_rejected(models, rig_factory):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path))
    t0 = 1_700_000_200.0
    rig.feed([to_ns(t0 + 0.01 * k) for k in range(20)], np.zeros((20, 3)),
             [to_ns(t0), to_ns(t0 + 0.05)], [20.0, math.nan])
    assert rig.node.core.temps.rejected == 1
    expect = offline(model, [to_ns(t0 + 0.01 * k) for k in range(20)], np.zeros((20, 3)),
                     [to_ns(t0)], [20.0])
    np.testing.assert_allclose(rates(rig.out), expect, rtol=0, atol=1e-9)
    assert 'non-finite temperature' in rig.node.diagnostic_status().message


def test_no_model_passes_through_with_error(rig_factory, tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('format_version: [\n')
    rig = rig_factory(model_file=str(bad))
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=20)
    sent = rig.feed(imu_ns, omega, temp_ns, temp_c)
    np.testing.assert_array_equal(rates(rig.out), rates(sent))
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.ERROR and 'no model loaded' in st.message
    assert 'malformed YAML' in st.message


@pytest.mark.parametrize('executor', ['single', 'events'])
def test_reload_via_parameter_good_and_bad(models, rig_factory, tmp_path, executor):
    path_a, model_a = models['paper']
    path_b, model_b = models['dynamic']
    # load_wait: answer every set with the file's verdict, however busy the machine.
    rig = rig_factory(executor_kind=executor, model_file=str(path_a), load_wait=10.0)
    client = AsyncParameterClient(rig.io, 'compensator_node')
    spin_until(rig.executor, lambda: client.services_are_ready(), 10.0)

    def set_model_file(value):
        future = client.set_parameters([Parameter('model_file', value=value)])
        spin_until(rig.executor, future.done, 10.0)
        return future.result().results[0]

    bad = tmp_path / 'broken.yaml'
    bad.write_text('kind: rbf\nfeatures: [dT]\n')
    result = set_model_file(str(bad))
    assert not result.successful and 'format_version' in result.reason
    assert rig.node.core.model.model_id == model_a.model_id
    assert rig.node.get_parameter('model_file').value == str(path_a)
    missing = set_model_file(str(tmp_path / 'nope.yaml'))
    assert not missing.successful and 'nope.yaml' in missing.reason

    result = set_model_file(str(path_b))
    assert result.successful
    assert rig.node.core.model.model_id == model_b.model_id
    values = diag_values(rig.node.diagnostic_status())
    assert values['model id'] == model_b.model_id
    assert values['model features'] == 'dT,dT2,dTdt,lag,warmup'
    assert values['last reload'] == f'loaded {model_b.model_id}'


@pytest.mark.parametrize('executor', ['single', 'events'])
def test_reload_service_good_and_bad(models, rig_factory, tmp_path, executor):
    src, model_a = models['paper']
    path = tmp_path / 'live.yaml'
    path.write_text(Path(src).read_text())
    rig = rig_factory(executor_kind=executor, model_file=str(path), load_wait=10.0)
    client = rig.io.create_client(Trigger, 'compensator_node/reload')
    spin_until(rig.executor, lambda: client.service_is_ready(), 10.0)

    def reload():
        future = client.call_async(Trigger.Request())
        spin_until(rig.executor, future.done, 10.0)
        return future.result()

    path.write_text('not: [a model\n')
    res = reload()
    assert not res.success and 'live.yaml' in res.message and 'YAML' in res.message
    assert rig.node.core.model.model_id == model_a.model_id
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=100, t_hi=10.0)  # 5 degC in 0.5 s: plausible
    rig.feed(imu_ns, omega, temp_ns, temp_c)  # still compensating with the old model
    np.testing.assert_allclose(rates(rig.out), offline(model_a, imu_ns, omega, temp_ns, temp_c),
                               rtol=0, atol=1e-9)

    path.write_text(Path(models['dynamic'][0]).read_text())
    res = reload()
    assert res.success and models['dynamic'][1].model_id in res.message
    assert rig.node.core.model.model_id == models['dynamic'][1].model_id


def test_reanchor_on_start(models, rig_factory):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path), reanchor_on_start=True, still_window=1.0)
    n = 400
    t0 = 1_700_000_300.0
    imu_ns = [to_ns(t0 + k * 0.005) for k in range(n)]
    rng = np.random.default_rng(2)
    offset = np.array([0.8e-3, -0.6e-3, 0.4e-3])
    drift = -offline(model, imu_ns, np.zeros((n, 3)), [to_ns(t0 - 1)], [22.0])
    raw = drift + offset + rng.normal(0, 1e-3, (n, 3))
    rig.feed(imu_ns, raw, [to_ns(t0 - 1)], [22.0])
    anchor = rig.node.core.anchor
    assert anchor is not None and anchor.t == pytest.approx(t0 + 1.0, abs=0.006)
    np.testing.assert_allclose(anchor.delta, offset, atol=3e-4)
    out = rates(rig.out)
    after = np.array([stamp_s(ns) for ns in imu_ns]) > anchor.t
    assert np.abs(out[after].mean(axis=0)).max() < 3e-4
    values = diag_values(rig.node.diagnostic_status())
    assert values['reanchor'].startswith('done at t=')
    assert len(values['reanchor shift dps'].split(',')) == 3


def test_config_file_matches_declared_parameters():
    doc = yaml.safe_load((CONFIG / 'compensator.yaml').read_text())
    params = doc['/**']['ros__parameters']
    specs = {s.name: s for s in PARAMS}
    assert set(params) <= set(specs)
    assert set(params) == set(specs), set(specs) - set(params)   # every row, for the reader
    for key, value in params.items():
        assert type(value) is type(specs[key].default), key
        assert value == specs[key].default, key       # the file shows the defaults
        if specs[key].choices:
            assert value in specs[key].choices
        if specs[key].lo is not None:
            assert specs[key].lo <= value <= specs[key].hi, key
    # The file's policies make a valid pure-logic policy.
    CompensatorCore(Policy(**{k: v for k, v in params.items()
                              if k in Policy.__dataclass_fields__}))


def test_main_runs_as_a_process_and_stops_on_sigint(models, ros_context, tmp_path):
    """Run ``compensator_node`` main() (EventsExecutor) in a child process, params file."""
    path, model = models['paper']
    params = tmp_path / 'compensator.yaml'
    doc = yaml.safe_load((CONFIG / 'compensator.yaml').read_text())
    doc['/**']['ros__parameters']['model_file'] = str(path)
    params.write_text(yaml.safe_dump(doc))
    with node_process('gyro_tdc.nodes.compensator_node', '--params-file',
                      str(params)) as child:
        io = rclpy.create_node('feeder', context=ros_context)
        executor = make_executor('single', ros_context)
        executor.add_node(io)
        imu_pub = io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        temp_pub = io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
        out = []
        io.create_subscription(Imu, 'imu/data_compensated', out.append, RELIABLE)
        spin_until(executor, lambda: imu_pub.get_subscription_count() > 0
                   and temp_pub.get_subscription_count() > 0
                   and io.count_publishers('imu/data_compensated') > 0, 60.0,
                   what='discovery of the compensator process')
        t0 = 1_700_000_400.0
        temp = Temperature()
        temp.header.stamp.sec = int(t0)
        temp.temperature = 30.0
        sent = []
        for k in range(200):
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(to_ns(t0 + 0.001 * (k + 1)),
                                                                    10 ** 9)
            msg.angular_velocity.x = 0.01
            sent.append(msg)
        # Until both subscriptions of the process are matched on its side too, a message
        # may be lost: repeat the temperature and one probe sample until it comes back
        # compensated.

        def probe():
            temp_pub.publish(temp)
            imu_pub.publish(sent[0])
            return any(abs(m.angular_velocity.x - 0.01) > 1e-9 for m in out)

        spin_until(executor, probe, 60.0, what='compensation')
        out.clear()
        for msg in sent[1:]:
            imu_pub.publish(msg)
        spin_until(executor, lambda: len(out) >= 199, 60.0, what='199 outputs')
        t = np.array([stamp_s(to_ns(t0 + 0.001 * (k + 1))) for k in range(1, 200)])
        expect = compensate(model, t, np.full(199, 30.0), np.tile([0.01, 0, 0], (199, 1)))
        np.testing.assert_allclose(rates(out), expect, rtol=0, atol=1e-9)
        code, log = interrupt(child)
        assert code == 0
    assert f'model {model.model_id}' in log


@pytest.mark.parametrize('raw_cdr', [True, False])
def test_unexpected_failure_passes_the_sample_through(models, rig_factory, raw_cdr):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path), passthrough_variance=0.25, raw_cdr=raw_cdr)

    def broken(*args):
        rig.node.core.counts['in'] += 1
        raise FloatingPointError('overflow in the model')

    rig.node.core.process = broken
    imu_ns, omega, temp_ns, temp_c = warming_stream(n=30)
    sent = rig.feed(imu_ns, omega, temp_ns, temp_c)
    np.testing.assert_array_equal(rates(rig.out), rates(sent))
    assert all(o.angular_velocity_covariance[0] == 1e-6 + 0.25 for o in rig.out)
    st = rig.node.diagnostic_status()
    values = diag_values(st)
    assert st.level == DiagnosticStatus.ERROR and 'overflow in the model' in st.message
    assert values['messages in'] == values['messages out'] == '30'
    assert values['errors'] == '30'


@pytest.mark.parametrize('frame_id', ['', 'a', 'imu', 'imu_lin', 'imu_link', 'imu_link_0',
                                      'base_link/imu_sensor_frame'])
def test_imu_cdr_view_matches_rclpy_serialization(frame_id):
    msg = Imu()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_000, 123_456_789
    msg.orientation.w = 1.0
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = 0.1, -0.2, 0.3
    msg.angular_velocity_covariance[:] = np.arange(9) * 1e-6
    msg.linear_acceleration.x, msg.linear_acceleration.z = 0.5, 9.81
    msg.linear_acceleration_covariance[0] = 1e-3
    data = serialize_message(msg)
    sec, nanosec, base = locate(data)
    assert (sec, nanosec) == (1_700_000_000, 123_456_789)
    view = ImuView(data, base)
    assert view.angular_velocity() == (0.1, -0.2, 0.3)
    assert view.linear_acceleration() == (0.5, 0.0, 9.81)
    out = deserialize_message(view.patched(1.5, 2.5, -3.5, (1.0, 2.0, 4.0)), Imu)
    assert out.header == msg.header and out.orientation == msg.orientation
    assert (out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z) == \
        (1.5, 2.5, -3.5)
    expect = np.arange(9) * 1e-6
    expect[[0, 4, 8]] += (1.0, 2.0, 4.0)
    np.testing.assert_array_equal(out.angular_velocity_covariance, expect)
    assert out.linear_acceleration == msg.linear_acceleration
    np.testing.assert_array_equal(out.linear_acceleration_covariance,
                                  msg.linear_acceleration_covariance)
    msg.linear_acceleration_covariance[0] = -1.0
    assert ImuView(serialize_message(msg), base).linear_acceleration() is None
    msg.angular_velocity_covariance[0] = -1.0
    data = serialize_message(msg)
    out = deserialize_message(ImuView(data, base).patched(0.0, 0.0, 0.0, (1.0, 1.0, 1.0)), Imu)
    assert out.angular_velocity_covariance[0] == -1.0  # "no data" stays so


def test_imu_cdr_refuses_what_it_does_not_know():
    data = serialize_message(Imu())
    assert locate(data) is not None
    assert locate(b'\x00\x00' + data[2:]) is None      # big-endian encapsulation
    assert locate(data[:-8]) is None                     # truncated
    assert locate(data + b'\x00' * 8) is None           # trailing bytes
    assert locate(b'') is None
