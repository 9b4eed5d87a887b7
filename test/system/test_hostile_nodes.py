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
compensator_node against hostile input, with real rclpy: each case reproduces one failure.

Files that crash parsers, a slow model file read while the IMU streams, loops and double
compensation, input losses, re-anchoring across reloads, the stale passthrough on
/diagnostics and start-up parameter errors.
"""

from __future__ import annotations

from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from compensator_rig import ok_but_backlog, rates, RELIABLE, stamp_s, to_ns
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from gyro_tdc.errors import ConfigError
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.nodes.compensator_backlog import QUEUE_AGE_WARN_S
from gyro_tdc.nodes.compensator_node import CompensatorNode, read_model
from gyro_tdc.nodes.executors import make_executor
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosutil import (graph_report, Lines, matched_readers, matched_writers, node_process,
                     spin_until, spin_until_quiet)
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger
from synth import synth_run

HERE = Path(__file__).resolve().parent
NODE = 'gyro_tdc.nodes.compensator_node'
NESTED = '[' * 600 + ']' * 600 + '\n'   # 1.2 KB: RecursionError in an unbounded parser
T0 = 1_700_000_600.0


@pytest.fixture(scope='module')
def models(tmp_path_factory):
    """Two static models fitted on the same run: paper (dT, dT2) and linear (dT only)."""
    root = tmp_path_factory.mktemp('models')
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    paper = fit_model([run], features=('dT', 'dT2'), n_centers=10)
    linear = fit_model([run], features=('dT',), n_centers=6)
    return {'paper': (save_model(paper, root / 'paper.yaml'), paper),
            'linear': (save_model(linear, root / 'linear.yaml'), linear)}


def values(status):
    return {kv.key: kv.value for kv in status.values}


def reload(rig):
    """Call the compensator's ~/reload and return the response."""
    client = rig.io.create_client(Trigger, 'compensator_node/reload')
    spin_until(rig.executor, client.service_is_ready, 10.0, what='reload service')
    future = client.call_async(Trigger.Request())
    spin_until(rig.executor, future.done, 15.0, what='reload answered')
    rig.io.destroy_client(client)
    return future.result()


def set_model_file(rig, value):
    """Set model_file through the parameter service; return the SetParametersResult."""
    client = AsyncParameterClient(rig.io, 'compensator_node')
    spin_until(rig.executor, client.services_are_ready, 10.0, what='parameter services')
    future = client.set_parameters([Parameter('model_file', value=value)])
    spin_until(rig.executor, future.done, 15.0, what='parameter set answered')
    return future.result().results[0]


def steady(model, temp_c, omega=(0.01, -0.02, 0.005)):
    """Return the compensated rate of ``omega`` at a constant temperature (static model)."""
    return compensate(model, np.array([T0]), np.array([temp_c]), np.array([omega]))[0]


# -- 1: a file that crashes parsers -------------------------------------------------------


def test_nested_brackets_at_start_up_are_one_line_and_the_node_runs(tmp_path):
    nested = tmp_path / 'nested.yaml'
    nested.write_text(NESTED)
    with node_process(NODE, '-p', f'model_file:={nested}') as child:
        lines = Lines(child.stdout)
        line = lines.wait_for('cannot load model_file', 60.0)
        assert child.poll() is None  # still running, passing the raw rate through
        child.send_signal(signal.SIGINT)
        code = child.wait(timeout=60)
        out = lines.join()
    assert code == 0, out
    assert 'Traceback' not in out and 'RecursionError' not in out
    assert str(nested) in line and 'nesting deeper than' in line
    assert sum('nested.yaml' in x for x in out.splitlines()) == 1


def test_nested_brackets_on_reload_and_parameter_set_keep_the_model(models, rig_factory,
                                                                    tmp_path):
    path, model = models['paper']
    live = tmp_path / 'live.yaml'
    live.write_text(Path(path).read_text())
    # load_wait: each reload answers with the file's verdict, however busy the machine.
    rig = rig_factory(model_file=str(live), load_wait=10.0)
    imu_ns = [to_ns(T0 + 0.01 * k) for k in range(50)]
    omega = np.tile([0.01, -0.02, 0.005], (50, 1))
    rig.feed(imu_ns, omega, [to_ns(T0 - 1.0)], [20.0])
    live.write_text(NESTED)
    res = reload(rig)
    assert not res.success and 'nesting deeper than' in res.message and '\n' not in res.message
    assert rig.node.core.model_id == model.model_id
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN and '\n' not in st.message
    assert f'model file refused, keeping {model.model_id}' in st.message
    other = tmp_path / 'other.yaml'
    other.write_text(NESTED)
    result = set_model_file(rig, str(other))
    assert not result.successful and 'nesting deeper than' in result.reason
    assert rig.node.get_parameter('model_file').value == str(live)
    more = [to_ns(T0 + 1.0 + 0.01 * k) for k in range(50)]
    rig.feed(more, omega)  # still compensating with the old model
    np.testing.assert_allclose(rates(rig.out[-50:]), np.tile(steady(model, 20.0), (50, 1)),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize('crash', [RecursionError, MemoryError])
def test_a_parser_crash_is_a_refused_file(models, rig_factory, crash):
    """Should a parser limit ever let a hostile file through, the node's load edge holds."""
    path, model = models['paper']
    hostile = {'on': True}

    def loader(name):
        if hostile['on']:
            raise crash('deep in the parser')
        return read_model(name)

    rig = rig_factory(model_file=str(path), node_kwargs={'loader': loader}, load_wait=10.0)
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.ERROR
    assert f'{crash.__name__} while reading the model file' in st.message
    hostile['on'] = False
    assert reload(rig).success and rig.node.core.model_id == model.model_id
    hostile['on'] = True
    res = reload(rig)
    assert not res.success and crash.__name__ in res.message
    result = set_model_file(rig, str(models['linear'][0]))
    assert not result.successful and crash.__name__ in result.reason
    assert rig.node.core.model_id == model.model_id


# -- 3: a slow model file never stalls compensation ----------------------------------------


class Streamer(threading.Thread):
    """
    Publish the rig's Imu at a steady rate from its own thread until stopped.

    Stamped one period apart, as a live IMU: the node's queue age reads them against its
    steady clock (stamps slower than real time would read as a node falling behind).
    """

    def __init__(self, rig, rate_hz):
        super().__init__(daemon=True)
        self.rig, self.period = rig, 1.0 / rate_hz
        self.sent = 0
        self._halt = threading.Event()

    def run(self):
        start = time.monotonic()
        while not self._halt.is_set():
            self.publish_next()
            # Pacing of the producer (not a wait for the system under test).
            time.sleep(max(0.0, start + self.sent * self.period - time.monotonic()))

    def publish_next(self):
        """Publish the stream's next sample; return its stamp as the node reads it, s."""
        ns = to_ns(T0 + self.sent * self.period)
        self.rig.imu(ns, (0.01, -0.02, 0.005), self.sent)
        self.sent += 1
        return stamp_s(ns)

    def stop(self):
        self._halt.set()
        self.join(5.0)
        return self.sent

    def close(self, tries=10):
        """
        Once the node is idle, publish samples until one comes in; return the count sent.

        A lost tail has no later stamp to show it missing: the sample that comes in does.
        """
        for _ in range(tries):
            stamp = self.publish_next()
            deadline = time.monotonic() + 10.0
            while self.rig.node.core.last_t != stamp and time.monotonic() < deadline:
                self.rig.executor.spin_once(timeout_sec=0.05)
            if self.rig.node.core.last_t == stamp:
                return self.sent
        raise AssertionError(f'none of {tries} closing samples came in')


@pytest.mark.parametrize('via', ['reload', 'parameter'])
def test_a_slow_model_file_never_stalls_compensation(models, rig_factory, via):
    path_a, model_a = models['paper']
    path_b, model_b = models['linear']
    target = str(path_a if via == 'reload' else path_b)
    reading, release, timed_out = threading.Event(), threading.Event(), threading.Event()
    slow = {'name': None}

    def loader(name):
        if name == slow['name']:
            reading.set()
            # The test releases it once messages flowed (in a finally): the bound is longer
            # than the test's own waits before the release (15 s + 15 s), even under load.
            if not release.wait(60.0):
                timed_out.set()
        return read_model(name)

    rig = rig_factory(executor_kind='events', model_file=str(path_a), temperature_timeout=60.0,
                      node_kwargs={'loader': loader})
    rig.temperature(to_ns(T0 - 1.0), 20.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='temperature')
    streamer = Streamer(rig, 1000.0)
    streamer.start()
    try:
        rig.spin_until(lambda: len(rig.out) >= 200, what='200 outputs before the reload')
        slow['name'] = target
        if via == 'reload':
            client = rig.io.create_client(Trigger, 'compensator_node/reload')
            rig.spin_until(client.service_is_ready, what='reload service')
            future = client.call_async(Trigger.Request())
        else:
            client = AsyncParameterClient(rig.io, 'compensator_node')
            rig.spin_until(client.services_are_ready, what='parameter services')
            future = client.set_parameters([Parameter('model_file', value=target)])
        rig.spin_until(future.done, 15.0, what='answer')
        assert reading.is_set() and not release.is_set()
        n0 = len(rig.out)
        rig.spin_until(lambda: len(rig.out) >= n0 + 1000, 15.0,
                       what='1000 outputs while the file is being read')
        assert rig.node.loading.last_reload == f'loading {target}'
        assert rig.node.core.model_id == model_a.model_id
        release.set()
        rig.spin_until(lambda: rig.node.loading.last_reload.startswith('loaded'), what='swap')
        swapped_at = rig.node.core.counts['out']  # samples compensated before the swap
        n1 = len(rig.out)
        rig.spin_until(lambda: len(rig.out) >= n1 + 200, what='200 outputs after the swap')
    finally:
        release.set()
        sent = streamer.stop()
    rig.spin_until(lambda: len(rig.out) >= sent, what='every output')
    assert not timed_out.is_set()
    assert len(rig.out) == sent
    assert rig.node.core.counts == {'in': sent, 'out': sent, 'compensated': sent}
    assert rig.node.inputs.lost == 0
    if via == 'reload':
        assert future.result().success and 'background' in future.result().message
    else:
        assert future.result().results[0].successful
    assert rig.node.core.model_id == (model_a if via == 'reload' else model_b).model_id
    # One model or the other for every sample, and a single switch: an atomic swap.
    got = rates(rig.out)
    is_a = np.all(np.abs(got - steady(model_a, 20.0)) < 1e-12, axis=1)
    is_b = np.all(np.abs(got - steady(model_b, 20.0)) < 1e-12, axis=1)
    assert np.all(is_a | is_b)
    if via == 'parameter':
        first_b = int(np.argmax(is_b))
        assert n0 + 1000 <= first_b <= swapped_at     # the 1000 taken before the release
        assert is_b[first_b:].all() and is_a[:first_b].all()


# -- 9: loops and double compensation ------------------------------------------------------


def test_refuses_to_subscribe_to_its_own_output(ros_context):
    with pytest.raises(ConfigError, match='both resolve to /imu/data_compensated'):
        CompensatorNode(context=ros_context, cli_args=[
            '--ros-args', '-r', 'imu/data_raw:=imu/data_compensated'])
    done = subprocess.run([sys.executable, '-m', NODE, '--ros-args', '-r',
                           'imu/data_raw:=imu/data_compensated'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    errors = [x for x in done.stderr.splitlines() if x.strip()]
    assert len(errors) == 1 and 'Traceback' not in done.stderr + done.stdout
    assert errors[0].startswith('compensator_node: error: ') and 'loop' in errors[0]


def test_chained_compensators_are_reported(models, ros_context):
    path, model = models['paper']
    executor = make_executor('single', ros_context)
    first = CompensatorNode(context=ros_context, parameter_overrides=[
        Parameter('model_file', value=str(path))], cli_args=[
        '--ros-args', '-r', 'imu/data_compensated:=chain/middle'])
    second = CompensatorNode(context=ros_context, node_name='second', parameter_overrides=[
        Parameter('model_file', value=str(path))], cli_args=[
        '--ros-args', '-r', 'imu/data_raw:=chain/middle'])
    io = rclpy.create_node('feeder', context=ros_context)
    pub = io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
    temp_pub = io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
    out, diag = [], []
    io.create_subscription(Imu, 'imu/data_compensated', out.append, RELIABLE)
    io.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diag.extend(m.status), 10)
    for node in (first, second, io):
        executor.add_node(node)
    try:
        links = {'imu/data_raw': lambda: (pub.get_subscription_count(),
                                          matched_writers(first, 'imu/data_raw')),
                 'imu/temperature': lambda: (temp_pub.get_subscription_count(),
                                             matched_writers(first, 'imu/temperature'),
                                             matched_writers(second, 'imu/temperature')),
                 'chain/middle': lambda: (second.count_publishers('chain/middle'),
                                          matched_readers(first, 'chain/middle'),
                                          matched_writers(second, 'chain/middle')),
                 'imu/data_compensated': lambda: (
                     io.count_publishers('imu/data_compensated'),
                     matched_readers(second, 'imu/data_compensated'),
                     matched_writers(io, 'imu/data_compensated'))}
        want = {'imu/data_raw': (1, 1), 'imu/temperature': (2, 1, 1), 'chain/middle': (1, 1, 1),
                'imu/data_compensated': (1, 1, 1)}
        try:
            spin_until(executor, lambda: all(links[k]() == v for k, v in want.items()),
                       what='discovery')
        except AssertionError as exc:      # say which link, and who the graph lists
            raise AssertionError(f'{exc}: {({k: f() for k, f in links.items()})} against '
                                 f'{want}; {graph_report(io, *want)}') from None
        temp = Temperature()
        temp.header.stamp.sec = int(T0) - 1
        temp.temperature = 20.0
        temp_pub.publish(temp)
        spin_until(executor, lambda: first.core.temps.received == 1
                   and second.core.temps.received == 1, what='temperatures')
        for k in range(100):
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(to_ns(T0 + 0.01 * k),
                                                                    10 ** 9)
            msg.angular_velocity.x = 0.01
            msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
            msg.angular_velocity_covariance[8] = 1e-6
            pub.publish(msg)
        spin_until(executor, lambda: len(out) == 100, what='100 outputs of the chain')
        upstream = second.diagnostics.upstream_compensators
        spin_until(executor, lambda: upstream() == ('/compensator_node',),
                   what='the graph shows the first compensator upstream')
        assert first.diagnostics.upstream_compensators() == ()
        # The 1 Hz timer may have reported the marked samples already: look at every report.
        reports = [s for s in diag if s.name.startswith('/second')]
        st = second.diagnostic_status()
        assert st.level == DiagnosticStatus.WARN
        assert any('input already compensated by gyro_tdc (' in s.message and
                   s.level == DiagnosticStatus.WARN for s in reports + [st])
        assert 'published by gyro_tdc compensator /compensator_node' in st.message
        assert values(st)['already compensated'] == '100'
        st = first.diagnostic_status()
        # OK: a falling-behind report of its own (the burst on a starved machine) aside.
        assert ok_but_backlog(st), (st.level, st.message)
        assert values(st)['already compensated'] == '0'
        assert not any('compensator' in s.message for s in diag
                       if s.name.startswith('/compensator_node'))
    finally:
        executor.shutdown()
        for node in (io, second, first):
            node.destroy_node()


# -- 10: input losses ----------------------------------------------------------------------


def burst(rig, count, reliability, history, depth=None, stall=False, every=False):
    """
    Run burst_publisher.py in a child process; return the rig's input count when done.

    With ``stall`` the executor does not spin while the burst is published: the compensator
    is held up (as by a long pause of its process) and takes the queued messages after.
    With ``every`` the burst is done when all ``count`` came in (a lost one never does: the
    deadline fails the test), not after a quiet second: a reliable writer repairs what the
    transport dropped only at its next heartbeat, seconds later on a loaded machine.
    """
    child = subprocess.Popen([sys.executable, str(HERE.parent / 'support' / 'burst_publisher.py'),
                              str(count), reliability, history, str(depth or count)],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        lines = Lines(child.stdout)
        rig.spin_until(lambda: lines.has('matched'), 30.0, what='burst publisher matched')
        # Matched already; the graph cache can trail the match under load.
        try:
            rig.spin_until(lambda: rig.node.count_publishers('imu/data_raw') == 2, 60.0,
                           what='burst publisher in the graph')
        except AssertionError as exc:      # who the graph lists: a stale or a missing one
            raise AssertionError(f'{exc}; {graph_report(rig.node, "imu/data_raw")}') from None
        child.stdin.write('go\n')
        child.stdin.flush()
        if stall:
            lines.wait_for('published', 120.0)
        rig.spin_until(lambda: lines.has('published'), 120.0, what='burst published')
        if every:
            rig.spin_until(lambda: rig.node.core.counts['in'] >= count, 300.0,
                           what=f'all {count} messages in')
        spin_until_quiet(rig.executor, lambda: rig.node.core.counts['in'], 1.0, 60.0)
    finally:
        child.stdin.close()
        child.wait(timeout=30)
    return rig.node.core.counts['in']


@pytest.mark.serial  # losses depend on the load: not beside other tests
def test_a_burst_beyond_capacity_keeps_one_output_per_input(models, rig_factory):
    """Best-effort input: what DDS reports lost is a lower bound (its own queue overwrites)."""
    rig = rig_factory(executor_kind='events', model_file=str(models['paper'][0]))
    rig.temperature(to_ns(1_700_000_499.0), 20.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='temperature')
    received = burst(rig, 20000, 'best_effort', 'keep_last', stall=True)
    counts = rig.node.core.counts
    assert counts['in'] == counts['out'] == received
    assert received < 20000
    assert 0 <= rig.node.inputs.lost <= 20000 - received
    reports = rig.diag + [rig.node.diagnostic_status()]
    assert values(reports[-1])['input lost'] == str(rig.node.inputs.lost)
    if rig.node.inputs.lost:
        assert any(s.level == DiagnosticStatus.WARN and 'input messages lost (' in s.message
                   for s in reports)


@pytest.mark.serial  # losses depend on the load: not beside other tests
def test_reliable_input_counts_every_loss_of_a_keep_last_publisher(models, rig_factory):
    """A held-up compensator: the publisher (keep last 100) drops, DDS reports the drops."""
    rig = rig_factory(executor_kind='events', model_file=str(models['paper'][0]),
                      input_reliability='reliable')
    rig.temperature(to_ns(1_700_000_499.0), 20.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='temperature')
    received = burst(rig, 20000, 'reliable', 'keep_last', depth=100, stall=True)
    counts = rig.node.core.counts
    assert counts['in'] == counts['out'] == received < 20000
    # The message-lost event is dispatched on its own, after the samples (under load: later).
    rig.spin_until(lambda: rig.node.inputs.lost > 0, 60.0, what='message-lost event')
    # Most of the publisher's drops are reported (measured: 76 % to 99 %), never more.
    assert 0 < rig.node.inputs.lost <= 20000 - received
    # /diagnostics said so (WARN) at the report after the losses, with the count.
    reports = rig.diag + [rig.node.diagnostic_status()]
    assert any(s.level == DiagnosticStatus.WARN and 'input messages lost (' in s.message
               for s in reports)
    assert values(reports[-1])['input lost'] == str(rig.node.inputs.lost)


@pytest.mark.serial  # losses depend on the load: not beside other tests
def test_reliable_input_loses_nothing(rig_factory):
    rig = rig_factory(executor_kind='events', input_reliability='reliable')
    received = burst(rig, 20000, 'reliable', 'keep_all', every=True)
    counts = rig.node.core.counts
    assert received == counts['out'] == 20000 and rig.node.inputs.lost == 0
    st = rig.node.diagnostic_status()
    assert 'lost' not in st.message and values(st)['input reliability'] == 'reliable'


def dtdt_model(centres):
    """Return a valid dTdt model of ``centres`` RBF centres (spread from a fitted one)."""
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    base = fit_model([run], features=('dT', 'dT2', 'dTdt'), n_centers=10, fit_params=False)
    rng = np.random.default_rng(8)
    pick = rng.integers(0, base.centers.shape[0], centres)
    return base.replace(
        centers=base.centers[pick] + 0.01 * rng.standard_normal((centres, 3)),
        widths=base.widths[pick], weights=base.weights[pick] * (10 / centres))


@pytest.mark.serial        # a full core for 5 s: it would slow the tests beside it
def test_a_node_that_cannot_keep_up_says_so_with_the_count(rig_factory, tmp_path):
    """
    A valid 10,000-centre dTdt model at 2 kHz costs about the whole budget per sample.

    The node falls behind (WARN: samples wait over a second in its 2000-sample queue), the
    queue overwrites its oldest samples (DDS reports none of them): /diagnostics says WARN
    with the count, and every sample sent either came in or is counted missing, exactly (the
    stamps are 0.5 ms apart).
    """
    path = save_model(dtdt_model(10_000), tmp_path / 'dtdt10k.yaml')
    read_model(str(path))                                   # valid: loaded, not refused
    rig = rig_factory(executor_kind='events', model_file=str(path), temperature_timeout=60.0)
    rig.temperature(to_ns(T0 - 1.0), 20.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='temperature')
    streamer = Streamer(rig, 2000.0)
    streamer.start()
    # 5 s of stream (10,000 samples when the streamer gets the CPU and the interpreter lock:
    # it shares them with the node it floods, and on a loaded machine sends far fewer).
    end = time.monotonic() + 5.0
    try:
        while time.monotonic() < end:
            rig.executor.spin_once(timeout_sec=0.05)
    finally:
        streamer.stop()
    assert streamer.sent > 0
    spin_until_quiet(rig.executor, lambda: rig.node.core.counts['in'], 1.0, 60.0)
    sent = streamer.close()
    node = rig.node
    # Each report counts the samples missing since the one before: wait until the timer has
    # judged every sample and its report has come back (under load the last one was still
    # in flight, and the sum below came out short).
    rig.spin_until(lambda: not node.diagnostics.backlog.samples and rig.diag and values(
        rig.diag[-1])['input missing'] == str(node.diagnostics.backlog.missing), 60.0,
        what='the report of the last samples received')
    reports = rig.diag + [node.diagnostic_status()]
    missing = node.diagnostics.backlog.missing
    assert node.core.model.centers.shape[0] == 10_000 and node.core.counts['compensated'] > 0
    assert missing < sent
    assert node.core.counts['in'] + missing == sent
    assert values(reports[-1])['input missing'] == str(missing)
    warned = [s for s in reports if s.level == DiagnosticStatus.WARN
              and 'input samples missing by stamp (' in s.message]
    if missing:         # it fell behind: the WARNs name every sample lost
        assert warned and sum(
            int(s.message.split('input samples missing by stamp (')[1].split()[0])
            for s in warned) == missing
    else:               # a quiet, fast CPU kept up even here: nothing lost, nothing warned
        assert not warned
    # How far behind depends on the CPU: the WARN is owed when a report measured a sample
    # waiting longer than the threshold.
    ages = [float(values(s)['queue age max s']) for s in reports if values(s)['queue age max s']]
    behind = any('falling behind: a sample waited' in s.message for s in reports)
    assert behind == (max(ages, default=0.0) > QUEUE_AGE_WARN_S), (ages, behind)


# -- 12: re-anchoring across reloads -------------------------------------------------------


def test_reload_of_the_same_file_keeps_the_reanchoring(models, rig_factory, tmp_path):
    path, model = models['paper']
    live = tmp_path / 'live.yaml'
    live.write_text(Path(path).read_text())
    rig = rig_factory(model_file=str(live), reanchor_on_start=True, still_window=1.0,
                      load_wait=10.0)
    rng = np.random.default_rng(12)
    n = 400  # 2 s: still after 1 s, the last 100 samples compensated with the shift
    raw = -np.tile(steady(model, 22.0, (0.0, 0.0, 0.0)), (n, 1)) + [8e-4, -6e-4, 4e-4] \
        + rng.normal(0, 1e-3, (n, 3))
    stamps = [to_ns(T0 + 0.005 * k) for k in range(n)]
    rig.feed(stamps, raw, [to_ns(T0 - 1.0)], [22.0])
    anchor = rig.node.core.anchor
    assert anchor is not None
    before = rates(rig.out[-100:])
    assert reload(rig).success
    assert rig.node.core.anchor is anchor
    assert values(rig.node.diagnostic_status())['reanchor'] == f'done at t={anchor.t:.3f} s'
    rig.feed([to_ns(T0 + 2.0 + 0.005 * k) for k in range(100)], raw[-100:])
    np.testing.assert_array_equal(rates(rig.out[-100:]), before)  # the shift stays applied
    # A different model clears it and waits for stillness again.
    save_model(models['linear'][1], live)
    assert reload(rig).success
    assert rig.node.core.anchor is None
    assert values(rig.node.diagnostic_status())['reanchor'] == 'waiting for stillness'
    rig.feed([to_ns(T0 + 3.0 + 0.005 * k) for k in range(n)], raw)
    assert rig.node.core.anchor is not None and rig.node.core.anchor.t > T0 + 3.0


# -- 15: /diagnostics under passthrough, start-up errors -----------------------------------


def test_diagnostics_name_the_stale_temperature_under_passthrough(models, rig_factory):
    path, model = models['paper']
    rig = rig_factory(model_file=str(path), temperature_timeout=0.5, stale_policy='passthrough')
    diag = []
    rig.io.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diag.extend(
        s for s in m.status if s.name.startswith('/compensator_node')), 10)
    rig.feed([to_ns(T0 + 0.01 * k) for k in range(200)], np.zeros((200, 3)),
             [to_ns(T0)], [20.0])
    rig.spin_until(lambda: any(values(s)['messages in'] == '200' for s in diag),
                   what='/diagnostics after the stream')
    v = values(next(s for s in diag if values(s)['messages in'] == '200'))
    assert v['why not'] == 'temperature stale, raw rate passed through'
    assert v['temperature stale'] == 'True' and int(v['stale']) > 0


@pytest.mark.parametrize('module', [NODE, 'gyro_tdc.nodes.driver_node'])
@pytest.mark.parametrize('content', [None, 'a: [unclosed\n'])
def test_a_params_file_that_cannot_be_used_is_named_without_traceback(module, content, tmp_path):
    """A missing params file: one line, exit 2; one rcl cannot parse: rcl's log, ours."""
    bad = tmp_path / 'params.yaml'
    if content is not None:
        bad.write_text(content)
    done = subprocess.run([sys.executable, '-m', module, '--ros-args', '--params-file',
                           str(bad)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert 'Traceback' not in done.stderr + done.stdout
    errors = [x for x in done.stderr.splitlines() if x.strip()]
    ours = [x for x in errors if ': error: ' in x]
    assert len(ours) == 1 and str(bad) in ours[0] and 'parser.c' not in ours[0], done.stderr
    if content is None:
        assert errors == ours and 'cannot read the params file' in ours[0]
    else:           # rcl logs its own line first: the file's parse error is its to say
        assert 'cannot start: ' in ours[0] and all('[rcl]' in x for x in errors if x not in ours)


@pytest.mark.parametrize('module,arg,name', [
    (NODE, 'out_of_range:=bogus', 'out_of_range'),
    (NODE, 'queue_depth:=abc', 'queue_depth'),
    (NODE, 'temperature_timeout:=-1.0', 'temperature_timeout'),
    (NODE, 'input_reliability:=sometimes', 'input_reliability'),
    ('gyro_tdc.nodes.driver_node', 'backend:=bogus', 'backend'),
])
def test_start_up_parameter_errors_are_one_line(module, arg, name):
    done = subprocess.run([sys.executable, '-m', module, '--ros-args', '-p', arg],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert 'Traceback' not in done.stderr + done.stdout
    errors = [x for x in done.stderr.splitlines() if x.strip()]
    assert len(errors) == 1 and name in errors[0] and ': error: ' in errors[0], done.stderr


def test_a_slow_refused_parameter_is_named_back(models, rig_factory, tmp_path):
    """A set accepted before the file was read, then refused: model_file names the old one."""
    path_a, model_a = models['paper']
    broken = tmp_path / 'broken.yaml'
    broken.write_text('format_version: [\n')
    release = threading.Event()

    def loader(name):
        if name == str(broken):
            release.wait(10.0)
        return read_model(name)

    rig = rig_factory(model_file=str(path_a), node_kwargs={'loader': loader})
    client = AsyncParameterClient(rig.io, 'compensator_node')
    rig.spin_until(client.services_are_ready, what='parameter services')
    future = client.set_parameters([Parameter('model_file', value=str(broken))])
    rig.spin_until(future.done, 15.0, what='answer')
    assert future.result().results[0].successful  # slower than load_wait: accepted
    assert rig.node.get_parameter('model_file').value == str(broken)
    release.set()
    rig.spin_until(lambda: rig.node.get_parameter('model_file').value == str(path_a),
                   what='model_file named back')
    assert rig.node.core.model_id == model_a.model_id
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN and 'malformed YAML' in st.message


def test_a_newer_request_wins_over_a_file_still_being_read(models, rig_factory):
    path_a, model_a = models['paper']
    path_b, model_b = models['linear']
    release, finished = threading.Event(), threading.Event()

    def loader(name):
        if name == str(path_b):
            release.wait(10.0)
            try:
                return read_model(name)
            finally:
                finished.set()
        return read_model(name)

    rig = rig_factory(model_file=str(path_a), node_kwargs={'loader': loader})
    assert set_model_file(rig, str(path_b)).successful  # accepted, being read
    assert set_model_file(rig, '').successful  # newer: no model
    release.set()
    rig.spin_until(finished.is_set, what='the slow read finished')
    spin_until_quiet(rig.executor, lambda: rig.node.loading.last_reload, 0.3)
    assert rig.node.core.model is None and rig.node.loading.last_reload == 'no model'


# -- malformed CDR on imu/data_raw ----------------------------------------------------------


def _malformed_payloads():
    """Return serialized messages that are not an Imu: each once killed the node (exit 1)."""
    from rclpy.serialization import serialize_message
    good = serialize_message(Imu())
    big_endian = b'\x00\x00' + good[2:]
    huge_frame_id = good[:12] + b'\xff\xff\xff\xff' + good[16:]
    return {'truncated': good[:40], 'garbage': bytes(range(256)) * 3,
            'big-endian header': big_endian, 'frame_id length 2**32-1': huge_frame_id,
            'empty': b''}


@pytest.mark.parametrize('executor_kind', ['single', 'events'])
def test_malformed_messages_are_dropped_counted_and_reported(models, rig_factory,
                                                             executor_kind):
    """Any participant can publish bytes: the node drops them, counts them and goes on."""
    rig = rig_factory(executor_kind=executor_kind, model_file=str(models['paper'][0]))
    raw = rig.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
    rig.spin_until(lambda: raw.get_subscription_count() > 0
                   and matched_writers(rig.node, 'imu/data_raw') >= 2,
                   what='raw publisher matched')
    rig.temperature(to_ns(T0 - 1.0), 20.0)
    rig.spin_until(lambda: rig.node.core.temps.received == 1, what='temperature')
    payloads = _malformed_payloads()
    for k, data in enumerate(payloads.values()):
        rig.imu(to_ns(T0 + k), (0.01, 0.0, 0.0), k)
        raw.publish(data)
    rig.imu(to_ns(T0 + len(payloads)), (0.01, 0.0, 0.0))
    rig.spin_until(lambda: len(rig.out) == len(payloads) + 1
                   and rig.node.inputs.malformed == len(payloads), what='outputs and drops')
    counts = rig.node.core.counts
    assert counts['in'] == counts['out'] == len(payloads) + 1
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN
    assert f'malformed input messages dropped ({len(payloads)}' in st.message
    assert values(st)['input malformed'] == str(len(payloads))
    # The next report, with nothing new, is OK again; the total stays.
    st = rig.node.diagnostic_status()
    assert 'malformed' not in st.message and values(st)['input malformed'] == str(len(payloads))
