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

r"""
rosbag2 bags no one here wrote, read as ``train`` reads them: read, or refused in one line.

Every folder under the roots given that holds ``.db3`` or ``.mcap`` files is read three
ways: as it is; copied without its metadata.yaml (as a power loss leaves a bag); and each
of its storage files alone. Each is read by ``read_bag`` (the trainer's read: the columnar
read, rosbags' where it gives way) and by ``read_motion`` of ``/cmd_vel`` (rosbags' reader
through the same listing). An outcome is ok; listed (refused in one line that lists the
bag's topics: it was opened, the IMU or motion topic is not among them); refused (a
``DatasetError`` of one line, its reason printed); or a defect (anything else). Printed: a
line per bag and the counts. rosbag2's own test bags (its C++ storage plugins wrote them;
services, split files, wrong formats), from ROSBAG2, a clone of
https://github.com/ros2/rosbag2 (25304dd here)::

    mkdir -p out/rosbag2_bags
    git -C ROSBAG2 archive HEAD rosbag2_py/test/resources rosbag2_tests/resources \
        rosbag2_transport/test/resources ros2bag/test/resources \
        rosbag2_cpp/test/rosbag2_cpp/bags | tar -x -C out/rosbag2_bags
    .venv/bin/python bench/bench_foreign_bags.py out/rosbag2_bags
"""

import argparse
import collections
import os
from pathlib import Path
import shutil
import sys
import tempfile

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from gyro_tdc.data import read_bag, read_motion  # noqa: E402
from gyro_tdc.errors import DatasetError  # noqa: E402


def outcome(read, path: Path) -> str:
    """Return 'ok', 'listed', 'refused: why' or 'defect: ...' of one read."""
    try:
        read(path)
    except DatasetError as exc:
        text = str(exc)
        if '\n' in text:
            return 'defect: a refusal of several lines'
        return 'listed' if 'topics present: ' in text else f'refused: {text[-90:]}'
    except Exception as exc:  # noqa: B902 (any other exception is the defect counted)
        return f'defect: {type(exc).__name__}: {exc}'[:200]
    return 'ok'


def main(argv=None) -> int:
    """Read every bag three ways, twice each; print the outcomes and their counts."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('roots', nargs='+', type=Path, help='folders to walk')
    args = ap.parse_args(argv)
    folders = sorted({p.parent for root in args.roots for p in root.rglob('*')
                      if p.suffix in ('.db3', '.mcap') and p.is_file()})
    counts = collections.Counter()
    reads = (('read_bag', read_bag),
             ('read_motion', lambda p: read_motion(p, '/cmd_vel')))
    with tempfile.TemporaryDirectory(prefix='gyro_tdc_foreign_') as tmp:
        for k, folder in enumerate(folders):
            bare = Path(tmp) / str(k) / folder.name
            shutil.copytree(folder, bare)
            (bare / 'metadata.yaml').unlink(missing_ok=True)
            files = sorted(p for p in bare.iterdir() if p.suffix in ('.db3', '.mcap'))
            said = []
            for how, path in [('as it is', folder), ('no metadata.yaml', bare),
                              *((f'{p.name} alone', p) for p in files)]:
                for name, read in reads:
                    got = outcome(read, path)
                    counts[got.split(':')[0]] += 1
                    said.append(f'{how} {name} {got}')
            print(f'{folder}: ' + '; '.join(said))
    print(f'{len(folders)} bags, {sum(counts.values())} reads: {counts["ok"]} ok, '
          f'{counts["listed"]} listed (no IMU or motion topic), {counts["refused"]} refused in '
          f'one line, {counts["defect"]} defects')
    return 0


if __name__ == '__main__':
    sys.exit(main())
