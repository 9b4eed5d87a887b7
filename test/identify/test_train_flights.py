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

"""Training on flight-controller logs without a reference: only what is still is fitted."""

from __future__ import annotations

from flightlogs import flight_day, still_drift, write_dataflash
from gyro_tdc.data.dataset import load_run
from gyro_tdc.errors import FitError
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.still_only import moving_share, proxy_lag, train_still_only
from gyro_tdc.identify.train import train
from gyro_tdc.model import compensate, DEFAULT_OUT_OF_RANGE
import numpy as np
import pytest
from real_logs import ARDUPILOT_CUBEBLACK


@pytest.fixture(scope='module')
def board(tmp_path_factory):
    """Return eight power cycles of one IMU at 25 Hz, flights between 10-60 s stops."""
    root = tmp_path_factory.mktemp('board')
    days = [flight_day(seed, legs=6) for seed in range(8)]
    paths = [write_dataflash(root / f'day{seed}.bin', [d.imu]) for seed, d in enumerate(days)]
    return days, paths


def _held_out_ratio(model, days, paths):
    """Return the within-log drift of still stretches, compensated over raw, per axis."""
    comp = []
    for path in paths:
        r = load_run(path)
        comp.append(compensate(model, r.t, r.temp, r.omega, out_of_range=DEFAULT_OUT_OF_RANGE))
    return still_drift(days, comp) / still_drift(days)


def test_default_train_on_logs_with_flights_fits_only_the_still_stretches(board, tmp_path):
    days, paths = board
    lines = []
    result = train(paths[:4], tmp_path / 'm.yaml', TrainOptions(), log=lines.append)
    assert any('no reference rate and the IMU moves' in line
               and 'training on the still stretches only' in line for line in lines)
    assert result.still is not None
    still_s = result.still.still_s
    truly = sum(d.still.sum() for d in days[:4]) / 25.0
    assert 0.6 * truly < still_s <= truly * 1.01     # the 10-60 s stretches are found
    assert 0.0 < still_s / result.still.total_s < 1.0
    ratio = _held_out_ratio(result.model, days[4:], paths[4:])
    assert np.all(ratio <= 1.1), ratio              # no harm held out on any axis
    assert np.all(ratio < 0.5), ratio               # and the drift is learnt
    # The same model as --still-only with its defaults.
    same = train_still_only(paths[:4], tmp_path / 's.yaml', TrainOptions())
    np.testing.assert_allclose(_held_out_ratio(same.model, days[4:], paths[4:]), ratio)


def test_still_only_with_a_log_without_still_time_among_three_or_more(board, tmp_path):
    days, paths = board
    flying = flight_day(99, legs=2, still_s=(0.5, 1.0), flight_s=(300.0, 300.0))
    moving = write_dataflash(tmp_path / 'flying.bin', [flying.imu])
    result = train_still_only([paths[0], moving, paths[1], paths[2]], tmp_path / 'm.yaml',
                              TrainOptions(min_still_s=20.0))
    assert len(result.model.metrics['sessions']['offset_dps']) == 3
    assert result.still.total_s > sum(d.imu.t[-1] - d.imu.t[0] for d in days[:3])
    ratio = _held_out_ratio(result.model, days[4:], paths[4:])
    assert np.all(ratio <= 1.1), ratio


def test_moving_share_tells_a_flight_log_from_a_still_one(board):
    days, paths = board
    run = load_run(paths[0])
    share = moving_share([run])
    assert 0.3 < share < 1.0 - days[0].still.mean() + 0.05
    still = flight_day(5, legs=1, still_s=(300.0, 300.0))
    assert moving_share([load_run(write_dataflash(paths[0].parent / 'still.bin',
                                                  [still.imu]))]) == 0.0


def test_a_real_flight_log_with_too_little_still_time_is_refused_in_one_line(tmp_path):
    with pytest.raises(FitError, match=r'--still-only: the still time spans 0\.\d+ degC only'):
        train([ARDUPILOT_CUBEBLACK], tmp_path / 'm.yaml', TrainOptions())


def test_a_proxy_thermometer_turns_the_thermal_state_on_with_auto_features(board):
    days, paths = board
    run = load_run(paths[0])
    proxied = type(run)(run.t, run.temp, run.omega, run.omega_ref, run.name,
                        {**run.info, 'temperature_proxy': True}, run.accel)
    said = []
    assert proxy_lag([proxied], ('dT', 'dT2'), TrainOptions(), said.append) == (
        'dT', 'dT2', 'lag')
    assert said and 'proxy' in said[0]
    assert proxy_lag([run], ('dT', 'dT2'), TrainOptions()) == ('dT', 'dT2')
    assert proxy_lag([proxied], ('dT',), TrainOptions(features='dT')) == ('dT',)
