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
A trained model as the learner's prior on a still 1 Hz logger (``config/still_logger.yaml``).

Three simulated days of a motionless L3GD20 logger, a turn-on offset per day, bias wander;
trained on days 1-2 (one offset per session), day 3 reaching ~5 degC beyond the trained
range streamed through the core as the node runs it. ``bench/bench_sessions.py`` (family 2)
sweeps such loggers; this is one of its draws.
"""

from __future__ import annotations

import math

from gyro_tdc.data import Run, split_sessions
from gyro_tdc.identify import estimate_t0, fit_model
from gyro_tdc.identify.features import features_for_fit
from gyro_tdc.learn import Learner
from gyro_tdc.model import compensate
from gyro_tdc.runtime import CompensatorCore, Policy
from gyro_tdc.signal import block_mean
from gyro_tdc.sim import load_scenario, simulate_run
from gyro_tdc.sim.simulator import to_run
import numpy as np
import pytest

DEG = math.pi / 180.0
DAY_S = 86400.0
GAP_S = 600.0
DRAW = {'offset': 0.2, 'res': 0.004, 'lo': 6.3, 'hi': 23.7, 'amp': 2.5, 'curvature': 0.91,
        'tau_pkg': 1513.0, 'bi': 0.0037, 'rrw': 4.1e-05}


def _day(k: int, seed: int):
    """Simulate day ``k`` (0-based): one power cycle, the trend and the daily cycle."""
    d = DRAW
    t = np.arange(0.0, DAY_S + 1.0, 3600.0)
    tg = t + k * DAY_S
    temp = (d['lo'] + (d['hi'] - d['lo']) * tg / (3 * DAY_S)
            + d['amp'] * np.sin(2.0 * np.pi * tg / DAY_S - np.pi / 2.0))
    c = d['curvature']
    sc = {'format_version': 1, 'name': f'day{k + 1}', 'sensor': 'l3gd20', 'imu_rate_hz': 1.0,
          'duration_s': DAY_S - GAP_S,
          'profile': {'start_c': float(temp[0]), 'segments': [
              {'kind': 'points', 't_s': t.tolist(), 'temp_c': temp.tolist()}]},
          'thermal': {'tau_package_s': d['tau_pkg']},
          'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': d['res']},
          'gyro': {'effects': ['bias', 'dT', 'dT2', 'dT3'],
                   'dT2_dps_per_c2': [c * v for v in (8.0e-4, 6.0e-4, -2.5e-4)],
                   'dT3_dps_per_c3': [c * v for v in (4.0e-6, -3.0e-6, 2.0e-6)]},
          'noise': {'arw_dps_per_rt_hz': [0.03] * 3, 'bias_instability_dps': [d['bi']] * 3,
                    'bias_instability_tau_s': [100.0, 1000.0, 10000.0],
                    'rrw_dps_per_rt_s': [d['rrw']] * 3},
          'runs': {'count': 1, 'bias_offset_dps_std': d['offset']}}
    return simulate_run(load_scenario(sc), seed=seed)


def _drift(err: np.ndarray) -> np.ndarray:
    """Return the RMS of 10 min means of ``err`` (rad/s, 1 Hz) in deg/s, per axis."""
    return np.sqrt(np.mean(block_mean(err, 600) ** 2, axis=0)) / DEG


def _stream(core: CompensatorCore, sim) -> np.ndarray:
    """Feed day 3 to ``core`` as the node does; its learner stepped every 100 messages."""
    out = np.empty_like(sim.gyro)
    tt, tc = sim.temp_t.tolist(), sim.temp_c.tolist()
    j = 0
    for k, (t, w, a) in enumerate(zip(sim.imu_t.tolist(), sim.gyro.tolist(),
                                      sim.accel.tolist())):
        while j < len(tt) and tt[j] <= t:
            core.add_temperature(tt[j], tc[j])
            j += 1
        out[k] = core.process(t, w[0], w[1], w[2], a)[:3]
        if core.learner is not None and k % 100 == 99:
            core.learn_step()
    return out


@pytest.fixture(scope='module')
def logger():
    """Return (trained model, day-3 simulation, day-3 run, best simple anchor per axis)."""
    sims = [_day(j, 25000 + j) for j in range(3)]
    days = [to_run(s) for s in sims]
    joined = Run(np.concatenate([r.t + DAY_S * i for i, r in enumerate(days[:2])]),
                 np.concatenate([r.temp for r in days[:2]]),
                 np.concatenate([r.omega for r in days[:2]]),
                 np.concatenate([r.omega_ref for r in days[:2]]), 'days1-2')
    split = split_sessions([joined])
    assert split.count == 2                     # the 10 min gap cuts the bag
    t0 = estimate_t0(split.runs[0])
    ids, params, _ = features_for_fit(split.runs, 'auto', t0=t0)
    ours = fit_model(split.runs, features=ids, params=params or None, t0=t0,
                     sessions=split.labels)
    held = days[2]
    head = held.t <= held.t[0] + 600.0
    simple = []
    for feats in ('dT', 'dT,dT2,dT3'):
        m = fit_model(split.runs, kind='poly', features=feats, t0=t0)
        c = compensate(m, held.t, held.temp, held.omega, out_of_range='linear')
        simple += [_drift(c), _drift(c - c[head].mean(axis=0))]
    return ours, sims[2], held, np.min(simple, axis=0)


def test_learning_on_a_trained_prior_beats_every_simple_anchor(logger):
    """With learn:=true the node tracks day 3 beyond the trained range; without, it cannot."""
    ours, sim, held, best = logger
    plain = _drift(_stream(CompensatorCore(Policy(), ours), sim) - held.omega_ref) / best
    core = CompensatorCore(Policy(), ours)
    core.learner = Learner(prior=ours)
    learned = _drift(_stream(core, sim) - held.omega_ref) / best
    s = core.learner.summary()
    # Measured: plain 0.66 / 2.77 / 0.12, learned 0.22 / 0.59 / 0.06 of the best of four
    # simple anchors (the learner's model is day 3's own: features dT, 15.5-23.4 degC).
    assert np.max(plain) > 1.5, plain
    assert np.all(learned <= 0.9), learned
    assert np.all(learned <= plain + 0.05), (learned, plain)
    assert s['swaps'] > 10 and s['features'][:1] == ['dT'], s
