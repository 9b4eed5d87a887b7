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
The suite's own isolation: one ROS_DOMAIN_ID per pytest process, and ``serial`` tests alone.

``ros_domain`` and ``serial_gate`` (test/support) are exercised across real processes, as the
xdist workers of two runs use them.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import subprocess
import sys
import time

import pytest
import ros_domain
from rosutil import Lines
from serial_gate import SerialGate

SUPPORT = Path(__file__).resolve().parents[1] / 'support'


def _distance(a, b):
    d = (a - b) % ros_domain.DOMAINS
    return min(d, ros_domain.DOMAINS - d)


@pytest.mark.parametrize('base', [1, 2, 40, 100, 101])
def test_worker_ids_are_every_other_id_once_and_never_the_base(base):
    for worker in (0, 1, 3):
        ids = list(ros_domain.candidates(base, worker))
        assert len(ids) == len(set(ids)) == 100
        assert base not in ids and all(1 <= d <= 101 for d in ids)
    firsts = [next(ros_domain.candidates(base, w)) for w in range(4)]
    # The first four workers: 20 or more apart from the base, from each other, and from the
    # first ids of any run whose base is within 19 of this one's.
    for other in range(base - 19, base + 20):
        others = [(other - 1) % 101 + 1] + [next(ros_domain.candidates(other, w))
                                            for w in range(4)]
        for d in firsts:
            assert d not in others or other == base
    assert min(_distance(a, b) for a in firsts + [base] for b in firsts + [base] if a != b) >= 20


def test_this_process_holds_its_id():
    """The id conftest set is claimed (by this process, or by a run told to use it too)."""
    domain = int(os.environ['ROS_DOMAIN_ID'])
    assert 1 <= domain <= 101
    other = subprocess.run([sys.executable, '-c', f'import ros_domain; print(ros_domain.claim('
                            f'{domain}))'], cwd=SUPPORT, capture_output=True, text=True,
                           timeout=60)
    assert other.stdout.strip() == 'False'


def _holder(code):
    child = subprocess.Popen([sys.executable, '-c', code], cwd=SUPPORT, text=True,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    return child, Lines(child.stdout)


def test_two_runs_on_one_base_never_share_an_id():
    code = ('import ros_domain, sys\n'
            'print(*[ros_domain.worker_domain(7, f"gw{i}")[0] for i in range(3)], flush=True)\n'
            'sys.stdin.read()\n')
    first, first_lines = _holder(code)
    second, second_lines = _holder(code)
    try:
        ids = [set(map(int, lines.wait_for(' ', 30.0).split()))
               for lines in (first_lines, second_lines)]
        assert len(ids[0]) == len(ids[1]) == 3 and not ids[0] & ids[1]
        assert 7 not in ids[0] | ids[1]
    finally:
        for child in (first, second):
            child.stdin.close()
            child.wait(timeout=30)
    # Their locks went with them.
    again = subprocess.run([sys.executable, '-c', 'import ros_domain; print(all('
                            f'ros_domain.claim(d) for d in {sorted(ids[0])}))'],
                           cwd=SUPPORT, capture_output=True, text=True, timeout=60)
    assert again.stdout.strip() == 'True'


def _try(path, mode):
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, mode | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    finally:
        os.close(fd)


def _until(condition, what, timeout_s=30.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.02)


def test_a_serial_test_waits_for_the_others_and_keeps_them_out():
    key = f'selftest-{os.getpid()}'
    gate_file, room_file = SerialGate(key).paths
    code = ('import serial_gate, sys\n'
            f'g = serial_gate.SerialGate({key!r})\n'
            'g.enter(sys.argv[1] == "serial"); print("in", flush=True)\n'
            'sys.stdin.readline(); g.leave(False); print("out", flush=True)\n'
            'sys.stdin.read()\n')
    plain = subprocess.Popen([sys.executable, '-c', code, 'plain'], cwd=SUPPORT, text=True,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    serial = None
    try:
        plain_lines = Lines(plain.stdout)
        plain_lines.wait_for('in', 30.0)
        assert _try(room_file, fcntl.LOCK_SH) and not _try(room_file, fcntl.LOCK_EX)
        serial = subprocess.Popen([sys.executable, '-c', code, 'serial'], cwd=SUPPORT,
                                  text=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        serial_lines = Lines(serial.stdout)
        # Waiting for the room, the serial test holds the gate: no new test gets in.
        _until(lambda: not _try(gate_file, fcntl.LOCK_EX), 'the serial test takes the gate')
        assert not serial_lines.has('in')
        plain.stdin.write('\n')
        plain.stdin.flush()
        serial_lines.wait_for('in', 30.0)
        assert _try(gate_file, fcntl.LOCK_EX)          # the gate is open again ...
        assert not _try(room_file, fcntl.LOCK_SH)      # ... but the room is the serial test's
        serial.stdin.write('\n')
        serial.stdin.flush()
        serial_lines.wait_for('out', 30.0)
        assert _try(room_file, fcntl.LOCK_SH)
    finally:
        for child in (plain, serial):
            if child is not None:
                child.stdin.close()
                child.wait(timeout=30)
        SerialGate(key).remove()
    assert not any(Path(p).exists() for p in (gate_file, room_file))
