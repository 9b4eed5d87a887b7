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
Trainer vs bag read: ``gyro-tdc train BAG`` as a process against reading the bag's bytes.

Writes (once, cached under /tmp) two 1 h, 1 kHz bags of 3.6 M ``sensor_msgs/Imu`` and 3,600
``sensor_msgs/Temperature`` messages, each as sqlite3 and as mcap: ``bench``, a chamber
cycle (soak, heating ramp, hold, cooling ramp) with a constant 1 g accelerometer, and
``die``, the simulator's ``die_lag`` scenario compressed to 1 h (the die lags the package
thermometer by 300 s, so ``--features auto`` adds the thermal state, with a still, level
accelerometer whose part is fitted). Per bag and storage, ``--repeat`` rounds run side by
side, each stage a fresh process timed from outside (wall clock, its CPU, its peak RSS):

* ``raw``: a process iterating the bag with rosbags' ``AnyReader.messages()``, touching
  only the raw bytes (the issue's baseline: what merely reading the bag costs with rosbags);
* ``storage``: a process reading the bytes of the topics the trainer needs through the
  columnar read (:mod:`gyro_tdc.data.bag.columnar`), nothing decoded: the storage limit;
* ``train``: ``python -m gyro_tdc train BAG --out ... --no-progress`` with its defaults
  (``--features auto``, the thermal state, the accelerometer part), as a user runs it;

and prints the medians, ``train / raw`` (goal <= 1.0), ``train / storage``, the peak RSS
and the model id of every train run. ``--stages`` adds in-process stages of the older
benchmark (``load``: ``load_run``; ``train_paper``: ``--features dT,dT2 --no-accel``;
``rosbags``: ``read_bag(via='rosbags')``; ``mcap_package``: the ``mcap`` PyPI package's
``iter_messages``, an alternative to the columnar read of the MCAP format, not a dependency;
``bare``: ``train`` on the storage file alone, without metadata.yaml, as a power loss leaves it);
``--profile`` a cProfile of the train stage; ``--baseline DIR`` runs another checkout's train
(``baseline``) in the same rounds, for before/after figures side by side. Each checkout's
package is byte-compiled first (into its ``__pycache__``), as an installed one is: where
bytecode is not written (``PYTHONDONTWRITEBYTECODE``), a checkout would otherwise compile
every module at every start, which rosbags, installed, does not::

    .venv/bin/python bench/bench_train.py                       # both bags, both storages
    .venv/bin/python bench/bench_train.py --bags die --storage mcap --repeat 5 --profile
    .venv/bin/python bench/bench_train.py --bags die --storage sqlite3 --baseline ../main
"""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import argparse  # noqa: E402, I100
import compileall  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DEG = np.pi / 180.0
GOAL = 1.0


def _profile_c(t):
    """Chamber cycle (degC): soak 20, heat to 60 at 1.5 degC/min, hold, cool to 20."""
    return np.interp(t, [0.0, 300.0, 1900.0, 2300.0, 3600.0], [20.0, 20.0, 60.0, 60.0, 27.0])


def make_bag(path, *, minutes=60.0, rate_hz=1000.0, storage='sqlite3', seed=0):
    """
    Write the benchmark bag (IMU at ``rate_hz``, thermometer at 1 Hz, 0.03 degC steps).

    Parameters
    ----------
    path : Path
        Bag directory to create.
    minutes : float
        Duration.
    rate_hz : float
        IMU rate.
    storage : str
        ``sqlite3`` or ``mcap``.
    seed : int
        Noise seed.

    """
    from gyro_tdc.data import write_bag
    from gyro_tdc.model.effects import first_order_lag

    rng = np.random.default_rng(seed)
    n = int(round(minutes * 60.0 * rate_hz))
    t = np.arange(n) / rate_hz
    t_temp = np.arange(int(minutes * 60.0) + 1, dtype=np.float64)
    package = first_order_lag(t_temp, _profile_c(t_temp), 120.0)     # chamber air -> package
    reading = np.round((package + rng.normal(0, 0.01, package.shape)) / 0.03) * 0.03
    die = np.interp(t, t_temp, package)
    d = die - 25.0
    gyro = (np.array([0.3, -0.2, 0.1]) + d[:, None] * np.array([0.02, -0.015, 0.01])
            + d[:, None] ** 2 * np.array([2e-4, 1.5e-4, -1e-4])) * DEG
    gyro += rng.normal(0.0, 0.03 * np.sqrt(rate_hz) * DEG, size=gyro.shape)
    accel = np.zeros((n, 3))
    accel[:, 2] = 9.80665
    write_bag(path, imu_t=t + 1.0, gyro=gyro, accel=accel, temp_t=t_temp + 1.0,
              temp_c=reading, storage=storage)


#: The lagging die's chamber profile (1 h): soak, heat 0 -> 50 degC at 150 degC/h, hold, cool to
#: 20 degC at 180 degC/h, hold; the die lags the package thermometer by ``DIE_TAU_S``.
DIE_SEGMENTS = ({'kind': 'hold', 'duration_s': 600.0},
                {'kind': 'ramp', 'to_c': 50.0, 'rate_c_per_h': 150.0},
                {'kind': 'hold', 'duration_s': 900.0},
                {'kind': 'ramp', 'to_c': 20.0, 'rate_c_per_h': 180.0},
                {'kind': 'hold', 'duration_s': 300.0})
DIE_TAU_S = 300.0


def make_die_bag(path, *, rate_hz=1000.0, storage='sqlite3', seed=0):
    """
    Write the lagging-die bag: the simulator's ``die_lag`` scenario compressed to 1 h.

    The L3GD20 preset with its drift in the die temperature, the die a first-order lag of
    the package thermometer (``DIE_TAU_S``), one run of ``DIE_SEGMENTS`` at ``rate_hz``, a
    still, level accelerometer: ``train --features auto`` adds the thermal state (``lag``).
    """
    from gyro_tdc.data import write_bag
    from gyro_tdc.sim import simulate_scenario

    sim, = simulate_scenario('die_lag', seed=seed, rate_hz=rate_hz, runs=[0], overrides={
        'profile.segments': [dict(s) for s in DIE_SEGMENTS], 'runs.count': 1,
        'thermal.tau_die_s': DIE_TAU_S})
    write_bag(path, imu_t=sim.imu_t, gyro=sim.gyro, accel=sim.accel, temp_t=sim.temp_t,
              temp_c=sim.temp_c, storage=storage)


def _count_raw(reader):
    """Open a rosbags reader and iterate every message, touching its raw bytes only."""
    count = nbytes = 0
    with reader:
        for _conn, _stamp, raw in reader.messages():
            count += 1
            nbytes += len(raw)
    return {'messages': count, 'bytes': nbytes}


def _stage_raw_reader(bag):
    """Raw bytes through rosbags' lower-level ``rosbags.rosbag2.Reader``."""
    from rosbags.rosbag2 import Reader

    return _count_raw(Reader(Path(bag)))


def _stage_load(bag):
    """Extract the aligned run with the dataset loader."""
    from gyro_tdc.data.dataset import load_run

    run = load_run(bag)
    return {'samples': len(run)}


def _stage_train(bag, profile=False, extra=()):
    """Run the train command end to end (read, fit, coverage, save) with stdout discarded."""
    import contextlib
    import io

    from gyro_tdc.cli.train import main

    with tempfile.TemporaryDirectory() as tmp:
        argv = [str(bag), '--out', str(Path(tmp) / 'model.yaml'), '--no-progress', *extra]
        sink = io.StringIO()
        if profile:
            import cProfile
            import pstats
            prof = cProfile.Profile()
            with contextlib.redirect_stdout(sink):
                prof.enable()
                rc = main(argv)
                prof.disable()
            out = io.StringIO()
            pstats.Stats(prof, stream=out).sort_stats('cumulative').print_stats(25)
            return {'rc': rc, 'profile': out.getvalue()}
        with contextlib.redirect_stdout(sink):
            rc = main(argv)
    if rc != 0:
        raise RuntimeError(f'train exited {rc}')
    return {'rc': rc}


def _stage_train_paper(bag):
    """
    Run the train command with the paper's model only, as the defaults were before discovery.

    ``--features dT,dT2 --no-accel``: no discovery gates, no thermal state, no accelerometer
    part; the same work the trainer did when the 1.5x goal was first met, so this ratio shows
    what the restructuring itself costs, apart from what the newer defaults add.
    """
    return _stage_train(bag, extra=('--features', 'dT,dT2', '--no-accel'))


def _stage_rosbags(bag):
    """read_bag through rosbags' reader (the reference read of the columnar one)."""
    from gyro_tdc.data.bag.reader import read_bag

    return {'samples': len(read_bag(bag, via='rosbags').imu_t)}


def _stage_mcap_package(bag):
    """
    Read the trainer's topics' bytes through the ``mcap`` PyPI package (mcap bags only).

    The alternative the columnar read was measured against: ``make_reader(...)
    .iter_messages(topics=...)`` in log-time order, touching every message's bytes. The
    package is not a dependency; install it beside the venv to run this stage
    (``pip install --target DIR mcap==1.6.0`` and ``PYTHONPATH=DIR``).
    """
    try:
        from mcap.reader import make_reader
    except ImportError:
        raise SystemExit('bench_train: stage mcap_package needs the mcap package '
                         '(pip install --target DIR mcap==1.6.0; PYTHONPATH=DIR)') from None
    files = sorted(Path(bag).glob('*.mcap'))
    if not files:
        raise SystemExit(f'bench_train: stage mcap_package: {bag} holds no .mcap file')
    count = nbytes = 0
    for f in files:
        with open(f, 'rb') as stream:
            reader = make_reader(stream)
            for _schema, _channel, message in reader.iter_messages(
                    topics=['/imu/data_raw', '/imu/temperature'], log_time_order=True):
                count += 1
                nbytes += len(message.data)
    return {'messages': count, 'bytes': nbytes}


STAGES = {'raw_reader': _stage_raw_reader, 'load': _stage_load, 'train_paper':
          _stage_train_paper, 'rosbags': _stage_rosbags, 'train': _stage_train,
          'mcap_package': _stage_mcap_package, 'bare': _stage_train}

# The process stages: each a whole interpreter, as a user or a script would run it.
_RAW = """
import sys
from pathlib import Path
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
n = b = 0
with AnyReader([Path(sys.argv[1])], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
    for _conn, _stamp, raw in r.messages():
        n += 1
        b += len(raw)
print(n, b)
"""
_STORAGE = """
import sys
from pathlib import Path
from gyro_tdc.data.bag import columnar, metadata, reader
bag = Path(sys.argv[1])
wanted = [('imu', '/imu/data_raw', (reader.IMU_TYPE,), True),
          ('temperature', '/imu/temperature', reader.TEMPERATURE_TYPES, True)]
class Bytes:
    n_main = 0
    floating = False
    roles = ['imu', 'temperature']
    nbytes = 0
    received = {'imu': 0, 'temperature': 0}
    def add(self, role, buf, lengths, logs=None, before=None):
        self.n_main += len(lengths) if role == 'imu' else 0
        self.received[role] += len(lengths)
        self.nbytes += len(buf)
out = Bytes()
with columnar.open_bag(bag, metadata.load(bag)) as opened:
    _, conns = reader._connections(opened.topics, opened.conns, bag, wanted)
    opened.feed(conns, out, lambda n: None, reader._CHUNK)
print(out.n_main, out.nbytes)
"""


# Forks and times the command from a lean interpreter: a child's peak RSS (ru_maxrss)
# includes the memory of the process it was forked from, which here would be this one's.
_LAUNCH = """
import json, os, sys, time
out, cmd = sys.argv[1], sys.argv[2:]
t0 = time.perf_counter()
pid = os.fork()
if pid == 0:
    os.execv(cmd[0], cmd)
_, status, ru = os.wait4(pid, 0)
with open(out, 'w') as f:
    json.dump({'seconds': time.perf_counter() - t0, 'cpu': ru.ru_utime + ru.ru_stime,
               'peak_rss': ru.ru_maxrss * 1024, 'rc': os.waitstatus_to_exitcode(status)}, f)
"""


def _process(cmd, env=None, cwd=None):
    """Run ``cmd`` (in ``cwd``); return wall seconds, CPU seconds, peak RSS (bytes), stdout."""
    with tempfile.TemporaryDirectory() as tmp:
        stats = Path(tmp) / 'stats.json'
        proc = subprocess.run([sys.executable, '-S', '-c', _LAUNCH, str(stats), *cmd],
                              capture_output=True, text=True, env=env, cwd=cwd, check=False)
        r = json.loads(stats.read_text()) if stats.is_file() else {'rc': proc.returncode}
    if proc.returncode != 0 or r['rc'] != 0:
        raise RuntimeError(f'{cmd[1:3]} failed ({r["rc"]}):\n{proc.stderr}')
    return {**r, 'stdout': proc.stdout}


def _env(root=ROOT):
    return dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get('PYTHONPATH', ''))


#: ``--baseline DIR``: another checkout whose train runs beside this one's (stage 'baseline').
BASELINE = []


def _run_stage(stage, bag, tmp):
    """Run one stage of one bag in its own process."""
    if stage == 'raw':
        return _process([sys.executable, '-c', _RAW, str(bag)], _env())
    if stage == 'storage':
        return _process([sys.executable, '-c', _STORAGE, str(bag)], _env())
    if stage == 'bare':         # the power lost: the storage file alone, no metadata.yaml
        bare = Path(tmp) / 'bare'
        if not bare.is_dir():
            bare.mkdir()
            (f,) = [x for x in bag.iterdir() if x.suffix in ('.db3', '.mcap')]
            os.link(f, bare / f'bare_0{f.suffix}')
        bag = bare
    if stage in ('train', 'baseline', 'bare'):
        root = BASELINE[0] if stage == 'baseline' else ROOT
        # In the checkout: ``-m`` puts the working directory first on sys.path.
        r = _process([sys.executable, '-m', 'gyro_tdc', 'train', str(bag), '--out',
                      str(Path(tmp) / 'model.yaml'), '--no-progress'], _env(root), cwd=root)
        last = r['stdout'].strip().splitlines()[-1]
        r['model_id'] = last.rsplit('model_id ', 1)[-1].rstrip(')')
        return r
    return _run_child(stage, bag)


def _child(stage, bag, profile):
    """Run one in-process stage; print seconds, CPU time, peak RSS and details as JSON."""
    # Import what every stage needs before the clock starts: the stage is timed, not Python.
    import gyro_tdc.cli.train  # noqa: F401
    import rosbags.highlevel  # noqa: F401

    t0, c0 = time.perf_counter(), time.process_time()
    info = _stage_train(bag, profile=True) if profile else STAGES[stage](bag)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024   # Linux: KiB
    print(json.dumps({'stage': stage, 'seconds': seconds, 'cpu': cpu, 'peak_rss': peak,
                      **info}))


def _run_child(stage, bag, profile=False):
    cmd = [sys.executable, __file__, '--child', stage, '--bag', str(bag)]
    if profile:
        cmd.append('--profile')
    proc = subprocess.run(cmd, capture_output=True, text=True, env=_env(), check=False)
    if proc.returncode != 0:
        raise RuntimeError(f'stage {stage} failed:\n{proc.stderr}')
    return json.loads(proc.stdout.strip().splitlines()[-1])


MAKERS = {'bench': make_bag, 'die': make_die_bag}
LABELS = {'raw': "rosbags' raw read (process: AnyReader.messages())",
          'storage': 'storage read (process: columnar bytes only)',
          'train': 'gyro-tdc train BAG (process, defaults)',
          'baseline': 'gyro-tdc train BAG, the --baseline checkout',
          'raw_reader': "rosbags' raw read (rosbag2.Reader, in process)",
          'load': 'load_run (in process)', 'rosbags': "read_bag(via='rosbags') (in process)",
          'train_paper': 'train --features dT,dT2 --no-accel (in process)',
          'mcap_package': "the mcap package's iter_messages (in process)",
          'bare': 'gyro-tdc train BAG without metadata.yaml (process)'}


def _bag_path(name, storage, minutes, rate_hz):
    tag = '' if name == 'bench' else f'{name}_'
    return Path(tempfile.gettempdir()) / (
        f'gyro_tdc_bench_{tag}{minutes:g}min_{rate_hz:g}hz_{storage}')


def main(argv=None):
    """Build or reuse the bags, time each stage side by side, print the figures."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--bags', choices=('bench', 'die', 'both'), default='both')
    p.add_argument('--storage', choices=('sqlite3', 'mcap', 'both'), default='both')
    p.add_argument('--minutes', type=float, default=60.0, help='duration of the bench bag')
    p.add_argument('--rate-hz', type=float, default=1000.0)
    p.add_argument('--repeat', type=int, default=3, help='rounds per bag (medians reported)')
    p.add_argument('--stages', default='', metavar='A,B',
                   help='in-process stages to add: '
                        f'{", ".join(sorted(set(STAGES) - {"train"}))}')
    p.add_argument('--profile', action='store_true', help='cProfile the train stage once')
    p.add_argument('--baseline', metavar='DIR', default=None,
                   help="also run DIR's gyro-tdc train side by side (e.g. the main checkout)")
    p.add_argument('--bag', default=None, help=argparse.SUPPRESS)
    p.add_argument('--child', choices=sorted(STAGES), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        _child(args.child, args.bag, args.profile)
        return 0
    extra = [x for x in args.stages.split(',') if x]
    bad = [x for x in extra if x not in STAGES or x == 'train']
    if bad:
        p.error(f'unknown stage(s) {", ".join(bad)}')
    stages = ['raw', 'storage', 'train'] + (['baseline'] if args.baseline else []) + extra
    BASELINE[:] = [Path(args.baseline).resolve()] if args.baseline else []
    for root in (ROOT, *BASELINE):          # as installed: the bytecode compiled once
        compileall.compile_dir(root / 'gyro_tdc', quiet=1)
    names = ('bench', 'die') if args.bags == 'both' else (args.bags,)
    storages = ('sqlite3', 'mcap') if args.storage == 'both' else (args.storage,)
    sys.path.insert(0, str(ROOT))
    summary = []
    for name in names:
        for storage in storages:
            minutes = args.minutes if name == 'bench' else 60.0
            bag = _bag_path(name, storage, minutes, args.rate_hz)
            if not (bag / 'metadata.yaml').is_file():
                print(f'writing {bag} ...', flush=True)
                t0 = time.perf_counter()
                kw = {'minutes': minutes} if name == 'bench' else {}
                MAKERS[name](bag, rate_hz=args.rate_hz, storage=storage, **kw)
                print(f'  written in {time.perf_counter() - t0:.1f} s', flush=True)
            size = sum(f.stat().st_size for f in bag.iterdir() if f.is_file())
            print(f'\n{name} bag, {storage}: {bag} ({size / 1e6:.0f} MB)', flush=True)
            runs = {stage: [] for stage in stages}
            with tempfile.TemporaryDirectory() as tmp:
                for k in range(args.repeat):
                    # Side by side: every stage once per round, the order turned each round.
                    order = stages if k % 2 == 0 else stages[::-1]
                    for stage in order:
                        r = _run_stage(stage, bag, tmp)
                        runs[stage].append(r)
                        mid = f'  model_id {r["model_id"]}' if 'model_id' in r else ''
                        print(f'  round {k + 1}/{args.repeat} {stage:<11} {r["seconds"]:7.2f} s'
                              f'  CPU {r["cpu"]:6.2f} s  peak RSS {r["peak_rss"] / 1e6:5.0f} MB'
                              f'{mid}', flush=True)
            med = {stage: {key: statistics.median(r[key] for r in rs)
                           for key in ('seconds', 'cpu', 'peak_rss')}
                   for stage, rs in runs.items()}
            print(f'median of {args.repeat} rounds ({name}, {storage}):')
            for stage in stages:
                m = med[stage]
                print(f'  {LABELS[stage]:<52} {m["seconds"]:7.2f} s  CPU {m["cpu"]:6.2f} s  '
                      f'peak RSS {m["peak_rss"] / 1e6:5.0f} MB')
            raw, store, train = (med[x]['seconds'] for x in ('raw', 'storage', 'train'))
            ratios = [r['seconds'] / q['seconds'] for r, q in zip(runs['train'], runs['raw'])]
            ids = sorted({r['model_id'] for r in runs['train']})
            verdict = 'met' if train / raw <= GOAL else 'NOT met'
            print(f'  train / raw     = {train / raw:.2f}  (goal <= {GOAL}: {verdict}; per round '
                  f'{", ".join(f"{x:.2f}" for x in ratios)})')
            print(f'  train / storage = {train / store:.2f}')
            # On a loaded machine (other processes on the cores) the wall clock of a
            # two-thread train suffers more than the one-thread raw read: CPU beside it.
            print(f'  train CPU / raw CPU = {med["train"]["cpu"] / med["raw"]["cpu"]:.2f}')
            if args.baseline:
                base = med['baseline']
                cpu = med['train']['cpu'] / base['cpu']
                print(f'  baseline ({args.baseline}) / raw = {base["seconds"] / raw:.2f}, '
                      f'CPU {base["cpu"] / med["raw"]["cpu"]:.2f}; train / baseline = '
                      f'{train / base["seconds"]:.2f}, CPU {cpu:.2f}')
            if 'bare' in med:
                print(f'  bare / train = {med["bare"]["seconds"] / train:.2f} (no metadata.yaml: '
                      'the topics counted in the storage first)')
            print(f'  model id {", ".join(ids)}')
            summary.append((name, storage, raw, store, train, med['train']['peak_rss'],
                            ', '.join(ids), med['train']['cpu'] / med['raw']['cpu']))
            if args.profile:
                print('\ncProfile of the train stage (cumulative):')
                print(_run_child('train', bag, profile=True)['profile'])
    print('\nsummary (medians): bag, storage, raw s, storage s, train s, train / raw, '
          'train / storage, train CPU / raw CPU, train peak RSS MB, model id')
    for name, storage, raw, store, train, rss, ids, cpu in summary:
        print(f'  {name:<5} {storage:<7} {raw:6.2f} {store:6.2f} {train:6.2f}  '
              f'{train / raw:5.2f}  {train / store:5.2f}  {cpu:5.2f}  {rss / 1e6:5.0f}  {ids}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
