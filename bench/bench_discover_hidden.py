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
Discovery on hidden effects: the figures of the cases the discovery tests assert.

The same scenarios, calibrations and seeds as ``test/identify/discover/test_search.py``
(imported from ``test/support/discover_cases.py``): each hidden effect
is scaled so that what the datasheet base (bias, dT) cannot absorb has an RMS of ``k`` times
the per-sample noise standard deviation, written to a bag and read back; the table gives what
discovery named (aliases in brackets), the gap before and after in its own noise floors, in
sample for ``k = 0.25`` and ``k = 1`` and held out for ``k = 1``; the last row is the null
cases of the test (no hidden effect: three seeds, and three sessions with offsets and a
non-thermal bump), where discovery must name nothing::

    .venv/bin/python bench/bench_discover_hidden.py      # ~10 s

``--sweep`` runs, instead of the table, the seed sweep outside the suite at 2 Hz: every
effect at ``k = 0.25`` on new seeds (found: :func:`discover_cases.check_found` holds), the
test's null scenarios on new seeds (at 2 Hz its first two are the same scenario) and the
multi-session null (offsets and a bump) on new seeds (named nothing), and prints the counts;
``--seeds E,N,S`` sets the seeds per effect, per null scenario and of the multi-session null
(default 8,20,10: 40, 60 and 10 runs)::

    .venv/bin/python bench/bench_discover_hidden.py --sweep
"""

import argparse
import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from pathlib import Path  # noqa: E402, I100
import sys  # noqa: E402
import tempfile  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / 'test', ROOT / 'test' / 'support'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

LABELS = {'dT2': 'ΔT²', 'lag': 'thermometer-to-die lag, heat + cool',
          'dTdt': 'dT/dt hysteresis', 'scale': 'scale, rate-table steps',
          'warmup': 'warm-up after power-on'}


def _run(sc: dict, seed: int, folder: Path, excursion_dps: float = 0.0):
    """Write the runs of ``sc`` as bags and run discovery on them."""
    from discover_cases import write_runs

    from gyro_tdc.data.dataset import load_runs
    from gyro_tdc.identify.discover import discover

    folder.mkdir(parents=True, exist_ok=True)
    return discover(load_runs(write_runs(folder, sc, seed, excursion_dps=excursion_dps)),
                    allan=False)


def _session_null(seed: int, folder: Path):
    """Run the test's multi-session null: 3 sessions with offsets and a non-thermal bump."""
    from discover_cases import scenario

    sc = scenario(['bias', 'dT'], rate_hz=2.0, runs=3, offset_dps=0.05)
    return _run(sc, seed, folder, excursion_dps=0.03)


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


def _null_row(tmp: Path) -> str:
    """Return the table row of the test's null cases (test_null_* of test_search.py)."""
    from discover_cases import NULLS, scenario

    res = [_run(scenario(['bias', 'dT'], **opts), seed, tmp / f'null{seed}')
           for _name, seed, opts in NULLS]
    res.append(_session_null(31, tmp / 'sessions'))
    named = sorted({_named(r) for r in res})
    gaps = ', '.join(_gap(r) for r in res[:-1]) + f'; {_gap(res[-1])}'
    return (f'| nothing ({len(NULLS)} seeds; 3 sessions with offsets and a non-thermal bump) '
            f'| {" / ".join(named)} (gap / floor {gaps}) | | | |')


def sweep(effect_seeds: int, null_seeds: int, session_seeds: int) -> int:
    """Run the seed sweep at 2 Hz and print how many runs found the effect / named nothing."""
    from discover_cases import calibrate, CASES, check_found, NULLS, scenario

    quarter = {next(iter(h)): (k, opts) for name, h, k, _s, opts in CASES
               if name.endswith('-quarter')}
    found, total, missed = 0, 0, []
    nulls, null_total, named = 0, 0, []
    with tempfile.TemporaryDirectory() as tmp:
        for effect, (k, opts) in quarter.items():
            for j in range(effect_seeds):
                seed = 1000 + j
                sc = calibrate(scenario(['bias', 'dT', effect], **dict(opts, rate_hz=2.0)),
                               effect, k, seed)
                res = _run(sc, seed, Path(tmp) / f'{effect}{seed}')
                try:
                    check_found(res, {effect})
                    found += 1
                except AssertionError:
                    missed.append(f'{effect} seed {seed}: {_named(res)}')
                total += 1
        for i, (name, _seed, opts) in enumerate(NULLS):
            for j in range(null_seeds):
                seed = 2000 + 100 * i + j
                res = _run(scenario(['bias', 'dT'], **dict(opts, rate_hz=2.0)), seed,
                           Path(tmp) / f'null{seed}')
                nulls += not res.steps
                null_total += 1
                if res.steps:
                    named.append(f'{name} seed {seed}: {_named(res)}')
        sessions = 0
        for j in range(session_seeds):
            seed = 3000 + j
            res = _session_null(seed, Path(tmp) / f'sessions{seed}')
            sessions += not res.steps
            if res.steps:
                named.append(f'3 sessions seed {seed}: {_named(res)}')
    for line in missed + named:
        print(f'  {line}')
    print(f'seed sweep (2 Hz, k = 0.25): {found}/{total} effects found, '
          f'{nulls}/{null_total} null runs named nothing, {sessions}/{session_seeds} '
          'multi-session nulls with offsets and a bump named nothing')
    return 0


def _seeds(text: str) -> tuple:
    """Parse ``--seeds E,N,S`` (argparse type): three integers >= 1."""
    try:
        v = tuple(int(q) for q in text.split(','))
    except ValueError:
        v = ()
    if len(v) != 3 or min(v) < 1:
        raise argparse.ArgumentTypeError(f'expected three integers >= 1, got {text!r}')
    return v


def main(argv=None) -> int:
    """Run the cases and print the table (or, with ``--sweep``, the seed sweep)."""
    from discover_cases import calibrate, CASES, scenario

    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    p.add_argument('--sweep', action='store_true', help='run the seed sweep instead')
    p.add_argument('--seeds', type=_seeds, default=(8, 20, 10), metavar='E,N,S',
                   help='seeds per effect, per null scenario, of the multi-session null '
                        '(default 8,20,10)')
    args = p.parse_args(argv)
    if args.sweep:
        return sweep(*args.seeds)

    print('| hidden | named (aliases) | gap / floor, k = 0.25 | k = 1 | held out, k = 1 |')
    print('|---|---|---|---|---|')
    with tempfile.TemporaryDirectory() as tmp:
        found = {}
        for i, (name, hidden, k, seed, opts) in enumerate(CASES):
            (effect,) = hidden
            sc = calibrate(scenario(['bias', 'dT', effect], **opts), effect, k, seed)
            folder = Path(tmp) / f'case{i}'
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
        res = _run(sc, 11, folder)
        tau = res.thermal.tau_s[0] if res.thermal is not None else float('nan')
        print(f'| ΔT² and lag, k = 0.5 each (die τ 150 s) | {_named(res)}; τ = {tau:.0f} s | '
              f'{_gap(res)} | | {_gap(res, True)} |', flush=True)
        print(_null_row(Path(tmp)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
