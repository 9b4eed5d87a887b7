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
Running a fleet on Dask: the per-sensor task, the engine, resuming, writing the models.

Every sensor is one Dask task (:func:`run_sensor`, run on a worker process): it trains a model
with the options of ``train``, evaluates it on the sensor's test bags and returns it; the
client writes ``DIR/<sensor_id>.yaml`` (``sensor.sensor_id`` set) and the resume state
``DIR/.fleet/<sensor_id>.json`` as each task finishes. Nothing here imports rclpy.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import asdict, dataclass, replace
import gc
import hashlib
import json
import logging
import math
import os
from pathlib import Path
import signal
import tempfile
import threading
import time
from typing import Callable, Iterator, Sequence

from gyro_tdc import __version__
from gyro_tdc.base import atomic_json, AXES
from gyro_tdc.data import BagOptions
from gyro_tdc.errors import FleetError, GyroTdcError, one_line, OutputError
from gyro_tdc.evaluate import evaluate, mean_scores, NamedModel
from gyro_tdc.fleet.manifest import input_key, SensorSpec
from gyro_tdc.fleet.results import FleetResult, SensorResult, write_summary
from gyro_tdc.fleet.stats import DEFAULT_OUTLIER_Z, drift_polynomial, fleet_statistics
from gyro_tdc.identify import train, TrainOptions
from gyro_tdc.model import CompensationModel, save_model

__all__ = ['Engine', 'STATE_DIR', 'SensorOutcome', 'check_workers', 'open_engine', 'run_fleet',
           'run_sensor', 'sigterm_as_interrupt', 'worker_version']

STATE_DIR = '.fleet'         # DIR/.fleet/<sensor_id>.json: the resume state of each sensor
STATE_FORMAT = 1
#: A sensor's figures, as its task returns them, its resume state keeps and its summary shows.
_FIGURES = ('train_bs', 'heldout_bs', 'drift_poly', 'temp_range_c', 'constant_axes')


@dataclass
class SensorOutcome(SensorResult):
    """
    What one sensor task returned (computed on a worker): its figures as a summary line has them.

    ``status`` is ``'ok'`` (trained), ``'skipped'`` (inputs unchanged) or ``'failed'``
    (``error`` says why); ``seconds`` is the task's wall time on the worker, ``train_bs``,
    ``heldout_bs``, ``drift_poly`` (:func:`drift_polynomial` as nested lists),
    ``temp_range_c`` and ``constant_axes`` the model's (``heldout_bs`` None without test bags).
    """

    #: Input key (:func:`input_key`); empty when it could not be computed.
    key: str = ''
    #: The trained model (``sensor_id`` set) when ok.
    model: CompensationModel | None = None


#: The held-out bags are scored re-anchored, session by session (``evaluate --reanchor
#: auto``): a model fixes the thermal curve, each power cycle its own turn-on offset.
HELDOUT_REANCHOR = 'auto'


def run_sensor(spec: SensorSpec, options: TrainOptions, *, bag: BagOptions | None = None,
               previous_key: str | None = None, command: str = '') -> SensorOutcome:
    """
    Train, evaluate and characterise one sensor (the Dask task; writes only a temporary file).

    Parameters
    ----------
    spec : SensorSpec
        The sensor and its bags (paths as the worker sees them).
    options : TrainOptions
        How to train (:func:`gyro_tdc.identify.train.train`).
    bag : BagOptions, optional
        How to read the train and test bags; ``progress`` is ignored (no bar on workers).
    previous_key : str, optional
        Input key of the model already written; when equal to this run's key the sensor is
        skipped without reading a bag.
    command : str
        Command line recorded in the model's ``created``.

    Returns
    -------
    SensorOutcome
        ``failed`` with a one-line reason for bad input (unreadable bag, missing topic, too
        small a span...): the error never escapes, so one sensor never stops the others.

    """
    start = time.perf_counter()
    bag = replace(BagOptions() if bag is None else bag, progress=False)
    out = SensorOutcome(spec.sensor_id, 'failed')
    try:
        # The resume key hashes every option but the progress bar (off here).
        out.key = input_key(spec, {'train': asdict(options), 'bag': asdict(bag),
                                   'heldout_reanchor': HELDOUT_REANCHOR})
        if previous_key == out.key:
            out.status = 'skipped'
            return out
        with tempfile.TemporaryDirectory(prefix='gyro_tdc_fleet_') as tmp:
            result = train(list(spec.train), Path(tmp) / 'model.yaml', options, bag,
                           command=command)
        model = result.model.replace(sensor_id=spec.sensor_id)
        if spec.test:
            named = NamedModel(f'{spec.sensor_id}.yaml', spec.sensor_id, model)
            evals = evaluate(list(spec.test), [named], bag=bag, reanchor_s=HELDOUT_REANCHOR)
            out.heldout_bs = [float(v) for v in mean_scores(evals)[1][1]]
        out.train_bs = [float(v) for v in model.metrics.get('train_bs_dps2', [math.nan] * 3)]
        out.drift_poly = drift_polynomial(model).tolist()
        out.temp_range_c = [float(v) for v in model.temp_range_c]
        out.constant_axes = [str(a) for a in model.metrics.get('constant_axes', ())]
        out.model, out.status = model, 'ok'
    except (GyroTdcError, OSError) as exc:
        out.error = one_line(exc)
    finally:
        out.seconds = time.perf_counter() - start
    return out


@dataclass
class Engine:
    """A Dask client and what to report about it."""

    #: Connected client (``distributed.Client``).
    client: object
    #: ``'local'`` or the scheduler address.
    scheduler: str
    #: Workers connected at the start.
    workers: int
    #: How long a fleet waits while the cluster has no worker before it gives up, s.
    timeout_s: float = 30.0


@contextlib.contextmanager
def open_engine(*, workers: int | None = None, scheduler: str | None = None,
                timeout_s: float = 30.0) -> Iterator[Engine]:
    """
    Start an embedded Dask cluster, or connect to one, for the duration of a ``with``.

    ``workers``: processes of the embedded ``LocalCluster`` (default the cores; ignored with
    ``scheduler``, a ``tcp://HOST:PORT`` whose workers read the bags at the manifest's
    paths). ``timeout_s`` (s): the wait for the scheduler and its first worker, and
    :attr:`Engine.timeout_s`. Yields the :class:`Engine`.

    Raises
    ------
    FleetError
        Scheduler unreachable or without a worker in time, or a worker cannot import this
        gyro_tdc (:func:`check_workers`).

    """
    from distributed import Client, LocalCluster
    timeouts = (OSError, ValueError, asyncio.TimeoutError)
    if scheduler is None:
        n = max(1, int(workers or os.cpu_count() or 1))
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                          host='127.0.0.1', scheduler_port=0, dashboard_address='127.0.0.1:0',
                          silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
            check_workers(client, 'local')
            yield Engine(client, 'local', n, timeout_s)
        return
    failure = None
    try:
        client = Client(scheduler, timeout=f'{timeout_s}s')
    except timeouts as exc:
        failure = one_line(exc)
    if failure is not None:
        # The half-made Client sits in a reference cycle; its finaliser takes distributed's
        # process-wide loop lock. Collected later on another thread (a new cluster's IO loop
        # starting under that lock) it deadlocks: collect it here, where nothing holds it.
        gc.collect()
        raise FleetError(f'--scheduler {scheduler}: cannot connect: {failure}')
    with client:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except timeouts as exc:
            raise FleetError(f'--scheduler {scheduler}: no Dask worker connected within '
                             f'{timeout_s:g} s (start some with: dask worker {scheduler})'
                             ) from exc
        check_workers(client, scheduler)
        yield Engine(client, scheduler, len(client.nthreads()), timeout_s)


def worker_version() -> str:
    """Return the gyro_tdc version importable here (run on every worker before a fleet)."""
    return __version__


def check_workers(client: object, where: str) -> None:
    """
    Check that every worker of ``client`` imports this gyro_tdc (else a task hangs unpickled).

    Raises
    ------
    FleetError
        A worker cannot import ``gyro_tdc.fleet`` or has another version; names ``where``.

    """
    for address, got in client.run(worker_version, on_error='return').items():
        if isinstance(got, BaseException):
            raise FleetError(f'Dask worker {address} ({where}) cannot run gyro_tdc: '
                             f'{one_line(got)}; install this gyro_tdc where the workers run')
        if got != __version__:
            raise FleetError(f'Dask worker {address} ({where}) has gyro_tdc {got}, this '
                             f'client {__version__}; install the same version everywhere')


def _read_state(path: Path, model_file: Path) -> dict | None:
    """Return a sensor's resume state when it matches the model file on disk, else None."""
    try:
        state = json.loads(path.read_text(encoding='utf-8'))
        digest = hashlib.sha256(model_file.read_bytes()).hexdigest()
    except (OSError, ValueError):
        return None
    return state if (isinstance(state, dict) and state.get('format') == STATE_FORMAT
                     and isinstance(state.get('constant_axes'), list)
                     and state.get('model_sha256') == digest) else None


def _record(out: SensorOutcome, out_dir: Path, state_dir: Path,
            state: dict | None) -> SensorResult:
    """Turn a task's outcome into a summary line; write its model and resume state."""
    model_file = out_dir / f'{out.sensor_id}.yaml'
    state_file = state_dir / f'{out.sensor_id}.json'
    if out.status == 'skipped' and state is not None:
        figures = {k: state.get(k) for k in _FIGURES}
        figures['constant_axes'] = [str(a) for a in state['constant_axes'] if a in AXES]
        return SensorResult(out.sensor_id, 'ok', model_file=str(model_file), skipped=True,
                            **figures)
    error = out.error or 'unknown failure'
    if out.status == 'ok' and out.model is not None:
        figures = {k: getattr(out, k) for k in _FIGURES}
        try:
            save_model(out.model, model_file)
            record = {'format': STATE_FORMAT, 'key': out.key,
                      'model_sha256': hashlib.sha256(model_file.read_bytes()).hexdigest(),
                      **figures, 'seconds': out.seconds}
            atomic_json(state_file, record, what='fleet state file', indent=None)
            return SensorResult(out.sensor_id, 'ok', model_file=str(model_file),
                                seconds=out.seconds, **figures)
        except (GyroTdcError, OSError) as exc:   # this sensor's output only: the others go on
            error = one_line(exc)
    with contextlib.suppress(OSError):
        state_file.unlink()           # the model on disk no longer matches these inputs
    return SensorResult(out.sensor_id, 'failed', error=error, seconds=out.seconds)


class _NoWorker(FleetError):
    """The cluster has had no worker for longer than the engine's timeout."""


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """
    Turn SIGTERM into KeyboardInterrupt for the duration of a ``with`` (main thread only).

    Batch systems stop a job with SIGTERM: a fleet stopped so ends as on Ctrl-C, with its
    summary written. Elsewhere than in the main thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt('terminated (SIGTERM)')

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _completed(futures: list, engine: Engine) -> Iterator[object]:
    """
    Yield the futures as they finish; raise _NoWorker when the cluster lost every worker.

    Tasks of a cluster without workers wait for ever: when no task finished and no worker
    was connected for ``engine.timeout_s``, the remaining tasks are cancelled.
    """
    from distributed import as_completed
    pending = as_completed(futures)
    idle_since, next_check = None, 0.0
    while not pending.is_empty():
        if pending.has_ready():
            idle_since = None
            yield next(pending)
            continue
        now = time.monotonic()
        if now >= next_check:
            next_check = now + min(1.0, engine.timeout_s / 4.0)
            try:                          # the workers connected (none when it cannot be asked)
                workers = len(engine.client.nthreads())
            except (OSError, TimeoutError):
                workers = 0
            if workers:
                idle_since = None
            elif idle_since is None:
                idle_since = now
            elif now - idle_since >= engine.timeout_s:
                with contextlib.suppress(OSError, TimeoutError):
                    engine.client.cancel([f for f in futures if not f.done()])
                raise _NoWorker(f'the Dask cluster ({engine.scheduler}) has had no worker for '
                                f'{engine.timeout_s:g} s')
        time.sleep(0.05)


def _summary_error(exc: Exception, pending: BaseException | None,
                   write_errors: list) -> OutputError:
    """Return one line: why the fleet stopped or what it could not write, then the summary."""
    why = [] if pending is None else [
        'interrupted' if isinstance(pending, KeyboardInterrupt) else one_line(pending)]
    if write_errors:
        more = len(write_errors) - 1
        why.append(write_errors[0] + (f' (and {more} more sensor(s))' if more else ''))
    return OutputError(f'{"; ".join(why)}; and no fleet summary: {one_line(exc)}' if why
                       else one_line(exc))


def _future_failure(sid: str, future: object) -> SensorOutcome:
    """Describe a task that raised on its worker (or was lost with it) as a failure."""
    exc = future.exception() if future.status == 'error' else None
    return SensorOutcome(sid, 'failed', error=(
        f'task {future.status} (worker lost or cluster shut down)' if exc is None
        else f'{type(exc).__name__} on the worker: {one_line(exc)}'))


def run_fleet(specs: Sequence[SensorSpec], out_dir: str | os.PathLike, options: TrainOptions,
              engine: Engine, *, bag: BagOptions | None = None, force: bool = False,
              outlier_z: float = DEFAULT_OUTLIER_Z,
              progress: bool = False, command: str = '',
              log: Callable[[str], None] | None = None) -> FleetResult:
    """
    Calibrate every sensor on the engine; write models, ``summary.json`` and ``summary.csv``.

    Parameters
    ----------
    specs : sequence of SensorSpec
        The sensors (see :func:`read_manifest`).
    out_dir : str or PathLike
        Output folder (created): ``<sensor_id>.yaml``, ``summary.json``, ``summary.csv`` and
        the resume state in ``.fleet/``.
    options : TrainOptions
        How to train, the same for every sensor.
    engine : Engine
        From :func:`open_engine`.
    bag : BagOptions, optional
        How to read the bags, the same for every sensor.
    force : bool
        Retrain sensors whose inputs are unchanged.
    outlier_z : float
        Robust z-score beyond which a drift coefficient is flagged.
    progress : bool
        Progress bar over sensors (stderr).
    command : str
        Command line recorded in every model's ``created``.
    log : callable, optional
        Receives one line per finished sensor.

    Returns
    -------
    FleetResult
        The summary (also written, even when sensors failed or the run is interrupted).

    """
    from tqdm import tqdm
    start = time.perf_counter()
    out = Path(out_dir)
    state_dir = out / STATE_DIR
    state_dir.mkdir(parents=True, exist_ok=True)
    futures = {}                        # future -> (sensor id, its resume state)
    done: dict[str, SensorResult] = {}
    write_errors: list[str] = []        # per-sensor output errors (a full disk...)
    pending: BaseException | None = None
    not_run = 'not run (fleet interrupted)'
    bar = tqdm(total=len(specs), unit='sensor', desc='fleet', disable=not progress,
               dynamic_ncols=True)
    try:
        with sigterm_as_interrupt():
            for spec in specs:
                sid = spec.sensor_id
                st = None if force else _read_state(state_dir / f'{sid}.json', out / f'{sid}.yaml')
                fut = engine.client.submit(run_sensor, spec, options, bag=bag, pure=False,
                                           previous_key=None if st is None else st.get('key'),
                                           command=command,
                                           key=f'gyro_tdc-fleet-{sid}-{os.urandom(6).hex()}')
                futures[fut] = sid, st
            for fut in _completed(list(futures), engine):
                sid, st = futures[fut]
                outcome = (fut.result() if fut.status == 'finished' else _future_failure(sid, fut))
                fut.release()
                done[sid] = res = _record(outcome, out, state_dir, st)
                if res.status != 'ok' and outcome.status == 'ok':
                    write_errors.append(f'{sid}: {res.error}')
                bar.update(1)
                if log is not None:
                    what = ('unchanged, skipped' if res.skipped else res.status
                            if res.status == 'ok' else f'failed: {res.error}')
                    log(f'{sid}: {what}' + (f' ({res.seconds:.1f} s)' if res.seconds else ''))
    except _NoWorker as exc:
        pending, not_run = exc, f'not run: {exc}'
        raise FleetError(f'{exc}; {len(specs) - len(done)} sensor(s) not run (see the '
                         'summary); start workers and run fleet again to finish them') from None
    except BaseException as exc:
        pending = exc
        raise
    finally:
        bar.close()
        sensors = [done.get(s.sensor_id) or SensorResult(s.sensor_id, 'failed', error=not_run)
                   for s in specs]
        result = FleetResult(engine.scheduler, engine.workers, sensors,
                             fleet_statistics(sensors, outlier_z=outlier_z), outlier_z,
                             time.perf_counter() - start)
        try:
            write_summary(result, out)
        except GyroTdcError as exc:     # say why, not only that the summary failed too
            raise _summary_error(exc, pending, write_errors) from pending
    return result
