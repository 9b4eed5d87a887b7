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
Both nodes stop cleanly on SIGINT and SIGTERM at random moments, beside a CPU hog.

Each node process is started and signalled at a seeded random moment of its start-up or its
1 kHz stream (``stop_stress``): the driver with the sim and the IIO back-ends (a fake sysfs
tree), the compensator behind a 1 kHz driver with learning off and on, on both executors,
while ``~/reload`` and ``~/learn_save`` are called over and over. Every stop exits 0 with
no traceback and no ``[FATAL]`` line, and a learning node writes learn_file after the
signal. Four stops per node here; ``bench/bench_clean_stops.py`` runs ten per node per
signal. Serial: the hog and the node start-ups would slow the tests beside them.
"""

import signal

import pytest
from stop_stress import CONFIGS, run_series

INT, TERM = signal.SIGINT, signal.SIGTERM
#: Per node, the signal of each stop: with the configurations taken in turn, every
#: configuration of the driver meets both signals, each of the compensator's one.
SIGNALS = {'driver': [INT, INT, TERM, TERM], 'compensator': [INT, TERM, TERM, INT]}


@pytest.mark.serial
@pytest.mark.parametrize('node', sorted(SIGNALS))
def test_a_node_stopped_at_random_moments_stops_cleanly(node, tmp_path):
    series = run_series(node, SIGNALS[node], seed=36, workdir=tmp_path, max_delay_s=1.5)
    report = '\n'.join(series.lines())
    print(report)
    assert {stop.config for stop in series.stops} == set(CONFIGS[node])
    unclean = [stop for stop in series.stops if not stop.clean]
    assert not unclean, report + ''.join(
        f'\n--- {stop.line()}\n{stop.output[-4000:]}' for stop in unclean)
    if node == 'compensator':
        assert series.reloads > 0 and series.saves > 0, report
