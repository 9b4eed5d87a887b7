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
The field criterion through a real compensator_node: learn on the vehicle, then restart.

A vehicle day 1 then day 2 (config/scenarios/vehicle_day*.yaml at a reduced 2 Hz, so the two
compressed 6 h days are 86,400 messages) stream through a real CompensatorNode with
``learn: true``, no model and ``learn_swap_delay`` 240 s: a feeder publishes pre-serialised
Imu and Temperature (reliable, the node's ``input_reliability: reliable``) with flow control:
400 messages (200 s of stamps) at a time, then it waits for every output from a draining
subscriber and for the node's own learn timer to have caught up with them. Each learned
model takes effect 240 s of stamps after the data that made it, always after the learner
has made it ready (asserted: no late swap), so the output does not depend on when the
timer ran (test_learning_cadence shows it bit for bit at the core). Judged against the
simulator's true rate with test_learning's figures: day 2 within 1.3x the noise floor per
axis; a node destroyed in the middle of day 2 and restarted from ``learn_file`` gives the
same result. And the other path: a ``train --still-only`` model of day 1 loaded by a node with
default parameters plus ``reanchor_on_start``: day 2 within 1.1x, equal to the node's pure
logic (tools/field_day.stream) message for message.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

from compensator_rig import learning_caught_up, RELIABLE
from gyro_tdc.data.imu_cdr import encode, field_slice, IMU_DOUBLES, Layout
from gyro_tdc.identify.train import train_still_only
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from gyro_tdc.sim import simulate_run, to_run
from learning_days import BOUND, day_offset, floor_ratio
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rosutil import matched_readers, matched_writers, spin_until
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger

RATE_HZ = 2.0        # Hz: the learner's 10 s windows still hold 20 samples
# Messages per flow-control chunk (200 s of stamps): its 200 temperatures stay within the
# core's TemperatureHold (256) when the executor takes them before the chunk's IMU messages.
STEP = 400
SWAP_DELAY_S = 240.0  # learn_swap_delay: longer than a chunk, so no swap comes late
FRAME = 'imu_link'
STILL_ONLY_BOUND = 1.1   # a still-only model of day 1, day 2 through the node
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def days():
    """Vehicle day 1 (seed 1) and day 2 (seed 2, hotter) at 2 Hz, as test_learning's."""
    return (simulate_run('vehicle_day1', seed=1, rate_hz=RATE_HZ),
            simulate_run('vehicle_day2', seed=2, rate_hz=RATE_HZ))


def _field_day():
    """Return tools/field_day.py as a module (its ``stream``: the node's pure logic)."""
    spec = importlib.util.spec_from_file_location('field_day', ROOT / 'tools' / 'field_day.py')
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool


def _ns(t):
    ns = np.round(np.asarray(t) * 1e9).astype(np.int64)
    return ns // 10 ** 9, ns % 10 ** 9


def serialised(d, off):
    """Return a day's Imu and Temperature messages as CDR bytes, stamps shifted by ``off``."""
    n = d.imu_t.size
    values = np.zeros((n, IMU_DOUBLES))
    values[:, field_slice('orientation')][:, 3] = 1.0
    values[:, field_slice('orientation_covariance')][:, 0] = -1.0
    values[:, field_slice('angular_velocity')] = d.gyro
    values[:, field_slice('linear_acceleration')] = d.accel
    imu = encode(*_ns(d.imu_t + off), FRAME, values)
    temps = encode(*_ns(d.temp_t + off), FRAME,
                   np.column_stack([d.temp_c, np.full(d.temp_c.size, 0.01)]))
    return imu, temps, d.imu_t + off, d.temp_t + off


class Live:
    """
    A learning compensator, a feeder and a draining subscriber on one executor.

    The feeder's writers are made afresh with each compensator (:meth:`start`): a reliable
    writer that outlives a reader keeps its old samples, and tells the reader that replaces
    it, once, as it matches it, that those are not for it. Within one process Fast DDS hands
    that over directly: a reader that has not matched the writer back by then (a loaded
    machine) drops it, and behind more such samples than its keep-all limit (5,000) it
    accepts nothing more. A fresh writer has no old samples.
    """

    def __init__(self, context, learn_file, params=None):
        self.context = context
        self.learn_file = str(learn_file)
        self.params = params
        self.executor = make_executor('events', context)
        self.io = rclpy.create_node('feeder', context=context)
        self.out: list[bytes] = []
        self.io.create_subscription(Imu, 'imu/data_compensated', self.out.append, RELIABLE,
                                    raw=True)
        self.executor.add_node(self.io)
        self.node = None
        self.start()

    def start(self):
        """Start a compensator (learn:=true, no model) resuming ``learn_file``, or ``params``."""
        params = self.params or [
            Parameter('learn', value=True), Parameter('learn_file', value=self.learn_file),
            Parameter('learn_swap_delay', value=SWAP_DELAY_S)]
        self.imu_pub = self.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.temp_pub = self.io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
        self.node = CompensatorNode(context=self.context, parameter_overrides=[
            *params, Parameter('input_reliability', value='reliable')])
        self.executor.add_node(self.node)
        self.save = self.io.create_client(Trigger, 'compensator_node/learn_save')
        # Each link matched on both sides: a reader drops what comes before it matched the
        # writer (the temperatures are best effort: for good). The service's discovery too.
        self.spin_until(lambda: self.imu_pub.get_subscription_count() > 0
                        and self.temp_pub.get_subscription_count() > 0
                        and matched_writers(self.node, 'imu/data_raw') > 0
                        and matched_writers(self.node, 'imu/temperature') > 0
                        and matched_readers(self.node, 'imu/data_compensated') > 0
                        and matched_writers(self.io, 'imu/data_compensated') > 0
                        and (self.params is not None or self.save.service_is_ready()),
                        'discovery')

    def stop(self):
        """Destroy the compensator (killed, it saves learn_file on the way out), its writers."""
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.node = None
        self.io.destroy_client(self.save)
        self.spin_until(lambda: self.imu_pub.get_subscription_count() == 0
                        and self.temp_pub.get_subscription_count() == 0
                        and matched_writers(self.io, 'imu/data_compensated') == 0, 'unmatched')
        self.io.destroy_publisher(self.imu_pub)
        self.io.destroy_publisher(self.temp_pub)

    def spin_until(self, predicate, what, timeout_s=30.0):
        try:
            spin_until(self.executor, predicate, timeout_s, what=what)
        except AssertionError as exc:
            raise AssertionError(f'{exc}; {self.where()}') from None

    def where(self):
        """Say where a stream stands: what the node took in and sent, what came back."""
        if self.node is None:
            return f'no compensator; {len(self.out)} outputs received'
        counts = self.node.core.counts
        busy = self.node.learning is not None and self.node.learning.job is not None
        return (f'the compensator took {counts["in"]} IMU messages in and sent {counts["out"]}, '
                f'{len(self.out)} outputs received; learner step running: {busy}')

    def stream(self, msgs, start=0, stop=None):
        """
        Publish ``msgs[start:stop]`` of a day in stamp order; one output for each input.

        Flow control: STEP messages at a time, then every output is awaited and the node's
        learn timer has caught up with them (a candidate is then ready before its stamp).
        """
        imu, temps, imu_t, temp_t = msgs
        stop = len(imu) if stop is None else stop
        first = len(self.out)
        j = max(int(np.searchsorted(temp_t, imu_t[start], side='right')) - 1, 0)
        if temp_t[j] <= imu_t[start]:
            # The reading held at the first sample, received before it: the executor may
            # take a burst's IMU messages before its temperatures (later ones are held).
            self.temp_pub.publish(temps[j])
            j += 1
            latest = self.node.core.temps.latest
            self.spin_until(lambda: latest != self.node.core.temps.latest, 'temperature')
        for lo in range(start, stop, STEP):
            hi = min(lo + STEP, stop)
            for k in range(lo, hi):
                while j < len(temps) and temp_t[j] <= imu_t[k]:
                    self.temp_pub.publish(temps[j])
                    j += 1
                self.imu_pub.publish(imu[k])
            self.spin_until(lambda: len(self.out) >= first + hi - start, 'outputs')
            if self.node.learning is not None:
                self.spin_until(learning_caught_up(self.node), 'learn timer')
        assert len(self.out) == first + stop - start          # one out for every one in
        if self.node.learning is not None:
            assert self.node.learning.learner.diagnostic_values()['learn late swaps'] == '0'
        return self.out[first:]

    def close(self):
        if self.node is not None:
            self.stop()
        self.executor.shutdown()
        self.io.destroy_node()


def rates(outs):
    """Return the angular velocity and the passthrough-free mask of compensated Imu bytes."""
    rec = np.frombuffer(b''.join(outs), dtype=Layout(len(FRAME) + 1).dtype)
    data = rec['data']
    cov = data[:, field_slice('angular_velocity_covariance')]
    return data[:, field_slice('angular_velocity')], cov[:, 0] < 1e-4


def test_learn_on_the_vehicle_through_a_live_node_and_restart(days, ros_context, tmp_path):
    d1, d2 = days
    day1, day2 = serialised(d1, 0.0), serialised(d2, day_offset(days))
    live = Live(ros_context, tmp_path / 'full.json')
    try:
        live.stream(day1)
        out, ok = rates(live.stream(day2))
    finally:
        live.close()
    ratio = floor_ratio(days, out, ok)
    print('day 2 / noise floor, uninterrupted:', np.round(ratio, 3))
    assert ok.all() and np.all(ratio <= BOUND), ratio
    # Killed (destroyed) in the middle of day 2, restarted from learn_file.
    half = len(day2[0]) // 2
    path = tmp_path / 'cut.json'
    live = Live(ros_context, path)
    try:
        live.stream(day1)
        live.stream(day2, stop=half)
        live.stop()
        saved = json.loads(path.read_text())
        live.start()                     # resumes learn_file: nothing lost
        assert json.loads(json.dumps(live.node.learning.learner.state())) == saved
        assert saved['bins'] and live.node.core.model is not None
        out2, ok2 = rates(live.stream(day2, start=half))
    finally:
        live.close()
    r_full = floor_ratio(days, out[half:], ok[half:], half)
    r_restart = floor_ratio(days, out2, ok2, half)
    print('second half of day 2: uninterrupted', np.round(r_full, 3), 'restarted',
          np.round(r_restart, 3))
    assert ok2.all() and np.all(r_restart <= BOUND), r_restart
    np.testing.assert_allclose(r_restart, r_full, rtol=0.02)


def test_still_only_model_of_day1_streams_day2_through_a_live_node(days, ros_context, tmp_path):
    """
    Train ``--still-only`` on day 1; day 2 through a real node is within 1.1x.

    Default parameters plus ``reanchor_on_start`` (and reliable input): day 2, driving
    included, within 1.1x the noise floor per axis against the simulator's true rate, and
    the node's output equal to its pure logic (tools/field_day.stream) message for message.
    """
    d1, d2 = days
    model_file = tmp_path / 'still_only.yaml'
    res = train_still_only(['vehicle_day1'], model_file, runs=[to_run(d1)])
    assert 'lag' in res.model.features
    live = Live(ros_context, tmp_path / 'unused.json', params=[
        Parameter('model_file', value=str(model_file)),
        Parameter('reanchor_on_start', value=True)])
    try:
        assert live.node.core.model is not None and live.node.learning is None
        out, ok = rates(live.stream(serialised(d2, 0.0)))
        anchored = live.node.core.anchor is not None
    finally:
        live.close()
    assert anchored and np.count_nonzero(ok) > 0.999 * ok.size
    ratio = floor_ratio(days, out, ok)
    print('still-only model of day 1, day 2 through the node / noise floor:', np.round(ratio, 3))
    assert np.all(ratio <= STILL_ONLY_BOUND), ratio
    core_out, core_ok, _ = _field_day().stream(
        res.model, d2.imu_t, d2.gyro, d2.accel, d2.temp_t, d2.temp_c)
    np.testing.assert_array_equal(ok, core_ok)
    np.testing.assert_allclose(out, core_out, rtol=0.0, atol=1e-12)
