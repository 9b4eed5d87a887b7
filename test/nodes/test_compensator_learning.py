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

"""compensator_node learn:=true: services, learn_file persistence, restart-resume."""

from __future__ import annotations

import json
import math
import os
import shutil
import stat

from compensator_rig import learning_caught_up, RELIABLE, to_ns
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Twist
from gyro_tdc.learn.learner import FORMAT, learned_model
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.nodes.compensator_inputs import MOTION_MESSAGES
from gyro_tdc.nodes.compensator_node import CompensatorNode
from gyro_tdc.nodes.executors import make_executor
from learn_states import BIAS, hostile_files, learned, plain_state
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rosutil import matched_readers, matched_writers, spin_until
from sensor_msgs.msg import Imu, Temperature
from std_srvs.srv import Trigger

RATE = 5.0          # Hz: 50 samples per 10 s still window


class LearnRig:
    """A learning compensator and a node that feeds it, calls its services and listens."""

    def __init__(self, context, **params):
        self.executor = make_executor('single', context)
        self.node = CompensatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.io = rclpy.create_node('feeder', context=context)
        self.imu_pub = self.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.temp_pub = self.io.create_publisher(Temperature, 'imu/temperature', RELIABLE)
        self.motion_pub = None
        if params.get('motion_topic'):
            self.motion_pub = self.io.create_publisher(
                MOTION_MESSAGES[params.get('motion_type', 'twist')], params['motion_topic'],
                RELIABLE)
        self.out: list[Imu] = []
        self.io.create_subscription(Imu, 'imu/data_compensated', self.out.append, RELIABLE)
        self.save = self.io.create_client(Trigger, 'compensator_node/learn_save')
        self.reset = self.io.create_client(Trigger, 'compensator_node/learn_reset')
        for node in (self.node, self.io):
            self.executor.add_node(node)
        spin_until(self.executor, lambda: self.imu_pub.get_subscription_count() > 0
                   and self.temp_pub.get_subscription_count() > 0
                   and self.save.service_is_ready() and self.reset.service_is_ready()
                   and matched_writers(self.node, 'imu/data_raw') > 0
                   and matched_writers(self.node, 'imu/temperature') > 0
                   and matched_readers(self.node, 'imu/data_compensated') > 0
                   and matched_writers(self.io, 'imu/data_compensated') > 0
                   and (self.motion_pub is None
                        or (self.motion_pub.get_subscription_count() > 0
                            and matched_writers(self.node, self.motion_pub.topic_name) > 0)),
                   10.0,
                   what='discovery')

    def feed(self, t0, secs, temp, bias, moving, seed, paced=False):
        """
        Publish ``secs`` of IMU at RATE (still at ``bias`` or moving) and 1 Hz temperature.

        ``paced``: each second's first output is awaited before the next temperature is
        published, so no reading is stamped seconds ahead of the last IMU sample compensated.
        """
        rng = np.random.default_rng(seed)
        n = int(secs * RATE)
        w = (0.3 if moving else 1e-4) * rng.standard_normal((n, 3)) + (0 if moving else bias)
        return self.stream(t0, w, temp, (lambda t: None) if paced else None)

    def stream(self, t0, w, temp, each_second=None):
        """
        Publish the rates ``w`` (N, 3) at RATE from ``t0``, a temperature every second.

        ``each_second(t)``, when given, runs once a second after that second's first IMU
        sample came out; the outputs are awaited at least every 200 samples.
        """
        start = len(self.out)
        for k, row in enumerate(w):
            t = t0 + k / RATE
            if k % int(RATE) == 0:
                m = Temperature()
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(to_ns(t), 10 ** 9)
                m.temperature = temp
                self.temp_pub.publish(m)
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(to_ns(t), 10 ** 9)
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = \
                (float(v) for v in row)
            msg.orientation_covariance[0] = -1.0
            msg.linear_acceleration_covariance[0] = -1.0
            self.imu_pub.publish(msg)
            if k % 200 == 199 or (each_second is not None and k % int(RATE) == 0):
                spin_until(self.executor, lambda: len(self.out) >= start + k + 1, 10.0,
                           what='outputs')
                if k % int(RATE) == 0:
                    each_second(t)
        spin_until(self.executor, lambda: len(self.out) >= start + len(w), 10.0,
                   what='outputs')
        return t0 + len(w) / RATE

    def call(self, client):
        future = client.call_async(Trigger.Request())
        spin_until(self.executor, future.done, 10.0, what='service answer')
        return future.result()

    def close(self):
        self.executor.shutdown()
        self.io.destroy_node()
        self.node.destroy_node()


def _values(node):
    assert node.learning.wait()           # the learner's figures after its step in progress
    return {kv.key: kv.value for kv in node.diagnostic_status().values}


def test_learn_save_reset_and_restart_resume(ros_context, tmp_path):
    path = tmp_path / 'learn' / 'learned.json'
    bias = np.array([0.01, -0.02, 0.005])
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        node = rig.node
        assert node.core.model is None and node.learning.learner is not None
        t = rig.feed(1000.0, 100.0, 20.0, bias, False, 1)
        t = rig.feed(t, 20.0, 20.0, bias, True, 2)
        r = rig.call(rig.save)
        assert r.success and r.message == f'saved {path}' and path.is_file()
        # The first still stretch's bias is the model now: a still sample comes out ~0.
        assert node.core.model is not None
        np.testing.assert_allclose(node.core.model.intercept, bias, atol=5e-5)
        t = rig.feed(t, 20.0, 20.0, bias, False, 3)
        assert abs(rig.out[-1].angular_velocity.x) < 1e-3
        v = _values(node)
        assert v['learn points'] == '1' and v['learn still s'] == '100'
        assert v['learn features'] == 'bias' and 'swapped' in v['learn prediction check']
        assert v['learn covered degC'] == '20.00 .. 20.00'
        # A second stretch 4 degC warmer: two bins, a dT model.
        t = rig.feed(t, 100.0, 24.0, bias + [4e-3, 0.0, 0.0], False, 4)
        t = rig.feed(t, 20.0, 24.0, bias, True, 5)
        assert rig.call(rig.save).success
        saved = json.loads(path.read_text())
        assert saved['fit']['features'] == ['dT'] and len(saved['bins']) >= 2
        assert node.learning.wait()       # the learner is the worker's during a step
        state = json.loads(json.dumps(node.learning.learner.state()))
        assert state == saved
    finally:
        rig.close()            # destroy_node saves again: the window in progress judged too
    final = json.loads(path.read_text())
    assert final['bins'] == saved['bins'] and final['fit'] == saved['fit']
    assert final['windows'] == saved['windows'] + 1
    saved = final
    # Restarted: resumes learn_file, nothing lost; the learned model is in use at once.
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        node = rig.node
        assert json.loads(json.dumps(node.learning.learner.state())) == saved
        assert node.core.model is not None
        np.testing.assert_allclose(node.core.model.linear[0, 0], 1e-3, rtol=0.05)
        r = rig.call(rig.reset)
        assert r.success and 'no model' in r.message
        assert node.core.model is None and _values(node)['learn points'] == '0'
    finally:
        rig.close()
    assert json.loads(path.read_text())['bins'] == {}


def _motion(cls, t, speed, turn):
    """Return a motion report of type ``cls`` (a bare Twist carries no stamp)."""
    msg = cls()
    twist = msg if isinstance(msg, Twist) else (
        msg.twist.twist if isinstance(msg, Odometry) else msg.twist)
    if not isinstance(msg, Twist):
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(to_ns(t), 10 ** 9)
    twist.linear.x, twist.angular.z = speed, turn
    return msg


def _zero_model(path):
    """Save a model that corrects nothing (the re-anchoring needs a model to shift)."""
    return save_model(learned_model(np.zeros((2, 3)), ('dT',), 20.0, (0.0, 40.0),
                                    np.full(3, 1e-8)), path)


@pytest.mark.parametrize('motion_type,moving', [
    ('twist', True), ('twist_stamped', True), ('odometry', True), ('twist', False)])
def test_a_slow_constant_turn_reported_by_motion_topic_is_not_still(ros_context, tmp_path,
                                                                    motion_type, moving):
    """
    A vehicle turning slowly at a constant rate looks still to the gyro.

    The gyro reads a constant 0.005 rad/s (below still_max_rate) with tiny noise for 150 s,
    a textbook still stretch. While cmd_vel (or odometry) reports the turn, the node neither
    re-anchors nor learns; the same data with zero motion reports does both. A learned model
    takes effect ``learn_swap_delay`` (200 s) of stamps after the data that made it, so none
    replaces the re-anchored prior during the 150 s stream, whenever the learn timer runs; a
    sample stamped past that delay installs it.
    """
    rig = LearnRig(ros_context, learn=True, model_file=str(_zero_model(tmp_path / 'm.yaml')),
                   reanchor_on_start=True, reanchor_tolerance=3e-5, motion_topic='cmd_vel',
                   motion_type=motion_type, input_reliability='reliable',
                   learn_swap_delay=200.0)
    node, cls = rig.node, MOTION_MESSAGES[motion_type]
    turn = 0.005 if moving else 0.0
    n = int(150.0 * RATE)

    def report(t):                        # the report of this second, at its first stamp
        reports = node.core.motion_reports
        rig.motion_pub.publish(_motion(cls, t, 2.0 * turn, turn))
        spin_until(rig.executor, lambda: node.core.motion_reports > reports, 10.0,
                   what='motion report')

    try:
        early = motion_type == 'twist'   # a bare Twist before any IMU stamp: ignored, counted
        if early:
            rig.motion_pub.publish(_motion(cls, 0.0, 1.0, 1.0))
            spin_until(rig.executor, lambda: node.motion.ignored == 1, 10.0, what='ignored')
        w = (0.0, 0.0, 0.005) + 1e-5 * np.random.default_rng(7).standard_normal((n, 3))
        t = rig.stream(1000.0, w, 20.0, report)
        anchor = node.core.anchor         # a learned model swapped in below clears it
        assert node.learning.wait()
        node.learning.learner.flush()              # the stretch in progress too
        assert rig.call(rig.save).message.startswith('no learn_file')   # steps, schedules
        assert node.core.model_id == node.learning.learner.prior.model_id        # not due yet
        rig.stream(t + 250.0, w[:1], 20.0)   # a sample past the delay: a learned one is due
        assert node.learning.wait()
        v = _values(node)
        assert v['motion'] == ('moving' if moving else 'not moving')
        assert v['motion reports'] == str(int(n / RATE))
        assert v['motion reports ignored'] == ('1' if early else '0')
        s = node.learning.learner.summary()
        if moving:
            assert anchor is None and node.core.still_windows_rejected > 0
            assert s['points'] == 0 and s['still_s'] == 0.0
            assert node.core.model_id == node.learning.learner.prior.model_id  # none swapped in
        else:             # the same data, reported still: a false stillness, by design here
            assert anchor is not None
            np.testing.assert_allclose(anchor.delta, (0.0, 0.0, 0.005), atol=3e-5)
            assert s['points'] >= 1 and s['still_s'] >= 60.0
            assert node.core.model_id != node.learning.learner.prior.model_id   # the turn, learned
    finally:
        rig.close()


def test_a_model_file_loaded_while_learning_becomes_the_prior(ros_context, tmp_path):
    """A model_file set (or ~/reload) at run time is the model a learned one must beat."""
    b1 = np.array([0.01, -0.02, 0.005])
    b2 = b1 + [0.01, 0.0, 0.0]
    # The set and ~/reload answer once the file is installed (a busy machine can read it
    # slower than the default 0.1 s load_wait; then it would install after the answer).
    rig = LearnRig(ros_context, learn=True, load_wait=10.0)
    try:
        node = rig.node
        t = rig.feed(1000.0, 100.0, 20.0, b1, False, 1)
        t = rig.feed(t, 20.0, 20.0, b1, True, 2)
        rig.call(rig.save)                       # steps the learner: b1 learned, in use
        assert node.learning.wait()
        assert node.loading.model_file == 'learned' and node.learning.learner.fit is not None
        path = tmp_path / 'b2.yaml'
        save_model(learned_model(np.vstack([b2, np.zeros(3)]), ('dT',), 20.0, (0.0, 40.0),
                                 np.full(3, 1e-8)), path)
        result = node.set_parameters([Parameter('model_file', value=str(path))])[0]
        assert result.successful
        b2_id = node.core.model_id
        learner = node.learning.learner
        assert node.loading.model_file == str(path) and learner.prior.model_id == b2_id
        assert learner.model is learner.prior and learner.fit is None
        # The next power-up (a new session) is still at b2: the file predicts it, so the
        # check compares the candidate with the file's model (not the old learned b1).
        t = rig.feed(t + 3600.0, 100.0, 20.0, b2, False, 3)
        rig.feed(t, 20.0, 20.0, b2, True, 4)
        rig.call(rig.save)
        assert node.learning.wait()
        check = node.learning.learner.check
        assert check is not None and check['current_mse'] < 1e-8, check
        # ~/reload of a changed file: the new contents are the prior.
        save_model(learned_model(np.vstack([b1, np.zeros(3)]), ('dT',), 20.0, (0.0, 40.0),
                                 np.full(3, 1e-8)), path)
        reload = rig.io.create_client(Trigger, 'compensator_node/reload')
        spin_until(rig.executor, reload.service_is_ready, 10.0, what='reload service')
        assert rig.call(reload).success and node.learning.wait()
        assert node.core.model_id not in ('', b2_id)
        assert node.learning.learner.prior.model_id == node.core.model_id
    finally:
        rig.close()


@pytest.fixture(scope='module')
def learned_state():
    """Return the state of a learner that learned two still stretches (a file's content)."""
    return plain_state(learned(rate_hz=20.0))


def _unusable(tmp_path, state, name):
    """Make learn.json a file the node cannot use; return it and the file to watch."""
    path = tmp_path / 'learn.json'
    if name == 'symlink':                 # as root, a link to the real /etc/passwd
        watched = tmp_path / 'passwd'
        shutil.copyfile('/etc/passwd', watched)
        path.symlink_to(watched)
        return path, watched
    if name == 'too_big':                 # a valid state past the 4 MiB limit
        path.write_text(json.dumps({**state, 'motion': [[float(k), False]
                                                        for k in range(300_000)]}))
    else:
        path.write_bytes(hostile_files(state)[name])
    return path, path


@pytest.mark.parametrize('name', ['model_yaml', 'truncated', 'list', 'bins_list', 'deep',
                                  'nan_fit', 'symlink', 'too_big'])
def test_a_learn_file_the_node_cannot_use_is_kept_and_learning_goes_beside_it(
        ros_context, tmp_path, learned_state, name):
    """
    Not a learner state: the node starts, keeps the file byte for byte and learns beside it.

    A model YAML given by mistake, truncated JSON, a JSON list, ``"bins": []``, deep
    nesting, a fit holding NaN, a symbolic link (to a copy of /etc/passwd) and a state over
    the size limit: one WARN line, /diagnostics WARN naming the file learned into, the
    stream compensated with finite values, and the restart resumes from that file.
    """
    path, watched = _unusable(tmp_path, learned_state, name)
    before = watched.read_bytes()
    alt = tmp_path / 'learn.json.gyro_tdc-learn.json'
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        node = rig.node
        assert node.core.model is None and node.learning.learner.summary()['points'] == 0
        t = rig.feed(1000.0, 100.0, 20.0, np.array(BIAS), False, 1, paced=True)
        rig.feed(t, 20.0, 20.0, np.array(BIAS), True, 2, paced=True)
        assert all(math.isfinite(m.angular_velocity.x) for m in rig.out)
        r = rig.call(rig.save)
        assert watched.read_bytes() == before, 'the file was written over'
        assert r.success and r.message == f'saved {alt}'
        where = _values(node)['learn file']
        assert where.startswith(f'{alt} (learn_file ') and 'kept as it is' in where, where
        status = node.diagnostic_status()
        assert status.level >= DiagnosticStatus.WARN and 'learn_file refused' in status.message
    finally:
        rig.close()
    assert watched.read_bytes() == before and path.is_symlink() == (name == 'symlink')
    saved = json.loads(alt.read_text())
    assert saved['format'] == FORMAT and len(saved['bins']) == 1
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:                                  # restarted: resumes from the file beside it
        node = rig.node
        assert node.learning.learner.summary()['points'] == 1 and node.core.model is not None
        assert node.learning.learn_store.path == alt
    finally:
        rig.close()
    assert watched.read_bytes() == before


def test_a_mode_000_learn_file_is_resumed_and_written_readable(ros_context, tmp_path,
                                                               learned_state):
    """A learn_file of mode 000 is written back with u+rw, so the next start can read it."""
    path = tmp_path / 'learn.json'
    path.write_text(json.dumps(learned_state))
    os.chmod(path, 0)
    rig = LearnRig(ros_context, learn=True, learn_file=str(path))
    try:
        learner = rig.node.learning.learner
        assert learner.summary()['points'] == 2 and rig.node.core.model is not None
    finally:
        rig.close()
    mode = stat.S_IMODE(path.stat().st_mode)
    assert mode & 0o600 == 0o600, oct(mode)
    assert json.loads(path.read_text())['bins'] == learned_state['bins']


def test_a_failing_save_is_on_diagnostics_and_logged_once_a_minute(ros_context, tmp_path,
                                                                   capfd):
    """
    learn_file's directory becomes unwritable (a file where it was): saves fail, go on.

    Each failed periodic save is counted and its reason shown on /diagnostics (WARN), the log
    says so at most once a minute (not once a save), and the next good save clears it.
    """
    where = tmp_path / 'learn'
    path = where / 'learned.json'
    rig = LearnRig(ros_context, learn=True, learn_file=str(path), learn_save_period=1.0)
    try:
        node = rig.node
        t = rig.feed(1000.0, 120.0, 20.0, np.array(BIAS), False, 1)
        spin_until(rig.executor, learning_caught_up(node), 10.0, what='learning')
        # The periodic save runs on the learner's thread a save period after the step.
        spin_until(rig.executor, path.is_file, 10.0, what='the first save')
        assert _values(node)['learn save error'] == ''
        where.rename(tmp_path / 'moved')
        where.write_text('not a directory any more\n')
        for k in range(4):                # four windows, each stepped and saved on its own
            t = rig.feed(t, 11.0, 20.0, np.array(BIAS), False, 2 + k)
            spin_until(rig.executor, learning_caught_up(node), 10.0, what='learning')
        v = _values(node)
        status = node.diagnostic_status()         # ERROR too: no model learned yet
        assert status.level >= DiagnosticStatus.WARN
        assert 'learn_file not saved (' in status.message, status.message
        assert str(path) in v['learn save error'] and int(v['learn save failures']) >= 3
        logged = [line for line in capfd.readouterr().err.splitlines()
                  if 'cannot save learn_file' in line]
        assert len(logged) == 1, logged
        where.unlink()                    # the directory is back: the next save succeeds
        (tmp_path / 'moved').rename(where)
        rig.feed(t, 11.0, 20.0, np.array(BIAS), False, 9)
        spin_until(rig.executor, learning_caught_up(node), 10.0, what='learning')
        v = _values(node)
        assert v['learn save error'] == '' and 'learn_file not saved' not in \
            node.diagnostic_status().message
        assert json.loads(path.read_text())['format'] == FORMAT
    finally:
        rig.close()
