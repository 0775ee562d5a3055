"""Recording files as an adversary meets them (issue 11, items 7-12): every case from outside.

Recorders, loaders and the replayer run in their own processes on real files: concurrent
recorders in one folder, planted symbolic links, folders that cannot be entered, type names that
name arbitrary Python modules, a chunk that inflates a 2 kB file to 64 MiB, and non-finite
command-line numbers.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
import sys
import textwrap
import time
import zlib
from pathlib import Path
from typing import Any

import pytest
import zstandard
from mcap.writer import CompressionType, Writer
from rclpy.serialization import serialize_message
from recording_support import read_independently
from std_msgs.msg import Float64

from pendulum_sim.recording.reader import MAX_CHUNK_BYTES
from pendulum_sim.recording.schemas import ros2msg_schema

TEST_DIR = Path(__file__).resolve().parents[1] / 'support'
NODE = Path(sys.executable).parent / 'pendulum_node'
REPLAY = Path(sys.executable).parent / 'pendulum_replay'
ZEN = 'Beautiful is better than ugly'
# Root passes every permission check; without these capabilities it meets them like anyone.
NO_OVERRIDE = (['setpriv', '--bounding-set=-dac_override,-dac_read_search']
               if os.geteuid() == 0 else [])

# Records COUNT Float64 messages (value MARKER + k) on /energy; opens after a line on stdin, so
# that several such processes open at the same moment. Prints what happened as JSON.
RECORDER = textwrap.dedent("""
    import json, sys
    from std_msgs.msg import Float64
    from pendulum_sim.recording import McapRecorder, RecorderError
    path, overwrite, count, marker = sys.argv[1], sys.argv[2] == '1', int(sys.argv[3]), float(
        sys.argv[4])
    try:
        rec = McapRecorder(path, overwrite=overwrite)
        print('ready', flush=True)
        sys.stdin.readline()
        rec.open()
        rec.add_channel('/energy', Float64, 10)
        for k in range(count):
            rec.write('/energy', Float64(data=marker + k), k * 1_000_000)
        if len(sys.argv) > 5:   # hold the file open until told to close it
            print(json.dumps({'open': str(rec.path)}), flush=True)
            sys.stdin.readline()
        rec.close()
        print(json.dumps({'path': str(rec.path), 'error': None if rec.error is None
                          else str(rec.error)}), flush=True)
    except RecorderError as exc:
        print('ready', flush=True)
        print(json.dumps({'refused': str(exc)}), flush=True)
""")

LOADER = textwrap.dedent("""
    import json, resource, sys, warnings
    from pendulum_sim.recording import RecorderError, load
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            rec = load(sys.argv[1])
            out = {'topics': sorted(rec.topics),
                   'energy': None if rec.energy is None else rec.energy.value.tolist()}
        except RecorderError as exc:
            out = {'error': str(exc)}
    out['warnings'] = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    out['imported'] = sorted(m for m in ('this', 'os.path.join', 'foo_msgs') if m in sys.modules)
    out['maxrss_kb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps(out))
""")


def env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(TEST_DIR), os.environ.get('PYTHONPATH', '')]))


def start_recorder(path: Path, overwrite: bool, count: int, marker: float,
                   hold: bool = False, prefix: list[str] | None = None) -> subprocess.Popen[str]:
    cmd = [*(prefix or []), sys.executable, '-c', RECORDER, str(path), '1' if overwrite else '0',
           str(count), str(marker), *(['hold'] if hold else [])]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env())
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == 'ready', proc.communicate()
    return proc


def go(proc: subprocess.Popen[str]) -> None:
    assert proc.stdin is not None
    try:
        proc.stdin.write('\n')
        proc.stdin.flush()
    except BrokenPipeError:
        pass   # it refused already and is gone; finish() reads why


def finish(proc: subprocess.Popen[str]) -> dict[str, Any]:
    # Read through the same buffered stream as start_recorder's readline, which may hold the
    # last line already.
    assert proc.stdin is not None and proc.stdout is not None and proc.stderr is not None
    try:
        proc.stdin.close()
    except BrokenPipeError:
        pass
    out, err = proc.stdout.read(), proc.stderr.read()
    proc.wait(timeout=60)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err, err
    result: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    return result


def record_once(path: Path, overwrite: bool, marker: float = 0.0,
                prefix: list[str] | None = None) -> dict[str, Any]:
    proc = start_recorder(path, overwrite, 10, marker, prefix=prefix)
    go(proc)
    return finish(proc)


def load_elsewhere(path: Path) -> dict[str, Any]:
    result = subprocess.run([sys.executable, '-c', LOADER, str(path)], capture_output=True,
                            text=True, env=env(), timeout=120)
    assert result.returncode == 0, result.stderr
    assert ZEN not in result.stdout and 'Traceback' not in result.stderr
    out: dict[str, Any] = json.loads(result.stdout)
    return out


def energy_values(path: Path) -> list[float]:
    _, decoded = read_independently(path)
    return [m.data for _, channel, _, m in decoded if channel.topic == '/energy']


# -- 7. concurrent recorders, one folder -----------------------------------------------------


def test_concurrent_recorders_in_one_folder_each_get_their_own_complete_file(
        tmp_path: Path) -> None:
    procs = [start_recorder(tmp_path, True, 300, 1000.0 * i) for i in range(6)]
    for proc in procs:   # every name is chosen already; now all open at once
        go(proc)
    results = [finish(proc) for proc in procs]
    assert all(r['error'] is None for r in results), results
    paths = [Path(r['path']) for r in results]
    assert len(set(paths)) == 6
    assert sorted(tmp_path.iterdir()) == sorted(paths)
    for i, path in enumerate(paths):
        assert energy_values(path) == [1000.0 * i + k for k in range(300)]


def test_a_recording_being_written_is_never_replaced(tmp_path: Path) -> None:
    path = tmp_path / 'run.mcap'
    first = start_recorder(path, True, 50, 1.0, hold=True)
    go(first)
    assert first.stdout is not None
    assert json.loads(first.stdout.readline()) == {'open': str(path)}
    second = record_once(path, overwrite=True, marker=2.0)
    assert second == {'refused': f'cannot replace recording {path}: another recorder is '
                                 'writing it'}
    go(first)
    assert finish(first) == {'path': str(path), 'error': None}
    assert energy_values(path) == [1.0 + k for k in range(50)]
    # Once closed, it may be replaced (on purpose, with overwrite).
    assert record_once(path, overwrite=True, marker=3.0) == {'path': str(path), 'error': None}
    assert energy_values(path) == [3.0 + k for k in range(10)]


@pytest.mark.ros
@pytest.mark.slow
def test_two_nodes_recording_into_one_folder_with_overwrite_get_two_files(
        tmp_path: Path) -> None:
    cmd = [str(NODE), '--ros-args', '-p', f'recording.path:={tmp_path}',
           '-p', 'recording.overwrite:=true', '-p', 'status_line:=false']
    nodes = [subprocess.Popen([*cmd, '-r', f'__ns:=/rec{i}'], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, env=os.environ)
             for i in range(2)]
    logs = []
    for node in nodes:   # both run until they have recorded a few chunks
        assert node.stdout is not None
        line = ''
        while 'recording to' not in line:
            line = node.stdout.readline()
            assert line, node.communicate()
        logs.append(line)
    files = [Path(log.split('recording to ', 1)[1].strip()) for log in logs]
    deadline = time.monotonic() + 30.0
    for path in files:
        while not path.exists() or path.stat().st_size < 20_000:
            assert all(node.poll() is None for node in nodes)
            assert time.monotonic() < deadline
            time.sleep(0.05)
    for node in nodes:
        node.send_signal(2)
    for node in nodes:
        node.communicate(timeout=20)
        assert node.returncode == 0
    assert files[0] != files[1] and sorted(tmp_path.iterdir()) == sorted(files)
    for path in files:
        summary, decoded = read_independently(path)
        assert summary is not None and len(decoded) > 100


# -- 8. symbolic links ---------------------------------------------------------------------------


@pytest.mark.parametrize('overwrite', [False, True])
def test_a_planted_symlink_is_never_followed(tmp_path: Path, overwrite: bool) -> None:
    victim = tmp_path / 'victim.txt'
    victim.write_text('precious')
    path = tmp_path / 'run.mcap'
    path.symlink_to(victim)
    result = record_once(path, overwrite=overwrite)
    reason = ('cannot replace recording {p}: it is a symbolic link; a recording is never '
              'written through one') if overwrite else (
        'recording {p} is a symbolic link; a recording is never written through one')
    assert result == {'refused': reason.format(p=path)}
    assert victim.read_text() == 'precious' and path.is_symlink()
    dangling = tmp_path / 'dangling.mcap'
    dangling.symlink_to(tmp_path / 'created_through_the_link.mcap')
    result = record_once(dangling, overwrite=overwrite)
    assert 'is a symbolic link' in result['refused']
    assert not (tmp_path / 'created_through_the_link.mcap').exists()


def test_a_link_at_the_chosen_name_makes_the_recorder_choose_another(tmp_path: Path) -> None:
    victim = tmp_path.parent / f'{tmp_path.name}_victim2.txt'
    victim.write_text('precious')
    script = textwrap.dedent("""
        import os, sys
        from std_msgs.msg import Float64
        from pendulum_sim.recording import McapRecorder
        rec = McapRecorder(sys.argv[1], overwrite=True)
        planted = rec.path
        os.symlink(sys.argv[2], planted)   # the attacker wins the race for the name
        with rec:
            rec.add_channel('/energy', Float64, 10)
            rec.write('/energy', Float64(data=7.0), 0)
        print(planted, rec.path)
    """)
    out = subprocess.run([sys.executable, '-c', script, str(tmp_path), str(victim)],
                         capture_output=True, text=True, env=env(), check=True).stdout.split()
    planted, used = Path(out[0]), Path(out[1])
    assert planted != used and planted.is_symlink() and not used.is_symlink()
    assert victim.read_text() == 'precious'
    assert energy_values(used) == [7.0]


# -- 9. folders that cannot be entered -----------------------------------------------------------


@pytest.fixture
def locked(tmp_path: Path) -> Any:
    if os.geteuid() == 0 and shutil.which('setpriv') is None:
        pytest.skip('running as root without setpriv: permissions cannot be met')
    folder = tmp_path / 'locked'
    (folder / 'inside').mkdir(parents=True)
    folder.chmod(0)
    yield folder
    folder.chmod(0o700)


@pytest.mark.parametrize('name', ['inside', 'inside/run.mcap'])
def test_a_folder_that_cannot_be_entered_is_a_clean_error(locked: Path, name: str) -> None:
    path = locked / name
    result = record_once(path, overwrite=True, prefix=NO_OVERRIDE)
    what = ('cannot use recording folder' if name == 'inside' else 'cannot create recording')
    assert result == {'refused': f'{what} {path}: Permission denied'}


@pytest.mark.ros
@pytest.mark.parametrize('name', ['inside', 'inside/run.mcap'])
def test_the_node_exits_2_with_the_reason_when_it_cannot_record(locked: Path,
                                                                 name: str) -> None:
    path = locked / name
    result = subprocess.run(
        [*NO_OVERRIDE, str(NODE), '--ros-args', '-p', f'recording.path:={path}',
         '-p', 'status_line:=false'], capture_output=True, text=True, env=os.environ,
        timeout=60)
    what = ('cannot use recording folder' if name == 'inside' else 'cannot create recording')
    assert result.returncode == 2, result.stderr
    assert f'pendulum_node: {what} {path}: Permission denied' in result.stderr
    assert 'Traceback' not in result.stderr + result.stdout


# -- 10. type names from a file ------------------------------------------------------------------


HOSTILE_TYPES = {'/zen': 'this/msg/Zen', '/join': 'os/path/join', '/bar': 'foo_msgs/msg/Bar',
                 '/nope': 'std_msgs/msg/Nope'}


@pytest.fixture
def hostile_types(tmp_path: Path) -> Path:
    path = tmp_path / 'hostile.mcap'
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='test')
        channels = [writer.register_channel(topic, 'cdr', writer.register_schema(
            type_name, 'ros2msg', b'float64 x')) for topic, type_name in HOSTILE_TYPES.items()]
        energy = writer.register_channel('/energy', 'cdr', writer.register_schema(
            'std_msgs/msg/Float64', 'ros2msg', ros2msg_schema('std_msgs/msg/Float64').encode()))
        for k in range(20):
            for channel in channels:
                writer.add_message(channel, log_time=k * 1000, data=b'\0\1\0\0' + bytes(8),
                                   publish_time=k * 1000)
            writer.add_message(energy, log_time=k * 1000,
                               data=serialize_message(Float64(data=float(k))),
                               publish_time=k * 1000)
        writer.finish()
    return path


def test_load_imports_nothing_a_file_names(hostile_types: Path) -> None:
    out = load_elsewhere(hostile_types)
    assert out['imported'] == []
    assert out['topics'] == ['/energy'] and out['energy'] == [float(k) for k in range(20)]
    refused = "{t}: skipping topic {topic}: message type '{type}' is refused: "
    assert out['warnings'] == [
        refused.format(t=hostile_types, topic='/zen', type='this/msg/Zen')
        + 'this is not one of the allowed interface packages (std_msgs, sensor_msgs, ...: '
          'pendulum_sim.recording.schemas.INTERFACE_PACKAGES)',
        refused.format(t=hostile_types, topic='/join', type='os/path/join')
        + "it is not a name of the form 'pkg/msg/Type'",
        refused.format(t=hostile_types, topic='/bar', type='foo_msgs/msg/Bar')
        + 'foo_msgs is not one of the allowed interface packages (std_msgs, sensor_msgs, ...: '
          'pendulum_sim.recording.schemas.INTERFACE_PACKAGES)',
        f'{hostile_types}: skipping topic /nope: unknown message type std_msgs/msg/Nope: no '
        f'.msg file for std_msgs/msg/Nope in any share directory (AMENT_PREFIX_PATH or '
        f'{sys.prefix})',
    ]


@pytest.mark.ros
def test_replay_imports_nothing_a_file_names(hostile_types: Path) -> None:
    result = subprocess.run([str(REPLAY), str(hostile_types), '--rate', '100'],
                            capture_output=True, text=True, env=os.environ, timeout=60)
    assert result.returncode == 0, result.stderr
    assert ZEN not in result.stdout + result.stderr and 'Traceback' not in result.stderr
    assert re.findall(r'^pendulum_replay: warning: skipping (\S+): ', result.stderr,
                      re.MULTILINE) == ['/zen', '/join', '/bar', '/nope']
    assert result.stderr.rstrip().endswith('20/20 messages')


# -- 11. a chunk that inflates far beyond its file -----------------------------------------------


def bomb(path: Path, declared: int) -> int:
    """Write an MCAP whose one chunk inflates to 64 MiB; return the chunk's byte offset."""
    inflated = 64 << 20
    payload = bytearray(inflated)   # message records of 64 MiB, zeros inside
    record_length = inflated - 9
    struct.pack_into('<BQHIQQ', payload, 0, 0x05, record_length, 1, 0, 0, 0)
    compressed = zstandard.ZstdCompressor(level=3).compress(bytes(payload))
    with open(path, 'wb') as stream:
        writer = Writer(stream, compression=CompressionType.NONE, use_chunking=False)
        writer.start(profile='ros2', library='test')
        writer.register_channel('/energy', 'cdr', writer.register_schema(
            'std_msgs/msg/Float64', 'ros2msg', b'float64 data'))
        offset = stream.tell()
        body = (struct.pack('<QQQI', 0, 0, declared, zlib.crc32(bytes(payload)))
                + struct.pack('<I', 4) + b'zstd' + struct.pack('<Q', len(compressed))
                + compressed)
        stream.write(struct.pack('<BQ', 0x06, len(body)) + body)
        writer.finish()
    return offset


@pytest.mark.parametrize('declared', [64 << 20, 1000])
def test_a_chunk_bomb_is_refused_before_it_inflates(tmp_path: Path, declared: int) -> None:
    path = tmp_path / 'bomb.mcap'
    offset = bomb(path, declared)
    assert path.stat().st_size < 4096
    out = load_elsewhere(path)
    reason = (f'it declares {64 << 20} bytes uncompressed, more than the {MAX_CHUNK_BYTES} '
              f'bytes allowed' if declared > MAX_CHUNK_BYTES
              else f'it inflates to more than the {declared} bytes it declares')
    assert out['error'] == (f'{path} is corrupted: the chunk record at byte {offset} cannot be '
                            f'read ({reason})')
    # Nothing near 64 MiB was ever allocated: the peak is that of loading a small good file.
    good = tmp_path / 'good.mcap'
    assert record_once(good, overwrite=False)['error'] is None
    baseline = load_elsewhere(good)
    assert baseline['energy'] == [float(k) for k in range(10)]
    assert out['maxrss_kb'] < baseline['maxrss_kb'] + 16 * 1024


def test_chunk_decompression_never_produces_more_than_declared() -> None:
    from pendulum_sim.recording.reader import inflate
    data = bytes(1 << 20)
    for compression, packed in [('zstd', zstandard.ZstdCompressor().compress(data)),
                                ('', data)]:
        assert inflate(compression, packed, len(data)) == data
        with pytest.raises(ValueError, match='more than the 100 bytes it declares'):
            inflate(compression, packed, 100)
        with pytest.raises(ValueError, match=f'inflates to {len(data)} bytes, not the'):
            inflate(compression, packed, len(data) + 1)
