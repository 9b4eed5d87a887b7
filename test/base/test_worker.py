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

"""Background jobs (no rclpy): the newest request wins, each result is claimed once."""

from __future__ import annotations

import threading

from gyro_tdc.base.worker import LatestJob


def test_a_job_runs_off_the_calling_thread_and_is_claimed_once():
    jobs = LatestJob()
    release = threading.Event()
    caller = threading.get_ident()
    job = jobs.start('a.yaml', 'reload', lambda: (release.wait(10.0),
                                                  threading.get_ident() != caller))
    assert not job.wait(0.01) and jobs.claim() is None and jobs.pending is job
    release.set()
    assert job.wait(10.0) and job.result == (True, True)
    assert jobs.claim(job) is job
    assert jobs.claim() is None and jobs.pending is None


def test_a_newer_request_makes_the_older_one_stale():
    jobs = LatestJob()
    release = threading.Event()
    old = jobs.start('old.yaml', 'parameter', lambda: release.wait(10.0) and 'old')
    new = jobs.start('new.yaml', 'parameter', lambda: 'new')
    assert new.wait(10.0) and jobs.claim(old) is None
    release.set()
    assert old.wait(10.0) and old.result == 'old'
    assert jobs.claim() is new and new.result == 'new'
    assert jobs.claim() is None


def test_a_dropped_job_is_never_handed_out():
    jobs = LatestJob()
    job = jobs.start('a.yaml', 'parameter', lambda: 'a')
    assert job.wait(10.0)
    jobs.drop()
    assert jobs.pending is None and jobs.claim() is None and jobs.claim(job) is None
