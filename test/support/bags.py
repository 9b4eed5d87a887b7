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

"""Bags for tests: synthetic and simulated runs as rosbag2, and the one-line error check."""

from __future__ import annotations

from pathlib import Path
import sqlite3

from gyro_tdc.cli.train import main
from gyro_tdc.data import write_bag
from gyro_tdc.data.runs import Run
from gyro_tdc.sim import simulate_scenario
import numpy as np

DEG = np.pi / 180.0


def bag_from_run(run: Run, path: Path, *, storage: str = 'sqlite3', temp_hz: float = 1.0,
                 reference: str = 'none', t_offset: float = 100.0) -> Path:
    """
    Write a synthetic run as a bag: IMU at the run's rate, thermometer at ``temp_hz``.

    ``reference``: ``'none'`` (no topic), ``'topic'`` (one message per change of
    ``run.omega_ref`` on ``/rate_table/reference``).
    """
    rate = 1.0 / float(np.median(np.diff(run.t)))
    step = max(1, int(round(rate / temp_hz)))
    kw = {}
    if reference == 'topic':
        change = np.ones(len(run), dtype=bool)
        change[1:] = np.any(np.diff(run.omega_ref, axis=0) != 0, axis=1)
        kw = {'ref_t': run.t[change] + t_offset, 'ref': run.omega_ref[change]}
    write_bag(path, imu_t=run.t + t_offset, gyro=run.omega, accel=np.zeros((len(run), 3)),
              temp_t=run.t[::step] + t_offset, temp_c=run.temp[::step], storage=storage, **kw)
    return path


def bag_from_sim(sim, path: Path, *, storage: str = 'sqlite3') -> Path:
    """Write a :class:`gyro_tdc.sim.SimRun` as a bag (reference topic when it moves)."""
    kw = {'ref_t': sim.ref_t, 'ref': sim.ref} if sim.moving else {}
    write_bag(path, imu_t=sim.imu_t, gyro=sim.gyro, accel=sim.accel, temp_t=sim.temp_t,
              temp_c=sim.temp_c, storage=storage, **kw)
    return path


def sim_bags(tmp_path: Path, scenario: str, *, rate_hz: float, seed: int = 3,
             storage: str = 'sqlite3', overrides: dict | None = None):
    """Simulate every run of ``scenario`` into ``tmp_path/scenario/runK``; return the sims."""
    sims = simulate_scenario(scenario, seed=seed, rate_hz=rate_hz, overrides=overrides)
    folder = tmp_path / scenario
    folder.mkdir()
    for k, sim in enumerate(sims, start=1):
        bag_from_sim(sim, folder / f'run{k}', storage=storage)
    return folder, sims


def assert_bad_input(capsys, argv, *needles, entry=main):
    """Run ``entry(argv)``; check exit 2 and one stderr line holding every needle."""
    rc = entry([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1, err
    assert 'Traceback' not in err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def null_message_data(db3: Path, topic: str, index: int = 0) -> None:
    """
    Make message ``index`` of ``topic`` in a sqlite3 storage file hold NULL data.

    As a damaged record header does: the schema's ``NOT NULL`` is lifted for the write and
    put back, so the file says ``NOT NULL`` and holds a NULL (``PRAGMA writable_schema``).
    """
    edit = "UPDATE sqlite_master SET sql = replace(sql, ?, ?) WHERE name = 'messages'"
    for step in ('lift', 'null', 'restore'):
        db = sqlite3.connect(db3, isolation_level=None)
        db.execute('PRAGMA writable_schema = ON')
        if step == 'null':
            db.execute('UPDATE messages SET data = NULL WHERE id = (SELECT id FROM messages '
                       'WHERE topic_id = (SELECT id FROM topics WHERE name = ?) '
                       'ORDER BY timestamp LIMIT 1 OFFSET ?)', (topic, index))
        else:
            db.execute(edit, ('data BLOB NOT NULL', 'data BLOB')[::1 if step == 'lift' else -1])
        db.close()
