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
The compensator's model loading, off the message path: start-up, parameter set, ``~/reload``.

:class:`ModelLoading` is a part of :class:`~gyro_tdc.nodes.compensator_node.CompensatorNode`
(how a file is read, primed and swapped in: doc/internals/runtime.md): it keeps ``model_file``,
``last_reload`` and its jobs; the node registers its parameter callbacks, its poll timer and
its ``~/reload`` service.
"""

from __future__ import annotations

from typing import Any, Callable

from gyro_tdc.base import Job, LatestJob
from gyro_tdc.errors import GyroTdcError, one_line
from gyro_tdc.learn import read_model as read_any_model
from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime import prepare, PreparedModel, sensor_mismatch
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

__all__ = ['LOAD_ERRORS', 'LOAD_POLL_S', 'ModelLoading', 'read_model']

#: What the node's load edge turns into a refused file: the loader's documented errors
#: (every :class:`~gyro_tdc.errors.GyroTdcError`, ModelFileError above all) and, as a
#: last resort should a parser limit ever let a hostile file through, RecursionError and
#: MemoryError: no file may stop the node.
LOAD_ERRORS = (GyroTdcError, RecursionError, MemoryError)
#: How often the executor's thread looks for a model finished in the background [s].
LOAD_POLL_S = 0.02


#: Resolve and load a model file: a path, a model shipped in ``config/models`` or a learn_file's
#: current learned model (:func:`gyro_tdc.learn.read_model`); a ModelFileError or
#: LearnFileError says why not in one line.
read_model = read_any_model


class ModelLoading:
    """
    Load, check and install the compensator ``node``'s model files off the IMU callback.

    ``loader(name) -> CompensationModel`` reads one (default :func:`read_model`). Every
    install or clear makes the model the learner's new prior.
    """

    def __init__(self, node: Any, loader: Callable[[str], CompensationModel] | None) -> None:
        self.node, self.core, self.log = node, node.core, node.get_logger()
        self._read = loader or read_model
        #: The model in use: a file name, 'learned' or '' (none).
        self.model_file = ''
        self.last_reload = 'none'
        self._jobs = LatestJob()
        self._pending: dict[str, Job] = {}
        self._reverting: str | None = None

    def _param_value(self) -> str:
        return self.node.get_parameter('model_file').value

    def on_model(self, model: CompensationModel | None) -> None:
        """Make a model loaded from ``model_file`` (or none) the learner's prior."""
        if self.node.learning is not None:
            self.node.learning.new_prior(model)

    def load_at_start(self) -> None:
        """Load ``model_file`` on this thread (at start: nothing to hold up yet)."""
        name = self.node.params.model_file
        if not name:
            self.log.warning('no model_file: passing the raw rate through')
            return
        prepared, error = self._load_work(name)()
        if prepared is not None:
            self._install(name, prepared)
        else:
            self.last_reload = f'failed: {error}'
            self.log.error(f'cannot load model_file {name!r}: {error}; '
                           'passing the raw rate through')

    def _load_work(self, name: str) -> Callable[[], tuple[PreparedModel | None, str]]:
        """Return the job that reads, checks and primes ``name``: (prepared, '') or (None, why)."""
        read, policy, priming = self._read, self.core.policy, self.core.priming()

        def work() -> tuple[PreparedModel | None, str]:
            try:
                return prepare(read(name), policy, priming), ''
            except LOAD_ERRORS as exc:  # a refused file, in one line whatever it held
                if isinstance(exc, GyroTdcError):
                    return None, one_line(exc)
                return None, f'{name}: {type(exc).__name__} while reading the model file'
            except Exception as exc:  # the worker's edge: a bug must not leave a load hanging
                return None, f'{name}: unexpected {type(exc).__name__}: {one_line(exc)}'
        return work

    def _start_load(self, name: str, origin: str) -> Job:
        """Read ``name`` in a worker thread (a newer request makes an older one stale)."""
        self.last_reload = f'loading {name}'
        return self._jobs.start(name, origin, self._load_work(name))

    def _claim(self, job: Job) -> bool:
        """Wait up to ``load_wait`` for ``job``; return whether it finished and is ours."""
        return job.wait(self.node.params.load_wait) and self._jobs.claim(job) is not None

    def _install(self, name: str, prepared: PreparedModel) -> None:
        """Swap the model in (one assignment inside the core), log it, tell the learner."""
        self.core.install(prepared)
        self.model_file = name
        model = prepared.model
        self.last_reload = f'loaded {prepared.model_id}'
        lo, hi = model.temp_range_c
        self.log.info(
            f'model {prepared.model_id} from {name!r}: {model.kind}, features '
            f'{",".join(model.features)}, valid {lo:.1f}..{hi:.1f} degC')
        mismatch = sensor_mismatch(model, self.node.params.sensor_id)
        if mismatch:
            self.log.warning(mismatch)
        self.on_model(model)

    def _refuse(self, name: str, error: str) -> None:
        self.last_reload = f'rejected: {error}'
        kept = self.core.model_id or 'no model'
        self.log.error(f'model {name!r} rejected, keeping {kept}: {error}')

    def _finish(self, job: Job) -> tuple[bool, str]:
        """Install a finished job's model, or report why not; return (success, message)."""
        prepared, error = job.result
        if prepared is None:
            self._refuse(job.name, error)
            return False, error
        self._install(job.name, prepared)
        return True, f'loaded model {prepared.model_id} from {job.name}'

    def load(self, name: str) -> tuple[bool, str]:
        """Load ``name`` ('' for none) now and install it, or keep the model; (success, why)."""
        self._jobs.drop()  # this request is newer than any file still being read
        if not name:
            self.core.set_model(None)
            self.model_file = ''
            self.last_reload = 'no model'
            self.on_model(None)
            return True, 'no model: passing the raw rate through'
        job = Job(name, 'load')
        job.result = self._load_work(name)()
        return self._finish(job)

    def on_poll(self) -> None:
        """Install (or refuse) a model finished in the background."""
        if self._jobs.pending is None:
            return
        job = self._jobs.claim()
        if job is None:
            return
        ok, _ = self._finish(job)
        if not ok and job.origin == 'parameter' and self._param_value() == job.name:
            # The set was accepted before the file was read: name the model in use again.
            self._reverting = self.model_file
            try:
                self.node.set_parameters([Parameter('model_file', value=self.model_file)])
            finally:
                self._reverting = None

    def on_set(self, params: list[Parameter]) -> SetParametersResult:
        """Check a new ``model_file`` by reading it; a file slower than ``load_wait`` reads on."""
        for param in params:
            if param.name != 'model_file':
                continue
            name = param.value
            if not isinstance(name, str):
                return SetParametersResult(successful=False,
                                           reason='model_file must be a string')
            if not name or name == self._reverting:
                continue
            job = self._start_load(name, 'parameter')
            if not self._claim(job):
                continue  # slower than load_wait: installed (or refused) by on_poll
            prepared, error = job.result
            if prepared is None:
                self._refuse(name, error)
                return SetParametersResult(successful=False, reason=error)
            self._pending[name] = job
        return SetParametersResult(successful=True)

    def on_parameters_set(self, params: list[Parameter]) -> None:
        """Install the model read by :meth:`on_set`."""
        for param in params:
            if param.name == 'model_file':
                name = param.value
                job = self._pending.pop(name, None)
                if job is not None:
                    self._finish(job)
                elif not name and self._reverting is None:
                    self.load('')
        self._pending.clear()

    def on_reload(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        """Read ``model_file`` again (``~/reload``); one slower than ``load_wait`` reads on."""
        name = self._param_value()
        if not name:
            response.success, response.message = self.load('')
            return response
        job = self._start_load(name, 'reload')
        if self._claim(job):
            response.success, response.message = self._finish(job)
        else:
            kept = self.core.model_id or 'no model'
            response.success = True
            response.message = (f'reading {name} in the background (longer than load_wait); '
                                f'{kept} stays in use until it is ready; the outcome goes to '
                                '/diagnostics and the log')
        return response
