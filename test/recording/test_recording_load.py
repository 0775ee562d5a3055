"""load(): reset events split the run into segments in write order; the fast decoder equals the
per-message one (rclpy) and the independent reader (mcap-ros2-support) on every layout."""
from __future__ import annotations

import json
import math
import random
import struct
import subprocess
import sys
import warnings
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from recording_support import assert_same, read_independently, record, scripted_messages
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.recording import RESET_TOPIC, McapRecorder, Recording, Segment, load
from pendulum_sim.recording import loader as loader_module
from pendulum_sim.recording.schemas import ros2msg_schema

SEGMENT_FIELDS = [f.name for f in fields(Segment)]


class Slow:
    """Count the messages that went through the per-message decoder during a load."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.rows = 0
        original = loader_module._Topic._decode_row

        def counted(topic: Any, *args: Any) -> None:
            self.rows += 1
            original(topic, *args)

        monkeypatch.setattr(loader_module._Topic, '_decode_row', counted)


def node_like(k: int, ns: int, joints: int = 1) -> JointState:
    """Return a JointState as the node publishes it: one joint (or several), all arrays set."""
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
    msg.name = ['pendulum_joint'] if joints == 1 else [f'j{i}' for i in range(joints)]
    msg.position = [math.sin(1e-3 * k + i) for i in range(joints)]
    msg.velocity = [math.cos(1e-3 * k + i) for i in range(joints)]
    msg.effort = [0.01 * (k % 17) - i for i in range(joints)]
    return msg


def record_run(path: Path, ticks: int, joints: int = 1, resets: dict[int, str] | None = None,
               stamp: Any = None, **kwargs: Any) -> McapRecorder:
    """Record ``ticks`` node-like ticks (joint_states, energy, a command every 10th)."""
    stamp = stamp or (lambda k: 1_000_000_000 + k * 1_000_000)
    with McapRecorder(path, **kwargs) as rec:
        rec.add_channel('/joint_states', JointState, QoSProfile(depth=10))
        rec.add_channel('/energy', Float64, 10)
        rec.add_channel('/effort_command', Float64, 10)
        for k in range(ticks):
            if resets and k in resets:
                rec.write_reset(stamp(k), resets[k])
            ns = stamp(k)
            rec.write('/joint_states', node_like(k, ns, joints), ns)
            rec.write('/energy', Float64(data=1.0 / (k + 1)), ns)
            if k % 10 == 0:
                rec.write('/effort_command', Float64(data=0.5 * k), ns)
    return rec


# -- resets and segments -------------------------------------------------------------------------


def test_resets_split_the_run_into_segments_in_write_order(tmp_path: Path) -> None:
    path = tmp_path / 'resets.mcap'
    record_run(path, 300, resets={100: 'reset by ~/reset', 250: 'second'}, chunk_size=2048)
    rec = load(path)
    assert rec.complete and rec.problems == ()
    assert isinstance(rec, Recording) and len(rec.segments) == 3
    stamps = 1_000_000_000 + np.arange(300) * 1_000_000
    np.testing.assert_array_equal(rec.resets, [stamps[100], stamps[250]])
    assert rec.reset_messages == ('reset by ~/reset', 'second')
    assert rec.topics[RESET_TOPIC].type == 'std_msgs/msg/String'
    assert rec.topics[RESET_TOPIC].message_count == 2
    for segment, (a, b) in zip(rec.segments, [(0, 100), (100, 250), (250, 300)], strict=True):
        assert segment.joint_states is not None and segment.energy is not None
        np.testing.assert_array_equal(segment.joint_states.stamp_ns, stamps[a:b])
        np.testing.assert_array_equal(segment.joint_states.position,
                                      [math.sin(1e-3 * k) for k in range(a, b)])
        np.testing.assert_array_equal(segment.energy.value, [1.0 / (k + 1) for k in range(a, b)])
        assert segment.effort_command is not None
        np.testing.assert_array_equal(segment.effort_command.value,
                                      [0.5 * k for k in range(a, b) if k % 10 == 0])
    # The whole run stays at the top level; the independent reader sees the events in place.
    assert rec.joint_states is not None
    np.testing.assert_array_equal(rec.joint_states.stamp_ns, stamps)
    _, decoded = read_independently(path)
    order = [(c.topic, m.data if c.topic == RESET_TOPIC else None) for _, c, _, m in decoded
             if c.topic in (RESET_TOPIC, '/joint_states')]
    assert order.index((RESET_TOPIC, 'reset by ~/reset')) == 100
    assert order.index((RESET_TOPIC, 'second')) == 251


def test_segments_keep_write_order_when_stamps_go_back(tmp_path: Path) -> None:
    path = tmp_path / 'back.mcap'
    # Stamps restart after each reset (what a clock sent back would record).
    record_run(path, 90, resets={30: 'a', 60: 'b'}, stamp=lambda k: (k % 30) * 1_000_000,
               chunk_size=1024)
    rec = load(path)
    assert rec.joint_states is not None and len(rec.segments) == 3
    np.testing.assert_array_equal(rec.joint_states.stamp_ns,
                                  np.tile(np.arange(30) * 1_000_000, 3))   # not sorted
    for i, segment in enumerate(rec.segments):
        assert segment.joint_states is not None
        np.testing.assert_array_equal(segment.joint_states.stamp_ns, np.arange(30) * 1_000_000)
        np.testing.assert_array_equal(segment.joint_states.position,
                                      [math.sin(1e-3 * k) for k in range(30 * i, 30 * i + 30)])
    np.testing.assert_array_equal(rec.resets, [0, 0])


def test_a_run_without_resets_is_one_segment_and_edge_resets_give_empty_ones(
        tmp_path: Path) -> None:
    plain = tmp_path / 'plain.mcap'
    record_run(plain, 20)
    rec = load(plain)
    assert len(rec.segments) == 1 and len(rec.resets) == 0 and RESET_TOPIC not in rec.topics
    assert_same(rec.segments[0], Segment(**{n: getattr(rec, n) for n in SEGMENT_FIELDS}))
    edges = tmp_path / 'edges.mcap'
    with McapRecorder(edges) as recorder:
        recorder.add_channel('/energy', Float64, 10)
        recorder.write_reset(0, 'at start')
        for k in range(5):
            recorder.write('/energy', Float64(data=float(k)), k)
        recorder.write_reset(5, 'at end')
    rec = load(edges)
    assert [len(s.energy.value) for s in rec.segments if s.energy is not None] == [0, 5, 0]
    assert rec.reset_messages == ('at start', 'at end') and rec.joint_states is None


# -- the fast decoder equals the per-message decoder ---------------------------------------------


def test_node_layout_is_decoded_many_at_once_and_equals_the_slow_path(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / 'node_like.mcap'
    record_run(path, 5000, resets={1234: 'r'})
    slow = load(path, fast=False)
    counter = Slow(monkeypatch)
    fast = load(path)
    assert counter.rows == 0                 # every message took the fast path
    assert_same(fast, slow)
    assert fast.joint_states is not None and fast.joint_states.position.shape == (5000,)
    _, decoded = read_independently(path)
    js = [m for _, c, _, m in decoded if c.topic == '/joint_states']
    np.testing.assert_array_equal(fast.joint_states.effort, [m.effort[0] for m in js])
    np.testing.assert_array_equal(fast.joint_states.header_stamp_ns,
                                  [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                                   for m in js])


def test_varying_layouts_equal_the_slow_path(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # Frame ids of two lengths and messages without effort: several templates per chunk.
    path = tmp_path / 'scripted.mcap'
    record(path, scripted_messages(3000), chunk_size=16 * 1024)
    slow = load(path, fast=False)
    counter = Slow(monkeypatch)
    fast = load(path)
    assert counter.rows < 3000 // 10   # most took the fast path
    assert_same(fast, slow)


def test_several_joints_fall_back_to_the_per_message_decoder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / 'three.mcap'
    record_run(path, 400, joints=3)
    counter = Slow(monkeypatch)
    fast = load(path)
    assert counter.rows == 400                # every JointState, none of the Float64
    assert_same(fast, load(path, fast=False))
    assert fast.joint_states is not None and fast.joint_states.position.shape == (400, 3)
    assert fast.joint_states.name == ('j0', 'j1', 'j2')
    np.testing.assert_array_equal(fast.joint_states.velocity[:, 2],
                                  [math.cos(1e-3 * k + 2) for k in range(400)])


def test_special_values_and_stamps_survive_bit_for_bit(tmp_path: Path) -> None:
    path = tmp_path / 'special.mcap'
    nan_payload = struct.unpack('<d', struct.pack('<Q', 0x7FF8_0000_DEAD_BEEF))[0]
    values = [0.0, -0.0, math.inf, -math.inf, nan_payload, 5e-324, -1.7976931348623157e308]
    with McapRecorder(path) as rec:
        rec.add_channel('/joint_states', JointState, 10)
        rec.add_channel('/energy', Float64, 10)
        for k, value in enumerate(values):
            msg = JointState()
            msg.header.stamp.sec, msg.header.stamp.nanosec = -5 + k, 999_999_999 - k
            msg.name, msg.position, msg.velocity, msg.effort = ['pendulum_joint'], [value], [
                -value], [value]
            rec.write('/joint_states', msg, 2**62 + k)
            rec.write('/energy', Float64(data=value), 2**62 + k)
    fast, slow = load(path), load(path, fast=False)
    assert_same(fast, slow)
    assert fast.energy is not None and fast.joint_states is not None
    assert fast.energy.value.tobytes() == struct.pack(f'<{len(values)}d', *values)
    np.testing.assert_array_equal(fast.joint_states.header_stamp_ns,
                                  [(-5 + k) * 10**9 + 999_999_999 - k for k in range(7)])
    np.testing.assert_array_equal(fast.energy.stamp_ns, 2**62 + np.arange(7))


def blank_message_indexes(data: bytearray, channel_id: int) -> int:
    """Make every message index of a channel empty (as if the index left messages out)."""
    blanked = 0
    pos = 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from('<BQ', data, pos)
        if opcode == 0x07 and struct.unpack_from('<H', data, pos + 9)[0] == channel_id:
            struct.pack_into('<I', data, pos + 11, 0)
            blanked += 1
        if opcode == 0x0F:   # data end: the summary follows
            break
        pos += 9 + length
    return blanked


def test_an_index_that_leaves_messages_out_is_not_trusted(tmp_path: Path) -> None:
    path = tmp_path / 'run.mcap'
    record_run(path, 2000, chunk_size=4096)
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    energy = next(c.id for c in summary.channels.values() if c.topic == '/energy')
    data = bytearray(path.read_bytes())
    assert blank_message_indexes(data, energy) > 10
    damaged = tmp_path / 'index.mcap'
    damaged.write_bytes(bytes(data))
    assert_same(load(damaged).energy, load(path).energy)
    rec = load(damaged)
    assert rec.energy is not None and len(rec.energy.value) == 2000


# -- load() at scale (issue 11, item 16) ---------------------------------------------------------

_CDR_HEADER = b'\x00\x01\x00\x00'
MEASURE = """
import json, resource, sys
import numpy as np
from pendulum_sim.recording import load
load(sys.argv[2])                     # message types imported, type support loaded
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
rec = load(sys.argv[1])
grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
arrays = sum(v.nbytes for part in (rec.joint_states, rec.energy)
             for v in vars(part).values() if isinstance(v, np.ndarray))
exact = (np.array_equal(rec.joint_states.position, np.arange(300_000) * 1e-3)
         and np.array_equal(rec.energy.value, np.arange(300_000) * 0.5))
print(json.dumps({'grown': grown, 'arrays': arrays, 'count': len(rec.energy.value),
                  'exact': bool(exact)}))
"""


@pytest.mark.slow
def test_a_long_recording_loads_within_three_times_its_arrays(tmp_path: Path) -> None:
    # The case: 300k joint_states + 300k energy in 0.25 s chunks, as the node records
    # them (the bytes rclpy serializes, written here with mcap's own writer for speed).
    path, small = tmp_path / 'long.mcap', tmp_path / 'small.mcap'
    record_run(small, 10)
    state = bytearray(serialize_message(node_like(1000, 0)))
    at = state.index(struct.pack('<d', math.sin(1.0)))   # where the position is
    with open(path, 'wb') as stream:
        writer = Writer(stream, chunk_size=1 << 20)
        writer.start(profile='ros2', library='test')
        js = writer.register_channel('/joint_states', 'cdr', writer.register_schema(
            'sensor_msgs/msg/JointState', 'ros2msg', ros2msg_schema(
                'sensor_msgs/msg/JointState').encode()))
        energy = writer.register_channel('/energy', 'cdr', writer.register_schema(
            'std_msgs/msg/Float64', 'ros2msg', ros2msg_schema('std_msgs/msg/Float64').encode()))
        for k in range(300_000):
            struct.pack_into('<d', state, at, 1e-3 * k)
            writer.add_message(js, log_time=k * 10**6, publish_time=k * 10**6,
                               data=bytes(state))
            writer.add_message(energy, log_time=k * 10**6, publish_time=k * 10**6,
                               data=_CDR_HEADER + struct.pack('<d', 0.5 * k))
        writer.finish()
    out = subprocess.run([sys.executable, '-c', MEASURE, str(path), str(small)],
                         capture_output=True, text=True, check=True).stdout
    figures = json.loads(out)
    assert figures['count'] == 300_000 and figures['exact']
    assert figures['grown'] <= 3 * figures['arrays'], figures


# -- damaged files: a RecorderError or a warning, never anything else ----------------------------


@pytest.mark.parametrize('compression', ['zstd', 'none'])
def test_random_damage_gives_a_recorder_error_or_the_same_result_both_ways(
        tmp_path: Path, compression: str) -> None:
    from pendulum_sim.recording import RecorderError
    from pendulum_sim.recording.reader import scan
    path = tmp_path / 'run.mcap'
    record(path, scripted_messages(300), chunk_size=2048, compression=compression)
    data = path.read_bytes()
    rng = random.Random(11)
    damaged = tmp_path / 'damaged.mcap'
    outcomes = {'loaded': 0, 'refused': 0}
    for _ in range(100):
        flipped = bytearray(data)
        for _ in range(rng.choice([1, 2, 8])):
            flipped[rng.randrange(len(flipped))] = rng.randrange(256)
        if rng.random() < 0.3:
            flipped = flipped[:rng.randrange(len(flipped))]
        damaged.write_bytes(bytes(flipped))
        results = []
        for fast in (True, False):
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                try:
                    results.append(load(damaged, fast=fast))
                except RecorderError as exc:
                    results.append(str(exc))
        if isinstance(results[0], str):
            assert results[0] == results[1]
            outcomes['refused'] += 1
        else:
            assert_same(results[0], results[1])
            outcomes['loaded'] += 1
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            try:
                scan(damaged, corrupt='skip')
            except RecorderError:
                pass
    assert outcomes['loaded'] > 10 and outcomes['refused'] > 10, outcomes
