"""Recorder and loader: files read back with an independent reader, and damaged files."""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.writer import Writer
from rclpy.duration import Duration
from rclpy.qos import (
    QoSDurabilityPolicy,
    QoSLivelinessPolicy,
    QoSProfile,
    QoSReliabilityPolicy,
)
from rclpy.serialization import deserialize_message
from recording_support import (
    SCENE,
    TOPICS,
    joint_states_on_disk,
    read_independently,
    record,
    ros_node,
    scripted_messages,
)

from pendulum_sim.recording import McapRecorder, RecorderError, load
from pendulum_sim.recording.loader import Recording, TruncatedRecordingWarning
from pendulum_sim.recording.reader import MAGIC
from pendulum_sim.recording.rosbag2 import offered_qos, qos_to_dict
from pendulum_sim.recording.schemas import (
    SEPARATOR,
    message_class,
    ros2msg_schema,
    type_hash,
    type_name_of,
)

SHARE = Path(sys.prefix) / 'share'
TYPE_NAMES = sorted({type_name_of(t) for t, _ in TOPICS.values()})


def msg_file(name: str) -> str:
    """Return the installed .msg text of ``pkg/Type`` or ``pkg/msg/Type``."""
    parts = name.split('/')
    return (SHARE / parts[0] / 'msg' / f'{parts[-1]}.msg').read_text()


def nested_types(cls: type) -> set[str]:
    """Return every message type nested in a class, found by rclpy introspection."""
    from rosidl_parser.definition import AbstractNestedType, NamespacedType
    found: set[str] = set()
    for slot in cls.SLOT_TYPES:  # type: ignore[attr-defined]
        if isinstance(slot, AbstractNestedType):
            slot = slot.value_type
        if isinstance(slot, NamespacedType):
            name = '/'.join([*slot.namespaces, slot.name])
            found.add(name)
            found |= nested_types(message_class(name))
    return found


def same_fields(original: Any, decoded: Any, where: str = 'msg') -> None:
    """Assert that a decoded message equals the original in every field, recursively."""
    for field in original.get_fields_and_field_types():
        a, b = getattr(original, field), getattr(decoded, field)
        here = f'{where}.{field}'
        if hasattr(a, 'get_fields_and_field_types'):
            same_fields(a, b, here)
        elif isinstance(a, (list, tuple)) and a and hasattr(a[0], 'get_fields_and_field_types'):
            assert len(a) == len(b), here
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                same_fields(x, y, f'{here}[{i}]')
        elif isinstance(a, bytes) and isinstance(b, int):   # a 'byte' field: rclpy gives bytes
            assert a == bytes([b]), here
        elif isinstance(a, (str, int, float, bool)):
            assert a == b, here
        else:
            assert list(a) == list(b), here


# -- schemas, type hashes, QoS ------------------------------------------------------------------

DEPENDENCIES = {   # worked out by hand from the .msg files: depth-first, sorted at each level
    'diagnostic_msgs/msg/DiagnosticArray': [
        'diagnostic_msgs/DiagnosticStatus', 'diagnostic_msgs/KeyValue', 'std_msgs/Header',
        'builtin_interfaces/Time'],
    'rcl_interfaces/msg/ParameterEvent': [
        'builtin_interfaces/Time', 'rcl_interfaces/Parameter', 'rcl_interfaces/ParameterValue'],
    'sensor_msgs/msg/JointState': ['std_msgs/Header', 'builtin_interfaces/Time'],
    'std_msgs/msg/Float64': [],
}


@pytest.mark.parametrize('type_name', TYPE_NAMES)
def test_schema_is_the_msg_then_each_dependency_once(type_name: str) -> None:
    sections = ros2msg_schema(type_name).split(f'\n{SEPARATOR}\n')
    assert sections[0] == msg_file(type_name)
    names = []
    for section in sections[1:]:
        head, _, text = section.partition('\n')
        assert head.startswith('MSG: ')
        names.append(head.removeprefix('MSG: '))
        assert text == msg_file(names[-1])
    assert names == DEPENDENCIES[type_name]
    full = {n.replace('/', '/msg/', 1) for n in names}
    assert full == nested_types(message_class(type_name))


def graph_publisher_info(node: Any, topic: str) -> Any:
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        infos = node.get_publishers_info_by_topic(topic)
        if infos:
            return infos[0]
        time.sleep(0.02)
    raise AssertionError(f'no publisher on {topic} in the graph')


PROFILES = [
    QoSProfile(depth=10),
    QoSProfile(depth=1, reliability=QoSReliabilityPolicy.BEST_EFFORT),
    QoSProfile(depth=3, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL),
    QoSProfile(depth=10, deadline=Duration(seconds=2, nanoseconds=5),
               lifespan=Duration(seconds=7), liveliness=QoSLivelinessPolicy.MANUAL_BY_TOPIC,
               liveliness_lease_duration=Duration(seconds=3)),
]


@pytest.mark.ros
def test_type_hash_and_offered_qos_are_what_the_ros_graph_reports() -> None:
    with ros_node('hash_probe') as (node, _):
        for type_name in TYPE_NAMES:
            for index, profile in enumerate(PROFILES):
                topic = f'/probe_{type_name.replace("/", "_")}_{index}'
                node.create_publisher(message_class(type_name), topic, profile)
                info = graph_publisher_info(node, topic)
                assert info.topic_type == type_name
                assert str(info.topic_type_hash) == type_hash(type_name)
                assert offered_qos(profile) == qos_to_dict(info.qos_profile)


# -- round trip ---------------------------------------------------------------------------------


@pytest.fixture(scope='module')
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[str, Any, int]]]:
    path = tmp_path_factory.mktemp('rec') / 'run.mcap'
    messages = scripted_messages(1200, t0_ns=1_700_000_000_000_000_000)
    rec = record(path, messages, chunk_size=16 * 1024)
    assert rec.error is None
    assert rec.messages_written == len(messages)
    assert rec.path == path
    return path, messages


def test_round_trip_every_field_with_an_independent_reader(
        recorded: tuple[Path, list[tuple[str, Any, int]]]) -> None:
    path, messages = recorded
    summary, decoded = read_independently(path)
    assert len(decoded) == len(messages)
    sequences: dict[str, int] = {}
    for (topic, original, ns), (schema, channel, message, ros_msg) in zip(
            messages, decoded, strict=True):
        assert channel.topic == topic
        assert schema.name == type_name_of(type(original))
        assert message.log_time == ns and message.publish_time == ns
        # rclpy's CDR leaves alignment padding uninitialised: compare decoded, not bytes.
        assert deserialize_message(message.data, type(original)) == original
        assert message.data[:4] == b'\x00\x01\x00\x00'   # CDR little-endian encapsulation
        sequences[topic] = sequences.get(topic, 0) + 1
        assert message.sequence == sequences[topic]
        same_fields(original, ros_msg)
    assert summary is not None
    stats = summary.statistics
    assert stats.message_count == len(messages)
    assert stats.message_start_time == messages[0][2]
    assert stats.message_end_time == messages[-1][2]
    by_topic = {c.topic: c for c in summary.channels.values()}
    assert {t: stats.channel_message_counts[by_topic[t].id] for t in TOPICS} == sequences
    assert stats.chunk_count == len(summary.chunk_indexes) > 1
    for index in summary.chunk_indexes:
        assert index.compression == 'zstd'
        assert index.message_index_offsets and index.message_index_length > 0
    assert stats.metadata_count == 3
    assert sorted(i.name for i in summary.metadata_indexes) == ['pendulum_sim', 'rosbag2',
                                                                 'scene']


def test_indexes_summary_and_crcs_point_at_what_they_describe(
        recorded: tuple[Path, list[tuple[str, Any, int]]]) -> None:
    import struct
    import zlib

    import zstandard
    from mcap.stream_reader import StreamReader

    path, messages = recorded
    assert sum(1 for _ in StreamReader(str(path), validate_crcs=True).records) > len(messages)
    data = path.read_bytes()
    footer = len(data) - 8 - 29
    opcode, _, summary_start, summary_offset_start, summary_crc = struct.unpack_from(
        '<BQQQI', data, footer)
    assert opcode == 0x02
    assert summary_crc == zlib.crc32(data[summary_start:footer + 25])
    groups = {}
    pos = summary_offset_start
    while pos < footer:
        op, length, group_opcode, start, group_length = struct.unpack_from('<BQBQQ', data, pos)
        assert op == 0x0E and (group_length == 0 or data[start] == group_opcode)
        groups[group_opcode] = (start, group_length)
        pos += 9 + length
    assert set(groups) == {0x03, 0x04, 0x0B, 0x08, 0x0A, 0x0D}   # the summary's groups
    indexed = 0
    start, length = groups[0x08]
    pos = start
    while pos < start + length:       # every chunk index record
        op, size, t0, t1, chunk_at, chunk_len, n_offsets = struct.unpack_from(
            '<BQQQQQI', data, pos)
        assert op == 0x08
        offsets = dict(struct.iter_unpack('<HQ', data[pos + 45:pos + 45 + n_offsets]))
        assert data[chunk_at] == 0x06
        assert 9 + struct.unpack_from('<Q', data, chunk_at + 1)[0] == chunk_len
        c_t0, c_t1, raw_size, _crc = struct.unpack_from('<QQQI', data, chunk_at + 9)
        assert (c_t0, c_t1) == (t0, t1)
        (n_comp,) = struct.unpack_from('<I', data, chunk_at + 37)
        assert data[chunk_at + 41:chunk_at + 41 + n_comp] == b'zstd'
        body_at = chunk_at + 41 + n_comp + 8
        body = zstandard.decompress(data[body_at:chunk_at + chunk_len], raw_size)
        for channel_id, index_at in offsets.items():
            op, _, index_channel, n_bytes = struct.unpack_from('<BQHI', data, index_at)
            assert op == 0x07 and index_channel == channel_id
            for log_time, offset in struct.iter_unpack(
                    '<QQ', data[index_at + 15:index_at + 15 + n_bytes]):
                m_op, _, m_channel, _, m_log, m_pub = struct.unpack_from('<BQHIQQ', body, offset)
                assert (m_op, m_channel, m_log, m_pub) == (0x05, channel_id, log_time, log_time)
                assert t0 <= log_time <= t1
                indexed += 1
        pos += 9 + size
    assert indexed == len(messages)


def test_header_schemas_and_channel_metadata(
        recorded: tuple[Path, list[tuple[str, Any, int]]]) -> None:
    path, _ = recorded
    with open(path, 'rb') as stream:
        from mcap.reader import make_reader
        reader = make_reader(stream)
        header = reader.get_header()
        summary = reader.get_summary()
    assert header.profile == 'ros2'
    assert summary is not None
    assert len(summary.schemas) == 4          # the two Float64 topics share one schema
    for channel in summary.channels.values():
        msg_type, qos = TOPICS[channel.topic]
        schema = summary.schemas[channel.schema_id]
        assert schema.name == type_name_of(msg_type)
        assert schema.encoding == 'ros2msg'
        assert schema.data.decode() == ros2msg_schema(schema.name)
        assert channel.message_encoding == 'cdr'
        assert set(channel.metadata) == {'offered_qos_profiles', 'topic_type_hash'}
        assert yaml.safe_load(channel.metadata['offered_qos_profiles']) == [offered_qos(qos)]
        assert channel.metadata['topic_type_hash'] == type_hash(schema.name)
        assert re.fullmatch(r'RIHS01_[0-9a-f]{64}', channel.metadata['topic_type_hash'])


def test_rosbag2_and_scene_metadata_records(
        recorded: tuple[Path, list[tuple[str, Any, int]]]) -> None:
    path, messages = recorded
    with open(path, 'rb') as stream:
        from mcap.reader import make_reader
        records = {m.name: m.metadata for m in make_reader(stream).iter_metadata()}
    assert records['scene'] == SCENE
    assert records['pendulum_sim'] == {'version': '0.1.0'}
    assert set(records['rosbag2']) == {'serialized_metadata'}
    bag = yaml.safe_load(records['rosbag2']['serialized_metadata'])
    start, end = messages[0][2], messages[-1][2]
    counts = {t: sum(1 for m in messages if m[0] == t) for t in TOPICS}
    assert bag['version'] == 9
    assert bag['storage_identifier'] == 'mcap'
    assert bag['ros_distro'] == 'jazzy'
    assert bag['message_count'] == len(messages)
    assert bag['starting_time'] == {'nanoseconds_since_epoch': start}
    assert bag['duration'] == {'nanoseconds': end - start}
    assert bag['relative_file_paths'] == ['run.mcap']
    assert bag['files'] == [{'path': 'run.mcap', 'starting_time': {'nanoseconds_since_epoch':
                             start}, 'duration': {'nanoseconds': end - start},
                             'message_count': len(messages)}]
    assert bag['compression_format'] == '' and bag['compression_mode'] == ''
    listed = {t['topic_metadata']['name']: t for t in bag['topics_with_message_count']}
    assert set(listed) == set(TOPICS)
    for topic, (msg_type, qos) in TOPICS.items():
        entry = listed[topic]
        assert entry['message_count'] == counts[topic]
        assert entry['topic_metadata'] == {
            'name': topic, 'type': type_name_of(msg_type), 'serialization_format': 'cdr',
            'offered_qos_profiles': [offered_qos(qos)],
            'type_description_hash': type_hash(type_name_of(msg_type))}


def test_loader_agrees_with_the_independent_decoder(
        recorded: tuple[Path, list[tuple[str, Any, int]]]) -> None:
    path, messages = recorded
    _, decoded = read_independently(path)
    rec = load(path)
    assert rec.complete and rec.problems == () and rec.profile == 'ros2'
    assert rec.scene == SCENE and rec.metadata['pendulum_sim'] == {'version': '0.1.0'}
    assert {t: i.message_count for t, i in rec.topics.items()} == {
        t: sum(1 for m in messages if m[0] == t) for t in TOPICS}

    def of(topic: str) -> list[tuple[Any, Any]]:
        return [(m, r) for _, c, m, r in decoded if c.topic == topic]

    js = of('/joint_states')
    assert rec.joint_states is not None and rec.joint_states.name == ('pendulum_joint',)
    np.testing.assert_array_equal(rec.joint_states.stamp_ns, [m.log_time for m, _ in js])
    np.testing.assert_array_equal(rec.joint_states.t, [m.log_time * 1e-9 for m, _ in js])
    np.testing.assert_array_equal(rec.joint_states.header_stamp_ns,
                                  [r.header.stamp.sec * 10**9 + r.header.stamp.nanosec
                                   for _, r in js])
    np.testing.assert_array_equal(rec.joint_states.position, [r.position[0] for _, r in js])
    np.testing.assert_array_equal(rec.joint_states.velocity, [r.velocity[0] for _, r in js])
    np.testing.assert_array_equal(rec.joint_states.effort,
                                  [r.effort[0] if len(r.effort) else np.nan for _, r in js])
    assert rec.energy is not None and rec.effort_command is not None
    np.testing.assert_array_equal(rec.energy.value, [r.data for _, r in of('/energy')])
    np.testing.assert_array_equal(rec.effort_command.value,
                                  [r.data for _, r in of('/effort_command')])
    np.testing.assert_array_equal(rec.effort_command.stamp_ns,
                                  [m.log_time for m, _ in of('/effort_command')])
    diags = of('/diagnostics')
    assert rec.diagnostics is not None
    np.testing.assert_array_equal(
        rec.diagnostics.values['pendulum: loop/overruns'],
        [float(r.status[0].values[1].value) for _, r in diags])
    events = of('/parameter_events')
    assert [e.changed_parameters[0].value.double_value for _, e in rec.parameter_events] == [
        r.changed_parameters[0].value.double_value for _, r in events]


def test_a_chunk_never_holds_more_than_chunk_interval_of_data(tmp_path: Path) -> None:
    # Written in a burst (as in lockstep, far faster than real time): chunks end by log time.
    path = tmp_path / 'burst.mcap'
    record(path, scripted_messages(3000), chunk_interval=0.25)
    with open(path, 'rb') as stream:
        from mcap.reader import make_reader
        summary = make_reader(stream).get_summary()
    assert summary is not None
    spans = [c.message_end_time - c.message_start_time for c in summary.chunk_indexes]
    assert len(spans) >= 12 and max(spans) <= 250_000_000


def test_a_stalled_writer_never_blocks_the_loop_and_loses_nothing(tmp_path: Path) -> None:
    import threading

    from recording_support import joint_state
    path = tmp_path / 'stalled.mcap'
    count = 30_000              # about 4 MB of frames: far more than the pipe holds
    rec = McapRecorder(path)
    rec.open()
    rec.add_channel('/joint_states', *TOPICS['/joint_states'])
    messages = [joint_state(k, k * 1_000_000) for k in range(count)]
    pid = rec.writer_pid
    assert pid is not None
    os.kill(pid, signal.SIGSTOP)
    try:
        loop = threading.Thread(target=lambda: [
            rec.write('/joint_states', m, k * 1_000_000) for k, m in enumerate(messages)])
        loop.start()
        loop.join(timeout=60)
        assert not loop.is_alive(), 'write() blocked on the stalled writer'
    finally:
        os.kill(pid, signal.SIGCONT)
    rec.close()
    assert rec.error is None and rec.messages_written == count
    loaded = load(path)
    assert loaded.joint_states is not None
    np.testing.assert_array_equal(loaded.joint_states.position,
                                  [m.position[0] for m in messages])


# -- creating files: existing, unwritable, folders, misuse --------------------------------------


def test_an_existing_recording_is_never_overwritten_unless_asked(tmp_path: Path) -> None:
    path = tmp_path / 'run.mcap'
    path.write_bytes(b'precious')
    with pytest.raises(RecorderError, match=re.escape(
            f'recording {path} already exists; pass overwrite=True to replace it')):
        McapRecorder(path).open()
    assert path.read_bytes() == b'precious'
    record(path, scripted_messages(10), overwrite=True)
    assert load(path).joint_states is not None


def test_unwritable_paths_give_clear_errors(tmp_path: Path) -> None:
    afile = tmp_path / 'file.txt'
    afile.write_text('x')
    for path, reason in [(afile / 'run.mcap', 'Not a directory'),
                         (tmp_path / 'missing' / 'run.mcap', 'No such file or directory')]:
        with pytest.raises(RecorderError, match=re.escape(
                f'cannot create recording {path}: {reason}')):
            McapRecorder(path).open()
    with pytest.raises(RecorderError, match=re.escape(
            "recording path must be a '.mcap' file or an existing folder, got "
            f"'{tmp_path / 'run.txt'}'")):
        McapRecorder(tmp_path / 'run.txt')


def test_a_folder_gets_timestamped_recordings(tmp_path: Path) -> None:
    first = record(tmp_path, scripted_messages(5)).path
    second = record(tmp_path, scripted_messages(5)).path
    assert first != second and first.parent == second.parent == tmp_path
    for path in (first, second):
        assert re.fullmatch(
            rf'pendulum_sim_\d{{4}}_\d\d_\d\d-\d\d_\d\d_\d\d_{os.getpid()}_[0-9a-f]{{6}}\.mcap',
            path.name)
        assert load(path).complete


def test_misuse_is_refused_with_clear_errors(tmp_path: Path) -> None:
    path = tmp_path / 'run.mcap'
    rec = McapRecorder(path)
    rec.add_channel('/a', TOPICS['/energy'][0])
    with pytest.raises(RecorderError, match=re.escape(f'recording {path} is new, not open')):
        rec.write('/a', TOPICS['/energy'][0](data=1.0), 0)
    with pytest.raises(RecorderError, match=r'^topic /a already has a channel$'):
        rec.add_channel('/a', TOPICS['/energy'][0])
    rec.open()
    with pytest.raises(RecorderError, match=re.escape(f'recording {path} is already open')):
        rec.open()
    with pytest.raises(RecorderError,
                       match=r'^topic /b has no channel; call add_channel first$'):
        rec.write('/b', TOPICS['/energy'][0](data=1.0), 0)
    for stamp in (-1, 2**64, 1.5):
        with pytest.raises(RecorderError, match=re.escape(
                'a message stamp must be an integer number of nanoseconds in [0, 2**64), got '
                f'{stamp!r}')):
            rec.write('/a', TOPICS['/energy'][0](data=1.0), stamp)  # type: ignore[arg-type]
    rec.write('/a', TOPICS['/energy'][0](data=2.0), 5)
    rec.close()
    rec.close()
    with pytest.raises(RecorderError, match=re.escape(f'recording {path} is closed, not open')):
        rec.write('/a', TOPICS['/energy'][0](data=1.0), 0)
    with pytest.raises(RecorderError, match=re.escape(f'recording {path} is closed')):
        rec.add_channel('/c', TOPICS['/energy'][0])
    assert rec.messages_written == 1 and load(path).topics['/a'].message_count == 1
    with pytest.raises(RecorderError, match=re.escape(
            "metadata record 'scene' must map str to str, got 'gamma': 1.0")):
        McapRecorder(tmp_path / 'x.mcap', metadata={'scene': {'gamma': 1.0}})  # type: ignore
    for interval in (0.0, math.inf, math.nan):
        with pytest.raises(RecorderError, match=re.escape(
                f'chunk_interval must be a finite number > 0 s, got {interval}')):
            McapRecorder(tmp_path / 'x.mcap', chunk_interval=interval)


# -- damaged files ------------------------------------------------------------------------------


@pytest.fixture(scope='module')
def many_chunks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp('chunks') / 'run.mcap'
    record(path, scripted_messages(3000), chunk_size=8 * 1024)
    return path


@pytest.mark.parametrize('fraction', [0.2, 0.5, 0.9, 'summary'])
def test_a_truncated_file_loads_what_is_readable(many_chunks: Path, tmp_path: Path,
                                                 fraction: float | str) -> None:
    full = load(many_chunks)
    data = many_chunks.read_bytes()
    # The footer (opcode, length, summary_start, ...) is the last 29 bytes before the magic.
    data_end = int.from_bytes(data[-37 + 9:-37 + 17], 'little')
    assert data[-37] == 0x02 and data[data_end - 13] == 0x0F   # footer; data end record
    cut = tmp_path / 'cut.mcap'
    size = data_end + 40 if fraction == 'summary' else int(data_end * float(fraction))
    cut.write_bytes(data[:size])
    with pytest.warns(TruncatedRecordingWarning, match=re.escape(f'{cut} is truncated: ')):
        part = load(cut)
    assert not part.complete and len(part.problems) == 1
    assert part.joint_states is not None and full.joint_states is not None
    n = len(part.joint_states.t)
    if fraction == 'summary':   # every chunk is there, only the summary is cut
        assert n == len(full.joint_states.t)
    else:
        assert 0 < n < len(full.joint_states.t)
    np.testing.assert_array_equal(part.joint_states.position, full.joint_states.position[:n])
    np.testing.assert_array_equal(part.joint_states.stamp_ns, full.joint_states.stamp_ns[:n])
    assert part.scene == SCENE


def test_not_mcap_other_profile_and_corrupted_files_raise(many_chunks: Path,
                                                          tmp_path: Path) -> None:
    for name, content in [('text.mcap', b'hello, not an mcap file\n'), ('empty.mcap', b'')]:
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(RecorderError, match=re.escape(
                f'{path} is not an MCAP file (it does not start with the MCAP magic bytes)')):
            load(path)
    ros1 = tmp_path / 'ros1.mcap'
    with open(ros1, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros1', library='test')
        writer.finish()
    with pytest.raises(RecorderError, match=re.escape(
            f"{ros1} has MCAP profile 'ros1', expected 'ros2'")):
        load(ros1)
    with open(many_chunks, 'rb') as stream:
        from mcap.reader import make_reader
        summary = make_reader(stream).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[1]
    data = bytearray(many_chunks.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle] ^= 0xFF
    broken = tmp_path / 'broken.mcap'
    broken.write_bytes(bytes(data))
    with pytest.raises(RecorderError, match=re.escape(
            f'{broken} is corrupted: the chunk record at byte {chunk.chunk_start_offset} '
            'cannot be read (')):
        load(broken)


# -- the recording process dies or its disk fills up --------------------------------------------

RECORDING_SCRIPT = textwrap.dedent("""
    import json, resource, signal, sys, time
    from pendulum_sim.recording import McapRecorder
    from recording_support import TOPICS, joint_state
    path, limit = sys.argv[1], int(sys.argv[2])
    if limit:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    msg_type, qos = TOPICS['/joint_states']
    rec = McapRecorder(path, chunk_interval=0.05, compression='none' if limit else 'zstd')
    rec.open()
    rec.add_channel('/joint_states', msg_type, qos)
    print('ready', flush=True)
    report = len(sys.argv) > 3   # print each k once its write returned
    k, after_error, start = 0, 0, time.monotonic()
    while time.monotonic() - start < 20.0:
        now = time.time_ns()
        rec.write('/joint_states', joint_state(k, now), now)
        if report:
            print(k, flush=True)
        k += 1
        if rec.error is not None:
            after_error += 1
            if after_error == 500:
                break
        time.sleep(0.001)
    rec.close()
    print(json.dumps({'error': str(rec.error), 'steps': k, 'after_error': after_error,
                      'written': rec.messages_written}), flush=True)
""")


def start_recording(path: Path, limit: int = 0, report: bool = False) -> subprocess.Popen[str]:
    """Start a process recording at 1 kHz in a session of its own (it and its writer).

    With ``report`` it prints each message's k once ``write()`` returned.
    """
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(Path(__file__).resolve().parents[1] / 'support'), os.environ.get('PYTHONPATH', '')]))
    proc = subprocess.Popen([sys.executable, '-c', RECORDING_SCRIPT, str(path), str(limit),
                             *(['report'] if report else [])],
                            stdout=subprocess.PIPE, text=True, env=env, start_new_session=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == 'ready'
    return proc


def assert_readable_prefix(rec: Recording) -> int:
    """Assert the file holds messages k = 0, 1, ... in order, none missing; return how many."""
    assert rec.joint_states is not None
    n = len(rec.joint_states.t)
    assert n > 0
    np.testing.assert_array_equal(rec.joint_states.position,
                                  [0.5 * k - 1.0 / (k + 1) for k in range(n)])
    return n


@pytest.mark.slow
def test_sigkill_of_process_and_writer_loses_only_what_was_not_yet_written_out(
        tmp_path: Path) -> None:
    """Killing both loses at most the open chunk and the pipe: never a message on disk."""
    path = tmp_path / 'killed.mcap'
    proc = start_recording(path)
    deadline = time.monotonic() + 30.0
    on_disk = 0
    while on_disk < 1000 and time.monotonic() < deadline:
        assert proc.poll() is None
        on_disk = joint_states_on_disk(path)
        time.sleep(0.05)
    assert on_disk >= 1000, f'{path} held {on_disk} messages after 30 s'
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=10)
    with pytest.warns(TruncatedRecordingWarning, match='is truncated'):
        rec = load(path)
    assert not rec.complete
    assert assert_readable_prefix(rec) >= on_disk


@pytest.mark.slow
def test_sigkill_of_the_recording_process_alone_loses_no_message_it_wrote(
        tmp_path: Path) -> None:
    """The writer process drains the pipe and finalises the file: every write() survives, and
    the file ends with the stop event at the last message (the recording was never closed)."""
    path = tmp_path / 'killed.mcap'
    proc = start_recording(path, report=True)
    assert proc.stdout is not None
    last = -1
    while last < 2000:
        line = proc.stdout.readline()
        assert line, 'the recording process ended before it was killed'
        last = int(line)
    proc.send_signal(signal.SIGKILL)   # k = 0..last were written before this
    proc.communicate(timeout=10)
    deadline = time.monotonic() + 10.0   # the writer process finishes the file on its own
    while time.monotonic() < deadline and path.read_bytes()[-8:] != MAGIC:
        time.sleep(0.05)
    with pytest.warns(TruncatedRecordingWarning, match='without CLOSE'):
        rec = load(path)
    n = assert_readable_prefix(rec)
    assert n >= last + 1
    assert rec.joint_states is not None
    end = int(rec.joint_states.stamp_ns[-1])
    assert not rec.complete and rec.stopped_ns == end
    assert rec.problems == (
        f'{path} was cut short at {end} ns (t = {end / 1e9:.9g} s): the writer process saw its '
        f'input end without CLOSE (the recording process was killed, or closed the recording '
        f'while the writer process was stopped, with frames not handed over) after the message '
        f'stamped {end} ns; nothing later is recorded',)


@pytest.mark.slow
def test_a_full_disk_stops_the_recording_only(tmp_path: Path) -> None:
    path = tmp_path / 'full.mcap'
    limit = 64 * 1024
    proc = start_recording(path, limit=limit)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0
    report = json.loads(out)
    assert report['error'] == f'recording {path} stopped: File too large'
    assert report['after_error'] == 500          # the loop went on; writes were dropped
    assert path.stat().st_size <= limit
    with pytest.warns(TruncatedRecordingWarning):
        rec = load(path)
    assert rec.joint_states is not None
    n = len(rec.joint_states.t)
    # All reported as written is there; a chunk may be complete though its index was cut.
    assert 0 < report['written'] <= n <= report['steps'] - report['after_error']
    np.testing.assert_array_equal(rec.joint_states.position,
                                  [0.5 * k - 1.0 / (k + 1) for k in range(n)])


def test_loader_reports_unknown_topics(recorded: tuple[Path, list[Any]]) -> None:
    path, _ = recorded
    rec = load(path)
    with pytest.raises(RecorderError, match=re.escape(
            f'{path} has no topic /nope; it has /diagnostics, /effort_command, /energy, '
            '/joint_states, /parameter_events')):
        rec.messages('/nope')
    assert len(rec.messages('/energy')) == rec.topics['/energy'].message_count

