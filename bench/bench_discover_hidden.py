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
Discovery on hidden effects: the figures of the cases ``test/test_discover.py`` asserts.

The same scenarios, calibrations and seeds as the test (imported from it): each hidden effect
is scaled so that what the datasheet base (bias, dT) cannot absorb has an RMS of ``k`` times
the per-sample noise standard deviation, written to a bag and read back; the table gives what
discovery named (aliases in brackets), the gap before and after in its own noise floors, in
sample for ``k = 0.25`` and ``k = 1`` and held out for ``k = 1``::

    .venv/bin/python bench/bench_discover_hidden.py      # ~30 s
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402
import tempfile  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

LABELS = {'dT2': 'ΔT²', 'lag': 'thermometer-to-die lag, heat + cool',
          'dTdt': 'dT/dt hysteresis', 'scale': 'scale, rate-table steps',
          'warmup': 'warm-up after power-on'}


def _run(sc: dict, seed: int, folder: Path):
    """Write the runs of ``sc`` as bags and run discovery on them."""
    from test_discover import write_runs

    from gyro_tdc.dataset import load_runs
    from gyro_tdc.discover import discover

    return discover(load_runs(write_runs(folder, sc, seed)), allan=False)


def _named(res) -> str:
    """Return ``effect (aliases)`` of every step, in order."""
    return ', then '.join(s.effect + (f' ({", ".join(s.aliases)})' if s.aliases else '')
                          for s in res.steps) or 'nothing'


def _gap(res, held: bool = False) -> str:
    """Return the gap before the first step and after the last, in noise floors."""
    if not res.steps:
        return f'{res.gap_dps / res.noise_floor_dps:.2f}'
    a, b = res.steps[0], res.steps[-1]
    if held:
        before, after = a.heldout_gap_before_dps, b.heldout_gap_after_dps
    else:
        before, after = a.gap_before_dps, b.gap_after_dps
    return f'{before / res.noise_floor_dps:.2f} → {after / res.noise_floor_dps:.2f}'


def main() -> int:
    """Run the cases and print the table."""
    from test_discover import calibrate, CASES, scenario

    print('| hidden | named (aliases) | gap / floor, k = 0.25 | k = 1 | held out, k = 1 |')
    print('|---|---|---|---|---|')
    with tempfile.TemporaryDirectory() as tmp:
        found = {}
        for i, (name, hidden, k, seed, opts) in enumerate(CASES):
            (effect,) = hidden
            sc = calibrate(scenario(['bias', 'dT', effect], **opts), effect, k, seed)
            folder = Path(tmp) / f'case{i}'
            folder.mkdir()
            found[name] = _run(sc, seed, folder)
        for effect, label in LABELS.items():
            q, one = found[f'{effect}-quarter'], found[f'{effect}-one']
            named = _named(one) if _named(one) == _named(q) else \
                f'{_named(q)} / {_named(one)}'
            print(f'| {label} | {named} | {_gap(q)} | {_gap(one)} | {_gap(one, True)} |',
                  flush=True)
        # Two hidden effects, as test_two_hidden_effects_dT2_and_lag.
        sc = scenario(['bias', 'dT', 'lag'], rate_hz=2.0, runs=2)
        sc = calibrate(sc, 'lag', 0.5, 11)
        sc['gyro']['effects'] = ['bias', 'dT', 'dT2', 'lag']
        sc = calibrate(sc, 'dT2', 0.5, 11)
        folder = Path(tmp) / 'two'
        folder.mkdir()
        res = _run(sc, 11, folder)
        tau = res.thermal.tau_s[0] if res.thermal is not None else float('nan')
        print(f'| ΔT² and lag, k = 0.5 each (die tau 150 s) | {_named(res)} (tau {tau:.0f} s) | '
              f'{_gap(res)} | | {_gap(res, True)} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
