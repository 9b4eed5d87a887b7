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

"""train, evaluate and discover on a bag whose metadata lies: one line, exit 2."""

from __future__ import annotations

import importlib
import shutil

from bags import assert_bad_input, bag_from_run
import pytest
from synth import synth_run
import yaml


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    run = synth_run(seed=4, hours=0.2)
    return bag_from_run(run, tmp_path_factory.mktemp('meta') / 'run1')


def _imu_count(value):
    def edit(info):
        for entry in info['topics_with_message_count']:
            if entry['topic_metadata']['name'] == '/imu/data_raw':
                entry['message_count'] = value
    return edit


def _compressed(info):
    info['compression_format'] = 'zstd'
    info['compression_mode'] = 'message'


LIES = {
    'huge count': (_imu_count(10 ** 15), 'holds 1000000000000000 messages, more than its'),
    'negative count': (_imu_count(-5), 'a message_count of -5, not a whole number >= 0'),
    'not compressed': (_compressed, 'not compressed as metadata.yaml says'),
}
EXTRA = {'train': ['--out', 'm.yaml'], 'evaluate': ['--model', 'l3gd20_modified'],
         'discover': []}


@pytest.mark.parametrize('lie', LIES)
@pytest.mark.parametrize('command', EXTRA)
def test_lying_metadata_is_one_line_and_exit_2(tmp_path, capsys, bag, command, lie):
    edit, needle = LIES[lie]
    copy = tmp_path / 'run1'
    shutil.copytree(bag, copy)
    meta = copy / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    edit(doc['rosbag2_bagfile_information'])
    meta.write_text(yaml.safe_dump(doc, sort_keys=False))
    extra = [tmp_path / a if a.endswith('.yaml') else a for a in EXTRA[command]]
    main = importlib.import_module(f'gyro_tdc.cli.{command}').main
    assert_bad_input(capsys, [copy, *extra, '--no-progress'], str(copy), needle, entry=main)
