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


"""`gyro-tdc demo`: the whole offline pipeline runs, shows what it should, and re-runs."""

import json
import re

from gyro_tdc.cli import demo
import numpy as np
import pytest


def test_demo_offline_pipeline(tmp_path, capsys):
    out = tmp_path / 'demo'
    assert demo.main(['--out', str(out), '--skip-live']) == 0
    text = capsys.readouterr().out
    # Every step prints the command a user would type.
    for cmd in ('simulate --scenario l3gd20_paper', 'train ', 'evaluate ', 'discover '):
        assert f'$ gyro-tdc {cmd}' in text
    assert 'paper table (eq. 31-32)' in text
    # The steps are numbered 1..N of the one list --help and doc/getting_started.md show too.
    total = len(demo.STEPS) - 1
    found = re.findall(r'^\[(\d+)/(\d+)\] (.*?)  \(t = \d+ s\)$', text, flags=re.M)
    assert [(int(i), int(n), title) for i, n, title in found] == [
        (i, total, title) for i, title in enumerate(demo.STEPS[:-1], 1)]
    # Six trainings on two bags: each bag's coverage is printed by the first only.
    runs = text.split('$ gyro-tdc train ')[1:]
    repeated = [r for r in runs if 'as printed above)' in r.split('\n[', 1)[0]]
    assert len(repeated) == 4
    for r in runs:
        shown = 'coverage per 5 degC bin' in r.split('\n[', 1)[0]
        assert shown == (r not in repeated)

    tables = json.loads((out / 'report' / 'paper_tables.json').read_text())
    assert [b['bag'].rsplit('/', 1)[-1] for b in tables['bags']] == ['run2', 'run3', 'run4',
                                                                     'run5']
    for bag in tables['bags']:
        raw = np.array(bag['raw']['bs'])
        conv, modi = (np.array(m['bs']) for m in bag['models'])
        assert np.all(modi < conv) and np.all(conv < raw)
        # Held out, the modified model reaches the white-noise floor of the 10 Hz L3GD20
        # ((0.03 dps/sqrt(Hz))^2 * 10 Hz = 0.009 (deg/s)^2) within the run-to-run offset.
        assert np.all(modi < 2.0 * 0.009)

    found = json.loads((out / 'report' / 'discovery.json').read_text())
    named = {s['effect'] for s in found['steps']} | {
        a for s in found['steps'] for a in s['aliases']}
    assert 'lag' in named
    last = found['steps'][-1]
    assert last['heldout_gap_after_dps'] < 1.3 * found['noise_floor_dps']
    assert (out / 'models' / 'discovered.yaml').is_file()
    assert (out / 'report' / 'discovery' / 'report.md').is_file()
    assert sorted(p.name for p in (out / 'report' / 'evaluate').glob('*.png'))
    # --help promises only what is written: every output it lists exists (live.json is the
    # live step's, left out here).
    for pattern in demo.OUTPUTS:
        if pattern == 'report/live.json':
            assert not (out / pattern).exists()
            continue
        for part in pattern.replace(' .. ', ', ').split(', '):
            part = part if '/' in part else f'{pattern.rsplit("/", 1)[0]}/{part}'
            assert list(out.glob(part.strip())), part


def test_help_lists_the_steps_and_outputs(capsys):
    assert demo.main(['--help']) == 0
    text = capsys.readouterr().out
    flat = ' '.join(text.split())
    for i, title in enumerate(demo.STEPS, 1):
        assert f'{i}. {" ".join(title.split())}' in flat
    for pattern in demo.OUTPUTS:
        assert pattern in text
    assert 'csv' not in text.lower()


def test_out_is_cleared_only_when_an_earlier_demo_wrote_it(tmp_path, capsys):
    out = tmp_path / 'demo'
    demo.prepare_out(out)                       # new folder: created and marked
    assert (out / demo.MARKER).is_file()
    (out / 'bags' / 'l3gd20_paper').mkdir(parents=True)
    (out / 'old.txt').write_text('from the last demo')
    demo.prepare_out(out)                       # an earlier demo's: cleared, marked again
    assert sorted(p.name for p in out.iterdir()) == [demo.MARKER]
    assert 'removing the previous demo output' in capsys.readouterr().out
    mine = tmp_path / 'mine'
    mine.mkdir()
    (mine / 'thesis.tex').write_text('keep')
    assert demo.main(['--out', str(mine), '--skip-live']) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and 'was not written by the demo' in err[0]
    assert (mine / 'thesis.tex').read_text() == 'keep'
    empty = tmp_path / 'empty'
    empty.mkdir()
    demo.prepare_out(empty)                     # an empty folder is fine
    assert (empty / demo.MARKER).is_file()


@pytest.mark.parametrize('counts, needles', [
    ((8320, 8050, 8050, 8050), ['one out per in: while both streams were heard, 8050 raw',
                                'the totals (8320 raw, 8050 compensated) differ', 'DDS']),
    ((8440, 9460, 8440, 8440), ['one out per in', '8440 compensated came out',
                                'no raw twin']),
    ((500, 500, 500, 500), ['one out per in', '500 raw messages went in']),
    ((600, 590, 600, 590), ['not one out per in', '(10 lost']),
])
def test_live_counts_are_explained(counts, needles):
    lines = demo.live_counts_explained(*counts)
    text = '\n'.join(lines)
    for needle in needles:
        assert needle in text
    assert len(lines) == (1 if counts[:2] == counts[2:] else 2)


def test_only_a_bag_trained_again_has_its_coverage_left_out(monkeypatch, capsys):
    # Every step but train streams its output; the second non-train step was buffered to the
    # end and its coverage-like lines dropped ("coverage of None"), as if a bag seen before.
    import io
    import sys
    streamed = []

    def fake_main(argv):
        streamed.append(not isinstance(sys.stdout, io.StringIO))   # the demo's buffer
        print('coverage 15 .. 20 degC' if argv[0] == 'bag' else f'step {argv[0]}')
        return 0
    monkeypatch.setattr(demo, 'load_main', lambda command: fake_main)
    monkeypatch.setattr(demo, 'is_coverage_line', lambda line: line.startswith('coverage'))
    covered = set()
    for n, (command, argv) in enumerate([('evaluate', ['a']), ('discover', ['b']),
                                         ('train', ['bag']), ('train', ['bag']),
                                         ('evaluate', ['c'])]):
        demo._run_step(n, command, argv, covered)
    out = capsys.readouterr().out
    assert streamed == [True, True, True, False, True]
    assert out.count('coverage 15 .. 20 degC') == 1 and 'coverage of None' not in out
    assert '(coverage of bag: as printed above)' in out and covered == {'bag'}
