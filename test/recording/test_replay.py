"""pendulum_replay: a real replayer process publishing to a subscriber in this process."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.writer import Writer
from rclpy.qos import QoSProfile, QoSReliabilityPolicy
from rclpy.serialization import serialize_message
from recording_support import TOPICS, record, ros_node, scripted_messages, spin_until
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from pendulum_sim.recording import load
from pendulum_sim.recording.loader import TruncatedRecordingWarning
from pendulum_sim.recording.schemas import ros2msg_schema

REPLAY = Path(sys.executable).parent / 'pendulum_replay'
T0 = 1_700_000_000_000_000_000
PERIOD = 2_000_000          # 2 ms between loop ticks: 500 ticks are 1 s


def replay_command(*args: str) -> list[str]:
    return [str(REPLAY), *args]


def run_replay(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(replay_command(*args), capture_output=True, text=True,
                          timeout=timeout, env=os.environ)


@pytest.fixture(scope='module')
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Any]]:
    path = tmp_path_factory.mktemp('replay') / 'run.mcap'
    messages = scripted_messages(500, period_ns=PERIOD, t0_ns=T0)
    record(path, messages, chunk_size=4096)
    return path, messages


def receive(path: Path, *args: str, topics: tuple[str, ...] = tuple(TOPICS),
            clock: bool = False) -> tuple[dict[str, list[tuple[float, Any]]], str]:
    """Replay in another process; return what each topic received (arrival time, message)."""
    received: dict[str, list[tuple[float, Any]]] = {t: [] for t in topics}
    if clock:
        received['/clock'] = []
    with ros_node('replay_listener') as (node, executor):
        proc = subprocess.Popen(
            replay_command(str(path), '--topics', *topics, '--wait-for-subscribers', '20',
                           *args), stderr=subprocess.PIPE, text=True, env=os.environ)
        # The replay waits for a subscriber on each topic before its clock starts: subscribing
        # only once its publishers exist makes this moment a lower bound of that start.
        spin_until(executor, lambda: all(node.count_publishers(t) > 0 for t in received),
                   timeout=30)
        received['subscribed'] = [(time.monotonic(), None)]
        for topic in [t for t in received if t != 'subscribed']:
            msg_type = Clock if topic == '/clock' else TOPICS[topic][0]
            reliability = (QoSReliabilityPolicy.BEST_EFFORT if topic == '/effort_command'
                           else QoSReliabilityPolicy.RELIABLE)
            node.create_subscription(
                msg_type, topic,
                lambda msg, topic=topic: received[topic].append((time.monotonic(), msg)),
                QoSProfile(depth=5000, reliability=reliability))
        spin_until(executor, lambda: proc.poll() is not None, timeout=60)
        spin_until(executor, lambda: False, timeout=0.3)   # the last messages in flight
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    return received, err


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('rate', [1.0, 3.0])
def test_replay_reproduces_sequence_and_timing(recording: tuple[Path, list[Any]],
                                               rate: float) -> None:
    path, messages = recording
    received, err = receive(path, '--rate', str(rate))
    for topic in TOPICS:
        expected = [msg for t, msg, _ in messages if t == topic]
        got = [msg for _, msg in received[topic]]
        if topic == '/parameter_events':      # every rclpy node announces its use_sim_time
            got = [msg for msg in got if msg.node == '/pendulum']
        if topic == '/effort_command':   # best effort: may drop, but never reorders or invents
            remaining = iter(expected)
            assert all(any(g == e for e in remaining) for g in got)
            assert len(got) >= 0.9 * len(expected)
        else:
            assert got == expected, (topic, len(got), len(expected))
    # Timing, as a causal bound (no wall-clock rate is asserted): the replay sends message k at
    # its start + (recorded offset of k) / rate, and it starts only after this listener
    # subscribed (both processes read the machine's one monotonic clock), so no message
    # arrives before subscribed + offset / rate, however loaded the machine is.
    launched = received['subscribed'][0][0]
    arrivals = np.array([t for t, _ in received['/joint_states']])
    first_ns = min(ns for _, _, ns in messages)
    recorded = np.array([ns for t, _, ns in messages if t == '/joint_states'])
    earliest = launched + (recorded - first_ns) * 1e-9 / rate
    assert np.all(arrivals >= earliest), float((earliest - arrivals).max())
    # A replay that ignored the rate would end sooner than the recording's span allows.
    assert arrivals[-1] - launched >= (recorded[-1] - first_ns) * 1e-9 / rate
    assert err.rstrip('\n').endswith(f'{len(messages)}/{len(messages)} messages')


@pytest.mark.ros
@pytest.mark.slow
def test_replay_window_topics_and_clock(recording: tuple[Path, list[Any]]) -> None:
    path, messages = recording
    received, _ = receive(path, '--rate', '4', '--start', '0.2', '--end', '0.5', '--clock',
                          '200', topics=('/energy',), clock=True)
    lo, hi = T0 + 200_000_000, T0 + 500_000_000
    window = [(msg, ns) for t, msg, ns in messages if t == '/energy' and lo <= ns <= hi]
    assert [msg for _, msg in received['/energy']] == [msg for msg, _ in window]
    clock = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in received['/clock']]
    assert len(clock) > 5
    assert clock == sorted(clock)
    assert lo <= clock[0] and clock[-1] == window[-1][1]


# -- damaged files and bad arguments (no subscriber needed) -------------------------------------


def final_count(err: str) -> str:
    """Return the last ``sent/total`` of the progress line."""
    return re.findall(r'(\d+/\d+) messages', err)[-1]


@pytest.mark.ros
def test_not_mcap_and_nothing_to_replay_are_errors(tmp_path: Path) -> None:
    text = tmp_path / 'notes.mcap'
    text.write_text('not a recording\n')
    result = run_replay(str(text))
    assert result.returncode == 1
    assert result.stderr == (f'pendulum_replay: error: {text} is not an MCAP file (it does not '
                             'start with the MCAP magic bytes)\n')
    ros1 = tmp_path / 'ros1.mcap'
    with open(ros1, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros1', library='test')
        schema = writer.register_schema('std_msgs/String', 'ros1msg', b'string data')
        channel = writer.register_channel('/chatter', 'ros1', schema)
        writer.add_message(channel, log_time=1, data=b'\x02\x00\x00\x00hi', publish_time=1)
        writer.finish()
    result = run_replay(str(ros1))
    assert result.returncode == 1
    assert result.stderr.splitlines() == [
        f"pendulum_replay: warning: {ros1} has MCAP profile 'ros1', not 'ros2'; replaying only "
        'its CDR channels with ROS 2 schemas',
        "pendulum_replay: warning: skipping /chatter: not a ROS 2 CDR channel (message encoding "
        "'ros1', schema encoding 'ros1msg')",
        f'pendulum_replay: error: {ros1} has nothing to replay',
    ]


@pytest.mark.ros
def test_unknown_types_are_skipped_and_the_rest_replayed(tmp_path: Path) -> None:
    path = tmp_path / 'mixed.mcap'
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='test')
        unknown = writer.register_channel(
            '/bar', 'cdr', writer.register_schema('foo_msgs/msg/Bar', 'ros2msg', b'float64 x'))
        energy = writer.register_channel('/energy', 'cdr', writer.register_schema(
            'std_msgs/msg/Float64', 'ros2msg', ros2msg_schema('std_msgs/msg/Float64').encode()))
        for k in range(20):
            writer.add_message(unknown, log_time=k * 1000, data=b'\0\1\0\0' + bytes(8),
                               publish_time=k * 1000)
            writer.add_message(energy, log_time=k * 1000,
                               data=serialize_message(Float64(data=k)), publish_time=k * 1000)
        writer.finish()
    result = run_replay(str(path), '--rate', '100')
    assert result.returncode == 0
    assert result.stderr.splitlines()[0] == (
        "pendulum_replay: warning: skipping /bar: message type 'foo_msgs/msg/Bar' is refused: "
        'foo_msgs is not one of the allowed interface packages (std_msgs, sensor_msgs, ...: '
        'pendulum_sim.recording.schemas.INTERFACE_PACKAGES)')
    assert final_count(result.stderr) == '20/20'


@pytest.mark.ros
def test_truncated_and_corrupted_files_replay_what_is_readable(
        recording: tuple[Path, list[Any]], tmp_path: Path) -> None:
    path, messages = recording
    data = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) // 2])
    with pytest.warns(TruncatedRecordingWarning):
        readable = sum(i.message_count for i in load(cut).topics.values())
    assert 0 < readable < len(messages)
    result = run_replay(str(cut), '--rate', '50')
    assert result.returncode == 0
    assert result.stderr.startswith(f'pendulum_replay: warning: {cut} is truncated: ')
    assert final_count(result.stderr) == f'{readable}/{readable}'

    with open(path, 'rb') as stream:
        from mcap.reader import make_reader
        summary = make_reader(stream).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[2]
    in_chunk = sum(len(index.records) for index in _message_indexes(data, chunk))
    broken = bytearray(data)
    broken[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(broken))
    result = run_replay(str(bad), '--rate', '50')
    assert result.returncode == 0
    assert result.stderr.startswith(
        f'pendulum_replay: warning: {bad} is corrupted: the chunk record at byte '
        f'{chunk.chunk_start_offset} cannot be read (')
    left = len(messages) - in_chunk
    assert final_count(result.stderr) == f'{left}/{left}'


def _message_indexes(data: bytes, chunk: Any) -> list[Any]:
    from io import BytesIO

    from mcap.data_stream import ReadDataStream
    from mcap.records import MessageIndex
    out = []
    for offset in chunk.message_index_offsets.values():
        length = int.from_bytes(data[offset + 1:offset + 9], 'little')
        out.append(MessageIndex.read(ReadDataStream(BytesIO(data[offset + 9:
                                                                 offset + 9 + length]))))
    return out


@pytest.mark.parametrize(('args', 'message'), [
    (['--rate', '0'], 'argument --rate: must be > 0, got 0'),
    (['--rate', 'fast'], "argument --rate: must be a number, got 'fast'"),
    (['--start', '-1'], 'argument --start: must be >= 0, got -1'),
    (['--start', '2', '--end', '1'], 'argument --end: must be after --start (2.0 s), got 1.0'),
    # Every number must be finite and small enough for int64 nanoseconds (issue 11, item 12).
    (['--end', 'inf'], 'argument --end: must be a finite number, got inf'),
    (['--start', '1e300'], 'argument --start: must be <= 9.2e+09, got 1e300'),
    (['--rate', 'inf', '--clock'], 'argument --rate: must be a finite number, got inf'),
    (['--rate', '1e300'], 'argument --rate: must be <= 1e+06, got 1e300'),
    (['--clock', 'nan'], 'argument --clock: must be a finite number, got nan'),
    (['--wait-for-subscribers=-inf'],
     'argument --wait-for-subscribers: must be a finite number, got -inf'),
    (['--topics', '/nope'], 'argument --topics: /nope not in {path} (it has /diagnostics, '
     '/effort_command, /energy, /joint_states, /parameter_events)'),
])
def test_argument_errors(recording: tuple[Path, list[Any]], args: list[str],
                         message: str) -> None:
    path, _ = recording
    result = run_replay(str(path), *args)
    assert result.returncode == 2
    assert 'Traceback' not in result.stderr
    assert result.stderr.splitlines()[-1] == (
        f'pendulum_replay: error: {message.format(path=path)}')


@pytest.mark.ros
@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_stops_a_looping_replay_cleanly(recording: tuple[Path, list[Any]],
                                                          signum: int) -> None:
    path, _ = recording
    proc = subprocess.Popen(replay_command(str(path), '--loop'), stderr=subprocess.PIPE,
                            text=True, env=os.environ)
    assert proc.stderr is not None
    seen = ''
    while not re.search(r' (\d+)/\1 messages', seen):   # a whole pass, then more
        char = proc.stderr.read(1)
        assert char, seen
        seen += char
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0
    assert 'Traceback' not in seen + err
