"""Record ROS 2 messages to an MCAP file that rosbag2 (Jazzy) and Foxglove open as their own.

The real-time loop calls :meth:`McapRecorder.write`, which serializes the message (rclpy's CDR,
with its encapsulation header) and hands the bytes to a writer *process*
(:mod:`pendulum_sim.recording.sink`) through a non-blocking pipe: one ``write`` system call, no
lock, no thread to wake. The writer process builds the chunks, compresses them and writes them
to disk; being another process, it never holds the GIL the loop needs. A chunk is closed at the
latest ``chunk_interval`` seconds (wall clock) after its first message, or once it spans that
much log time, so if both processes are killed at once at most that much is lost; if only the
recording process dies, the writer process sees its input end and finalises the file, ending
it with a stop event (below) since the recording was not closed.
:meth:`McapRecorder.close` has the writer add the ``rosbag2`` metadata, the summary (schemas,
channels, statistics, chunk, metadata and summary-offset indexes) and the footer. A write error
(full disk, file size limit) stops the recording only: it shows in :attr:`McapRecorder.error`,
further writes are dropped, and the chunks already written stay readable.

What the writer process has not taken yet waits in a backlog here, whole frames only. When a
frame would take it beyond ``max_backlog`` bytes (the writer process fell that far behind), the
recording stops there: that message and every later one are dropped whole, and a stop event
(:data:`~pendulum_sim.recording.events.STOPPED_TOPIC`, its log time the stamp of the first
message left out, its text why) goes behind the backlog, which is still handed over; so the file
holds every message written before the stop, intact, then says it was cut short, and
:func:`~pendulum_sim.recording.load` reports it.

The file is created exclusively (``O_CREAT | O_EXCL | O_NOFOLLOW``) and ``flock``-ed while it
is written; in a folder its name (:func:`generated_name`) is unique per process. Every
file-system error is a :class:`RecorderError` naming the path and the reason.
:meth:`McapRecorder.write_reset` records a reset as an event in write order
(:data:`~pendulum_sim.recording.events.RESET_TOPIC`).
"""
from __future__ import annotations

import errno
import fcntl
import json
import math
import os
import secrets
import select
import stat
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Final, NoReturn

import mcap
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from pendulum_sim import __version__
from pendulum_sim.recording import sink
from pendulum_sim.recording.errors import RecorderError
from pendulum_sim.recording.events import RESET_TOPIC, STOPPED_TOPIC
from pendulum_sim.recording.rosbag2 import offered_qos, qos_profiles_yaml
from pendulum_sim.recording.schemas import ros2msg_schema, type_hash, type_name_of

LIBRARY: Final = f'pendulum_sim {__version__}; mcap-python {mcap.__version__}'
PIPE_SIZE: Final = 1 << 20          # bytes the pipe holds while the writer is busy
# At most this long for a running writer process to finish the file at close (a stopped one,
# SIGSTOP, is not waited for).
CLOSE_TIMEOUT = 10.0
MAX_BACKLOG: Final = 64 << 20       # bytes kept here beyond that before giving up
_F_SETPIPE_SZ: Final = getattr(fcntl, 'F_SETPIPE_SZ', 1031)
_CREATE: Final = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
_NAME_TRIES: Final = 16
RESET_QOS: Final = QoSProfile(depth=10)
STOPPED_QOS: Final = QoSProfile(depth=1)


@dataclass(frozen=True)
class _Channel:
    id: int
    spec: dict[str, Any]


def generated_name() -> str:
    """Return a recording name unique to this process: date-time, process id, random letters.

    Two processes recording into one folder in the same second get different names (their
    process ids differ), and so does one process recording twice (the random part); the file is
    then created exclusively all the same, so a clash can never make two writers share a file.
    """
    stamp = time.strftime('%Y_%m_%d-%H_%M_%S')
    return f'pendulum_sim_{stamp}_{os.getpid()}_{secrets.token_hex(3)}.mcap'


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _size(count: int) -> str:
    """Return a byte count as people read it: ``'64 MiB'``, ``'1000 bytes'``."""
    return f'{count >> 20} MiB' if count % (1 << 20) == 0 else f'{count} bytes'


class McapRecorder:
    """Record messages of several topics to one MCAP file, written by a separate process.

    Parameters
    ----------
    path
        A ``.mcap`` file, or an existing folder in which a file named by
        :func:`generated_name` (unique to the process) is created.
    overwrite
        Replace an existing file; without it an existing recording is never touched. Files are
        always created exclusively, never through a symbolic link, and a recording another
        recorder is writing is never replaced (see :meth:`_create_file`).
    metadata
        Metadata records to write at the start, ``{record name: {key: value}}`` (strings).
    chunk_interval
        Close a chunk at the latest this many seconds (wall clock) after its first message, or
        once it holds this many seconds of data (log time), whichever comes first.
    chunk_size
        Close a chunk when its uncompressed size exceeds this many bytes.
    compression
        Chunk compression: ``'zstd'``, ``'lz4'`` or ``'none'``.
    max_backlog
        Bytes kept here for a writer process that falls behind (beyond what the pipe holds);
        a message that would exceed it stops the recording (see the module docstring).
    """

    def __init__(self, path: str | Path, overwrite: bool = False,
                 metadata: dict[str, dict[str, str]] | None = None, *,
                 chunk_interval: float = 0.25, chunk_size: int = 1024 * 1024,
                 compression: str = 'zstd', max_backlog: int = MAX_BACKLOG) -> None:
        requested = Path(path)
        self._folder = requested.suffix != '.mcap'
        if self._folder:
            try:
                is_folder = stat.S_ISDIR(os.stat(requested).st_mode)
            except (FileNotFoundError, NotADirectoryError):
                is_folder = False
            except OSError as exc:
                raise RecorderError(f'cannot use recording folder {requested}: '
                                    f'{_reason(exc)}') from exc
            if not is_folder:
                raise RecorderError(f"recording path must be a '.mcap' file or an existing "
                                    f"folder, got '{path}'")
            self._path = requested / generated_name()
        else:
            self._path = requested
        metadata = dict(metadata or {})
        for name, record in metadata.items():
            for key, value in record.items():
                if not isinstance(key, str) or not isinstance(value, str):
                    raise RecorderError(f'metadata record {name!r} must map str to str, got '
                                        f'{key!r}: {value!r}')
        if not (math.isfinite(chunk_interval) and chunk_interval > 0):
            raise RecorderError(f'chunk_interval must be a finite number > 0 s, got '
                                f'{chunk_interval}')
        if chunk_size < 1:
            raise RecorderError(f'chunk_size must be >= 1 byte, got {chunk_size}')
        if compression not in sink.COMPRESSIONS:
            raise RecorderError(f"compression must be one of 'zstd', 'lz4', 'none', got "
                                f'{compression!r}')
        if isinstance(max_backlog, bool) or not isinstance(max_backlog, int) or max_backlog < 1:
            raise RecorderError(f'max_backlog must be an integer >= 1 byte, got {max_backlog!r}')
        self._max_backlog = max_backlog
        self._overwrite = overwrite
        self._settings = {'chunk_interval': float(chunk_interval), 'chunk_size': int(chunk_size),
                          'compression': compression, 'library': LIBRARY, 'metadata': metadata}
        self._channels: dict[str, _Channel] = {}
        self._schema_ids: dict[str, int] = {}
        self._state = 'new'
        self._error: BaseException | None = None
        self._messages_written = 0
        self._process: subprocess.Popen[bytes] | None = None
        self._fd = -1
        self._backlog = bytearray()
        self._stopped = False
        self._reader: threading.Thread | None = None

    # -- public state -------------------------------------------------------------------------

    @property
    def path(self) -> Path:
        """Return the path of the recording file."""
        return self._path

    @property
    def error(self) -> BaseException | None:
        """Return the exception that stopped the recording, or None while it is healthy."""
        return self._error

    @property
    def messages_written(self) -> int:
        """Return how many messages are in closed chunks on disk (all of them once closed)."""
        return self._messages_written

    @property
    def writer_pid(self) -> int | None:
        """Return the process id of the writer process while the recording is open."""
        return None if self._process is None else self._process.pid

    @property
    def closed(self) -> bool:
        """Return whether :meth:`close` has been called."""
        return self._state == 'closed'

    @property
    def topics(self) -> tuple[str, ...]:
        """Return the topics that have a channel, in the order they were added."""
        return tuple(self._channels)

    # -- life cycle -----------------------------------------------------------------------------

    def __enter__(self) -> McapRecorder:
        if self._state == 'new':
            self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()

    def _create_file(self) -> int:
        """Create the recording file exclusively and lock it; return its descriptor.

        The file is always created with ``O_CREAT | O_EXCL | O_NOFOLLOW``: never through a
        symbolic link, never a file some other writer has open. In a folder a name that exists
        already (practically impossible, see :func:`generated_name`) is replaced by a new one.
        Replacing a recording (``overwrite``) creates the new file under a temporary name and
        renames it over the old one, which replaces a link itself, never its target; a recording
        another recorder still writes (it holds the ``flock`` every recorder takes) is refused.
        """
        if self._folder:
            for _ in range(_NAME_TRIES):
                try:
                    return self._create_exclusively(self._path)
                except FileExistsError:
                    self._path = self._path.with_name(generated_name())
            raise RecorderError(f'cannot create a recording in {self._path.parent}: '
                                f'{_NAME_TRIES} generated names exist already')
        try:
            if self._overwrite:
                return self._replace()
            return self._create_exclusively(self._path)
        except FileExistsError:
            if self._path.is_symlink():
                raise RecorderError(f'recording {self._path} is a symbolic link; a recording is '
                                    f'never written through one') from None
            raise RecorderError(f'recording {self._path} already exists; pass '
                                f'overwrite=True to replace it') from None

    def _create_exclusively(self, path: Path) -> int:
        try:
            fd = os.open(path, _CREATE, 0o644)
        except FileExistsError:
            raise
        except IsADirectoryError:
            raise RecorderError(f'cannot create recording {path}: it is a folder') from None
        except OSError as exc:
            raise RecorderError(f'cannot create recording {path}: {_reason(exc)}') from exc
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)   # a new file: nobody else holds it
        return fd

    def _replace(self) -> int:
        path = self._path
        try:
            old = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            return self._create_exclusively(path)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise RecorderError(f'cannot replace recording {path}: it is a symbolic link; '
                                    f'a recording is never written through one') from None
            raise RecorderError(f'cannot create recording {path}: {_reason(exc)}') from exc
        try:
            if stat.S_ISDIR(os.fstat(old).st_mode):
                raise RecorderError(f'cannot create recording {path}: it is a folder')
            if not stat.S_ISREG(os.fstat(old).st_mode):
                raise RecorderError(f'cannot replace recording {path}: it is not a regular file')
            try:
                fcntl.flock(old, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise RecorderError(f'cannot replace recording {path}: another recorder is '
                                    f'writing it') from None
            temporary = path.with_name(f'.{path.name}.{os.getpid()}.{secrets.token_hex(4)}')
            fd = self._create_exclusively(temporary)
            try:
                os.rename(temporary, path)
            except OSError as exc:
                os.close(fd)
                os.unlink(temporary)
                raise RecorderError(f'cannot replace recording {path}: '
                                    f'{_reason(exc)}') from exc
            return fd
        finally:
            os.close(old)

    def open(self) -> McapRecorder:
        """Create the file, start the writer process and have it write header and metadata."""
        if self._state != 'new':
            raise RecorderError(f'recording {self._path} is already {self._state}')
        fd = self._create_file()
        try:
            process = subprocess.Popen(
                [sys.executable, '-m', 'pendulum_sim.recording.sink', str(fd)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, pass_fds=(fd,), bufsize=0)
        except OSError as exc:
            raise RecorderError(f'cannot start the writer process of recording {self._path}: '
                                f'{_reason(exc)}') from exc
        finally:
            os.close(fd)
        assert process.stdin is not None and process.stdout is not None
        self._process, self._fd = process, process.stdin.fileno()
        spec = dict(self._settings, path=str(self._path), stop=self._stop_spec())
        self._send_blocking(self._frame(sink.OPEN, json.dumps(spec).encode()))
        reply = json.loads(process.stdout.readline() or b'{}')
        if not reply.get('ready'):
            process.stdin.close()
            process.stdout.close()
            code = process.wait()
            raise RecorderError(reply.get('error') or f'cannot start the writer process of '
                                f'recording {self._path} (exit code {code})')
        try:
            fcntl.fcntl(self._fd, _F_SETPIPE_SZ, PIPE_SIZE)
        except OSError:
            pass   # the system's maximum pipe size is lower; the backlog covers it
        os.set_blocking(self._fd, False)
        self._state = 'open'
        self._reader = threading.Thread(target=self._read_status, name='mcap-recorder-status',
                                        daemon=True)
        self._reader.start()
        for channel in self._channels.values():
            self._send(self._frame(sink.CHANNEL, json.dumps(channel.spec).encode()))
        return self

    @staticmethod
    def _stop_spec() -> dict[str, Any]:
        """Return the stop event's channel, for the writer process to end a file cut short."""
        type_name = type_name_of(String)
        offer = offered_qos(STOPPED_QOS)
        return {'topic': STOPPED_TOPIC, 'type': type_name, 'schema': ros2msg_schema(type_name),
                'qos': offer, 'metadata': {'offered_qos_profiles': qos_profiles_yaml([offer]),
                                           'topic_type_hash': type_hash(type_name)}}

    def close(self, timeout: float = CLOSE_TIMEOUT) -> None:
        """Have the writer finalise the file (rosbag2 metadata, summary, footer); idempotent.

        Waits at most ``timeout`` seconds for the writer process: one that does not run (say,
        stopped with SIGSTOP) is left to finish the file by itself when it runs again (it
        finalises what it was handed at the end of its input), and :attr:`error` says so. If
        not everything (the ``CLOSE`` frame included) could be handed over, the writer process
        sees its input end without ``CLOSE`` and ends the file with the stop event
        (:data:`~pendulum_sim.recording.events.STOPPED_TOPIC`): it says it was cut short.
        """
        if self._state == 'closed':
            return
        was_open, self._state = self._state == 'open', 'closed'
        if not was_open:
            return
        process = self._process
        assert process is not None and process.stdin is not None
        deadline = time.monotonic() + timeout
        unsent = bytes(self._backlog) + self._frame(sink.CLOSE, b'')
        self._backlog.clear()
        try:
            unsent = self._send_until(unsent, deadline)
        except OSError:
            unsent = b''   # the writer process is gone; its exit code tells below
        process.stdin.close()
        code = process.poll()
        while code is None and time.monotonic() < deadline and not self._writer_stopped():
            try:
                code = process.wait(timeout=0.02)
            except subprocess.TimeoutExpired:
                pass
        if code is None:
            lost = (f'; {len(unsent)} bytes were not handed over, so the file ends earlier '
                    'and says it was cut short' if unsent else '')
            state = 'is stopped' if self._writer_stopped() else f'did not finish in {timeout:g} s'
            self._error = RecorderError(
                f'recording {self._path}: the writer process (pid {process.pid}) {state}; it '
                f'finalises the file when it runs again{lost}')
            return
        assert self._reader is not None and process.stdout is not None
        self._reader.join()
        process.stdout.close()
        if code != 0 and self._error is None:
            self._error = RecorderError(f'recording {self._path}: the writer process exited '
                                        f'with code {code}')

    def _writer_stopped(self) -> bool:
        """Return True if the writer process is stopped (SIGSTOP, a debugger), from /proc."""
        process = self._process
        try:
            stat_line = Path(f'/proc/{process.pid}/stat').read_text() if process else ''
        except OSError:
            return False
        return stat_line.rsplit(')', 1)[-1].split()[:1] in (['T'], ['t'])

    def _send_until(self, data: bytes, deadline: float) -> bytes:
        """Write ``data`` to the writer until it is all sent or ``deadline``; return the rest.

        What the pipe takes is always handed over; only waiting for room stops early, when the
        writer process is stopped (it would not make room).
        """
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(self._fd, view):]
            except BlockingIOError:
                pass
            if not view:
                break
            left = deadline - time.monotonic()
            if left <= 0.0 or self._writer_stopped():
                break
            select.select([], [self._fd], [], min(left, 0.02))
        return bytes(view)

    # -- channels and messages ------------------------------------------------------------------

    def add_channel(self, topic: str, msg_type: type, qos: QoSProfile | int = 10) -> None:
        """Add a channel for a topic: its schema (``ros2msg``), QoS offer and type hash."""
        if self._state == 'closed':
            raise RecorderError(f'recording {self._path} is closed')
        if topic in self._channels:
            raise RecorderError(f'topic {topic} already has a channel')
        channel = self._new_channel(topic, msg_type, qos)
        if self._state == 'open' and not self._stopped:
            self._send(self._frame(sink.CHANNEL, json.dumps(channel.spec).encode()), force=True)

    def _new_channel(self, topic: str, msg_type: type, qos: QoSProfile | int) -> _Channel:
        profile = qos if isinstance(qos, QoSProfile) else QoSProfile(depth=qos)
        type_name = type_name_of(msg_type)
        serialize_message(msg_type())   # loads the type support now, not in the first write()
        offer = offered_qos(profile)
        channel = _Channel(id=len(self._channels) + 1, spec={
            'id': len(self._channels) + 1,
            'schema_id': self._schema_ids.setdefault(type_name, len(self._schema_ids) + 1),
            'topic': topic, 'type': type_name, 'schema': ros2msg_schema(type_name),
            'qos': offer,
            'metadata': {'offered_qos_profiles': qos_profiles_yaml([offer]),
                         'topic_type_hash': type_hash(type_name)}})
        self._channels[topic] = channel
        return channel

    def write(self, topic: str, msg: Any, stamp_ns: int) -> None:
        """Record one message with log and publish time ``stamp_ns``; cheap, never blocks.

        The message is serialized at once, so the caller may reuse it right away.
        """
        channel = self._channel_to_write(topic)
        if channel is not None:
            self._record(self._message(channel.id, serialize_message(msg), stamp_ns), stamp_ns)

    def write_serialized(self, topic: str, data: bytes, stamp_ns: int) -> None:
        """Record one already serialized (CDR) message; cheap, never blocks."""
        channel = self._channel_to_write(topic)
        if channel is not None:
            self._record(self._message(channel.id, data, stamp_ns), stamp_ns)

    def _channel_to_write(self, topic: str) -> _Channel | None:
        """Return the open channel of ``topic``; None once the writer failed (then drained).

        A topic not added, or a recorder not open, is refused (:meth:`_refuse`).
        """
        if self._error is not None:
            self._drain()
            return None
        channel = self._channels.get(topic)
        if channel is None or self._state != 'open':
            self._refuse(topic)
        return channel

    def _record(self, frame: bytes, stamp_ns: int) -> None:
        if not self._send(frame):
            self._stop(stamp_ns)

    def _stop(self, stamp_ns: int) -> None:
        """Stop the recording at the message stamped ``stamp_ns``: the stop event goes last."""
        self._stopped = True
        reason = (f'the writer process fell {_size(self._max_backlog)} behind at the message '
                  f'stamped {stamp_ns} ns; that message and every later one are not recorded')
        self._error = RecorderError(f'recording {self._path} stopped: {reason}')
        frames = b''
        if STOPPED_TOPIC not in self._channels:
            channel = self._new_channel(STOPPED_TOPIC, String, STOPPED_QOS)
            frames = self._frame(sink.CHANNEL, json.dumps(channel.spec).encode())
        frames += self._message(self._channels[STOPPED_TOPIC].id,
                                serialize_message(String(data=reason)), stamp_ns)
        self._backlog += frames
        self._drain()

    @staticmethod
    def _message(channel_id: int, data: bytes, stamp_ns: int) -> bytes:
        try:
            head = sink.MESSAGE_HEAD.pack(sink.MESSAGE, 10 + len(data), channel_id, stamp_ns)
        except struct.error:
            raise RecorderError(f'a message stamp must be an integer number of nanoseconds in '
                                f'[0, 2**64), got {stamp_ns!r}') from None
        return head + data

    def write_reset(self, stamp_ns: int, message: str) -> None:
        """Record a reset of the simulation: a ``std_msgs/msg/String`` on :data:`RESET_TOPIC`.

        The event is kept in write order, so :func:`~pendulum_sim.recording.load` splits the run
        into segments there. The channel is created on the first reset. Cheap, never blocks.
        """
        if RESET_TOPIC not in self._channels:
            self.add_channel(RESET_TOPIC, String, RESET_QOS)
        self.write(RESET_TOPIC, String(data=message), stamp_ns)

    def _refuse(self, topic: str) -> NoReturn:
        if self._state != 'open':
            raise RecorderError(f'recording {self._path} is {self._state}, not open')
        raise RecorderError(f'topic {topic} has no channel; call add_channel first')

    # -- the pipe to the writer process -----------------------------------------------------------

    @staticmethod
    def _frame(kind: int, payload: bytes) -> bytes:
        return sink.FRAME.pack(kind, len(payload)) + payload

    def _send(self, frame: bytes, force: bool = False) -> bool:
        """Write a frame without blocking; what the pipe does not take waits in the backlog.

        Return False, sending nothing, if the frame would take the backlog beyond
        ``max_backlog`` bytes, unless ``force`` (a channel: small, rare, and the messages
        already in the backlog may need it). Frames are only ever added whole and taken from
        the front, so the bytes the writer process reads are always whole frames in order.
        """
        backlog = self._backlog
        if backlog:   # keep the order: the backlog goes first, the new frame behind it
            if len(backlog) + len(frame) > self._max_backlog and not force:
                return False
            backlog += frame
            self._drain()
            return True
        try:
            sent = os.write(self._fd, frame)
        except BlockingIOError:
            sent = 0
        except OSError as exc:
            self._gone(exc)
            return True
        if sent == 0 and len(frame) > self._max_backlog and not force:
            return False
        backlog += memoryview(frame)[sent:]   # a frame the pipe took part of is completed
        return True

    def _drain(self) -> None:
        """Hand as much of the backlog to the writer process as the pipe takes now."""
        backlog = self._backlog
        if not backlog:
            return
        try:
            sent = os.write(self._fd, backlog)
        except BlockingIOError:
            return
        except OSError as exc:
            self._gone(exc)
            return
        del backlog[:sent]

    def _gone(self, exc: OSError) -> None:
        """The writer process is gone (its pipe is closed): stop, drop the backlog."""
        self._backlog.clear()
        if self._error is None:
            self._error = RecorderError(f'recording {self._path} stopped: the writer process '
                                        f'is gone ({exc.strerror})')

    def _send_blocking(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]

    def _read_status(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        for line in process.stdout:
            try:
                status = json.loads(line)
            except ValueError:
                continue   # not a status line
            if 'written' in status or 'closed' in status:
                self._messages_written = int(status.get('written', status.get('closed', 0)))
            if 'error' in status and self._error is None:
                self._error = RecorderError(status['error'])
