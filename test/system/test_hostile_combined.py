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
One malformed message, one 1e30 reading and one forged model in a 2 kHz stream (real rclpy).

The hardening's done-when: a compensator_node fed 2 kHz for 5 s keeps running, every input
either comes out or is counted on /diagnostics, and no output marked compensated is non-finite
or beyond the plausible bound.
"""

from __future__ import annotations

import math
import re
import threading
import time

from compensator_rig import RELIABLE, to_ns
from gyro_tdc.base import MAX_DRIFT_RAD_S
from gyro_tdc.data import diagonal_marked
from gyro_tdc.errors import ModelFileError
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import model_from_dict, model_to_dict, save_model
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import serialize_message
from rosutil import matched_writers, spin_until_quiet
from sensor_msgs.msg import Imu
from synth import synth_run
import yaml

T0 = 1_700_000_000.0
RATE_HZ = 2000.0
N = 10_000                         # 5 s at 2 kHz
OMEGA = (0.01, -0.02, 0.005)
TEMP_C = 25.0
GLITCH_AT, MALFORMED_AT, FORGED_AT = 3000, 5000, 2000
_ID = re.compile(r"field `model_id` '[^']*' does not match the parameters \((\w+)\)")


def forged(model, path):
    """
    Write ``model`` with a gain of zero at TEMP_C (scale -1/dT, x), under a matching id.

    Its compensated rate is infinite there; the id is the one its content hashes to, as
    anyone can compute it.
    """
    d = model_to_dict(model)
    d['scale'][0] = -1.0 / (TEMP_C - model.t0_c)
    for _ in range(2):
        try:
            model_from_dict(d)
        except ModelFileError as exc:
            hit = _ID.search(str(exc))
            if hit is None:
                break                  # refused for what it computes, not for its id
            d['model_id'] = hit.group(1)
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    evil = model.replace(scale=np.array([d['scale'][0], 0.0, 0.0]))
    with np.errstate(divide='ignore', invalid='ignore'):
        out = compensate(evil, np.array([T0]), np.array([TEMP_C]), np.array([OMEGA]))
    assert not np.isfinite(out).all() or np.abs(out).max() > 1e6   # it computes garbage
    return path


class Stream(threading.Thread):
    """2 kHz of Imu with 10 Hz temperatures, one 1e30 reading and one malformed message."""

    def __init__(self, rig, raw_pub):
        super().__init__(daemon=True)
        self.rig, self.raw_pub = rig, raw_pub
        self.sent = 0
        self.rng = np.random.default_rng(24)

    def run(self):
        rig = self.rig
        start = time.monotonic()
        for k in range(N):
            ns = to_ns(T0 + k / RATE_HZ)
            if k % 200 == 0:
                rig.temperature(ns - 100_000, TEMP_C + 1e-4 * k / 200)
            if k == GLITCH_AT:
                rig.temperature(ns - 50_000, 1e30)
            if k == MALFORMED_AT:
                self.raw_pub.publish(serialize_message(Imu())[:40])     # truncated
            rig.imu(ns, OMEGA + 1e-4 * self.rng.standard_normal(3), k)
            self.sent += 1
            # Pacing of the producer (not a wait for the system under test).
            time.sleep(max(0.0, start + (k + 1) / RATE_HZ - time.monotonic()))


def values(status):
    return {kv.key: kv.value for kv in status.values}


@pytest.mark.serial        # 2 kHz for 5 s: the node's losses depend on the load beside it
def test_a_malformed_message_a_1e30_reading_and_a_forged_model_in_a_2khz_stream(
        rig_factory, tmp_path):
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    model = fit_model([run], features=('dT', 'dT2'), n_centers=8)
    good = save_model(model, tmp_path / 'good.yaml')
    evil = forged(model, tmp_path / 'forged.yaml')
    rig = rig_factory(executor_kind='events', model_file=str(good), expected_rate_hz=RATE_HZ,
                      temperature_timeout=60.0)
    node = rig.node
    raw_pub = rig.io.create_publisher(Imu, 'imu/data_raw', RELIABLE)
    client = AsyncParameterClient(rig.io, 'compensator_node')
    rig.spin_until(lambda: raw_pub.get_subscription_count() > 0
                   and matched_writers(node, 'imu/data_raw') >= 2
                   and client.services_are_ready(), what='raw publisher and parameters')
    stream = Stream(rig, raw_pub)
    stream.start()
    try:
        rig.spin_until(lambda: stream.sent >= FORGED_AT, 20.0, what='the stream under way')
        future = client.set_parameters([Parameter('model_file', value=str(evil))])
        rig.spin_until(future.done, 20.0, what='the forged model_file answered')
        rig.spin_until(lambda: not stream.is_alive(), 60.0, what='the stream sent')
    finally:
        stream.join(60.0)
    spin_until_quiet(rig.executor, lambda: (node.core.counts['in'], len(rig.out)), 1.0, 60.0)
    status = node.diagnostic_status()
    reports = rig.diag + [status]
    v = values(status)
    # It kept running, on the good model: the forged file was refused (at once, or when read).
    assert node.core.model_id == model.model_id and node.loading.model_file == str(good)
    last_reload = node.loading.last_reload
    assert last_reload.startswith('rejected: ') and str(evil) in last_reload
    assert any('model file refused' in s.message for s in reports)
    # Every input came out or is counted on /diagnostics.
    counts = node.core.counts
    assert stream.sent == N and counts['in'] == counts['out'] == len(rig.out)
    assert int(v['messages in']) + int(v['input missing']) == N, v
    assert v['input malformed'] == '1' and v['messages out'] == v['messages in']
    assert any('malformed input messages dropped (1' in s.message for s in reports)
    # The 1e30 reading was refused, said so, and changed nothing.
    assert v['temperatures rejected (implausible)'] == '1'
    assert any('temperatures rejected (implausible): 1 ' in s.message for s in reports)
    # Every sample compensated, or passed through and counted as such on /diagnostics (under
    # load a sample may come before its temperature); none goes out unaccounted for.
    passed = int(v['passed through'])
    assert counts['compensated'] + passed == counts['in'], (counts, node.core.flag_counts)
    # No output marked compensated is non-finite or beyond the plausible bound.
    marked = 0
    for msg in rig.out:
        w = (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z)
        assert all(math.isfinite(x) for x in w)
        if diagonal_marked(msg.angular_velocity_covariance):
            marked += 1
            assert all(abs(x - o) <= MAX_DRIFT_RAD_S for x, o in zip(w, OMEGA))
    assert marked == counts['compensated'] and marked >= len(rig.out) - passed
    expect = compensate(model, np.array([T0]), np.array([TEMP_C]), np.array([OMEGA]))[0]
    got = np.array([(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z)
                    for m in rig.out if diagonal_marked(m.angular_velocity_covariance)])
    assert np.abs(got - expect).max() < 1e-3          # the good model throughout (+ noise)
