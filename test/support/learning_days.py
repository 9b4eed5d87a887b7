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

"""Two vehicle days streamed through the compensator core with a learner (learning tests)."""

from __future__ import annotations

import math

from gyro_tdc.runtime import PASSTHROUGH
import numpy as np

BOUND = 1.3


DEG2 = (180.0 / math.pi) ** 2


GAP_S = 3600.0          # night between the days: a new session


def day_offset(days):
    d1, d2 = days
    return d1.imu_t[-1] + GAP_S - d2.imu_t[0]


def stream(core, learner, d, off, *, poll=600, start=0, stop=None, on_poll=None,
           accepted=None):
    """
    Stream a day through the core, one message at a time; poll the learner off-path.

    ``accepted``, a list, collects ``(due stamp, model_id)`` of each model a poll scheduled.
    """
    stop = len(d.imu_t) if stop is None else stop
    imu_t = (d.imu_t + off)[start:stop]
    out = np.empty((imu_t.size, 3))
    ok = np.ones(imu_t.size, dtype=bool)
    tt, tc = (d.temp_t + off).tolist(), d.temp_c.tolist()
    j = int(np.searchsorted(tt, imu_t[0], side='left')) if imu_t.size else 0
    if j:                         # the newest reading before the first sample
        core.add_temperature(tt[j - 1], tc[j - 1])
    m = len(tt)
    acc = d.accel[start:stop].tolist()
    for k, (t, w, a) in enumerate(zip(imu_t.tolist(), d.gyro[start:stop].tolist(), acc)):
        while j < m and tt[j] <= t:
            core.add_temperature(tt[j], tc[j])
            j += 1
        ox, oy, oz, _, fl, _, _ = core.process(t, w[0], w[1], w[2], a)
        out[k] = (ox, oy, oz)
        ok[k] = not fl & PASSTHROUGH
        if k % poll == poll - 1:
            swaps = core.learn_step()
            if accepted is not None:
                accepted += [(due, model.model_id) for due, model in swaps]
            if on_poll is not None:
                on_poll(start + k)
    return out, ok


def floor_ratio(days, out, ok, start=0):
    d2 = days[1]
    ref = d2.ref[start:start + out.shape[0]]
    floor = d2.truth.noise_std ** 2 * DEG2
    return ((out[ok] - ref[ok]) ** 2).mean(axis=0) * DEG2 / floor
