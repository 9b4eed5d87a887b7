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
Clean stops: each node stopped N times with SIGINT and N times with SIGTERM, beside a CPU hog.

Issue 36's bar: every stop at a random moment of a 1 kHz stream is clean (exit 0, no
``Traceback``, no ``[FATAL]`` line; a learning node writes learn_file after the signal).
The driver runs the sim and the IIO (fake sysfs) back-ends in turn; the compensator, behind
a 1 kHz simulated driver, runs learning off and on on both executors in turn while
``~/reload`` and ``~/learn_save`` are called over and over (``test/support/stop_stress.py``).
Prints one line per stop and the clean/unclean counts per node and signal; exit 1 if any
stop was unclean. Run: ``.venv/bin/python bench/bench_clean_stops.py`` (about 5 minutes;
``--stops 2`` for a quick look).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import signal
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
for path in (ROOT, ROOT / 'test' / 'support'):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from stop_stress import run_series  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Run the series and print the counts; return 1 if a stop was unclean."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--stops', type=int, default=10,
                        help='stops per node per signal (default 10)')
    parser.add_argument('--seed', type=int, default=36, help='seed of the moments')
    parser.add_argument('--max-delay', type=float, default=3.0,
                        help='latest moment, seconds after the node installed its handlers')
    parser.add_argument('--nodes', default='driver,compensator',
                        help='comma-separated: driver, compensator')
    parser.add_argument('--no-hog', action='store_true', help='no CPU hog beside the nodes')
    args = parser.parse_args(argv)
    if args.stops < 1:
        parser.error(f'--stops must be >= 1, got {args.stops}')
    nodes = [n for n in args.nodes.split(',') if n]
    bad = [n for n in nodes if n not in ('driver', 'compensator')]
    if bad or not nodes:
        parser.error(f'--nodes: expected driver and/or compensator, got {args.nodes!r}')
    totals = []
    unclean = 0
    with tempfile.TemporaryDirectory(prefix='bench_clean_stops_') as tmp:
        for node in nodes:
            # All SIGINT stops, then all SIGTERM ones: each half takes the configurations in turn.
            signals = [signal.SIGINT] * args.stops + [signal.SIGTERM] * args.stops
            start = time.monotonic()
            series = run_series(node, signals, seed=args.seed, workdir=Path(tmp) / node,
                                max_delay_s=args.max_delay, hog=not args.no_hog)
            print(f'=== {node} ({time.monotonic() - start:.0f} s)')
            for line in series.lines():
                print(line)
            for stop in series.stops:
                if not stop.clean:
                    unclean += 1
                    print(f'--- {stop.line()}\n{stop.output[-3000:]}')
            for name in ('SIGINT', 'SIGTERM'):
                ours = [s for s in series.stops if s.signal == name]
                clean = sum(s.clean for s in ours)
                totals.append(f'{node} {name}: {clean} clean, {len(ours) - clean} unclean '
                              f'of {len(ours)}')
            sys.stdout.flush()
    print('=== summary' + (' (CPU hog on one core)' if not args.no_hog else ''))
    for line in totals:
        print(line)
    return 1 if unclean else 0


if __name__ == '__main__':
    sys.exit(main())
