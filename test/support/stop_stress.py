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
Stop node processes at random moments under a 1 kHz stream and a CPU hog (issue 36).

Used by ``test/nodes/test_executors.py`` (a few stops) and ``bench/bench_clean_stops.py``
(ten per node per signal). A stop is *clean* when the process exits 0 within the deadline and
prints no ``Traceback`` and no ``[FATAL]`` line; with ``learn: true`` and a ``learn_file``,
a node that answered ``~/learn_save`` before the signal must also have written the file
after it (the learner's last state). The moment is drawn after the child has installed its
SIGTERM handler (its ``main()`` runs; read from ``/proc/<pid>/status``): before that the
interpreter is still importing, and Python's defaults apply.

Nothing here imports ``rclpy`` at module level; :class:`Poker` does when started.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import threading
import time
from typing import Iterator

from cpu_load import cpu_hogs
from fake_iio import l3gd20_files, make_device

__all__ = ['Config', 'CONFIGS', 'Poker', 'run_series', 'Series', 'Stop', 'stream']

#: Node executables, as ``ros2 run`` starts them.
MODULES = {'driver': 'gyro_tdc.nodes.driver_node',
           'compensator': 'gyro_tdc.nodes.compensator_node'}
#: The stream's rate [Hz].
RATE_HZ = 1000.0
#: Longest wait for a child to install its signal handlers, then to exit after the signal [s].
READY_S = 60.0
EXIT_S = 60.0
#: What an unclean output holds.
UNCLEAN = ('Traceback', '[FATAL]')


@dataclass(frozen=True)
class Config:
    """One way to run a node: its executable and its parameters."""

    node: str
    label: str
    params: tuple[tuple[str, str], ...] = ()
    learn: bool = False


#: The configurations a series draws from: both back-ends of the driver; the compensator with
#: learning on and off, on both executors, with a model that ``~/reload`` reads again.
CONFIGS = {
    'driver': (
        Config('driver', 'sim', (('backend', 'sim'), ('scenario', 'demo_fast'),
                                 ('sim_rate_hz', f'{RATE_HZ}'), ('time_scale', '1.0'))),
        Config('driver', 'iio', (('backend', 'iio'), ('rate_hz', f'{RATE_HZ}'))),
    ),
    'compensator': tuple(
        Config('compensator', f'{executor}, learn {"on" if learn else "off"}',
               (('executor', executor), ('model_file', 'l3gd20_modified'),
                ('learn', str(learn).lower()), ('learn_save_period', '1.0')), learn=learn)
        for executor in ('single', 'events') for learn in (False, True)),
}


@dataclass
class Stop:
    """One start and stop of a node process, and what it printed."""

    config: Config
    signal: str
    delay_s: float
    code: int | None = None
    output: str = ''
    ready_s: float = 0.0        # from the start to the signal handlers installed [s]
    exit_s: float = 0.0         # from the signal to the exit [s]
    problems: list[str] = field(default_factory=list)

    @property
    def clean(self) -> bool:
        """Return whether the stop was clean."""
        return not self.problems

    def line(self) -> str:
        """Return one line: the node, its configuration, the signal, the moment, the outcome."""
        what = 'clean' if self.clean else 'UNCLEAN: ' + '; '.join(self.problems)
        return (f'{self.config.node} ({self.config.label}) {self.signal} '
                f'{self.delay_s:.2f} s after its handlers ({self.ready_s:.2f} s from the '
                f'start): exit {self.code} {self.exit_s:.2f} s later, {what}')


@dataclass(frozen=True)
class Series:
    """The stops of one series, and the ``~/reload`` and ``~/learn_save`` calls answered."""

    stops: list[Stop]
    reloads: int = 0
    saves: int = 0

    def lines(self) -> list[str]:
        """Return one line per stop, then the counts."""
        clean = sum(stop.clean for stop in self.stops)
        return [stop.line() for stop in self.stops] + [
            f'{clean} clean, {len(self.stops) - clean} unclean of {len(self.stops)} stops; '
            f'{self.reloads} ~/reload answered, {self.saves} ~/learn_save succeeded']


def _command(config: Config, extra: dict[str, str]) -> list[str]:
    cmd = [sys.executable, '-m', MODULES[config.node], '--ros-args']
    for key, value in (*config.params, *extra.items()):
        cmd += ['-p', f'{key}:={value}']
    return cmd


@contextlib.contextmanager
def stream(seconds: float = 3600.0) -> Iterator[subprocess.Popen]:
    """Run a simulated driver publishing ``imu/data_raw`` at 1 kHz for the block."""
    config = CONFIGS['driver'][0]
    child = subprocess.Popen(_command(config, {}), stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    try:
        yield child
    finally:
        child.send_signal(signal.SIGINT)
        try:
            child.wait(EXIT_S)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()


def handlers_installed(pid: int) -> bool:
    """Return whether process ``pid`` catches SIGTERM (``SigCgt`` of /proc/<pid>/status)."""
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return False
    for line in status.splitlines():
        if line.startswith('SigCgt:'):
            return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    return False


class Poker:
    """
    Call the compensator's ``~/reload`` and ``~/learn_save`` over and over from a thread.

    Every call is asynchronous and never awaited: the node may be starting, busy or gone.
    ``reloads`` counts the answered reloads, ``saves`` the successful saves.
    """

    def __init__(self, name: str = 'compensator_node', period_s: float = 0.15) -> None:
        self.name = name
        self.period_s = period_s
        self._halt = threading.Event()
        self._saved: list[float] = []
        self.reloads = 0          # ~/reload requests answered
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> 'Poker':
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._halt.set()
        self._thread.join(30.0)

    @property
    def saves(self) -> int:
        """Return how many ``learn_save`` requests succeeded."""
        return len(self._saved)

    def saved_between(self, t0: float, t1: float) -> bool:
        """Return whether a ``learn_save`` request sent in [t0, t1] (monotonic) succeeded."""
        return any(t0 <= t <= t1 for t in list(self._saved))

    def _run(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from std_srvs.srv import Trigger

        context = Context()
        rclpy.init(context=context, signal_handler_options=rclpy.SignalHandlerOptions.NO)
        node = rclpy.create_node('stop_stress_poker', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        reload = node.create_client(Trigger, f'{self.name}/reload')
        save = node.create_client(Trigger, f'{self.name}/learn_save')
        try:
            next_call = time.monotonic()
            while not self._halt.is_set():
                if time.monotonic() >= next_call:
                    next_call += self.period_s
                    if reload.service_is_ready():
                        reload.call_async(Trigger.Request()).add_done_callback(
                            lambda f: setattr(self, 'reloads', self.reloads + 1))
                    if save.service_is_ready():
                        sent = time.monotonic()
                        future = save.call_async(Trigger.Request())
                        future.add_done_callback(
                            lambda f, sent=sent: not f.cancelled() and f.result() is not None
                            and f.result().success and self._saved.append(sent))
                executor.spin_once(timeout_sec=0.02)
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=context)


def _inode(path: Path) -> tuple[int, int] | None:
    """Return the (device, inode) of ``path``, None when there is none."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return st.st_dev, st.st_ino


def _hold(path: Path) -> tuple[int | None, tuple[int, int] | None]:
    """
    Open ``path`` and return the descriptor and its (device, inode); (None, None) without one.

    Held open, the inode cannot be freed and handed to a later file: a save that replaces
    the file can then never come back under the same number (tmpfs and ext4 reuse them).
    """
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None, None
    st = os.fstat(fd)
    return fd, (st.st_dev, st.st_ino)


def _stop_once(config: Config, signum: int, delay_s: float, workdir: Path,
               poker: Poker | None, save_first: bool = False) -> Stop:
    """
    Start ``config``'s node, signal it ``delay_s`` after its handlers are in, judge the end.

    With ``save_first`` and no ``~/learn_save`` answered yet in the series, the moment is
    drawn after the first one is: the series then covers a stop after a save for certain.
    """
    name = signal.Signals(signum).name
    stop = Stop(config, name, delay_s)
    extra: dict[str, str] = {}
    learn_file = workdir / 'learn.json'
    if config.learn:
        extra['learn_file'] = str(learn_file)
    if config.node == 'driver' and dict(config.params).get('backend') == 'iio':
        root = workdir / 'iio'
        if not root.exists():
            make_device(root, l3gd20_files())
        extra['iio_root'] = str(root)
    launched = time.monotonic()
    child = subprocess.Popen(_command(config, extra), stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    chunks: list[str] = []
    reader = threading.Thread(target=lambda: chunks.append(child.stdout.read()), daemon=True)
    reader.start()
    held, before = None, None
    try:
        deadline = time.monotonic() + READY_S
        while not handlers_installed(child.pid):
            if child.poll() is not None or time.monotonic() > deadline:
                stop.problems.append('never installed its signal handlers')
                break
            time.sleep(0.005)   # polling /proc: the child's state, with a deadline
        started = time.monotonic()
        stop.ready_s = started - launched
        if save_first and poker is not None and poker.saves == 0:
            deadline = time.monotonic() + READY_S
            while poker.saves == 0 and child.poll() is None and time.monotonic() < deadline:
                time.sleep(0.01)    # polling the poker's count, with a deadline
        time.sleep(delay_s)     # the random moment itself
        signalled = time.monotonic()
        signalled_ns = time.time_ns()
        # Every save replaces the file (a new inode): the one there now, held open so that its
        # number is not reused, must not be the one left after the stop. (A new file's mtime
        # may read a few ms before this moment: the kernel stamps it from its coarse clock.)
        held, before = _hold(learn_file) if config.learn else (None, None)
        if child.poll() is not None and stop.clean:    # it ended by itself, unasked
            stop.problems.append(f'exited (status {child.returncode}) before the signal')
        child.send_signal(signum)
        try:
            stop.code = child.wait(EXIT_S)
            stop.exit_s = time.monotonic() - signalled
        except subprocess.TimeoutExpired:
            stop.problems.append(f'still running {EXIT_S:g} s after the signal')
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        reader.join(10.0)
    stop.output = ''.join(chunks)
    replaced = _inode(learn_file) != before if config.learn else False
    if held is not None:
        os.close(held)
    if stop.code not in (0, None):
        stop.problems.append(f'exit status {stop.code}')
    for text in UNCLEAN:
        if text in stop.output:
            stop.problems.append(f'{text!r} in its output')
    if config.learn and poker is not None and poker.saved_between(started, signalled):
        # It was learning before the signal: the last state is written after it.
        written = learn_file.stat().st_mtime_ns if learn_file.exists() else None
        if written is None or not replaced:
            when = ('missing' if written is None else
                    f'last written {(signalled_ns - written) * 1e-9:.3f} s before it')
            stop.problems.append(f'learn_file not written after the signal ({when})')
        else:
            try:
                json.loads(learn_file.read_text())
            except ValueError as exc:
                stop.problems.append(f'learn_file unreadable: {exc}')
    if config.learn and learn_file.exists():
        learn_file.unlink()
    return stop


def run_series(node: str, signals: list[int], *, seed: int, workdir: Path,
               max_delay_s: float = 3.0, hog: bool = True) -> Series:
    """
    Start and stop ``node`` once per entry of ``signals``, at seeded random moments.

    Stop ``i`` runs configuration ``i`` (cyclically) of :data:`CONFIGS` and draws its
    moment uniformly in ``[0, max_delay_s]`` s after the child installed its signal handlers
    (start-up, model load and the sim back-end's start included). The compensator runs
    behind a 1 kHz simulated driver, with :class:`Poker` calling ``~/reload`` and
    ``~/learn_save``; its last learning stop waits for a first answered save if none was yet.

    Parameters
    ----------
    node : str
        ``'driver'`` or ``'compensator'``.
    signals : list of int
        The signal of each stop, in order.
    seed : int
        Seed of the moments.
    workdir : Path
        Where fake devices and learn files go.
    max_delay_s : float, s
        Latest moment drawn.
    hog : bool
        Keep one core busy meanwhile.

    Returns
    -------
    Series
        One stop per signal, in order, and what the poker got answered.

    """
    rng = random.Random(seed)
    configs = CONFIGS[node]
    draws = [(configs[i % len(configs)], rng.uniform(0.0, max_delay_s))
             for i in range(len(signals))]
    workdir.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as stack:
        if hog:
            stack.enter_context(cpu_hogs())
        poker = None
        if node == 'compensator':
            stack.enter_context(stream())
            poker = stack.enter_context(Poker())
        last_learn = max((i for i, (config, _) in enumerate(draws) if config.learn),
                         default=-1)
        stops = [_stop_once(config, signum, delay, workdir, poker, save_first=i == last_learn)
                 for i, (signum, (config, delay)) in enumerate(zip(signals, draws))]
    return Series(stops, poker.reloads if poker else 0, poker.saves if poker else 0)
