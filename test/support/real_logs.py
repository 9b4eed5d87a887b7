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
Real flight-controller logs no one on the project wrote, as small extracts (and how made).

Each extract keeps the original records of the topics / message types a reader uses, byte
for byte, over a leading stretch of the log; ``test/support/files/flightlogs/SOURCE.md``
names the source and licence of each. ``python test/support/real_logs.py SRC_DIR`` rebuilds
them from the originals (the pyulog 1.2.1 sdist's ``test/``, bols-blue-org/ape's ``tests/``
PX4/px4-ulog-rs' ``tests/fixtures/``, dronekit/dronekit-la-testdata, the mavparser 0.0.1
sdist's ``data/`` and roboto-ai/robologs-px4-actions' ``actions/tag_ulog/test/input/``, all
in one folder).
"""

from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

#: Where the extracts live.
FILES = Path(__file__).parent / 'files' / 'flightlogs'
#: pyulog's ``sample_log_small.ulg``: sensor_gyro at 1 Hz beside sensor_combined at 200 Hz.
PX4_MULTI_RATE = FILES / 'px4_multi_rate.ulg'
#: pyulog's ``sample_appended.ulg``: the barometer is its only thermometer.
PX4_BARO_ONLY = FILES / 'px4_baro_only.ulg'
#: pyulog's ``sample_logging_tagged_and_default_params.ulg``: every thermometer reads 0.
PX4_ZERO_THERMOMETERS = FILES / 'px4_zero_thermometers.ulg'
#: pyulog's ``sample_appended_multiple.ulg``: 10 s of a hover, never still; baro only.
PX4_HOVER = FILES / 'px4_hover.ulg'
#: bols-blue-org/ape's CubeBlack log: three IMUs (IMU, IMU2, IMU3) at 25 Hz with ``T``.
ARDUPILOT_CUBEBLACK = FILES / 'ardupilot_cubeblack.bin'
#: px4-ulog-rs' ``quadrotor_local.ulg`` (Pixhawk 6C): the gyro's thermometers read NaN, the
#: accelerometer's of the same IMU (``vehicle_imu_status.temperature_accel``) serves.
PX4_ACCEL_THERMOMETER = FILES / 'px4_v6c_accel_thermometer.ulg'
#: dronekit-la-testdata's ``log171.bin`` (ArduCopter V3.3-dev): three IMUs at 50 Hz with
#: ``Temp``, stamped in ``TimeMS``.
ARDUPILOT_AC33 = FILES / 'ardupilot_ac33_three_imus.bin'

#: mavparser 0.0.1's ``00000081.BIN`` (ArduCopter V4.5.7, CubeOrangePlus): three IMUs in one
#: ``IMU`` message (``I``), two barometers in ``BARO`` (``I``), the heater's ``HEAT`` (whose
#: ``I`` is its integrator), ``INS_TCALn_ENABLE`` = 1.
ARDUPILOT_AC45 = FILES / 'ardupilot_ac45_cube_orange_plus.bin'

#: robologs-px4-actions' ``test.ulg`` (PX4 1.12.3, FMU v5): ``sensor_selection`` flips between
#: its two IMUs 2.6 s in; ``sensor_combined`` is each one's while it is selected.
PX4_SELECTION_FLIPS = FILES / 'px4_fmuv5_selection_flips.ulg'

_PX4_TOPICS = ['sensor_gyro', 'sensor_accel', 'sensor_combined', 'vehicle_imu',
               'vehicle_imu_status', 'sensor_baro', 'vehicle_air_data']


def extract_ulog(src: Path, dst: Path, *, seconds: float, topics: tuple = ()) -> Path:
    """Write the reader's topics (and ``topics``) of a ULog over its first ``seconds`` s."""
    from pyulog import ULog

    ulog = ULog(str(src), _PX4_TOPICS + list(topics))
    start = min(int(d.data['timestamp'][0]) for d in ulog.data_list)
    for d in ulog.data_list:
        keep = d.data['timestamp'] <= start + seconds * 1e6
        d.data = {k: v[keep] for k, v in d.data.items()}
    ulog.write_ulog(str(dst))
    return dst


def extract_dataflash(src: Path, dst: Path, *, seconds: float,
                      types: tuple = ('FMT', 'PARM', 'MSG', 'VER', 'IMU', 'IMU2', 'IMU3',
                                      'BARO', 'BAR2')) -> Path:
    """Write the whole records of ``types`` of a DataFlash log over its first ``seconds`` s."""
    from pymavlink.DFReader import DFReader_binary

    reader = DFReader_binary(str(src), zero_time_base=False)
    buf = np.frombuffer(reader.data_map, dtype=np.uint8)
    ids = {reader.name_to_id[n] for n in types if n in reader.name_to_id} | {0x80}
    rows = []
    t_end = None
    for mtype in sorted(ids):
        fmt = reader.formats.get(mtype)
        length = 89 if mtype == 0x80 else fmt.len
        for ofs in reader.offsets[mtype]:
            rows.append((int(ofs), length))
    rows.sort()
    out = bytearray()
    for ofs, length in rows:
        rec = bytes(buf[ofs:ofs + length])
        mtype = rec[2]
        stamp = reader.formats[mtype].columns[:1] if mtype != 0x80 else []
        if stamp in (['TimeUS'], ['TimeMS']):        # TimeMS: ArduPilot up to 3.3
            t_us = (int.from_bytes(rec[3:11], 'little') if stamp == ['TimeUS'] else
                    int.from_bytes(rec[3:7], 'little') * 1000)
            if t_end is None and t_us > 0:
                t_end = t_us + seconds * 1e6
            if t_end is not None and t_us > t_end:
                continue
        out += rec
    dst.write_bytes(bytes(out))
    return dst


def main(src_dir: str) -> None:
    """Rebuild every extract from the originals in ``src_dir``."""
    src = Path(src_dir)
    FILES.mkdir(parents=True, exist_ok=True)
    extract_ulog(src / 'sample_log_small.ulg', PX4_MULTI_RATE, seconds=60.0)
    extract_ulog(src / 'sample_appended.ulg', PX4_BARO_ONLY, seconds=15.0)
    extract_ulog(src / 'sample_appended_multiple.ulg', PX4_HOVER, seconds=15.0)
    extract_ulog(src / 'sample_logging_tagged_and_default_params.ulg',
                 PX4_ZERO_THERMOMETERS, seconds=2.0)
    extract_dataflash(src / 'log_0_2020-5-1-14-53-42.bin', ARDUPILOT_CUBEBLACK,
                      seconds=120.0)
    extract_ulog(src / 'quadrotor_local.ulg', PX4_ACCEL_THERMOMETER, seconds=20.0)
    extract_dataflash(src / 'log171.bin', ARDUPILOT_AC33, seconds=80.0)
    extract_dataflash(src / '00000081.BIN', ARDUPILOT_AC45, seconds=60.0,
                      types=('FMT', 'PARM', 'MSG', 'VER', 'IMU', 'BARO', 'HEAT', 'MCU'))
    extract_ulog(src / 'test.ulg', PX4_SELECTION_FLIPS, seconds=60.0,
                 topics=('sensor_selection',))


if __name__ == '__main__':
    main(sys.argv[1])
