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
The field defaults swept wider than the tests: out-of-range policies and re-anchoring precision.

1. **Beyond the trained range.** Models trained on a narrow run (0..40 degC) are scored on
   held-out runs reaching 5, 10 and 15 degC beyond either end, under ``clamp``, ``linear``
   and ``extrapolate``, as BS over the BS of the same model kind trained on a run covering
   everything (the "truth" a calibration over the whole range would give). Two drifts: the
   test simulator's (``test/synth.py``: curvature 2e-4, 1.5e-4, -1e-4 deg/s/degC^2) and the
   L3GD20 preset of :mod:`gyro_tdc.sim` (8e-4, 6e-4, -2.5e-4 plus a cubic term), whose
   stronger curvature is where a tangent falls short.
2. **Re-anchoring precision vs sample rate.** A still stream at 1 Hz (1 s means), 10 Hz,
   200 Hz, 1 kHz and 2 kHz (noise low-passed at tau = 5 ms, i.e. oversampled at 1 and 2 kHz),
   the same low-frequency noise (1e-3 rad/s over 1 s), through
   :func:`gyro_tdc.runtime.reanchor.reanchor_shift` with the defaults (tolerance 1.5e-4 rad/s: 0.1
   of a residual std of 1.5e-3): the SE it reports, the actual scatter of the shift over
   seeds, the time it took, and the per-sample SE a naive formula would claim.

Run: ``.venv/bin/python bench/bench_field_defaults.py`` (about a minute).
"""

from __future__ import annotations

import math
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from gyro_tdc.identify import fit_model  # noqa: E402
from gyro_tdc.model.compensation import compensate  # noqa: E402
from gyro_tdc.runtime.reanchor import reanchor_shift  # noqa: E402
from gyro_tdc.signal.metrics import bias_stability  # noqa: E402
from gyro_tdc.sim import load_scenario  # noqa: E402
from gyro_tdc.sim.simulator import simulate_run, to_run  # noqa: E402
import numpy as np  # noqa: E402
from scipy.signal import lfilter  # noqa: E402
from synth import synth_run  # noqa: E402

POLICIES = ('clamp', 'linear', 'extrapolate')
MODELS = (('poly', 'dT,dT2'), ('rbf', 'dT,dT2'), ('poly', 'dT,dT2,dT3'))


def _preset_run(lo: float, hi: float, seed: int):
    """Return a run of the L3GD20 preset: lo -> hi -> lo at 60 degC/h, 2 Hz, static effects."""
    sc = load_scenario({
        'format_version': 1, 'name': f'range_{lo:g}_{hi:g}', 'description': 'range sweep',
        'sensor': 'l3gd20', 'imu_rate_hz': 2.0,
        'profile': {'start_c': lo, 'segments': [
            {'kind': 'hold', 'duration_s': 300.0},
            {'kind': 'ramp', 'to_c': hi, 'rate_c_per_h': 60.0},
            {'kind': 'hold', 'duration_s': 300.0},
            {'kind': 'ramp', 'to_c': lo, 'rate_c_per_h': 60.0}]},
        'thermal': {'tau_package_s': 30.0},
        'thermometer': {'location': 'package', 'rate_hz': 2.0, 'resolution_c': 0.01,
                        'noise_c': 0.01},
        'gyro': {'effects': ['bias', 'dT', 'dT2', 'dT3']}, 'runs': {'count': 1}})
    return to_run(simulate_run(sc, seed=seed))


def _synth_run(lo: float, hi: float, seed: int):
    """Return a run of the test simulator: lo -> hi -> lo, 2 h at 1 Hz."""
    return synth_run(seed=seed, t_lo=lo, t_hi=hi, rate_hz=1.0, hours=2.0, cooling=True)


def sweep_range() -> None:
    """Print BS / BS(full-range model) per policy, extent and side."""
    print('1. beyond the trained range: BS / BS of the same kind trained on -15..55 degC '
          '(x y z); trained on 0..40 degC')
    for drift, make in (('synth', _synth_run), ('L3GD20 preset', _preset_run)):
        for kind, feats in MODELS:
            full = fit_model([make(-15.0, 55.0, 1)], kind=kind, features=feats)
            narrow = fit_model([make(0.0, 40.0, 2)], kind=kind, features=feats)
            for beyond in (5.0, 10.0, 15.0):
                for side, (lo, hi) in (('warm', (0.0, 40.0 + beyond)),
                                       ('cold', (-beyond, 40.0))):
                    held = make(lo, hi, 3)
                    truth = bias_stability(compensate(full, held.t, held.temp, held.omega),
                                           held.omega_ref)
                    cells = []
                    for p in POLICIES:
                        bs = bias_stability(compensate(narrow, held.t, held.temp, held.omega,
                                                       out_of_range=p), held.omega_ref)
                        cells.append(f'{p} ' + ' '.join(f'{v:6.2f}' for v in bs / truth))
                    print(f'  {drift:<14}{kind} {feats:<11}{beyond:4.0f} C {side}:  '
                          + '   '.join(cells))


def _noise(rng: np.random.Generator, n: int, dt: float, tau: float, sd_1s: float):
    """Low-passed noise whose 1 s means scatter by ``sd_1s``, shape (n, 3)."""
    a = math.exp(-dt / tau) if tau > 0 else 0.0
    sd = sd_1s / math.sqrt(2.0 * tau) if tau > 0 else sd_1s / math.sqrt(dt)
    w = rng.normal(0.0, sd * math.sqrt(1.0 - a * a), (n, 3))
    return lfilter([1.0], [1.0, -a], w, axis=0)


def sweep_reanchor(seeds: int = 40) -> None:
    """Print the reported SE, the actual scatter and the time per stream rate."""
    print('\n2. re-anchoring with the defaults (10 s .. 600 s, tolerance 1.5e-4 rad/s), '
          f'{seeds} seeds per rate')
    print(f'  {"rate":>8} {"noise":<24}{"SE reported":>12}{"actual":>10}{"naive SE":>10}'
          f'{"seconds":>9}')
    tol = [1.5e-4] * 3
    for rate, tau, what in ((1.0, 0.0, '1 s means'), (10.0, 0.0, 'white'),
                            (200.0, 5e-3, 'low-passed 32 Hz'),
                            (1000.0, 5e-3, 'low-passed 32 Hz'),
                            (2000.0, 5e-3, 'low-passed 32 Hz')):
        rng = np.random.default_rng(int(rate))
        dt = 1.0 / rate
        n = int(200 * rate)
        t = np.arange(n) * dt
        shifts, ses, naive, secs = [], [], [], []
        for _ in range(seeds):
            x = _noise(rng, n, dt, tau, 1e-3)
            r = reanchor_shift(t, x, tolerance=tol)
            shifts.append(r.delta)
            ses.append(r.se)
            naive.append(float(np.mean(x[:r.samples].std(axis=0))) / math.sqrt(r.samples))
            secs.append(r.duration_s)
        actual = float(np.sqrt(np.mean(np.square(shifts))))
        print(f'  {rate:6g} Hz {what:<24}{np.mean(ses):12.2e}{actual:10.2e}'
              f'{np.mean(naive):10.2e}{np.mean(secs):9.1f}')


def main() -> int:
    """Run both sweeps and print them."""
    start = time.perf_counter()
    sweep_range()
    sweep_reanchor()
    print(f'\n{time.perf_counter() - start:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
