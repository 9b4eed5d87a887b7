#!/usr/bin/env python3
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
The motion topic (``--motion-topic``) of mcap recordings the power cut, at random points.

One mcap bag per rate (IMU at 10 Hz, 200 Hz and 1 kHz for 10 min, a ``/cmd_vel`` Twist at a
tenth of it, random twists) is cut at ``--cuts`` seeded offsets, as a power cut leaves it
(no metadata.yaml, the file named as rosbag2 names it). ``read_motion`` must give the uncut
bag's first reports, or refuse in one line; anything else is a defect. Printed per rate:
read, refused, defects and the worst read (the largest share of the reports lost). ::

    .venv/bin/python bench/bench_cut_motion.py --cuts 40 --seed 0
"""

import argparse
from pathlib import Path
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.data import encode_twists, read_motion, TWIST_TYPE, write_bag  # noqa: E402
from gyro_tdc.errors import DatasetError  # noqa: E402
import numpy as np  # noqa: E402


def judge(bag: Path, whole) -> tuple[str, float]:
    """Return the outcome of reading one cut copy's motion topic and the share lost."""
    try:
        got = read_motion(bag, '/cmd_vel')
    except DatasetError as exc:
        return ('refused' if '\n' not in str(exc) else 'defect: a refusal of lines'), 1.0
    except Exception as exc:  # noqa: B902 (any other exception is the defect counted)
        return f'defect: {type(exc).__name__}', 1.0
    k = len(got.t)
    same = (got.t.tobytes() == whole.t[:k].tobytes()
            and got.twist.tobytes() == whole.twist[:k].tobytes())
    return ('read', 1.0 - k / len(whole.t)) if same else ('defect: not the first reports', 1.0)


def main(argv=None) -> int:
    """Write, cut, read and count; print per rate."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cuts', type=int, default=40, help='cut copies per rate')
    ap.add_argument('--seed', type=int, default=0, help='seed of the cut offsets and twists')
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f'rate Hz: read / refused / defects of {args.cuts} cut copies; worst read (share of '
          'the reports lost)')
    defects = 0
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (10.0, 200.0, 1000.0):
            n = int(600 * rate)
            t = np.arange(n) / rate
            twist = rng.normal(size=(n // 10, 6))
            bag = Path(tmp) / f'whole_{rate:g}'
            write_bag(bag, imu_t=t, gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)),
                      temp_t=t[::10], temp_c=np.full(n // 10, 20.0), storage='mcap',
                      extra=[('/cmd_vel', TWIST_TYPE, t[::10] + 0.5 / rate,
                              encode_twists(twist))])
            whole = read_motion(bag, '/cmd_vel')
            data = next(bag.glob('*.mcap')).read_bytes()
            counts, worst = {}, 0.0
            for k, at in enumerate(rng.integers(1, len(data), size=args.cuts)):
                cut = Path(tmp) / f'cut_{rate:g}_{k}'
                cut.mkdir()
                (cut / f'{cut.name}_0.mcap').write_bytes(data[:at])
                outcome, lost = judge(cut, whole)
                counts[outcome] = counts.get(outcome, 0) + 1
                if outcome == 'read':
                    worst = max(worst, lost)
            bad = sum(v for o, v in counts.items() if o.startswith('defect'))
            defects += bad
            print(f'  {rate:6g}: {counts.get("read", 0)} / {counts.get("refused", 0)} / {bad}; '
                  f'worst read {100 * worst:.1f} % lost'
                  + ''.join(f'; {o}: {v}' for o, v in counts.items() if o.startswith('defect')))
    print(f'defects: {defects}')
    return 1 if defects else 0


if __name__ == '__main__':
    sys.exit(main())
