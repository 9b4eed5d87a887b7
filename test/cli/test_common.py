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

"""Tests of gyro_tdc.cli.common: argparse types, --reference, exit codes, --help lists."""

from __future__ import annotations

import argparse
from dataclasses import asdict
import importlib
import math
from pathlib import Path

from gyro_tdc.base.resources import scenario_names
from gyro_tdc.cli import COMMANDS, load_main
from gyro_tdc.cli.common import (add_bag_options, add_driver_options, ArgumentParser,
                                 bag_options, command_line, finite_float, non_negative_float,
                                 non_negative_int, parse_reference, positive_float,
                                 positive_int, probability, run_command, UsageError)
from gyro_tdc.data import DriverInputs
from gyro_tdc.errors import DatasetError, one_line
from gyro_tdc.model.effects import EFFECTS
from gyro_tdc.runtime.policy import PARAMS, TEMPERATURE_TYPES
import pytest


@pytest.mark.parametrize('parse, good, bad, message', [
    (finite_float, {'-1.5': -1.5, '0': 0.0, '1e3': 1000.0}, ['nan', 'inf', 'x', ''],
     'expected a finite number'),
    (positive_float, {'0.5': 0.5, '7': 7.0}, ['0', '-1'], 'expected a number > 0'),
    (positive_float, {}, ['nan', 'x'], 'expected a finite number'),
    (non_negative_float, {'0': 0.0, '2.5': 2.5}, ['-0.1', 'inf', 'x'],
     'expected a number >= 0'),
    (probability, {'0.01': 0.01, '0.5': 0.5}, ['0', '1', '1.5'],
     'expected a number between 0 and 1'),
    (positive_int, {'1': 1, '12': 12}, ['0', '-3', '1.5', 'x'], 'expected an integer >= 1'),
    (non_negative_int, {'0': 0, '3': 3}, ['-1', '1.5', 'x'], 'expected an integer >= 0'),
])
def test_argparse_types(parse, good, bad, message):
    for text, value in good.items():
        assert parse(text) == value
    for text in bad:
        with pytest.raises(argparse.ArgumentTypeError, match=message) as info:
            parse(text)
        assert repr(text) in str(info.value)


@pytest.mark.parametrize('text, want_dps', [
    ('0,0,0', (0.0, 0.0, 0.0)), ('10,5,20dps', (10.0, 5.0, 20.0)),
    (' 1, -2 ,3 deg/s ', (1.0, -2.0, 3.0)), ('0.1,0,0 rad/s', (0.1 * 180 / math.pi, 0, 0)),
])
def test_parse_reference(text, want_dps):
    got = parse_reference(text)
    assert got == pytest.approx(tuple(v * math.pi / 180.0 for v in want_dps))


@pytest.mark.parametrize('text', ['1,2', 'a,b,c', '1,2,nan', '1,2,3 furlongs', ''])
def test_parse_reference_rejects(text):
    with pytest.raises(UsageError, match='--reference: expected three finite rates'):
        parse_reference(text)


def test_bag_options_from_the_shared_parser():
    p = ArgumentParser(prog='x')
    add_bag_options(p)
    opts = bag_options(p.parse_args(['--reference', '0,0,1', '--no-progress']))
    assert opts.imu_topic == '/imu/data_raw'
    assert opts.temperature_topic == '/imu/temperature'
    assert opts.reference == pytest.approx((0.0, 0.0, 1.0))
    assert opts.progress is False and opts.max_loss == 0.01 and opts.accel is False
    lossy = bag_options(p.parse_args(['--allow-loss', '--temperature-topic', '/t']), accel=True)
    assert (lossy.max_loss, lossy.temperature_topic, lossy.reference) == (1.0, '/t', None)
    assert lossy.accel is True
    with pytest.raises(UsageError, match='not allowed with argument'):
        p.parse_args(['--reference', '0,0,0', '--reference-topic', '/r'])


def test_driver_options_default_to_the_nodes_parameters():
    p = ArgumentParser(prog='x')
    add_driver_options(p)
    args = vars(p.parse_args([]))
    assert DriverInputs(**{k: args[k] for k in asdict(DriverInputs())}).plain
    # The node's input parameters of the same name have the same defaults, but the
    # temperature type: the node subscribes to one, the trainer reads what the bag holds.
    node = {s.name: s.default for s in PARAMS}
    same = {k: v for k, v in asdict(DriverInputs()).items() if k != 'temperature_type'}
    assert {k: node[k] for k in same} == same
    assert args['temperature_type'] == '' and node['temperature_type'] == TEMPERATURE_TYPES[0]


def _parser():
    p = ArgumentParser(prog='python -m gyro_tdc thing')
    p.add_argument('rest', nargs='*')
    p.add_argument('--n', type=positive_int, default=1)
    return p


@pytest.mark.parametrize('fail, code, line', [
    (None, 0, None),
    (UsageError('--x: bad'), 2, 'gyro-tdc thing: error: --x: bad'),
    (DatasetError("Bag 'b'\nis gone."), 2, "gyro-tdc thing: error: Bag 'b' is gone."),
    (PermissionError(13, 'Permission denied', '/out.yaml'), 2,
     "gyro-tdc thing: error: cannot access '/out.yaml': Permission denied"),
    (KeyboardInterrupt(), 130, 'gyro-tdc thing: error: interrupted'),
])
def test_run_command_maps_errors_to_one_line_and_an_exit_code(capsys, fail, code, line):
    seen = []

    def run(args, argv):
        seen.append((args.n, argv))
        if fail is not None:
            raise fail
        return 0

    assert run_command('thing', _parser, run, ['--n', '3', Path('p')]) == code
    assert seen == [(3, ['--n', '3', 'p'])]
    err = capsys.readouterr().err
    assert err.splitlines() == ([] if line is None else [line])


def test_run_command_argparse_errors_and_help(capsys):
    assert run_command('thing', _parser, lambda a, v: 0, ['--n', '0']) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["gyro-tdc thing: error: argument --n: expected an integer >= 1, got '0' "
                   '(see --help)']
    assert run_command('thing', _parser, lambda a, v: 0, ['--help']) == 0
    assert 'usage: gyro-tdc thing' in capsys.readouterr().out


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_every_command_reports_bad_input_with_the_common_prefix(capsys, name):
    assert load_main(name)(['--no-such-option']) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f'gyro-tdc {name}: error: '), err
    assert err[0].endswith(' (see --help)')


def test_one_line_and_command_line():
    assert one_line('a\n  b\tc ') == 'a b c'
    assert one_line(KeyError()) == 'KeyError'
    assert command_line('train', ['my bag', '--out', 'm.yaml']) == \
        "gyro-tdc train 'my bag' --out m.yaml"


# ---- gyro-tdc <command> --help: one program name, and the lists a newcomer needs ----------

def _help(capsys, name):
    assert load_main(name)(['--help']) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_every_command_names_itself_gyro_tdc(capsys, name):
    assert _help(capsys, name).startswith(f'usage: gyro-tdc {name} ')


@pytest.mark.parametrize('name', ['train', 'discover'])
def test_train_and_discover_list_the_effect_ids(capsys, name):
    tail = _help(capsys, name).split('\neffect ids', 1)[1]
    for eid, effect in EFFECTS.items():
        assert f'\n  {eid} ' in tail, eid
        assert effect.excited_by.split()[0] in tail


def test_simulate_lists_the_scenarios(capsys):
    tail = _help(capsys, 'simulate').split('\nshipped scenarios', 1)[1]
    assert [line.split(':')[0].strip() for line in tail.splitlines()
            if line.startswith('  ') and not line.startswith('      ')] == scenario_names()


@pytest.mark.parametrize('command,argv', [
    ('train', ['bag']), ('discover', ['bag']), ('export', ['--px4', 'm.yaml']),
    ('fleet', ['fleet.csv']), ('simulate', ['--scenario', 'l3gd20_paper']), ('demo', [])])
def test_o_is_out_in_every_command_that_writes(command, argv):
    parser = importlib.import_module(f'gyro_tdc.cli.{command}').build_parser()
    assert parser.prog == f'gyro-tdc {command}'     # one name, as run_command prints it
    assert str(parser.parse_args([*argv, '-o', 'x']).out) == 'x'
    assert str(parser.parse_args([*argv, '--out', 'x']).out) == 'x'
