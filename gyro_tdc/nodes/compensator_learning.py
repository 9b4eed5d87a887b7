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
The compensator's learning in the field (``learn: true``, :mod:`gyro_tdc.learn.learner`).

:class:`Learning` is a part of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`
(the steady-clock timer, the step and saves on a worker thread, ``~/learn_save`` and
``~/learn_reset``: doc/internals/runtime.md). It keeps ``learner``; the node creates the
timer and the services and routes them here.
"""

from __future__ import annotations

from array import array
from dataclasses import replace
import sys
from typing import Any

from gyro_tdc.base import Job, LatestJob
from gyro_tdc.errors import OutputError
from gyro_tdc.learn import held_out_line, LearnConfig, Learner, LearnFile, open_learn_file
from gyro_tdc.model import CompensationModel

__all__ = ['LEARN_LOG_THROTTLE_S', 'LEARN_STEP_S', 'LEARN_WAIT_S', 'Learning',
           'SWITCH_INTERVAL_S']

#: Period of the learner's timer (learn:=true), s, on the steady clock: the IMU callback only
#: appends; the timer hands what it appended to the learner and, when a window has ended
#: (or a save is due), starts the step on a worker thread.
LEARN_STEP_S = 0.1
#: Longest wait of a service call, a model_file install or a policy change for the learner's
#: step in progress (a save on a slow disk) [s]; a prior then applies when the step ends.
LEARN_WAIT_S = 10.0
#: Least time between two log lines of a failing save or step [s] (/diagnostics says it too).
LEARN_LOG_THROTTLE_S = 60.0
#: Python's thread switch interval while learning [s]: the worker holds the interpreter lock
#: at most this long before the IMU callback's thread may take it (the default is 5 ms, 10
#: samples at 2 kHz for every slice of a fit).
SWITCH_INTERVAL_S = 5e-4
#: A learning service's answer while the step in progress does not end in time.
BUSY = (f'busy: the learning step in progress did not end within {LEARN_WAIT_S:g} s (a slow '
        'disk?); try again')


class _Front:
    """
    What the message path hands the learner between two steps: appends, nothing else.

    The core sees it as its learner (``buf.extend``, ``add_temperature``, ``observe_motion``,
    ``config``), so the learner itself is touched by one thread at a time: the executor's
    while no step runs, the worker's during one.
    """

    def __init__(self, config: LearnConfig) -> None:
        self.config, self.buf = config, array('d')
        self.temps: list[tuple[float, float]] = []
        self.motion: list[tuple[float, bool]] = []

    def add_temperature(self, t: float, temp_c: float) -> None:
        self.temps.append((t, temp_c))

    def observe_motion(self, t: float, moving: bool) -> None:
        self.motion.append((t, moving))

    def hand_over(self, learner: Learner) -> None:
        """Give everything appended so far to ``learner`` (which must be idle)."""
        learner.buf.extend(self.buf)
        for t, temp_c in self.temps:
            learner.add_temperature(t, temp_c)
        for t, moving in self.motion:
            learner.observe_motion(t, moving)
        del self.buf[:], self.temps[:], self.motion[:]


def _step_and_save(learner: Learner, store: LearnFile | None) -> tuple[str, str, list[str]]:
    """
    Step ``learner`` and save it to ``store`` when due: the worker thread's job.

    Returns ``(what, text, notes)``: what is '' (stepped), 'saved', 'save failed' or
    'step failed' (text: why), notes the store's lines worth a warning.
    """
    try:
        learner.step()
        if store is None or not learner.tick_save_clock():
            return '', '', []
        learner.saved()                 # a failed save is tried again a save period later
        return _write(learner, store)
    except Exception as exc:  # the worker's edge: a bug must not stop learning silently
        return 'step failed', f'{type(exc).__name__}: {exc}', []


def _write(learner: Learner, store: LearnFile) -> tuple[str, str, list[str]]:
    """Write ``learner``'s state to ``store``: ('saved', path, notes) or ('save failed', why)."""
    try:
        store.write(learner.state())
    except OutputError as exc:
        return 'save failed', str(exc), []
    return 'saved', str(store.path), list(store.notes)


class Learning:
    """
    Learn the bias vs temperature from still time while the compensator ``node`` runs.

    Creates the learner (the model in use is its prior), resumes ``learn_file`` (or the file
    beside it) and becomes the core's learner front.
    """

    #: Where the learner's state is written (None: nowhere).
    learn_store: LearnFile | None = None
    #: One line while learn_file itself is refused (kept; learning goes beside it), else ''.
    learn_file_warning: str = ''
    #: Why the last save failed ('' once one succeeds), and how many failed.
    learn_save_error: str = ''
    learn_save_failures: int = 0
    #: Steps that raised (a bug; logged throttled), and the last one's error.
    learn_step_errors: int = 0

    def __init__(self, node: Any) -> None:
        self.node, self.core, self.params = node, node.core, node.params
        self.log = node.get_logger()
        self.learner = self._new_learner()
        self._learned_installs = 0
        #: The axes the learned model keeps offset-only, as last logged.
        self._offset_only: list[str] = []
        self._learn_jobs = LatestJob()
        # The step in progress; a 'prior' and a 'timeout' waiting for it to end.
        self.job: Job | None = None
        self._waiting: dict[str, Any] = {}
        if node.params.learn_file:
            self._open(node.params.learn_file)
        else:
            self.log.warning('learn without learn_file: nothing is kept across restarts')
        self._front = _Front(self.learner.config)
        self._learn_values = self.learner.diagnostic_values()
        sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL_S))
        node.core.learner = self._front

    def _new_learner(self) -> Learner:
        """Return a learner from the start (the model in use is the prior)."""
        return Learner(LearnConfig(temperature_timeout=self.core.policy.temperature_timeout,
                                   save_period_s=self.params.learn_save_period,
                                   swap_delay_s=self.params.learn_swap_delay),
                       prior=self.core.model)

    def _open(self, path: str) -> None:
        """Resume ``learn_file`` (or the file used beside it); a file refused is said once."""
        try:
            opened = open_learn_file(path, self.learner.load_state)
        except Exception as exc:  # the start-up edge: no file content stops the node
            self.learner = self._new_learner()
            self.learn_file_warning = (f'learn_file {path!r} not used '
                                       f'({type(exc).__name__}: {exc}): learning from '
                                       'the start, nothing is kept across restarts')
            return self.log.warning(self.learn_file_warning)
        self.learn_store, self.learn_file_warning = opened.file, opened.warning
        for line in filter(None, [*opened.notes, opened.warning]):
            self.log.warning(line)
        if opened.resumed:
            # Installed at once, on this thread.
            if (model := self.learner.take_model()) is not None:
                self.core.set_model(model)
                self.node.loading.model_file = 'learned'
            s = self.learner.summary()
            self.log.info(f'resumed learning from {opened.file.path}: {s["points"]} points, '
                          f'{s["still_s"]:.0f} s still')

    # -- the learner's owner: the worker during a step, else the executor's thread ------

    def _take(self, what: str, text: str, notes: list[str]) -> None:
        """Take the outcome of a step or save: clear or count a save error, log notes."""
        log = self.log
        if what == 'saved':
            self.learn_save_error = ''
            for note in notes:
                log.warning(note)
        elif what == 'save failed':     # kept for /diagnostics, logged throttled
            self.learn_save_error = text
            self.learn_save_failures += 1
            log.error(f'cannot save learn_file ({self.learn_save_failures} failed saves): '
                      f'{text}', throttle_duration_sec=LEARN_LOG_THROTTLE_S)
        elif what == 'step failed':
            self.learn_step_errors += 1
            log.error(f'learning step failed ({self.learn_step_errors} in total): {text}',
                      throttle_duration_sec=LEARN_LOG_THROTTLE_S)

    def _sync(self) -> None:
        """
        With the learner idle, on the executor's thread: what waited for it.

        A prior or timeout set during a step, the models it swapped in (scheduled by stamp:
        :meth:`gyro_tdc.runtime.core.CompensatorCore.schedule`) and the samples, readings
        and motion reports the message path appended since.
        """
        learner, core = self.learner, self.core
        if 'prior' in self._waiting:
            learner.set_prior(self._waiting.pop('prior'))
            core.learning.cancel()
        if 'timeout' in self._waiting:
            learner.config = replace(learner.config,
                                     temperature_timeout=self._waiting.pop('timeout'))
        for due, model in learner.take_swaps(core.last_t):
            core.schedule(model, due)
        if core.learned_installs != self._learned_installs:
            self._learned_installs = core.learned_installs
            self.node.loading.model_file = 'learned'    # the model in use
        flat = ((learner.fit or {}).get('held_out') or {}).get('offset_only', [])
        if flat != self._offset_only:         # said when the offset-only axes change
            self._offset_only = flat
            self.log.info(f'learning, held out: {held_out_line(learner.fit)}')
        self._front.hand_over(learner)

    def wait(self, timeout_s: float = LEARN_WAIT_S) -> bool:
        """
        Wait for the step in progress and bring the learner up to date; return whether idle.

        Call on the executor's thread; the learner may then be read or changed until the
        executor runs the learn timer again; ``timeout_s`` 0 only looks.
        """
        if (job := self.job) is not None:
            if not job.wait(timeout_s):
                return False
            self.job = None
            self._take(*job.result)
        self._sync()
        return True

    def set_timeout(self, timeout_s: float) -> None:
        """Give the learner a new temperature_timeout (from its next step)."""
        if timeout_s != self.learner.config.temperature_timeout:
            self._waiting['timeout'] = timeout_s
            if self.job is None:
                self._sync()

    def new_prior(self, model: CompensationModel | None) -> None:
        """
        Make a model loaded from ``model_file`` the learner's prior and current model.

        A learned model is then swapped in only when it predicts the recent still time better
        than this one; a learned swap not yet installed is older than the file and dropped
        (:meth:`gyro_tdc.learn.learner.Learner.set_prior`). During a step the prior waits
        for it (up to :data:`LEARN_WAIT_S`, then it applies when the step ends).
        """
        self._waiting['prior'] = model
        self.core.learning.cancel()
        self.wait()

    def save_now(self) -> str:
        """Write learn_file (or the file used instead) now; return what happened (one line)."""
        if not self.params.learn_file:
            return 'no learn_file'
        if (store := self.learn_store) is None:
            return f'failed: nothing is written ({self.learn_file_warning})'
        what, text, notes = _write(self.learner, store)
        if what == 'saved':
            self.learner.saved()
        self._take(what, text, notes)
        return f'saved {store.path}' if what == 'saved' else f'failed: {text}'

    def report(self) -> tuple[int, str, dict[str, str]]:
        """
        Return the learner's /diagnostics report: level, problems ('' none) and pairs.

        WARN while learn_file is refused (kept; learning goes beside it) or a save failed.
        """
        if self.job is None:         # idle: read it; during a step, the last figures
            self._learn_values = self.learner.diagnostic_values()
        store, warning, error = self.learn_store, self.learn_file_warning, self.learn_save_error
        where = 'none' if not self.params.learn_file else (
            (str(store.path) if store is not None else 'nothing written')
            + (f' ({warning})' if warning else ''))
        problems = ['learn_file refused (see learn file)'] if warning else []
        if error:
            problems.append(f'learn_file not saved ({self.learn_save_failures} failed saves, '
                            f'see learn save error): {error}')
        return (1 if problems else 0), '; '.join(problems), {
            **self._learn_values, 'learn file': where, 'learn save error': error,
            'learn save failures': str(self.learn_save_failures),
            'learn step errors': str(self.learn_step_errors)}

    # -- the timer and the services ------------------------------------------------------

    def on_timer(self) -> None:
        """Timer: hand the learner what came; start its step on the worker when there is work."""
        # A step in progress: again at the next tick; no window ended: nothing to do.
        if not self.wait(0.0) or self.learner.caught_up():
            return
        learner, store = self.learner, (self.learn_store if self.params.learn_file else None)
        self.job = self._learn_jobs.start(
            'learning step', 'timer', lambda: _step_and_save(learner, store))

    def _step_now(self) -> bool:
        """Wait for the step in progress, then step over what came here; return whether done."""
        if not self.wait():
            return False
        self.learner.step()
        self._sync()        # schedule what the step swapped in
        return True

    def save_service(self) -> tuple[bool, str]:
        """Write learn_file now (``~/learn_save``), the stretch in progress stepped first."""
        if not self._step_now():
            return False, BUSY
        message = self.save_now()
        return message.startswith('saved'), message

    def reset(self) -> tuple[bool, str]:
        """Forget what was learned (``~/learn_reset``): back to the prior, or no model."""
        if not self._step_now():
            return False, BUSY
        self.learner.reset()
        self.core.learning.cancel()
        self.core.set_model(self.learner.prior)
        return True, ('learning reset: back to the prior' if self.learner.prior is not None
                      else 'learning reset: no model until the next still stretch')

    def stop(self) -> None:
        """Save what was learned (the stretch in progress too) before the node goes away."""
        if not self.params.learn_file:
            return
        if not self.wait(3 * LEARN_WAIT_S):
            return self.log.error('learning step still running at shutdown: learn_file '
                                  'keeps its last save')
        self.learner.step()
        self.learner.flush()
        self.save_now()
