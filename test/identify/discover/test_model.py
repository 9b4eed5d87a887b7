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

"""Discovery on flight logs never fits motion: the still stretches only, or one line why."""

from __future__ import annotations

from flightlogs import flight_day, write_dataflash
from gyro_tdc.data import load_runs
from gyro_tdc.errors import FitError
from gyro_tdc.identify.discover import discover
from gyro_tdc.identify.discover.model import still_only_runs
import numpy as np
import pytest


@pytest.fixture(scope='module')
def flights(tmp_path_factory):
    """Three power cycles of one board at 25 Hz: flights between 10-60 s stops."""
    root = tmp_path_factory.mktemp('flights')
    days = [flight_day(seed, legs=8) for seed in range(3)]
    paths = [write_dataflash(root / f'day{seed}.bin', [d.imu]) for seed, d in enumerate(days)]
    return days, paths


def test_flight_logs_keep_their_still_stretches_only(flights):
    days, paths = flights
    runs = load_runs(paths)
    kept, line = still_only_runs(runs)
    assert line is not None and 'still stretches only' in line
    assert len(kept) == len(runs)
    for day, run, k in zip(days, runs, kept):
        idx = np.searchsorted(run.t, k.t)
        np.testing.assert_array_equal(run.t[idx], k.t)
        assert np.all(day.still[idx])                 # nothing of a flight is kept
        assert len(k) > 0.6 * day.still.sum()
        assert np.all(k.omega_ref == 0.0)
    pct = float(line.split(' %;')[0].rsplit(', ', 1)[1])
    assert 0.0 < pct <= 100.0


def test_discovery_on_flights_fits_the_drift_not_the_motion(flights):
    days, paths = flights
    runs = load_runs(paths)
    kept, _line = still_only_runs(runs)
    still = discover(kept, allan=False, max_steps=2)
    # The still stretches' noise: 0.05 deg/s per sample, a few mdeg/s on 10 s means; the
    # flights would put tens of deg/s of manoeuvres into the same gaps.
    assert still.white_noise_dps < 0.1
    assert still.noise_floor_dps < 0.01
    assert still.gap_dps < 2.0 * still.noise_floor_dps
    moving = discover(runs, allan=False, max_steps=0)
    assert moving.gap_dps > 20.0 * still.gap_dps
    # The drift slope found is the board's (0.004 deg/s per degC on x near 35 degC, the
    # curvature pulling it lower near the cold T0).
    slope = np.degrees(still.coef['dT'])
    assert 0.001 < slope[0] < 0.006


def test_data_with_a_reference_or_without_motion_are_kept_whole(flights, tmp_path):
    days, paths = flights
    runs = load_runs(paths)
    ref = [type(r)(r.t, r.temp, r.omega, r.omega_ref, r.name, {**r.info, 'reference': 'topic'})
           for r in runs]
    assert still_only_runs(ref) == (ref, None)
    quiet = flight_day(7, legs=1, still_s=(300.0, 300.0))
    run = load_runs([write_dataflash(tmp_path / 'quiet.bin', [quiet.imu])])
    assert still_only_runs(run) == (run, None)
    flying = flight_day(8, legs=2, still_s=(0.2, 0.3), flight_s=(300.0, 300.0))
    run = load_runs([write_dataflash(tmp_path / 'flying.bin', [flying.imu])])
    with pytest.raises(FitError, match='no still stretch to discover on'):
        still_only_runs(run)
