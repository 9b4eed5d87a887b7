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
Pieces shared by the command-line tools: argument parsing, bag options, exit codes.

Every command is a typed function plus a tiny ``main(argv) -> int`` built with
:func:`run_command`, which turns bad input (:class:`gyro_tdc.errors.GyroTdcError`,
:class:`UsageError`, an ``OSError``) into exit code 2 and one line on stderr, never a
traceback; :func:`bag_options` turns the shared bag options into one ``BagOptions``.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shlex
import sys
import textwrap
from typing import Callable, NoReturn, Optional, Sequence

from gyro_tdc.base import RAD_PER_DEG
from gyro_tdc.cli import PROG
from gyro_tdc.data import (BagOptions, DEFAULT_IMU_TOPIC, DEFAULT_REFERENCE_TOPIC,
                           DEFAULT_TEMPERATURE_TOPIC, GAP_PERIODS, LOG_FORMATS, MAX_LOSS_FRACTION,
                           SESSION_GAP_S, SESSION_MODES, TEMPERATURE_SOURCES)
from gyro_tdc.errors import GyroTdcError, one_line

__all__ = ['ArgumentParser', 'UsageError', 'add_bag_options', 'add_driver_options',
           'add_session_options', 'bag_options', 'comma_floats', 'command_line', 'driver_inputs',
           'effect_listing', 'finite_float', 'key_listing', 'non_negative_float',
           'non_negative_int', 'parse_reference', 'positive_float', 'positive_int', 'probability',
           'progress', 'progress_bar', 'refuse_driver_logs', 'run_command']

_UNITS = {'': 1.0, 'rad/s': 1.0, 'rads': 1.0, 'deg/s': RAD_PER_DEG, 'dps': RAD_PER_DEG}


class UsageError(GyroTdcError):
    """A command-line argument is missing or malformed."""


class ArgumentParser(argparse.ArgumentParser):
    """
    An ``argparse.ArgumentParser`` that raises :class:`UsageError` instead of exiting.

    ``help_tail``, when set to a function returning text, is called by ``--help`` and its text
    printed after the options, line breaks kept (the effect ids, the shipped scenarios).
    """

    help_tail: Optional[Callable[[], str]] = None

    def error(self, message: str) -> NoReturn:
        """Raise :class:`UsageError` with argparse's message (no usage dump, no exit)."""
        raise UsageError(f'{message} (see --help)')

    def format_help(self) -> str:
        """Return argparse's help, then the text of ``help_tail`` when set."""
        text = super().format_help()
        return text if self.help_tail is None else f'{text}\n{self.help_tail()}\n'


def effect_listing(width: int = 92) -> str:
    """
    Return the effect catalog as help text: each id, what it models, what excites it.

    Parameters
    ----------
    width : int
        Line width.

    Returns
    -------
    str
        One entry per effect of :data:`gyro_tdc.model.effects.EFFECTS`, in catalog order.

    """
    from gyro_tdc.model import EFFECTS
    texts = {eid: f'{e.description.rstrip(".")}. Excited by {e.excited_by}.'
             for eid, e in EFFECTS.items()}
    head = 'effect ids (for --features, --base, --candidates; bias is always in the model):'
    return '\n'.join([head, *key_listing(texts, width)])


def key_listing(items: dict[str, str], width: int = 92) -> list[str]:
    """Return ``KEY  TEXT`` help lines: the keys aligned, each text wrapped beside its key."""
    w = max(map(len, items))
    return [line for key, text in items.items()
            for line in textwrap.wrap(' '.join(text.split()), width,
                                      initial_indent=f'  {key:<{w}}  ',
                                      subsequent_indent=' ' * (w + 4))]


def parse_reference(text: str) -> tuple[float, float, float]:
    """
    Parse ``--reference x,y,z``: a constant reference rate, rad/s unless a unit follows.

    E.g. ``0,0,0``, ``10,5,20dps``, ``0.1,0,0 rad/s`` (units ``rad/s``, ``deg/s``, ``dps``).

    Raises
    ------
    UsageError
        When the text is not three finite numbers with an optional known unit.

    """
    m = re.fullmatch(r'\s*(.*?)\s*(rad/s|rads|deg/s|dps)?\s*', str(text))
    values = comma_floats(m.group(1)) if m else []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise UsageError(f'--reference: expected three finite rates x,y,z in rad/s (or with a '
                         f'deg/s suffix, e.g. 10,5,20dps), got {text!r}')
    k = _UNITS[m.group(2) or '']
    return (values[0] * k, values[1] * k, values[2] * k)


def comma_floats(text: str) -> list[float]:
    """Return the comma-separated numbers of ``text``; [] when one is not a number."""
    try:
        return [float(p) for p in str(text).split(',')]
    except ValueError:
        return []


def add_bag_options(parser: argparse.ArgumentParser, *, driver: bool = False,
                    sessions: bool = False) -> None:
    """
    Add the options every bag-reading command shares.

    ``--imu-topic``, ``--temperature-topic``, ``--reference x,y,z`` (constant, rad/s) and
    ``--reference-topic`` (mutually exclusive with ``--reference``), ``--no-progress``,
    ``--allow-loss``; for flight logs ``--log-format``, ``--imu-instance``,
    ``--allow-onboard-corrected`` and ``--temperature-source``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    driver : bool
        Also add the driver message options (:func:`add_driver_options`).
    sessions : bool
        Also add the session options (:func:`add_session_options`).

    """
    g = parser.add_argument_group('bag topics and reference rate')
    g.add_argument('--imu-topic', default=DEFAULT_IMU_TOPIC, metavar='TOPIC',
                   help='sensor_msgs/Imu topic (default: %(default)s)')
    g.add_argument('--temperature-topic', default=DEFAULT_TEMPERATURE_TOPIC, metavar='TOPIC',
                   help='sensor_msgs/Temperature topic (default: %(default)s)')
    ref = g.add_mutually_exclusive_group()
    ref.add_argument('--reference', metavar='X,Y,Z', help='constant reference (true) rate in '
                     'rad/s, or with a deg/s suffix (e.g. 10,5,20dps); default: the reference '
                     'topic when the bag has it, else zero')
    ref.add_argument('--reference-topic', default=DEFAULT_REFERENCE_TOPIC, metavar='TOPIC',
                     help='geometry_msgs/Vector3Stamped rate-table topic, held onto the IMU '
                          'stamps, used when present (default: %(default)s)')
    g.add_argument('--no-progress', dest='progress', action='store_false', default=None,
                   help='no progress bar while reading (default: shown on a terminal)')
    g.add_argument('--allow-loss', action='store_true', help='use a bag even when more than 1 %% '
                   'of the messages of a topic listed in its metadata cannot be read, or a flight '
                   'log cut short (the loss is reported either way)')
    f = parser.add_argument_group('flight-controller logs (PX4 ULog, ArduPilot DataFlash)')
    f.add_argument('--log-format', default='auto', choices=LOG_FORMATS,
                   help='how to read each path: auto tells a rosbag2 bag, a .ulg and a .bin '
                        'apart by their first bytes and name (default: %(default)s)')
    f.add_argument('--imu-instance', type=non_negative_int, default=0, metavar='N',
                   help='the IMU of a flight log to read: sensor_gyro instance (PX4) or IMU '
                        'instance (ArduPilot), from 0 (default: %(default)s)')
    f.add_argument('--allow-onboard-corrected', action='store_true',
                   help='use flight-log data the flight controller already thermally '
                        'compensated (TC_G_ENABLE=1, INS_TCALn_ENABLE=1) as they are '
                        '(default: refused, as a model of them would compensate twice)')
    f.add_argument('--temperature-source', default='imu', metavar='SRC',
                   help=f'the thermometer of a flight log: {" or ".join(TEMPERATURE_SOURCES)} '
                        "(the barometer's, e.g. PX4 sensor_combined.baro_temp_celcius, "
                        'ArduPilot BARO.Temp), or TOPIC.FIELD / MSG.Field (another thermometer '
                        'of the board); a proxy lags the die, so training adds the thermal '
                        'state (lag) with --features auto (default: %(default)s)')
    if driver:
        add_driver_options(parser)
    if sessions:
        add_session_options(parser)


def add_session_options(parser: argparse.ArgumentParser) -> None:
    """
    Add ``--sessions auto|bag|none`` and ``--session-gap S`` (commands that fit or score).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.

    """
    g = parser.add_argument_group('sessions (power cycles, one turn-on offset each)')
    g.add_argument('--sessions', default='auto', choices=SESSION_MODES, help='how the bags are '
                   'cut into sessions, each with its own turn-on offset beside one shared thermal '
                   'curve: auto (every bag, cut again where its stamps pause for longer than '
                   '--session-gap or its device clock restarts), bag (one per bag) or none (one '
                   'offset for all, as one power cycle) (default: %(default)s)')
    g.add_argument('--session-gap', dest='session_gap', type=non_negative_float, default=0.0,
                   metavar='S',
                   help='a stamp gap longer than S seconds starts a new session; 0: automatic '
                        f'(longer than {SESSION_GAP_S:g} s and than {GAP_PERIODS} sample '
                        'periods, and in a bursty log than 3 x its usual pause) (default: 0)')


def bag_options(args: argparse.Namespace, **more: object) -> BagOptions:
    """
    Return how to read the bags, from arguments parsed with :func:`add_bag_options`.

    The topics, the reference (rad/s), ``progress`` (a terminal when not given),
    ``max_loss`` (1.0 with ``--allow-loss``), the flight-log choices, the sessions
    (:func:`add_session_options`) and ``more``: :class:`~gyro_tdc.data.BagOptions` fields
    the command sets itself (``accel``, ``motion_topic``).
    """
    return BagOptions(
        imu_topic=args.imu_topic, temperature_topic=args.temperature_topic,
        reference=None if args.reference is None else parse_reference(args.reference),
        reference_topic=args.reference_topic, progress=progress(args),
        max_loss=1.0 if args.allow_loss else MAX_LOSS_FRACTION, log_format=args.log_format,
        imu_instance=args.imu_instance, allow_onboard_corrected=args.allow_onboard_corrected,
        sessions=getattr(args, 'sessions', 'auto'),
        session_gap_s=float(getattr(args, 'session_gap', 0.0)),
        temperature_source=args.temperature_source, driver=driver_inputs(args), **more)


def progress(args: argparse.Namespace) -> bool:
    """Return whether to show progress bars: ``--no-progress`` given, else a terminal."""
    return sys.stderr.isatty() if args.progress is None else bool(args.progress)


def progress_bar(total: int | None, unit: str, desc: str, shown: bool) -> tuple:
    """
    Return a tqdm bar on stderr (hidden unless ``shown``) and ``log(line)`` for stdout.

    ``log`` prints above the bar while it shows, so lines and bar never mix.
    """
    from tqdm import tqdm
    bar = tqdm(total=total, unit=unit, desc=desc, file=sys.stderr, leave=False, disable=not shown)

    def log(line: str) -> None:
        if bar.disable:
            print(line, flush=True)
        else:
            bar.write(line, file=sys.stdout)
    return bar, log


# --------------------------------------------------------------------------------------------
# argparse types: a bad value becomes one line naming the option (exit 2)
# --------------------------------------------------------------------------------------------

def _argtype(name: str, convert: Callable[[str], object], ok: Callable[[object], bool],
             expected: str) -> Callable[[str], object]:
    """Return an argparse type: ``convert`` the text, refuse what is not ``ok`` in one line."""
    def parse(text: str) -> object:
        try:
            value = convert(text)
        except ValueError:
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f'expected {expected}, got {text!r}')
        return value
    parse.__name__ = parse.__qualname__ = name
    parse.__doc__ = f'Parse {expected} (argparse type).'
    return parse


finite_float = _argtype('finite_float', float, math.isfinite, 'a finite number')
positive_float = _argtype('positive_float', finite_float, lambda v: v > 0, 'a number > 0')
non_negative_float = _argtype('non_negative_float', float,
                              lambda v: math.isfinite(v) and v >= 0, 'a number >= 0')
probability = _argtype('probability', finite_float, lambda v: 0.0 < v < 1.0,
                       'a number between 0 and 1')
positive_int = _argtype('positive_int', int, lambda v: v >= 1, 'an integer >= 1')
non_negative_int = _argtype('non_negative_int', int, lambda v: v >= 0, 'an integer >= 0')


def command_line(command: str, argv: Sequence[str]) -> str:
    """Return the shell-quoted command line ``gyro-tdc COMMAND ARGV...``."""
    return shlex.join([PROG, command, *map(str, argv)])


def run_command(command: str, build_parser: Callable[[], argparse.ArgumentParser],
                run: Callable[[argparse.Namespace, list[str]], int],
                argv: Optional[Sequence[str]] = None) -> int:
    """
    Parse ``argv`` and run a command; map bad input to exit code 2 and one stderr line.

    Parameters
    ----------
    command : str
        Command name (for the error prefix).
    build_parser : callable
        Returns the command's :class:`ArgumentParser`.
    run : callable
        ``run(args, argv) -> int`` doing the work.
    argv : sequence of str or PathLike, optional
        Arguments after the command name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 on success (or ``--help``), 2 on bad input, 130 on Ctrl-C.

    """
    argv = [os.fspath(a) if isinstance(a, os.PathLike) else str(a)
            for a in (sys.argv[1:] if argv is None else argv)]
    parser = build_parser()
    parser.prog = f'{PROG} {command}'    # one name in every usage line, whoever built it
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help / --version: argparse already printed
            return 0 if exc.code in (0, None) else 2
        return int(run(args, argv) or 0)
    except GyroTdcError as exc:
        _error(command, exc)
        return 2
    except OSError as exc:
        where = f' {exc.filename!r}' if exc.filename else ''
        _error(command, f'cannot access{where}: {exc.strerror or exc}')
        return 2
    except KeyboardInterrupt:
        _error(command, 'interrupted')
        return 130


def _error(command: str, message: object) -> None:
    """Print ``gyro-tdc COMMAND: error: MESSAGE`` on one stderr line."""
    sys.stdout.flush()
    print(f'{PROG} {command}: error: {one_line(message)}', file=sys.stderr, flush=True)


# --------------------------------------------------------------------------------------------
# Bags recorded from drivers as they publish (train, evaluate): the node's input parameters
# --------------------------------------------------------------------------------------------

def add_driver_options(parser: argparse.ArgumentParser) -> None:
    """
    Add the options naming a driver's message types and fields, as the node's parameters.

    ``--imu-type``, ``--angular-velocity-field``, ``--stamp-field``, ``--input-frame``,
    ``--temperature-type``, ``--temperature-field``, ``--temperature-stamp-field`` and
    ``--temperature-quirk`` (:class:`gyro_tdc.data.DriverInputs`).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.

    """
    from gyro_tdc.base import INPUT_FRAMES, TEMPERATURE_QUIRKS
    from gyro_tdc.data import DriverInputs
    d = DriverInputs()          # the defaults: a plain Imu + Temperature bag
    g = parser.add_argument_group("driver message types (as compensator_node's parameters)")
    # Each option sets the DriverInputs field of its name; a tuple is its choices, else metavar.
    for name, how, text in (
            ('imu_type', 'PKG/msg/TYPE', 'type of the IMU topic, e.g. geometry_msgs/msg/'
             'Vector3Stamped or px4_msgs/msg/SensorGyro (default: %(default)s)'),
            ('angular_velocity_field', 'PATH', 'dotted path to its x/y/z rate in rad/s, e.g. '
             "vector; '' the message itself (default: %(default)s)"),
            ('stamp_field', 'PATH', 'dotted path to its stamp: a builtin_interfaces/Time or an '
             'integer in microseconds, e.g. timestamp (default: %(default)s)'),
            ('input_frame', INPUT_FRAMES, 'axes of that rate: flu, or frd (PX4) turned to FLU '
             '(default: %(default)s)'),
            ('temperature_type', 'PKG/msg/TYPE', 'type of the temperature topic, checked '
             'against the bag (default: as the bag says)'),
            ('temperature_field', 'PATH', 'dotted path to its degC number, e.g. mean_temp '
             '(default: temperature, or data for std_msgs Float32/Float64)'),
            ('temperature_stamp_field', 'PATH', 'dotted path to its stamp, e.g. '
             'header.header.stamp (default: header.stamp where it has one, else the latest '
             'IMU stamp)'),
            ('temperature_quirk', TEMPERATURE_QUIRKS, "undo a driver's temperature encoding: "
             'bno055_unsigned_byte or sbg_legacy_div256 (default: none)')):
        how = {'choices': how} if isinstance(how, tuple) else {'metavar': how}
        g.add_argument('--' + name.replace('_', '-'), default=getattr(d, name), help=text, **how)


def driver_inputs(args: argparse.Namespace) -> object:
    """
    Return the :class:`gyro_tdc.data.DriverInputs` of :func:`add_driver_options`, or None.

    None when the command has no such options or every one is at its default (a plain Imu +
    Temperature bag). Raises ConfigError for a bad one (a line naming it).
    """
    from dataclasses import fields
    from gyro_tdc.data import DriverInputs
    if not hasattr(args, 'imu_type'):
        return None
    # Every option of add_driver_options is the DriverInputs field of its name.
    inputs = DriverInputs(**{f.name: getattr(args, f.name) for f in fields(DriverInputs)})
    return None if inputs.plain else inputs


def refuse_driver_logs(bag: BagOptions, paths: Sequence[str]) -> None:
    """Refuse a flight log among ``paths`` when the bags are read by field (UsageError)."""
    from gyro_tdc.data import expand_bags, is_flight_log
    for path in expand_bags(paths) if bag.driver is not None else ():
        if is_flight_log(path):
            raise UsageError(f'--imu-type and the other driver options read rosbag2 bags, '
                             f'not the flight log {str(path)!r}')
