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

:class:`Learning` is a mixin of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`
(the timer, saving, ``~/learn_save`` and ``~/learn_reset``: doc/internals/runtime.md). The node
provides ``core``, ``params`` and ``model_file``; this mixin keeps ``learner``.
"""

from __future__ import annotations

from gyro_tdc.errors import OutputError
from gyro_tdc.learn import LearnConfig, Learner, LearnFile, open_learn_file
from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime import Policy
from std_srvs.srv import Trigger

__all__ = ['LEARN_STEP_S', 'Learning']

#: Period of the learner's timer (learn:=true), s: the IMU callback only appends. Cheap when
#: no window has ended (one compare); short so that a candidate is ready before its stamp.
LEARN_STEP_S = 0.1


class Learning:
    """Learn the bias vs temperature from still time while compensating (mixin)."""

    learner: Learner | None = None
    #: Where the learner's state is written (None: nowhere).
    learn_store: LearnFile | None = None
    #: One line while learn_file itself is refused (kept; learning goes beside it), else ''.
    learn_file_warning: str = ''

    def _new_learner(self, policy: Policy) -> Learner:
        """Return a learner from the start (the model in use is the prior)."""
        p = self.params
        return Learner(LearnConfig(temperature_timeout=policy.temperature_timeout,
                                   save_period_s=p.learn_save_period,
                                   swap_delay_s=p.learn_swap_delay), prior=self.core.model)

    def _start_learning(self, policy: Policy) -> None:
        """Create the learner, resume learn_file (or the file beside it), services."""
        p = self.params
        self.learner = self._new_learner(policy)
        self._learned_installs = 0
        if p.learn_file:
            log = self.get_logger()
            try:
                opened = open_learn_file(p.learn_file, self.learner.load_state)
            except Exception as exc:  # the start-up edge: no file content stops the node
                self.learner = self._new_learner(policy)
                opened = None
                self.learn_file_warning = (f'learn_file {p.learn_file!r} not used '
                                           f'({type(exc).__name__}: {exc}): learning from '
                                           'the start, nothing is kept across restarts')
            else:
                self.learn_store = opened.file
                self.learn_file_warning = opened.warning
                for note in opened.notes:
                    log.warning(note)
            if self.learn_file_warning:
                log.warning(self.learn_file_warning)
            if opened is not None and opened.resumed:
                self._take_learned()
                s = self.learner.summary()
                log.info(f'resumed learning from {opened.file.path}: {s["points"]} points, '
                         f'{s["still_s"]:.0f} s still')
        else:
            self.get_logger().warning('learn without learn_file: nothing is kept across '
                                      'restarts')
        self.core.learner = self.learner
        self.create_service(Trigger, '~/learn_save', self._on_learn_save)
        self.create_service(Trigger, '~/learn_reset', self._on_learn_reset)
        self.create_timer(LEARN_STEP_S, self._on_learn)

    def _new_prior(self, model: CompensationModel | None) -> None:
        """
        Make a model loaded from ``model_file`` the learner's prior and current model.

        A learned model is then swapped in only when it predicts the recent still time better
        than this one; a learned swap not yet installed is older than the file and dropped
        (:meth:`gyro_tdc.learn.learner.Learner.set_prior`).
        """
        if self.learner is not None:
            self.learner.set_prior(model)
            self.core.cancel_scheduled()

    def _take_learned(self) -> None:
        """Install a model resumed from learn_file at once (on the thread that compensates)."""
        model = self.learner.take_model()
        if model is not None:
            self.core.set_model(model)
            self.model_file = 'learned'

    def _learn_step(self) -> None:
        """Step the learner, schedule what it swapped in; note a learned model in use."""
        core = self.core
        core.learn_step()
        if core.learned_installs != self._learned_installs:
            self._learned_installs = core.learned_installs
            self.model_file = 'learned'

    def save_learning(self) -> str:
        """Write learn_file (or the file used instead) now; return what happened (one line)."""
        if not self.params.learn_file:
            return 'no learn_file'
        store = self.learn_store
        if store is None:
            return f'failed: nothing is written ({self.learn_file_warning})'
        try:
            store.write(self.learner.state())
        except OutputError as exc:
            self.get_logger().error(f'cannot save learn_file: {exc}')
            return f'failed: {exc}'
        self.learner.saved()
        for note in store.notes:
            self.get_logger().warning(note)
        return f'saved {store.path}'

    def learning_values(self) -> dict[str, str]:
        """Return the learner's /diagnostics pairs and where its state is written."""
        values = self.learner.diagnostic_values()
        store = self.learn_store
        values['learn file'] = (
            'none' if not self.params.learn_file else
            (str(store.path) if store is not None else 'nothing written')
            + (f' ({self.learn_file_warning})' if self.learn_file_warning else ''))
        return values

    def _on_learn(self) -> None:
        """Timer: learn from the samples gathered since the last tick, save when due."""
        self._learn_step()
        if self.params.learn_file and self.learner.save_due():
            self.save_learning()

    def _on_learn_save(self, request: Trigger.Request, response: Trigger.Response
                       ) -> Trigger.Response:
        self._learn_step()
        response.message = self.save_learning()
        response.success = response.message.startswith('saved')
        return response

    def _on_learn_reset(self, request: Trigger.Request, response: Trigger.Response
                        ) -> Trigger.Response:
        self._learn_step()
        self.learner.reset()
        self.core.cancel_scheduled()
        self.core.set_model(self.learner.prior)
        response.success = True
        response.message = ('learning reset: back to the prior'
                            if self.learner.prior is not None else
                            'learning reset: no model until the next still stretch')
        return response

    def _stop_learning(self) -> None:
        """Save what was learned (the stretch in progress too) before the node goes away."""
        if self.learner is not None and self.params.learn_file:
            self.learner.step()
            self.learner.flush()
            self.save_learning()
