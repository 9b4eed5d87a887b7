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
Tests of gyro_tdc.data.bag.reader: blocks, output columns, Float temperature topics.

Bags whose temperature topic is std_msgs Float32 / Float64 are read as the node reads them
live: a reading without a header takes the stamp of the latest IMU message received before it, in
the bag's log-time order: the reader's stamps are checked against the compensator node's own
callbacks fed the bag's messages in that order, the Run against a sensor_msgs/Temperature
bag stamped that way, and ``train`` on both gives the same model.
"""

from __future__ import annotations

import gc
import mmap
from pathlib import Path
import sys

from gyro_tdc.cli.train import main as train_main
from gyro_tdc.data import IMU_TYPE, read_bag, TEMPERATURE_TYPE, write_bag
from gyro_tdc.data.bag import codec, reader as bag_reader
from gyro_tdc.data.dataset import load_run
from gyro_tdc.errors import DatasetError
from gyro_tdc.model.modelfile import load_model
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
from synth import synth_run

TS = get_typestore(Stores.ROS2_JAZZY)
FLOATS = ('std_msgs/msg/Float32', 'std_msgs/msg/Float64')
PLUGINS = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
N_IMU = 600


def _write_plain(path: Path, *, seed: int = 1, n: int = N_IMU) -> Path:
    rng = np.random.default_rng(seed)
    t = 100.0 + np.arange(n) * 0.01
    write_bag(path, imu_t=t, gyro=rng.normal(size=(n, 3)), accel=rng.normal(size=(n, 3)),
              temp_t=t[::100], temp_c=20.0 + rng.normal(size=len(t[::100])))
    return path


def _imu_raw(ns, gyro, frame_id='imu_link'):
    sec, nsec = divmod(int(ns), 10 ** 9)
    vec = TS.types['geometry_msgs/msg/Vector3']
    msg = TS.types[IMU_TYPE](
        TS.types['std_msgs/msg/Header'](TS.types['builtin_interfaces/msg/Time'](sec, nsec),
                                        frame_id),
        TS.types['geometry_msgs/msg/Quaternion'](0.0, 0.0, 0.0, 1.0),
        np.array([-1.0] + [0.0] * 8), vec(*map(float, gyro)), np.array([1e-6] + [0.0] * 8),
        vec(0.0, 0.0, 9.81), np.array([1e-3] + [0.0] * 8))
    return bytes(TS.serialize_cdr(msg, IMU_TYPE))


def _temperature_raw(ns, value):
    sec, nsec = divmod(int(ns), 10 ** 9)
    msg = TS.types[TEMPERATURE_TYPE](
        TS.types['std_msgs/msg/Header'](TS.types['builtin_interfaces/msg/Time'](sec, nsec),
                                        'imu_link'), float(value), 0.0)
    return bytes(TS.serialize_cdr(msg, TEMPERATURE_TYPE))


def _float_raw(kind, value):
    return bytes(TS.serialize_cdr(TS.types[kind](float(value)), kind))


def _write(path, storage, imu, temps, temp_type):
    """Write IMU [(log_ns, raw)] and temperatures [(log_ns, raw)], in log-time order."""
    with Writer(path, version=9, storage_plugin=PLUGINS[storage]) as writer:
        ci = writer.add_connection('/imu/data_raw', IMU_TYPE, typestore=TS)
        ct = writer.add_connection('/imu/temperature', temp_type, typestore=TS)
        for ns, conn, raw in sorted([(ns, ci, raw) for ns, raw in imu]
                                    + [(ns, ct, raw) for ns, raw in temps],
                                    key=lambda x: x[0]):
            writer.write(conn, int(ns), raw)
    return path


def _node_order(path):
    """Return the bag's IMU and temperature messages as (connection topic, raw), log order."""
    with AnyReader([path], default_typestore=codec.jazzy()) as reader:
        return [(conn.topic, conn.msgtype, bytes(raw))
                for conn, _, raw in reader.messages()]


def _mirror_node(messages):
    """
    Stamp Float readings as CompensatorNode._on_temperature does.

    The stamp of the latest IMU message received (its header, seconds as the node computes
    them); readings before any IMU message are ignored.
    """
    last = None
    out = []
    for topic, msgtype, raw in messages:
        if topic == '/imu/data_raw':
            try:
                msg = TS.deserialize_cdr(raw, IMU_TYPE)
            except Exception:   # the node drops what it cannot deserialise
                continue
            st = msg.header.stamp
            last = st.sec + st.nanosec * 1e-9
        elif last is not None:
            out.append((last, float(TS.deserialize_cdr(raw, msgtype).data)))
    return out


def _jittered_bag(path, storage, kind, rng, n=900):
    """IMU at 100 Hz whose header stamps lag and jitter against the log time; Float temps."""
    log = 50_000_000_000 + np.arange(n) * 10_000_000 + rng.integers(0, 3_000_000, n)
    stamp = log - 2_000_000 + rng.integers(-4_000_000, 4_000_000, n)   # not monotonic
    gyro = rng.normal(scale=0.01, size=(n, 3))
    gyro[17] = np.nan                       # the node still takes this message's stamp
    imu = [(int(a), _imu_raw(b, g)) for a, b, g in zip(log, stamp, gyro)]
    imu[40] = (imu[40][0], imu[40][1][:30])  # cut short: undecodable, the node drops it
    # Temperatures between IMU messages (never on one's log time), one before the first,
    # two in a row with no IMU message between them, a NaN reading.
    t_log = [log[0] - 5_000_000] + [int(log[k] + 1_000) for k in range(3, n, 37)]
    t_log.insert(5, t_log[4] + 500)
    values = 20.0 + np.round(rng.normal(size=len(t_log)), 3)
    values[7] = np.nan
    temps = [(ns, _float_raw(kind, v)) for ns, v in zip(t_log, values)]
    return _write(path, storage, imu, temps, kind)


def test_decode_float_agrees_with_rosbags():
    for kind in FLOATS:
        values = [21.5, -3.25, float('nan'), 1e-3]
        raws = [_float_raw(kind, v) for v in values]
        fast = codec.decode_float(b''.join(raws), [len(r) for r in raws], kind, TS)
        assert fast.fallback == 0 and fast.undecodable is None
        want = [float(TS.deserialize_cdr(r, kind).data) for r in raws]
        np.testing.assert_array_equal(fast.values[:, 0], want)
        assert np.all(fast.values[:, 1] == 0.0) and np.all(fast.sec == 0)
        # Big-endian and cut-short messages go to rosbags: read right, or marked undecodable.
        big = bytes(TS.serialize_cdr(TS.types[kind](7.5), kind, little_endian=False))
        mixed = [raws[0], big, raws[0][:5]]
        slow = codec.decode_float(b''.join(mixed), [len(r) for r in mixed], kind, TS)
        assert slow.fallback == 3
        assert slow.values[:2, 0].tolist() == [21.5, 7.5]
        assert slow.undecodable.tolist() == [False, False, True]


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
@pytest.mark.parametrize('kind', FLOATS)
def test_float_readings_take_the_latest_imu_stamp_before_them(tmp_path, storage, kind,
                                                              monkeypatch):
    monkeypatch.setattr(bag_reader, '_CHUNK', 64)     # readings fall across many blocks
    bag = _jittered_bag(tmp_path / 'bag', storage, kind, np.random.default_rng(4))
    data = read_bag(bag)
    want = _mirror_node(_node_order(bag))
    finite = [(t, c) for t, c in want if np.isfinite(c)]
    assert data.temp_t.tolist() == [t for t, _ in finite]
    assert data.temp_c.tolist() == [c for _, c in finite]
    assert np.all(data.temp_var == 0.0)
    assert data.rejected['temp_before_imu'] == 1
    assert data.rejected['temp_nonfinite'] == 1
    assert data.rejected['undecodable'] == 1
    assert data.topics['/imu/temperature'][0] == kind
    # Without the block boundaries the same.
    monkeypatch.setattr(bag_reader, '_CHUNK', 1 << 14)
    assert read_bag(bag).temp_t.tolist() == data.temp_t.tolist()


def test_the_node_stamps_the_readings_as_the_reader_does(ros_context, tmp_path):
    """Feed the compensator node's own callbacks the bag's messages in log order."""
    from gyro_tdc.nodes.compensator_node import CompensatorNode
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float32, Float64

    for kind, cls in zip(FLOATS, (Float32, Float64)):
        bag = _jittered_bag(tmp_path / kind.split('/')[-1], 'sqlite3', kind,
                            np.random.default_rng(9), n=400)
        node = CompensatorNode(context=ros_context, parameter_overrides=[
            Parameter('temperature_type', value=kind)])
        got = []
        add = node.core.add_temperature
        node.core.add_temperature = lambda t, c, add=add: got.append((t, c)) or add(t, c)
        try:
            for topic, _, raw in _node_order(bag):
                if topic == '/imu/data_raw':
                    node._on_imu_raw(raw)
                else:
                    node._on_temperature(deserialize_message(raw, cls))
            assert node.temperatures_ignored == 1
        finally:
            node.destroy_node()
        data = read_bag(bag)
        live = [(t, c) for t, c in got if np.isfinite(c)]
        assert data.temp_t.tolist() == [t for t, _ in live]
        assert data.temp_c.tolist() == [c for _, c in live]


def _run_bags(tmp_path, kind):
    """Write a synthetic run as a Float bag and as the sensor_msgs/Temperature bag it implies."""
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    rng = np.random.default_rng(2)
    log = (100 * 10 ** 9 + np.round(run.t * 1e9)).astype(np.int64)
    stamp = log - 3_000_000 - rng.integers(0, 2_000_000, len(log))
    imu = [(int(a), _imu_raw(b, g)) for a, b, g in zip(log, stamp, run.omega)]
    # A reading every 2 s, half way between two IMU messages (the run's temperature there).
    rows = np.arange(1, len(log) - 1, 4)
    t_log = log[rows] + (log[rows + 1] - log[rows]) // 2
    temps = run.temp[rows].astype(np.float32 if kind.endswith('32') else np.float64)
    floating = _write(tmp_path / 'float', 'sqlite3', imu,
                      [(int(a), _float_raw(kind, v)) for a, v in zip(t_log, temps)], kind)
    stamped = [(int(a), _temperature_raw(stamp[r], float(v)))
               for a, r, v in zip(t_log, rows, temps)]
    plain = _write(tmp_path / 'plain', 'sqlite3', imu, stamped, TEMPERATURE_TYPE)
    return floating, plain


@pytest.mark.parametrize('kind', FLOATS)
def test_float_bag_gives_the_run_and_model_of_the_stamped_bag(tmp_path, kind, capsys):
    floating, plain = _run_bags(tmp_path, kind)
    a, b = load_run(floating), load_run(plain)
    assert len(a.t) > 7000
    for key in ('t', 'temp', 'omega', 'omega_ref'):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.info['rejected'] == b.info['rejected']
    models = {}
    for bag in (floating, plain):
        out = tmp_path / f'{bag.name}.yaml'
        assert train_main([str(bag), '--features', 'dT,dT2', '--kind', 'poly', '--no-accel',
                           '--no-progress', '--out', str(out)]) == 0
        models[bag.name] = load_model(out)
    capsys.readouterr()
    # The same model but for the bag names it records: a hash of every fitted field.
    f, p = (m.replace(metrics=dict(m.metrics, runs=['bag'])) for m in models.values())
    assert f.model_id == p.model_id
    assert models['float'].metrics['runs'] == [str(floating)]
    np.testing.assert_array_equal(f.weights, p.weights)
    assert f.frame_id == p.frame_id == 'imu_link'


def test_a_temperature_topic_of_another_type_is_refused(tmp_path):
    imu = [(10 ** 9, _imu_raw(10 ** 9, (0.0, 0.0, 0.0)))]
    bag = _write(tmp_path / 'bag', 'sqlite3', imu, [(2 * 10 ** 9, _float_raw(
        'std_msgs/msg/Float64', 1.0))], 'std_msgs/msg/Float64')
    with pytest.raises(DatasetError, match=r"has type 'sensor_msgs/msg/Imu', expected "
                                           r"'sensor_msgs/msg/Temperature' or "
                                           r"'std_msgs/msg/Float32' or 'std_msgs/msg/Float64'"):
        read_bag(bag, temperature_topic='/imu/data_raw')


# ------------------------------------------------------------------------------------------
# The reused decode buffer in a long-lived process
# ------------------------------------------------------------------------------------------

@pytest.fixture()
def several_bags(tmp_path, monkeypatch):
    """Three bags of 600 IMU messages, read through rosbags in blocks of 64 (ten each)."""
    monkeypatch.setattr(bag_reader, '_CHUNK', 64)
    return [_write_plain(tmp_path / f'bag{k}', seed=k) for k in range(3)]


def _read_all(bags):
    # The reused buffer is the rosbags read's (the columnar read has none).
    return [read_bag(b, via='rosbags') for b in bags]


def test_a_profiler_holding_the_decode_frames_does_not_break_the_next_block(several_bags):
    # A sampling profiler (Dask's worker samples the stack of every running task every
    # 10 ms) holds the frames it took; a frame of the decode kept after it returned keeps
    # its views of the reader's buffer, which the next block must not be written into.
    plain = _read_all(several_bags)
    held = []

    def sample(frame, event, arg):
        if event == 'return' and frame.f_code.co_name in ('decode_joined', '_decode_records'):
            held.append(frame)
    sys.setprofile(sample)
    try:
        profiled = _read_all(several_bags)
    finally:
        sys.setprofile(None)
    assert len(held) >= 3 * 2 * (N_IMU // 64)
    for a, b in zip(profiled, plain):
        np.testing.assert_array_equal(a.gyro, b.gyro)
        np.testing.assert_array_equal(a.imu_t, b.imu_t)
        np.testing.assert_array_equal(a.accel, b.accel)


def test_views_kept_by_uncollected_cycles_do_not_break_the_next_block(several_bags,
                                                                      monkeypatch):
    plain = _read_all(several_bags)
    decode_joined = bag_reader.decode_joined
    cycles = []

    def decode_in_a_cycle(buf, *args, **kwargs):
        dec = decode_joined(buf, *args, **kwargs)
        cycle = [buf]
        cycle.append(cycle)                 # garbage only the cyclic collector frees
        if args[1] == IMU_TYPE:             # (the temperature blocks are decoded so too)
            cycles.append(id(cycle))
        return dec
    monkeypatch.setattr(bag_reader, 'decode_joined', decode_in_a_cycle)
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        cyclic = _read_all(several_bags)
    finally:
        if was_enabled:
            gc.enable()
    assert len(cycles) == 3 * -(-N_IMU // 64)
    for a, b in zip(cyclic, plain):
        np.testing.assert_array_equal(a.gyro, b.gyro)
        np.testing.assert_array_equal(a.temp_c, b.temp_c)


# ------------------------------------------------------------------------------------------
# The output columns
# ------------------------------------------------------------------------------------------

def test_large_columns_live_in_an_anonymous_mapping_small_ones_in_numpy():
    # Large columns are not given numpy's huge-page advice (costly first touch).
    big = bag_reader._columns(1 << 20, 3)
    assert big.shape == (1 << 20, 3) and big.dtype == np.float64 and big.flags.writeable
    base = big
    while isinstance(base, (np.ndarray, memoryview)):
        base = base.base if isinstance(base, np.ndarray) else base.obj
    assert isinstance(base, mmap.mmap)
    small = bag_reader._columns(10)
    assert small.shape == (10,) and small.base is None


def test_the_sink_grows_past_its_capacity_and_keeps_what_it_had():
    sink = bag_reader._Sink(4, (1, 2))
    rows = np.arange(30.0).reshape(10, 3)
    sink.add(np.arange(3.0), rows[:3])
    sink.add(np.arange(3.0, 10.0), rows[3:])           # past the capacity of 4
    t, a, b = sink.result()
    np.testing.assert_array_equal(t, np.arange(10.0))
    np.testing.assert_array_equal(a, rows[:, :1])
    np.testing.assert_array_equal(b, rows[:, 1:])


def test_the_collector_gathers_small_main_blocks_and_decodes_the_rest_on_result():
    raws = [_imu_raw(10 ** 9 * (k + 1), (0.1 * k, 0.0, 0.0)) for k in range(6)]
    out = bag_reader.Collector(['imu', 'temperature'], {'imu': IMU_TYPE,
                                                        'temperature': TEMPERATURE_TYPE},
                               {'imu': 6, 'temperature': 1}, TS, False, chunk=8)

    def add(k, n):
        out.add('imu', b''.join(raws[k:k + n]), [len(r) for r in raws[k:k + n]],
                np.arange(k, k + n) + 1)
    add(0, 2)
    assert out.sinks['imu'].n == 0 and out.n_main == 2     # 2 of 8: gathered
    add(2, 3)
    assert out.sinks['imu'].n == 0
    add(5, 1)
    out.flush()
    assert out.sinks['imu'].n == 6 and out.pending == []
    out.flush()                                            # nothing gathered: nothing added
    assert out.sinks['imu'].n == 6
    np.testing.assert_array_equal(out.sinks['imu'].t[:6], np.arange(6) + 1.0)
    add(0, 4)                                              # half a block: decoded at once
    assert out.sinks['imu'].n == 10
