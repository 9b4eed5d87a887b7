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

"""``train`` and ``evaluate`` on flight logs with flights in them, and on real logs."""

from __future__ import annotations

import re

from bags import assert_bad_input
from flightlogs import flight_day, write_dataflash
from gyro_tdc.cli.evaluate import main as evaluate
from gyro_tdc.cli.train import main as train
import pytest
from real_logs import (ARDUPILOT_CUBEBLACK, PX4_BARO_ONLY, PX4_MULTI_RATE,
                       PX4_ZERO_THERMOMETERS)


def _percentages(text):
    """Return every percentage printed in ``text``."""
    return [float(v) for v in re.findall(r'([0-9.]+(?:e[+-]?\d+)?) %', text)]


def test_default_train_and_evaluate_on_logs_with_flights(tmp_path, capsys):
    paths = [str(write_dataflash(tmp_path / f'day{k}.bin', [flight_day(k, legs=5).imu]))
             for k in range(5)]
    model = str(tmp_path / 'm.yaml')
    assert train([*paths[:3], '--out', model, '--no-progress']) == 0
    out = capsys.readouterr().out
    assert 'training on the still stretches only (as --still-only)' in out
    assert 'still time:' in out
    assert all(0.0 <= v <= 100.0 for v in _percentages(out)), _percentages(out)
    assert evaluate([*paths[3:], '--model', model, '--no-progress']) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if 'scored the still stretches only' in ln]
    assert len(lines) == 2 and all('re-anchored on the first still stretch' in ln
                                   for ln in lines)
    assert all(0.0 <= v <= 100.0 for v in _percentages(out))


@pytest.mark.parametrize('path, needles', [
    (PX4_BARO_ONLY, ('carries no temperature', '--temperature-source baro')),
    (PX4_ZERO_THERMOMETERS, ('carries no temperature', 'constant 0')),
    (ARDUPILOT_CUBEBLACK, ('the still time spans', 'degC only')),
])
def test_real_logs_are_refused_in_one_line(path, needles, tmp_path, capsys):
    assert_bad_input(capsys, [path, '--out', tmp_path / 'm.yaml', '--no-progress'], *needles,
                     entry=train)


def test_a_bad_temperature_source_is_one_line(tmp_path, capsys):
    assert_bad_input(capsys, [PX4_MULTI_RATE, '--out', tmp_path / 'm.yaml',
                              '--temperature-source', 'the moon'],
                     'temperature_source', 'imu, baro or TOPIC.FIELD', entry=train)


def test_a_real_log_that_never_stops_is_not_taken_for_still(tmp_path, capsys):
    from real_logs import PX4_HOVER
    assert_bad_input(capsys, [PX4_HOVER, '--out', tmp_path / 'm.yaml', '--no-progress',
                              '--temperature-source', 'baro'],
                     'no still stretch', 'the IMU moves', entry=train)
