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
The compensator node: raw Imu in, drift-compensated Imu out, one for one, in order.

Subscribes ``imu/data_raw`` (sensor-data QoS with a deep queue, or reliable keep-all with
``input_reliability: reliable``) and ``imu/temperature`` (sensor_msgs/Temperature, or
std_msgs/Float32 or Float64 with ``temperature_type``); publishes ``imu/data_compensated``
with the header and every field copied unchanged except ``angular_velocity`` (corrected by
the model) and ``angular_velocity_covariance`` (widened by the model's residual variance and
by the policies, and carrying :mod:`gyro_tdc.provenance`'s mark when compensated); with a
model that has an accelerometer part also ``linear_acceleration`` and
``linear_acceleration_covariance`` (the accelerometer residual variance, the same policies);
``/diagnostics`` at 1 Hz (``accelerometer``: compensated, not in model or passthrough).

``model_file`` can be changed at run time (parameter set) or re-read (``~/reload``,
std_srvs/Trigger). The file is read, checked and primed in a worker thread
(:mod:`gyro_tdc.loading`) and swapped in on the executor's thread, so a large or slow file
never holds up the IMU callback for more than ``load_wait``; an invalid file is refused
with its reason in one line and the old model stays.

``learn: true`` (:mod:`gyro_tdc.learning`): the IMU callback hands each raw sample to the
learner (float appends, at most 100 per second of stamps); a 1 s timer runs its still test,
refits and installs a learned model when it predicts the recent still time better; the
learner's state is saved atomically to ``learn_file`` every ``learn_save_period`` of stamp
time, on ``~/learn_save`` and at shutdown, and resumed at start; ``~/learn_reset`` forgets it
(back to the ``model_file`` prior, or none).

Guards: the node refuses to start when its input and output resolve to the same topic (a
loop); it warns on /diagnostics when a sample arrives already compensated (the mark), a
gyro_tdc compensator publishes its input (graph query) or the model was trained for
another sensor than ``sensor_id``, and counts the input messages DDS reports lost (the
subscription's message-lost event).

Every decision lives in :mod:`gyro_tdc.compensation_logic` and :mod:`gyro_tdc.health`; this
module converts. With ``raw_cdr`` (default) the Imu is taken as serialized bytes and patched
in place by :mod:`gyro_tdc.imu_cdr`, which saves most of a Python relay's per-message cost.
``main()`` spins rclpy's EventsExecutor (``executor: events``, see
:mod:`gyro_tdc.nodes.executors`).
"""

from __future__ import annotations

import sys
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_tdc.compensation_logic import CompensatorCore, PARAMS, Policy, prepare, PreparedModel
from gyro_tdc.errors import ConfigError, GyroTdcError, one_line, OutputError
from gyro_tdc.health import health, HealthMark, InputStatus, PASSTHROUGH, sensor_mismatch
from gyro_tdc.imu_cdr import ImuView, locate
from gyro_tdc.learning import LearnConfig, Learner
from gyro_tdc.loading import Job, LatestJob
from gyro_tdc.model import CompensationModel
from gyro_tdc.modelfile import load_model
from gyro_tdc.nodes._params import declare, print_help
from gyro_tdc.nodes.executors import run_node
from gyro_tdc.paramspec import spec_dataclass
from gyro_tdc.provenance import diagonal_marked, mark_diagonal
from gyro_tdc.resources import model_path
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float32, Float64
from std_srvs.srv import Trigger

__all__ = ['CompensatorNode', 'CompensatorParams', 'LOAD_ERRORS', 'PARAMS', 'main',
           'read_model']

#: The compensator's parameters, read once at start-up (``model_file`` also at run time).
CompensatorParams = spec_dataclass(
    'CompensatorParams', PARAMS, "The compensator's parameters (rows of ``PARAMS``).",
    module=__name__, methods={'policy': lambda self: Policy(
        **{s.name: getattr(self, s.name) for s in PARAMS if s.policy})})

#: What the node's load edge turns into a refused file: the loader's documented errors
#: (every :class:`~gyro_tdc.errors.GyroTdcError`, ModelFileError above all) and, as a
#: last resort should a parser limit ever let a hostile file through, RecursionError and
#: MemoryError: no file may stop the node.
LOAD_ERRORS = (GyroTdcError, RecursionError, MemoryError)
#: How often the executor's thread looks for a model finished in the background [s].
LOAD_POLL_S = 0.02
#: Period of the learner's timer (learn:=true), s: the IMU callback only appends.
LEARN_STEP_S = 1.0
#: The message class of each ``temperature_type`` (compensation_logic.TEMPERATURE_TYPES).
TEMPERATURE_MESSAGES = {'sensor_msgs/msg/Temperature': Temperature,
                        'std_msgs/msg/Float32': Float32, 'std_msgs/msg/Float64': Float64}


def read_model(name_or_file: str) -> CompensationModel:
    """
    Resolve and load a model file.

    Parameters
    ----------
    name_or_file : str
        A path or the name of a model shipped in ``config/models``.

    Returns
    -------
    CompensationModel
        The validated model.

    Raises
    ------
    ModelFileError
        The file is missing, malformed, inconsistent or beyond one of the model loader's
        limits (size, nesting, aliases, centres; one-line reason).

    """
    return load_model(model_path(name_or_file))


def _fqn(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


class CompensatorNode(Node):
    """
    Remove the temperature drift of a gyro, one output message per input message.

    Parameters
    ----------
    loader : callable, optional
        Reads a model file: ``loader(name) -> CompensationModel`` (default
        :func:`read_model`); tests inject a slow one.
    **kwargs
        Forwarded to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).

    Raises
    ------
    ConfigError
        A parameter is invalid, or ``imu/data_raw`` and ``imu/data_compensated`` resolve to
        the same topic.

    """

    def __init__(self, *, loader: Callable[[str], CompensationModel] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(kwargs.pop('node_name', 'compensator_node'), **kwargs)
        self.params = CompensatorParams(**declare(self, PARAMS))
        p = self.params
        try:
            policy = p.policy()
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self._in_topic = self.resolve_topic_name('imu/data_raw')
        out_topic = self.resolve_topic_name('imu/data_compensated')
        if self._in_topic == out_topic:
            raise ConfigError(f'imu/data_raw and imu/data_compensated both resolve to '
                              f'{out_topic}: the compensator would compensate its own output '
                              'in a loop; remap one of them')
        self._read = loader or read_model
        self.core = CompensatorCore(policy)
        self.inputs = InputStatus(p.input_reliability)
        self.temperatures_ignored = 0  # std_msgs readings before the first IMU message
        self.model_file = ''
        self.last_reload = 'none'
        self._jobs = LatestJob()
        self._pending: dict[str, Job] = {}
        self._reverting: str | None = None
        if p.model_file:
            prepared, error = self._load_work(p.model_file, self.core.priming())()
            if prepared is not None:
                self._install(p.model_file, prepared)
            else:
                self.last_reload = f'failed: {error}'
                self.get_logger().error(f'cannot load model_file {p.model_file!r}: {error}; '
                                        'passing the raw rate through')
        else:
            self.get_logger().warning('no model_file: passing the raw rate through')

        self._pub = self.create_publisher(Imu, 'imu/data_compensated', QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
            reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
        if p.input_reliability == 'reliable':
            # Keep all: nothing is overwritten here. A keep-all publisher is held back by
            # flow control; a keep-last one drops its oldest unacknowledged samples, which
            # the next accepted sample reveals as a sequence gap the message-lost event
            # counts (76-99 % of them measured). Bounded by the RMW's limits (Fast DDS: 5000).
            imu_qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=p.queue_depth,
                                 reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.VOLATILE)
        else:
            # REP 2003 sensor data, deep: the freshest queue_depth samples when behind. DDS
            # does not report the oldest ones this queue overwrites (only transport gaps).
            imu_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                                 reliability=ReliabilityPolicy.BEST_EFFORT,
                                 durability=DurabilityPolicy.VOLATILE)
        # As deep as the IMU queue: a simulated run streamed faster than real time sends
        # one temperature per IMU sample, and a lost temperature makes the next ones stale.
        temp_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p.queue_depth,
                              reliability=qos_profile_sensor_data.reliability,
                              durability=qos_profile_sensor_data.durability)
        events = SubscriptionEventCallbacks(message_lost=self._on_message_lost)
        self.create_subscription(Imu, 'imu/data_raw',
                                 self._on_imu_raw if p.raw_cdr else self._on_imu, imu_qos,
                                 raw=p.raw_cdr, event_callbacks=events)
        stamped = TEMPERATURE_MESSAGES[p.temperature_type] is Temperature
        self.create_subscription(
            TEMPERATURE_MESSAGES[p.temperature_type], 'imu/temperature',
            self._on_temperature if stamped else self._on_float_temperature, temp_qos)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_service(Trigger, '~/reload', self._on_reload)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self._seen = HealthMark()
        self._reported_anchor = None
        self.create_timer(1.0, self._on_diagnostics)
        self.create_timer(LOAD_POLL_S, self._on_load_poll)
        self.learner: Learner | None = None
        if p.learn:
            self._start_learning(policy)

    # -- learning in the field (gyro_tdc.learning) --------------------------------------

    def _start_learning(self, policy: Policy) -> None:
        """Create the learner (the model in use is the prior), resume learn_file, services."""
        p = self.params
        self.learner = Learner(LearnConfig(temperature_timeout=policy.temperature_timeout,
                                           save_period_s=p.learn_save_period),
                               prior=self.core.model)
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

    def _take_learned(self) -> None:
        """Install a model the learner swapped in (on the thread that compensates)."""
        model = self.learner.take_model()
        if model is not None:
            self.core.set_model(model)
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
        self.learner.step()
        self._take_learned()
        if self.params.learn_file and self.learner.save_due():
            self.save_learning()

    def _on_learn_save(self, request: Trigger.Request, response: Trigger.Response
                       ) -> Trigger.Response:
        self.learner.step()
        self._take_learned()
        response.message = self.save_learning()
        response.success = response.message.startswith('saved')
        return response

    def _on_learn_reset(self, request: Trigger.Request, response: Trigger.Response
                        ) -> Trigger.Response:
        self.learner.step()
        self.learner.reset()
        self.core.set_model(self.learner.prior)
        response.success = True
        response.message = ('learning reset: back to the prior'
                            if self.learner.prior is not None else
                            'learning reset: no model until the next still stretch')
        return response

    def destroy_node(self) -> None:
        """Save what was learned (the stretch in progress too) before going away."""
        if self.learner is not None and self.params.learn_file:
            self.learner.step()
            self.learner.flush()
            self.save_learning()
        super().destroy_node()

    # -- the hot path -----------------------------------------------------------------

    def _on_imu(self, msg: Imu) -> None:
        st = msg.header.stamp
        w = msg.angular_velocity
        cov = msg.angular_velocity_covariance
        if diagonal_marked(cov):
            self.inputs.already_compensated += 1
        core = self.core
        a = aout = avar = None
        if core.accel_on or (core.policy.reanchor_on_start and core.anchor is None):
            la = msg.linear_acceleration
            if msg.linear_acceleration_covariance[0] != -1.0:
                a = (la.x, la.y, la.z)
        try:
            wx, wy, wz, var, flags = core.process(
                st.sec + st.nanosec * 1e-9, w.x, w.y, w.z, a)
            if a is not None and core.accel_on:
                aout, avar = core.accel_out, core.accel_var
        except Exception as exc:  # the callback edge: never lose the message
            var, flags = self._on_error(exc), PASSTHROUGH
            wx, wy, wz = w.x, w.y, w.z
            if a is not None and core.accel_on:
                avar = var
        w.x, w.y, w.z = wx, wy, wz
        if cov[0] != -1.0:
            cov[0] += var[0]
            cov[4] += var[1]
            cov[8] += var[2]
            if not flags & PASSTHROUGH:
                mark_diagonal(cov)
        if aout is not None:
            la.x, la.y, la.z = aout
        if avar is not None:
            acov = msg.linear_acceleration_covariance
            acov[0] += avar[0]
            acov[4] += avar[1]
            acov[8] += avar[2]
        self._pub.publish(msg)

    def _on_imu_raw(self, data: bytes) -> None:
        found = locate(data)
        if found is None:  # not little-endian plain CDR: the slow, general way
            self._on_imu(deserialize_message(data, Imu))
            return
        sec, nanosec, base = found
        view = ImuView(data, base)
        if view.marked():
            self.inputs.already_compensated += 1
        wx, wy, wz = view.angular_velocity()
        core = self.core
        a = aout = avar = None
        if core.accel_on or (core.policy.reanchor_on_start and core.anchor is None):
            a = view.linear_acceleration()
        try:
            wx, wy, wz, var, flags = core.process(sec + nanosec * 1e-9, wx, wy, wz, a)
            if a is not None and core.accel_on:
                aout, avar = core.accel_out, core.accel_var
        except Exception as exc:  # the callback edge: never lose the message
            var, flags = self._on_error(exc), PASSTHROUGH
            if a is not None and core.accel_on:
                avar = var
        self._pub.publish(view.patched(wx, wy, wz, var, not flags & PASSTHROUGH, aout, avar))

    def _on_error(self, exc: Exception) -> tuple[float, float, float]:
        """Count an unexpected compensation failure; the raw sample goes out flagged."""
        var = self.core.fail(exc)
        self.get_logger().error(f'compensation failed, raw rate passed through: '
                                f'{self.core.last_error}', throttle_duration_sec=1.0)
        return var

    def _on_temperature(self, msg: Temperature) -> None:
        st = msg.header.stamp
        self.core.add_temperature(st.sec + st.nanosec * 1e-9, msg.temperature)

    def _on_float_temperature(self, msg: Float32 | Float64) -> None:
        """Take a reading without a header at the stamp of the latest IMU message received."""
        t = self.core.last_t
        if t is None:  # before the first IMU message there is no stamp to give it
            self.temperatures_ignored += 1
            return
        self.core.add_temperature(t, msg.data)

    def _on_message_lost(self, info: QoSMessageLostInfo) -> None:
        new = info.total_count - self.inputs.lost
        self.inputs.lost = info.total_count
        self.get_logger().warning(
            f'{new} imu/data_raw messages lost ({info.total_count} in total, reported by '
            'DDS): the compensator cannot keep up or the link drops', throttle_duration_sec=5.0)

    # -- model loading ----------------------------------------------------------------

    def _load_work(self, name: str, priming: Any
                   ) -> Callable[[], tuple[PreparedModel | None, str]]:
        """Return the job that reads, checks and primes ``name``: (prepared, '') or (None, why)."""
        read, policy = self._read, self.core.policy

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
        return self._jobs.start(name, origin, self._load_work(name, self.core.priming()))

    def _claim(self, job: Job) -> bool:
        """Wait up to ``load_wait`` for ``job``; return whether it finished and is ours."""
        return job.wait(self.params.load_wait) and self._jobs.claim(job) is not None

    def _install(self, name: str, prepared: PreparedModel) -> None:
        """Swap the model in (one assignment inside the core) and log it."""
        self.core.install(prepared)
        self.model_file = name
        model = prepared.model
        self.last_reload = f'loaded {prepared.model_id}'
        lo, hi = model.temp_range_c
        self.get_logger().info(
            f'model {prepared.model_id} from {name!r}: {model.kind}, features '
            f'{",".join(model.features)}, valid {lo:.1f}..{hi:.1f} degC')
        mismatch = sensor_mismatch(model, self.params.sensor_id)
        if mismatch:
            self.get_logger().warning(mismatch)

    def _refuse(self, name: str, error: str) -> None:
        self.last_reload = f'rejected: {error}'
        kept = self.core.model_id or 'no model'
        self.get_logger().error(f'model {name!r} rejected, keeping {kept}: {error}')

    def _finish(self, job: Job) -> tuple[bool, str]:
        """Install a finished job's model, or report why not; return (success, message)."""
        prepared, error = job.result
        if prepared is None:
            self._refuse(job.name, error)
            return False, error
        self._install(job.name, prepared)
        return True, f'loaded model {prepared.model_id} from {job.name}'

    def load(self, name: str) -> tuple[bool, str]:
        """
        Load ``name`` now and install it; on failure keep the current model.

        Parameters
        ----------
        name : str
            Model file path or shipped model name ('' to pass through).

        Returns
        -------
        tuple of (bool, str)
            Success and a one-line message.

        """
        self._jobs.drop()  # this request is newer than any file still being read
        if not name:
            self.core.set_model(None)
            self.model_file = ''
            self.last_reload = 'no model'
            return True, 'no model: passing the raw rate through'
        job = Job(name, 'load')
        job.result = self._load_work(name, self.core.priming())()
        return self._finish(job)

    def _on_load_poll(self) -> None:
        """Install (or refuse) a model finished in the background."""
        if self._jobs.pending is None:
            return
        job = self._jobs.claim()
        if job is None:
            return
        ok, _ = self._finish(job)
        if not ok and job.origin == 'parameter' and \
                self.get_parameter('model_file').value == job.name:
            # The set was accepted before the file was read: name the model in use again.
            self._reverting = self.model_file
            try:
                self.set_parameters([Parameter('model_file', value=self.model_file)])
            finally:
                self._reverting = None

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
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
                continue  # slower than load_wait: installed (or refused) by _on_load_poll
            prepared, error = job.result
            if prepared is None:
                self._refuse(name, error)
                return SetParametersResult(successful=False, reason=error)
            self._pending[name] = job
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        """Install the model read by :meth:`_on_set_parameters`."""
        for param in params:
            if param.name == 'model_file':
                name = param.value
                job = self._pending.pop(name, None)
                if job is not None:
                    self._finish(job)
                elif not name and self._reverting is None:
                    self.load('')
        self._pending.clear()

    def _on_reload(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        name = self.get_parameter('model_file').value
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

    # -- guards and diagnostics -------------------------------------------------------

    def upstream_compensators(self) -> tuple[str, ...]:
        """
        Return the other nodes publishing ``imu/data_raw`` that look like gyro_tdc compensators.

        A node is taken for one when it offers ``~/reload`` (std_srvs/srv/Trigger) and
        subscribes a temperature topic (any ``temperature_type``) besides publishing Imu on
        our input: the graph shows a compensator's interface whatever its name or remaps.
        """
        me = self.get_fully_qualified_name()
        found = set()
        try:
            publishers = self.get_publishers_info_by_topic(self._in_topic)
        except _rclpy.RCLError:  # the graph cannot say now: ask again at the next report
            return self.inputs.upstream
        for info in publishers:
            if not info.node_namespace.startswith('/'):
                continue  # a writer whose node is not discovered yet: next time
            fqn = _fqn(info.node_namespace, info.node_name)
            if fqn == me or fqn in found:
                continue
            who = (info.node_name, info.node_namespace)
            try:
                services = self.get_service_names_and_types_by_node(*who)
                subs = self.get_subscriber_names_and_types_by_node(*who)
            except _rclpy.RCLError:  # it left between the queries (NodeNameNonExistentError)
                continue
            if any(n == f'{fqn}/reload' and 'std_srvs/srv/Trigger' in t for n, t in services) \
                    and any(TEMPERATURE_MESSAGES.keys() & set(t) for _, t in subs):
                found.add(fqn)
        return tuple(sorted(found))

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the compensator's DiagnosticStatus (and log a new re-anchoring)."""
        upstream = self.upstream_compensators()
        if upstream and upstream != self.inputs.upstream:
            self.get_logger().warning(
                f'imu/data_raw ({self._in_topic}) is published by gyro_tdc compensator '
                f'{", ".join(upstream)}: chained compensators remove the drift twice')
        self.inputs.upstream = upstream
        h = health(self.core, self._seen, model_file=self.model_file,
                   sensor_id=self.params.sensor_id,
                   last_reload=self.last_reload, inputs=self.inputs)
        if h.mark.already_compensated > self._seen.already_compensated:
            self.get_logger().warning(
                f'{h.mark.already_compensated - self._seen.already_compensated} imu/data_raw '
                'samples were already compensated by gyro_tdc: the model is applied twice',
                throttle_duration_sec=10.0)
        self._seen = h.mark
        anchor = self.core.anchor
        if anchor is not None and anchor is not self._reported_anchor:
            self._reported_anchor = anchor
            self.get_logger().info(
                f're-anchored after {anchor.samples} still samples over '
                f'{anchor.duration_s:.1f} s at {anchor.temp_c:.2f} degC: offset shift '
                f'{h.values["reanchor shift dps"]} deg/s, standard error '
                f'{h.values["reanchor se dps"]} deg/s ({h.values["reanchor stopped on"]})')
        values = dict(h.values)
        if self.learner is not None:
            values.update(self.learner.diagnostic_values())
        return DiagnosticStatus(
            level=bytes((h.level,)), name=f'{self.get_name()}: gyro compensation',
            message=h.message, hardware_id=h.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [self.diagnostic_status()]
        self._diag_pub.publish(arr)


def main(args: list[str] | None = None) -> int:
    """Run the compensator node until shutdown (``ros2 run gyro_tdc compensator_node``); --help."""
    if print_help('compensator_node', __doc__, PARAMS, args, epilog=(
            'Parameter file: share/gyro_tdc/config/compensator.yaml (--params-file). A value '
            'of the wrong type, out of range or not one of the choices stops the node with '
            'one line and exit status 2.')):
        return 0
    # gc.freeze(): keep the ~30k start-up objects (numpy, the model...) out of the cyclic
    # collector's full passes, which otherwise stall the callback for ~10 ms now and then (p99).
    return run_node(CompensatorNode, args, executor=lambda node: node.params.executor,
                    freeze_heap=True, name='compensator_node')


if __name__ == '__main__':
    sys.exit(main())
