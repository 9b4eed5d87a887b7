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
Both nodes stop cleanly on SIGINT and SIGTERM at random moments, beside a CPU hog.

Each node process is started and signalled at a seeded random moment of its start-up or its
1 kHz stream (``stop_stress``): the driver with the sim and the IIO back-ends (a fake sysfs
tree), the compensator behind a 1 kHz driver with learning off and on, on both executors,
while ``~/reload`` and ``~/learn_save`` are called over and over. Every stop exits 0 with
no traceback and no ``[FATAL]`` line, and a learning node writes learn_file after the
signal. Four stops per node here; ``bench/bench_clean_stops.py`` runs ten per node per
signal. Serial: the hog and the node start-ups would slow the tests beside them. In process:
a destroyed node's timer callbacks (which an EventsExecutor may still dispatch) do nothing.
"""

import signal

from fake_iio import l3gd20_files, make_device
import pytest
from rclpy.parameter import Parameter
from stop_stress import CONFIGS, run_series

INT, TERM = signal.SIGINT, signal.SIGTERM
#: Per node, the signal of each stop: with the configurations taken in turn, every
#: configuration of the driver meets both signals, each of the compensator's one.
SIGNALS = {'driver': [INT, INT, TERM, TERM], 'compensator': [INT, TERM, TERM, INT]}


@pytest.mark.serial
@pytest.mark.parametrize('node', sorted(SIGNALS))
def test_a_node_stopped_at_random_moments_stops_cleanly(node, tmp_path):
    series = run_series(node, SIGNALS[node], seed=36, workdir=tmp_path, max_delay_s=1.5)
    report = '\n'.join(series.lines())
    print(report)
    assert {stop.config for stop in series.stops} == set(CONFIGS[node])
    unclean = [stop for stop in series.stops if not stop.clean]
    assert not unclean, report + ''.join(
        f'\n--- {stop.line()}\n{stop.output[-4000:]}' for stop in unclean)
    if node == 'compensator':
        assert series.reloads > 0 and series.saves > 0, report


def _driver(context, tmp_path):
    from gyro_tdc.nodes.driver_node import DriverNode
    make_device(tmp_path, l3gd20_files())
    return DriverNode(context=context, parameter_overrides=[
        Parameter('backend', value='iio'), Parameter('iio_root', value=str(tmp_path))])


def _compensator(context, tmp_path):
    from gyro_tdc.nodes.compensator_node import CompensatorNode
    return CompensatorNode(context=context, parameter_overrides=[
        Parameter('model_file', value='l3gd20_modified'), Parameter('learn', value=True),
        Parameter('learn_file', value=str(tmp_path / 'learn.json'))])


@pytest.mark.parametrize('make', [_driver, _compensator], ids=['driver', 'compensator'])
def test_a_destroyed_node_cancels_its_timers_and_its_callbacks_do_nothing(
        make, ros_context, tmp_path):
    node = make(ros_context, tmp_path)
    timers = list(node.timers)
    assert timers and not any(t.is_canceled() for t in timers)
    cancelled = []
    for timer in timers:            # seen just before rclpy destroys each one
        timer.destroy = lambda t=timer, destroy=timer.destroy: (
            cancelled.append(t.is_canceled()), destroy())
    callbacks = [t.callback for t in timers]
    node.destroy_node()
    assert cancelled == [True] * len(timers)
    assert node.stopping
    for callback in callbacks:      # a queued timer event after destruction: no InvalidHandle
        callback()


def test_stop_signals_are_one_request_and_a_second_one_ends_at_once():
    """SIGINT and SIGTERM set one request; during start-up it raises; a second exits 128+N."""
    from gyro_tdc.nodes.executors import StopRequested, StopSignals
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    stop = StopSignals()
    assert stop.install()
    try:
        with pytest.raises(StopRequested, match='SIGTERM'), stop.interrupting():
            signal.raise_signal(signal.SIGTERM)     # a node being built is abandoned
        assert stop.signum == signal.SIGTERM
        stop.signum = None
        signal.raise_signal(signal.SIGINT)          # running: only recorded
        assert stop.signum == signal.SIGINT
        with pytest.raises(SystemExit) as second:
            signal.raise_signal(signal.SIGTERM)
        assert second.value.code == 128 + signal.SIGTERM
    finally:
        stop.restore()
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before


class _Half:
    """A stop interrupts its ``__init__``; its ``__del__`` needs it (as rclpy's logger does)."""

    def __init__(self) -> None:
        signal.raise_signal(signal.SIGINT)      # lands here, before the attribute is set
        self.pair = None

    def __del__(self) -> None:
        if self.pair:
            pass


def test_a_stop_mid_build_prints_no_finaliser_traceback(monkeypatch):
    """The half-built object's ``__del__`` AttributeError is dropped; other unraisables are not."""
    import sys

    from gyro_tdc.nodes.executors import quiet_abandoned, run_node, StopSignals
    seen = []
    monkeypatch.setattr(sys, 'unraisablehook', seen.append)

    def make_node():
        _Half()
        raise AssertionError('not reached: the stop abandons the build')

    assert run_node(make_node, args=[]) == 0
    assert seen == []
    stop = StopSignals()        # nothing abandoned: the same finaliser error is reported
    with quiet_abandoned(stop):
        half = _Half.__new__(_Half)
        del half
    assert len(seen) == 1 and isinstance(seen[0].exc_value, AttributeError)
    stop.abandoned = True       # abandoned: any other unraisable still goes through
    with quiet_abandoned(stop):
        sys.unraisablehook(type('U', (), {'exc_value': ValueError('x'), 'object': _Half.__del__}))
    assert len(seen) == 2


def test_a_stop_an_import_wraps_mid_build_is_a_stop_not_a_traceback(capfd):
    """A signal inside an extension module's init surfaces as ImportError: still a stop."""
    from gyro_tdc.nodes.executors import run_node, StopRequested

    def make_node():
        try:
            signal.raise_signal(signal.SIGINT)      # lands in the module's init ...
        except StopRequested as exc:                # ... which reports its own failure
            raise ImportError('initialization failed') from exc
        raise AssertionError('not reached: the stop abandons the build')

    def failing_build():
        raise ImportError('no module named nowhere')

    assert run_node(make_node, args=[]) == 0
    out, err = capfd.readouterr()
    assert 'Traceback' not in out + err and 'ImportError' not in out + err
    with pytest.raises(ImportError, match='nowhere'):   # without a stop: a real error
        run_node(failing_build, args=[])


def test_a_stop_signal_a_non_python_thread_gets_mid_build_stops_it_at_once():
    """The kernel may hand the signal to one of rclpy's threads: the build still stops."""
    import ctypes
    import time

    from gyro_tdc.nodes.executors import run_node
    libc = ctypes.CDLL(None)
    thread = ctypes.c_ulong()       # a C thread, as DDS's: sleep(5), cut short by a signal
    assert libc.pthread_create(ctypes.byref(thread), None, libc.sleep, ctypes.c_void_p(5)) == 0
    sent = []

    def make_node():
        sent.append(time.monotonic())
        signal.pthread_kill(thread.value, signal.SIGTERM)
        while time.monotonic() - sent[0] < 60.0:
            pass                    # pure bytecode, as the sim back-end's simulation
        raise AssertionError('not reached: the stop abandons the build')

    assert run_node(make_node, args=[]) == 0
    assert time.monotonic() - sent[0] < 30.0
    libc.pthread_join(thread, None)
