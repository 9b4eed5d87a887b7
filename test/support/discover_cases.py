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
Hidden-effect cases of discovery: chamber scenarios, the calibration of an effect, bags.

Each case simulates a chamber run with :mod:`gyro_tdc.sim` (the L3GD20 preset's noise: white,
bias instability and rate random walk, 8.75 mdps quantisation; a package thermometer at 1 Hz,
0.03 degC resolution), with one effect switched on and scaled so that the part of it the base
model (bias, dT) cannot absorb has a chosen RMS, ``k`` times the per-sample noise standard
deviation, over the whole recording. Shared by the discovery tests and
``bench/bench_discover_hidden.py``.
"""

from __future__ import annotations

import math

from gyro_tdc.data import write_bag
from gyro_tdc.sim.simulator import simulate_run
import numpy as np

DEG = math.pi / 180.0

HEAT_COOL = [{'kind': 'hold', 'duration_s': 900.0},
             {'kind': 'ramp', 'to_c': 40.0, 'rate_c_per_h': 40.0},
             {'kind': 'hold', 'duration_s': 600.0},
             {'kind': 'ramp', 'to_c': 10.0, 'rate_c_per_h': 60.0},
             {'kind': 'hold', 'duration_s': 600.0}]
HEAT = [{'kind': 'hold', 'duration_s': 900.0},
        {'kind': 'ramp', 'to_c': 45.0, 'rate_c_per_h': 30.0}]
RATES = [[0.0, 0.0, 0.0], [30.0, -20.0, 60.0], [-60.0, 45.0, -30.0], [100.0, -90.0, 120.0],
         [-100.0, 60.0, -120.0], [45.0, 100.0, -60.0]]

# Per-effect coefficient keys of the simulator's `gyro` section (scaled by the calibration).
COEF_KEY = {'dT2': 'dT2_dps_per_c2', 'dTdt': 'dTdt_dps_per_c_per_s', 'scale': 'scale_ppm_per_c',
            'warmup': 'warmup_dps', 'lag': 'dT_dps_per_c'}


def scenario(effects, *, segments=HEAT_COOL, start_c=0.0, rate_hz=4.0, runs=1,
             offset_dps=0.0, rate_period_s=0.0, tau_die_s=150.0, gyro=None) -> dict:
    """Build a simulator scenario dict with the given effects switched on."""
    sc = {
        'format_version': 1, 'name': 'hidden', 'sensor': 'l3gd20', 'imu_rate_hz': rate_hz,
        'profile': {'start_c': start_c, 'segments': segments},
        'thermal': {'tau_package_s': 60.0, 'tau_die_s': tau_die_s},
        'thermometer': {'location': 'package', 'rate_hz': 1.0, 'resolution_c': 0.03,
                        'noise_c': 0.01},
        'gyro': {'effects': list(effects), 'warmup_tau_s': 240.0, **(gyro or {})},
        'runs': {'count': runs, 'bias_offset_dps_std': offset_dps},
    }
    if rate_period_s:
        total = 900.0 + 45.0 / 30.0 * 3600.0 + 3600.0
        sc['rate_table'] = [{'t_s': i * rate_period_s, 'rate_dps': RATES[i % len(RATES)]}
                            for i in range(int(total // rate_period_s) + 1)]
    return sc


def unexplained_rms(sims_on, sims_off) -> float:
    """RMS of the effect's drift that bias + dT (of the measured temperature) cannot absorb."""
    sq, n = 0.0, 0
    for on, off in zip(sims_on, sims_off):
        d = on.truth.drift - off.truth.drift
        temp = np.interp(on.imu_t, on.temp_t, on.temp_c)
        x = np.column_stack([np.ones_like(temp), temp - temp[0]])
        r = d - x @ np.linalg.lstsq(x, d, rcond=None)[0]
        sq += float((r * r).sum())
        n += r.size
    return math.sqrt(sq / n)


def calibrate(sc: dict, effect: str, k: float, seed: int) -> dict:
    """Scale the coefficient of ``effect`` so its unexplained RMS is ``k`` noise std."""
    from gyro_tdc.sim.specs import preset

    base = [e for e in sc['gyro']['effects'] if e != effect]
    key = COEF_KEY[effect]
    ref = np.asarray(sc['gyro'].get(key, preset('l3gd20')['gyro'][key]), dtype=float)
    count = sc['runs']['count']
    on = [simulate_run(sc, seed=seed, run_index=i) for i in range(count)]
    off = [simulate_run(dict(sc, gyro=dict(sc['gyro'], effects=base)), seed=seed, run_index=i)
           for i in range(count)]
    sigma = float(np.mean(on[0].truth.noise_std))
    factor = k * sigma / unexplained_rms(on, off)
    return dict(sc, gyro=dict(sc['gyro'], **{key: (ref * factor).tolist()}))


def write_runs(tmp_path, sc: dict, seed: int, *, excursion_dps: float = 0.0) -> list:
    """Simulate every run of ``sc``, write one bag each and return the bag paths."""
    rng = np.random.default_rng(seed + 1000)
    bags = []
    for i in range(sc['runs']['count']):
        run = simulate_run(sc, seed=seed, run_index=i)
        gyro = run.gyro.copy()
        if excursion_dps and i == 0:
            # A non-thermal bias excursion: a smooth bump of ~12 min somewhere in the run.
            centre = rng.uniform(0.3, 0.7) * run.imu_t[-1]
            bump = np.exp(-0.5 * ((run.imu_t - centre) / 360.0) ** 2)
            gyro += bump[:, None] * excursion_dps * DEG * np.array([1.0, -0.7, 0.5])
        path = tmp_path / f'run{i + 1}'
        write_bag(path, imu_t=run.imu_t, gyro=gyro, accel=run.accel, temp_t=run.temp_t,
                  temp_c=run.temp_c, ref_t=run.ref_t if run.moving else None,
                  ref=run.ref if run.moving else None)
        bags.append(path)
    return bags


def check_found(res, hidden: set) -> None:
    """Assert every hidden effect is named or an alias of a named step, and nothing else."""
    named = {s.effect for s in res.steps}
    explained = named | {a for s in res.steps for a in s.aliases}
    assert hidden <= explained, f'hidden {hidden}, named {named}, explained {explained}'
    for s in res.steps:
        assert s.effect in hidden or hidden & set(s.aliases), f'false discovery {s.effect}'
    first, last = res.steps[0], res.steps[-1]
    assert last.gap_after_dps <= 1.3 * res.noise_floor_dps, (
        f'gap {last.gap_after_dps:.4g} vs floor {res.noise_floor_dps:.4g}')
    assert last.heldout_gap_after_dps < first.heldout_gap_before_dps
    for s in res.steps:
        assert s.gap_after_dps < s.gap_before_dps


CASES = [
    # (id, hidden effects, k, seed, scenario options)
    ('dT2-quarter', {'dT2'}, 0.25, 1, {}),
    ('dT2-one', {'dT2'}, 1.0, 2, {'segments': HEAT}),
    ('lag-quarter', {'lag'}, 0.25, 3, {}),
    ('lag-one', {'lag'}, 1.0, 4, {'runs': 2, 'rate_hz': 2.0}),
    ('dTdt-quarter', {'dTdt'}, 0.25, 5, {}),
    ('dTdt-one', {'dTdt'}, 1.0, 6, {}),
    ('scale-quarter', {'scale'}, 0.25, 7, {'segments': HEAT, 'rate_period_s': 300.0}),
    ('scale-one', {'scale'}, 1.0, 8, {'segments': HEAT, 'rate_period_s': 240.0}),
    ('warmup-quarter', {'warmup'}, 0.25, 9, {}),
    ('warmup-one', {'warmup'}, 1.0, 10, {'segments': HEAT}),
]


NULLS = [('heat-cool', 21, {}), ('heat-cool', 22, {'rate_hz': 2.0}),
         ('heat-only', 23, {'segments': HEAT})]
