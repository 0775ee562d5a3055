"""The recording's writer process: MCAP chunks, compression and disk writes, off the node.

:class:`~pendulum_sim.recording.writer.McapRecorder` starts this module as a child process
(``python -m pendulum_sim.recording.sink FD``, FD being the recording file it opened) and feeds
it frames on stdin: ``<BI`` (kind, payload length) then the payload.

- ``OPEN``: JSON ``{path, chunk_interval, chunk_size, compression, library, metadata, stop}``
  (``stop``: the channel of the stop event, ``{topic, type, schema, metadata, qos}``);
- ``CHANNEL``: JSON ``{id, schema_id, topic, type, schema, metadata, qos}``;
- ``MESSAGE``: ``<HQ`` (channel id, log time = publish time in ns) then the CDR payload;
- ``CLOSE``: nothing.

It answers with JSON lines on stdout: ``{"ready": true}`` once the header and metadata records
are on disk, ``{"written": N}`` after each chunk, ``{"error": "..."}`` when writing fails (it
then writes nothing more) and ``{"closed": N}`` once the file is finalised. A chunk is closed at
the latest ``chunk_interval`` seconds (wall clock) after its first message, or once it spans
that much log time. When stdin ends without ``CLOSE`` (the recording process was killed, or it
closed the recording while this process was stopped and could not hand everything over) the file
is finalised all the same, ending with a stop event (the ``stop`` channel, the same mark a
recording cut short by a lagging writer ends with) stamped with the last log time received:
every message received is in it, and the file says that it was cut short. SIGINT and SIGTERM
are ignored: the recording process decides.
Input is taken in batches every few milliseconds (the pipe buffers it). This process never
imports rclpy, so it starts quickly, and it holds no GIL the node needs.
"""
from __future__ import annotations

import json
import os
import select
import signal
import struct
import sys
import time
from dataclasses import dataclass
from typing import IO, Any, Final

from mcap.well_known import MessageEncoding, Profile, SchemaEncoding
from mcap.writer import CompressionType, Writer

from pendulum_sim.recording.rosbag2 import TopicSummary, bag_metadata, dump_yaml

OPEN: Final = 1
CHANNEL: Final = 2
MESSAGE: Final = 3
CLOSE: Final = 4
FRAME: Final = struct.Struct('<BI')
MESSAGE_HEAD: Final = struct.Struct('<BIHQ')   # frame head and the message's own head
BATCH_PERIOD: Final = 0.005   # s
COMPRESSIONS: Final = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                       'none': CompressionType.NONE}


@dataclass
class _Channel:
    topic: str
    type: str
    qos: dict[str, Any]
    type_hash: str
    count: int = 0
    sequence: int = 0


class Sink:
    """Write what the frames say to an MCAP file; report on a status stream."""

    def __init__(self, stream: IO[bytes], status: IO[str]) -> None:
        self._stream, self._status = stream, status
        self._writer: Writer | None = None
        self._path = ''
        self._channels: dict[int, _Channel] = {}
        self._schemas: set[int] = set()
        self._interval = 0.25
        self._interval_ns = 250_000_000
        self._chunk_started: float | None = None
        self._chunk_first_ns = 0
        self._start_ns: int | None = None
        self._end_ns: int | None = None
        self._schema_ids: dict[str, int] = {}
        self._stop: dict[str, Any] | None = None
        self.written = 0      # messages handed to the MCAP writer
        self.flushed = 0      # of them, in chunks completely written to the file
        self.failed = False

    def report(self, **fields: Any) -> None:
        """Write one status line."""
        try:
            self._status.write(json.dumps(fields) + '\n')
            self._status.flush()
        except OSError:
            pass   # the recording process is gone; the file still gets finalised

    def fail(self, exc: BaseException, opening: bool) -> None:
        """Stop writing and report why, naming the file (the first failure only)."""
        if self.failed:
            return
        self.failed = True
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        if opening:
            self.report(error=f'cannot write recording {self._path}: {reason}')
        else:
            self.report(error=f'recording {self._path} stopped: {reason}', written=self.flushed)
        try:
            self._stream.close()
        except OSError:
            pass   # the buffered bytes fail again; the error is already reported

    def open(self, spec: dict[str, Any]) -> None:
        """Write the header and the metadata records, and flush them to disk."""
        self._path = spec['path']
        self._interval = float(spec['chunk_interval'])
        self._interval_ns = round(self._interval * 1e9)
        writer = Writer(self._stream, chunk_size=int(spec['chunk_size']),
                        compression=COMPRESSIONS[spec['compression']], enable_crcs=True)
        writer.start(profile=Profile.ROS2, library=spec['library'])
        for name, record in spec['metadata'].items():
            writer.add_metadata(name, record)
        self._stream.flush()
        self._writer = writer
        self._stop = spec.get('stop')
        self.report(ready=True)

    def channel(self, spec: dict[str, Any]) -> None:
        """Register a channel (and its schema, the first time)."""
        assert self._writer is not None
        if spec['schema_id'] not in self._schemas:
            schema_id = self._writer.register_schema(spec['type'], SchemaEncoding.ROS2,
                                                     spec['schema'].encode())
            assert schema_id == spec['schema_id']
            self._schemas.add(schema_id)
            self._schema_ids[spec['type']] = schema_id
        channel_id = self._writer.register_channel(spec['topic'], MessageEncoding.CDR,
                                                   spec['schema_id'], spec['metadata'])
        assert channel_id == spec['id']
        self._channels[channel_id] = _Channel(spec['topic'], spec['type'], spec['qos'],
                                              spec['metadata']['topic_type_hash'])

    def message(self, channel_id: int, stamp_ns: int, data: bytes) -> None:
        """Add one message to the current chunk; close the chunk once it spans the interval."""
        assert self._writer is not None
        channel = self._channels[channel_id]
        channel.sequence += 1
        self._writer.add_message(channel_id, log_time=stamp_ns, data=data,
                                 publish_time=stamp_ns, sequence=channel.sequence)
        channel.count += 1
        self.written += 1
        if self._start_ns is None or stamp_ns < self._start_ns:
            self._start_ns = stamp_ns
        if self._end_ns is None or stamp_ns > self._end_ns:
            self._end_ns = stamp_ns
        if self._chunk_started is None:
            self._chunk_started = time.monotonic()
            self._chunk_first_ns = stamp_ns
        elif abs(stamp_ns - self._chunk_first_ns) >= self._interval_ns:
            self.flush()

    def mark_cut_short(self) -> None:
        """Add the stop event: the input ended without CLOSE (unless a stop event is there)."""
        stop = self._stop
        if self._writer is None or stop is None:
            return
        ids = [cid for cid, c in self._channels.items() if c.topic == stop['topic']]
        if ids and self._channels[ids[0]].count:
            return   # the recording process stopped the recording itself, and said why
        if ids:
            channel_id = ids[0]
        else:
            schema_id = self._schema_ids.get(stop['type'])
            if schema_id is None:
                schema_id = self._writer.register_schema(stop['type'], SchemaEncoding.ROS2,
                                                         stop['schema'].encode())
                self._schema_ids[stop['type']] = schema_id
            channel_id = self._writer.register_channel(stop['topic'], MessageEncoding.CDR,
                                                       schema_id, stop['metadata'])
            self._channels[channel_id] = _Channel(stop['topic'], stop['type'], stop['qos'],
                                                  stop['metadata']['topic_type_hash'])
        end = self._end_ns or 0
        reason = (f'the writer process saw its input end without CLOSE (the recording process '
                  f'was killed, or closed the recording while the writer process was stopped, '
                  f'with frames not handed over) after the message stamped {end} ns; nothing '
                  f'later is recorded')
        self.message(channel_id, end, cdr_string(reason))

    def until_flush(self) -> float | None:
        """Return the seconds until the open chunk is due, or None without one."""
        if self._chunk_started is None:
            return None
        return max(0.0, self._chunk_started + self._interval - time.monotonic())

    def flush(self) -> None:
        """Close the current chunk: compress it, write it and its message indexes."""
        if self._writer is not None and self._chunk_started is not None:
            self._writer.flush()
            self._chunk_started = None
            self.flushed = self.written
            self.report(written=self.flushed)

    def finish(self) -> None:
        """Write the rosbag2 metadata, the summary and the footer, and close the file."""
        assert self._writer is not None
        topics = [TopicSummary(name=c.topic, type=c.type, offered_qos_profiles=(c.qos,),
                               type_description_hash=c.type_hash, message_count=c.count)
                  for c in self._channels.values()]
        metadata = bag_metadata(os.path.basename(self._path), topics, self.written,
                                self._start_ns, self._end_ns)
        self._writer.flush()
        self._writer.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(metadata)})
        self._writer.finish()
        self._stream.close()
        self.report(closed=self.written)


def cdr_string(text: str) -> bytes:
    """Return the CDR (little-endian, with its encapsulation header) of a std_msgs/String."""
    data = text.encode()
    return b'\x00\x01\x00\x00' + struct.pack('<I', len(data) + 1) + data + b'\x00'


def serve(sink: Sink, fd_in: int) -> None:
    """Read frames from ``fd_in`` and hand them to the sink until CLOSE or the end of input."""
    buffer = bytearray()
    opened = False
    while True:
        timeout = None if sink.failed else sink.until_flush()
        ready, _, _ = select.select([fd_in], [], [], timeout)
        data = os.read(fd_in, 1 << 20) if ready else None
        if data == b'':   # the input ended without CLOSE: finalise what we have, cut short
            if opened and not sink.failed:
                try:
                    sink.mark_cut_short()
                    sink.flush()
                    sink.finish()
                except Exception as exc:   # a full disk, ...: the chunks written stay readable
                    sink.fail(exc, opening=False)
            return
        if data:
            buffer += data
        pos = 0
        try:
            while len(buffer) - pos >= FRAME.size and not sink.failed:
                kind, length = FRAME.unpack_from(buffer, pos)
                if len(buffer) - pos - FRAME.size < length:
                    break
                body = pos + FRAME.size
                if kind == MESSAGE:
                    channel_id, stamp_ns = struct.unpack_from('<HQ', buffer, body)
                    sink.message(channel_id, stamp_ns, bytes(buffer[body + 10:body + length]))
                elif kind == CHANNEL:
                    sink.channel(json.loads(buffer[body:body + length]))
                elif kind == OPEN:
                    try:
                        sink.open(json.loads(buffer[body:body + length]))
                    except OSError as exc:
                        sink.fail(exc, opening=True)
                        return
                    opened = True
                elif kind == CLOSE:
                    sink.flush()
                    sink.finish()
                    return
                pos = body + length
            if not sink.failed and sink.until_flush() == 0.0:
                sink.flush()
        except Exception as exc:   # a full disk, a file size limit, ...: stop writing
            sink.fail(exc, opening=False)
        if sink.failed:
            buffer.clear()   # keep reading (and dropping) so the sender never blocks
        else:
            del buffer[:pos]
        # Take the input in batches (the pipe holds a second or more of it): waking for every
        # message would cost more than writing it.
        time.sleep(BATCH_PERIOD)


def main(argv: list[str] | None = None) -> int:
    """Run the writer process on the file descriptor given as the only argument."""
    args = sys.argv[1:] if argv is None else argv
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sink = Sink(os.fdopen(int(args[0]), 'wb'), sys.stdout)
    serve(sink, sys.stdin.fileno())
    return 1 if sink.failed else 0


if __name__ == '__main__':
    sys.exit(main())
