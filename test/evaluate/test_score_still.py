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

"""Scoring data without a reference: the still stretches only, each session re-anchored."""

from __future__ import annotations

from flightlogs import flight_day, write_dataflash
from gyro_tdc.data.dataset import load_run
from gyro_tdc.errors import FitError
from gyro_tdc.evaluate.score import evaluate, evaluate_run, NamedModel, still_rows
from gyro_tdc.identify.options import TrainOptions
from gyro_tdc.identify.train import train_still_only
import numpy as np
import pytest


@pytest.fixture(scope='module')
def logs(tmp_path_factory):
    """Three power cycles with flights; a model trained on the first two."""
    root = tmp_path_factory.mktemp('logs')
    days = [flight_day(seed, legs=5) for seed in range(3)]
    paths = [write_dataflash(root / f'day{k}.bin', [d.imu]) for k, d in enumerate(days)]
    model = train_still_only(paths[:2], root / 'm.yaml', TrainOptions()).model
    return days, paths, NamedModel('m.yaml', 'm', model)


def test_a_flight_log_is_scored_on_its_still_stretches_only(logs):
    days, paths, nm = logs
    run = load_run(paths[2])
    still = still_rows(run)
    assert still is not None and 0 < still.sum() < len(run)
    assert np.all(days[2].still[still])              # nothing of a flight is scored
    assert still.sum() > 0.6 * days[2].still.sum()
    b = evaluate_run(run, [nm], still=still)
    assert b.samples == int(still.sum()) == len(b.raw.omega)
    assert b.still['stretches'] >= 4 and b.still['sessions'] == 1
    assert 0.0 < b.still['still_s'] < b.still['total_s']
    # Re-anchored on the first still stretch: it averages to zero there, raw and model.
    first = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8)])) == -1)
    n_first = int(first[0]) - int(np.flatnonzero(still)[0]) if first.size else int(still.sum())
    np.testing.assert_allclose(b.raw.omega[:n_first].mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(b.models[0].omega[:n_first].mean(axis=0), 0.0, atol=1e-12)
    # The flights would be hundreds of (deg/s)^2; the still stretches are the drift and noise.
    whole = evaluate_run(run, [nm])
    assert np.all(whole.raw.bs > 100.0 * b.raw.bs)
    assert np.all(b.raw.bs < 0.02)
    assert np.all(b.models[0].p_vs_raw < 0.9)       # the model removes drift held out
    assert b.raw.adev_dps.size == 0                 # no Allan deviation across the gaps


def test_evaluate_scores_still_only_where_the_data_move_and_all_otherwise(logs, tmp_path):
    days, paths, nm = logs
    got = evaluate([paths[2]], [nm])
    assert got[0].still is not None and got[0].samples < len(days[2].imu.t)
    quiet = flight_day(7, legs=1, still_s=(200.0, 200.0))
    path = write_dataflash(tmp_path / 'quiet.bin', [quiet.imu])
    got = evaluate([path], [nm])
    assert got[0].still is None and got[0].samples == len(quiet.imu.t)
    flying = flight_day(8, legs=2, still_s=(5.0, 6.0), flight_s=(200.0, 200.0))
    path = write_dataflash(tmp_path / 'flying.bin', [flying.imu])
    with pytest.raises(FitError, match='no reference rate and no still stretch to score'):
        evaluate([path], [nm])
