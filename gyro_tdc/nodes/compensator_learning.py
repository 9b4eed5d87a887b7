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
from gyro_tdc.learn import LearnConfig, Learner
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

    def _start_learning(self, policy: Policy) -> None:
        """Create the learner (the model in use is the prior), resume learn_file, services."""
        p = self.params
        self.learner = Learner(LearnConfig(temperature_timeout=policy.temperature_timeout,
                                           save_period_s=p.learn_save_period,
                                           swap_delay_s=p.learn_swap_delay),
                               prior=self.core.model)
        self._learned_installs = 0
        if p.learn_file:
            try:
                resumed = self.learner.load(p.learn_file)
            except (ValueError, KeyError, TypeError, OSError) as exc:
                resumed = False
                self.get_logger().error(f'cannot resume learn_file {p.learn_file!r}: {exc}; '
                                        'learning from the start')
            if resumed:
                self._take_learned()
                s = self.learner.summary()
                self.get_logger().info(f'resumed learning from {p.learn_file}: '
                                       f'{s["points"]} points, {s["still_s"]:.0f} s still')
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
        """Write learn_file now; return what happened (one line)."""
        path = self.params.learn_file
        if not path:
            return 'no learn_file'
        try:
            self.learner.save(path)
        except OutputError as exc:
            self.get_logger().error(f'cannot save learn_file: {exc}')
            return f'failed: {exc}'
        return f'saved {path}'

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
