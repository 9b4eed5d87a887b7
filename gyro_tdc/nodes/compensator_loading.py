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
from gyro_tdc.learn import read_model
from gyro_tdc.model import CompensationModel
from gyro_tdc.runtime import prepare, PreparedModel, sensor_mismatch
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

__all__ = ['LOAD_ERRORS', 'LOAD_POLL_S', 'ModelLoading', 'read_model']

#: What the node's load edge turns into a refused file: the loader's documented errors
#: (every :class:`~gyro_tdc.errors.GyroTdcError`, ModelFileError above all) and, as a
#: last resort should a parser limit ever let a hostile file through, RecursionError and
#: MemoryError: no file may stop the node. The default reader, :func:`read_model`, takes a
#: path, a model shipped in ``config/models`` or a learn_file's current learned model.
LOAD_ERRORS = (GyroTdcError, RecursionError, MemoryError)
#: How often the executor's thread looks for a model finished in the background [s].
LOAD_POLL_S = 0.02
Loaded = tuple[PreparedModel | None, str]


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

    def _new_prior(self, model: CompensationModel | None) -> None:
        """Make a model loaded from ``model_file`` (or none) the learner's prior."""
        if self.node.learning is not None:
            self.node.learning.new_prior(model)

    def load_at_start(self) -> None:
        """Load ``model_file`` on this thread (at start: nothing to hold up yet)."""
        if not (name := self.node.params.model_file):
            return self.log.warning('no model_file: passing the raw rate through')
        prepared, error = self._load_work(name)()
        if prepared is not None:
            return self._install(name, prepared)
        self.last_reload = f'failed: {error}'
        self.log.error(f'cannot load model_file {name!r}: {error}; passing the raw rate through')

    def _load_work(self, name: str) -> Callable[[], Loaded]:
        """Return the job that reads, checks and primes ``name``: (prepared, '') or (None, why)."""
        read, policy, priming = self._read, self.core.policy, self.core.priming()

        def work() -> Loaded:
            try:
                return prepare(read(name), policy, priming), ''
            except GyroTdcError as exc:  # a refused file, in one line whatever it held
                return None, one_line(exc)
            except LOAD_ERRORS as exc:
                return None, f'{name}: {type(exc).__name__} while reading the model file'
            except Exception as exc:  # the worker's edge: a bug must not leave a load hanging
                return None, f'{name}: unexpected {type(exc).__name__}: {one_line(exc)}'
        return work

    def _read_within_wait(self, name: str, origin: str) -> Job | None:
        """
        Read ``name`` in a worker thread (a newer request makes an older one stale).

        Return the job when it finished within ``load_wait`` and is ours, else None (the
        poll timer installs or refuses it).
        """
        self.last_reload = f'loading {name}'
        job = self._jobs.start(name, origin, self._load_work(name))
        return job if job.wait(self.node.params.load_wait) and self._jobs.claim(job) else None

    def _install(self, name: str, prepared: PreparedModel) -> None:
        """Swap the model in (one assignment inside the core), log it, tell the learner."""
        self.core.install(prepared)
        self.model_file, model = name, prepared.model
        self.last_reload = f'loaded {prepared.model_id}'
        lo, hi = model.temp_range_c
        self.log.info(f'model {prepared.model_id} from {name!r}: {model.kind}, features '
                      f'{",".join(model.features)}, valid {lo:.1f}..{hi:.1f} degC')
        if mismatch := sensor_mismatch(model, self.node.params.sensor_id):
            self.log.warning(mismatch)
        self._new_prior(model)

    def _finish(self, name: str, loaded: Loaded) -> tuple[bool, str]:
        """Install a read model, or refuse it and keep the one in use; (success, message)."""
        prepared, error = loaded
        if prepared is not None:
            self._install(name, prepared)
            return True, f'loaded model {prepared.model_id} from {name}'
        self.last_reload = f'rejected: {error}'
        self.log.error(f'model {name!r} rejected, keeping {self.core.model_id or "no model"}: '
                       f'{error}')
        return False, error

    def clear(self) -> tuple[bool, str]:
        """Use no model (``model_file`` ''): the raw rate passes through; (True, why)."""
        self._jobs.drop()  # this request is newer than any file still being read
        self.core.set_model(None)
        self.model_file, self.last_reload = '', 'no model'
        self._new_prior(None)
        return True, 'no model: passing the raw rate through'

    def on_poll(self) -> None:
        """Install (or refuse) a model finished in the background."""
        if (job := self._jobs.claim()) is None:
            return
        ok, _ = self._finish(job.name, job.result)
        if (not ok and job.origin == 'parameter'
                and self.node.get_parameter('model_file').value == job.name):
            # The set was accepted before the file was read: name the model in use again.
            self._reverting = self.model_file
            try:
                self.node.set_parameters([Parameter('model_file', value=self.model_file)])
            finally:
                self._reverting = None

    def on_set(self, params: list[Parameter]) -> SetParametersResult:
        """
        Check a new ``model_file`` by reading it; a file slower than ``load_wait`` reads on.

        rclpy has refused a value that is not a string before this runs.
        """
        for name in (q.value for q in params if q.name == 'model_file'):
            if not name or name == self._reverting or (
                    job := self._read_within_wait(name, 'parameter')) is None:
                continue  # none, the revert, or slower than load_wait: on_poll installs it
            if job.result[0] is None:     # refused: said, and the set fails with why
                return SetParametersResult(successful=False,
                                           reason=self._finish(name, job.result)[1])
            self._pending[name] = job
        return SetParametersResult(successful=True)

    def on_parameters_set(self, params: list[Parameter]) -> None:
        """Install the model read by :meth:`on_set`."""
        for name in (q.value for q in params if q.name == 'model_file'):
            if (job := self._pending.pop(name, None)) is not None:
                self._finish(job.name, job.result)
            elif not name and self._reverting is None:
                self.clear()
        self._pending.clear()

    def reload(self) -> tuple[bool, str]:
        """Read ``model_file`` again (``~/reload``); one slower than ``load_wait`` reads on."""
        if not (name := self.node.get_parameter('model_file').value):
            return self.clear()
        if (job := self._read_within_wait(name, 'reload')) is not None:
            return self._finish(name, job.result)
        return True, (f'reading {name} in the background (longer than load_wait); '
                      f'{self.core.model_id or "no model"} stays in use until it is ready; '
                      'the outcome goes to /diagnostics and the log')
