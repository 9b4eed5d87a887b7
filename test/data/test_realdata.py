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

"""Tests of gyro_tdc.data.realdata: the PAN CubeSat CSV reader, its bag converter and tool."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from gyro_tdc.data import IMU_TYPE, read_bag, REFERENCE_TYPE, TEMPERATURE_TYPE
from gyro_tdc.data.dataset import load_run
from gyro_tdc.data.realdata import (default_pan_csv, LSM6DSM_TEMP_VARIANCE, pan_cubesat_to_bag,
                                    read_pan_cubesat_csv)
from gyro_tdc.errors import DatasetError
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PAN_CSV = default_pan_csv()
needs_pan = pytest.mark.skipif(not PAN_CSV.is_file(), reason=f'{PAN_CSV} not present')


@needs_pan
@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_pan_cubesat_converter(tmp_path, storage):
    data = pan_cubesat_to_bag(PAN_CSV, tmp_path / 'pan', storage=storage)
    assert data.rows_read == 6250 and data.rows_removed == 3
    run = load_run(tmp_path / 'pan')
    assert len(run) == 6247 and run.info['reference'] == 'topic'
    assert set(run.info['rejected'].values()) == {0}
    assert run.temp[0] == pytest.approx(23.8, abs=0.1)
    assert run.temp[-1] == pytest.approx(15.6, abs=0.1)
    assert run.temp.max() == pytest.approx(23.9, abs=0.05)
    assert run.temp.min() == pytest.approx(15.6, abs=0.05)
    assert not run.omega_ref.any()
    # Corrected rates (x 0.5) and no spike left.
    assert run.omega[:, 0].min() > -0.04 and abs(run.omega[:, 0].mean() + 0.033) < 0.002
    raw = read_bag(tmp_path / 'pan')
    np.testing.assert_allclose(raw.temp_var, LSM6DSM_TEMP_VARIANCE)
    assert raw.topics['/imu/temperature'] == (TEMPERATURE_TYPE, 6247)
    assert raw.topics['/rate_table/reference'] == (REFERENCE_TYPE, 6247)
    assert raw.topics['/imu/data_raw'] == (IMU_TYPE, 6247)


@needs_pan
def test_pan_cubesat_tool_main(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location('pan_tool', ROOT / 'tools' /
                                                  'pan_cubesat_to_bag.py')
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(['--out', str(tmp_path / 'pan'), '--storage', 'mcap']) == 0
    out = capsys.readouterr().out
    assert '6247 samples' in out and '3 spike rows removed' in out
    assert tool.main(['--out', str(tmp_path / 'pan')]) == 2
    err = capsys.readouterr().err
    assert 'exists already' in err and len(err.strip().splitlines()) == 1
    assert tool.main(['--csv', str(tmp_path / 'none.csv'), '--out', str(tmp_path / 'x')]) == 2


def test_pan_csv_errors(tmp_path):
    with pytest.raises(DatasetError, match='Cannot read PAN CubeSat CSV'):
        read_pan_cubesat_csv(tmp_path / 'none.csv')
    bad = tmp_path / 'bad.csv'
    bad.write_text('time (ms),a,b\n1,2,3\n')
    with pytest.raises(DatasetError, match='Expected PAN CubeSat CSV columns'):
        read_pan_cubesat_csv(bad)
    header = ('time (ms),mag1x [T],mag1y [T],mag1z [T],gyrox rad/s,gyroy rad/s,gyroz rad/s,'
              'temp\n')
    bad.write_text(header + '1,0,0,0,0,0,0,oops\n')
    with pytest.raises(DatasetError, match='Expected numbers'):
        read_pan_cubesat_csv(bad)
    bad.write_text(header + '1,0,0,0,0,0,0,70000\n')
    with pytest.raises(DatasetError, match='raw 16-bit register'):
        read_pan_cubesat_csv(bad)
    good = tmp_path / 'good.csv'
    good.write_text(header + '1000,0,0,0,-0.06,0.05,0.02,65280\n'
                             '1020,0,0,0,-0.10,0.05,0.02,65280\n'
                             '1040,0,0,0,-0.06,0.05,0.02,256\n')
    data = read_pan_cubesat_csv(good)
    assert data.rows_read == 3 and data.rows_removed == 1
    np.testing.assert_allclose(data.t, [1.0, 1.04])
    np.testing.assert_allclose(data.temp_c, [24.0, 26.0])      # int16: -256 and +256 LSB
    np.testing.assert_allclose(data.gyro[0], [-0.03, 0.025, 0.01])
