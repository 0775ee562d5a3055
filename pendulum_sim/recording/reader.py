"""Read the records of an MCAP file in file order, as untrusted input, tolerating a truncated end.

The file is read record by record (never whole), following the MCAP specification
(https://mcap.dev/spec): a chunk is decompressed only up to the ``uncompressed_size`` it declares,
and only if that is at most :data:`MAX_CHUNK_BYTES`; a chunk that declares more, or inflates to
more or less than it declares, or whose CRC does not match, is corrupted. A recording cut short
(the process was killed, the disk filled up) has no summary and no footer and may end inside a
record; everything before that record is still good and is returned, with ``complete`` False and
a note in ``problems``. A file that is not MCAP, or a record that cannot be parsed, raises
:class:`RecorderError` naming the record and its byte offset, or with ``corrupt='skip'`` is noted
and skipped.

:class:`Walker` yields the message records in blocks (a chunk, or one message record outside
chunks) with the chunk's message index when the file has one; :func:`scan` builds on it and
returns every message as a :class:`RawMessage`, for the replayer and for small files.
"""
from __future__ import annotations

import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import BinaryIO, Final, Literal

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Header, Metadata, Schema, Statistics
from numpy.typing import NDArray

from pendulum_sim.recording.errors import RecorderError

MAGIC: Final = bytes((137, 77, 67, 65, 80, 48, 13, 10))
MAX_CHUNK_BYTES: Final = 32 << 20
"""The most a chunk may inflate to: 32 MiB, 32 times the chunks :class:`McapRecorder` writes."""
RECORD_HEAD: Final = struct.Struct('<BQ')
MESSAGE_HEAD: Final = struct.Struct('<BQHIQQ')   # opcode, length, channel, sequence, log, publish
_CHUNK_HEAD: Final = struct.Struct('<QQQII')     # start, end, uncompressed size, CRC, name len
Corrupt = Literal['raise', 'skip']


@dataclass(frozen=True)
class RawMessage:
    """One message record: its channel, times and CDR payload, where it sits in the file."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes
    offset: int


@dataclass(frozen=True)
class Block:
    """Message records as they lie in the file: a chunk's records, or one message record.

    ``data`` holds whole records (opcode, length, body); ``index`` maps a channel id to the
    offsets in ``data`` its message index gives, or is None when the file has no index for it.
    ``offset`` is the byte offset of the chunk (or message) record in the file.
    """

    offset: int
    opcode: int
    data: bytes
    index: dict[int, NDArray[np.uint64]] | None


def record_name(opcode: int) -> str:
    """Return the name of a record type, as used in messages (``'chunk'``, ``'message'``)."""
    try:
        return Opcode(opcode).name.lower().replace('_', ' ')
    except ValueError:
        return f'unknown (opcode {opcode:#04x})'


def records_in(data: bytes, start: int = 0,
               end: int | None = None) -> Iterator[tuple[int, int, int]]:
    """Yield ``(opcode, offset, end)`` of the records in ``data[start:end]``; they must tile it."""
    stop = len(data) if end is None else end
    pos = start
    while pos < stop:
        if pos + RECORD_HEAD.size > stop:
            raise ValueError(f'a record head at offset {pos} runs past the end of its chunk')
        opcode, length = RECORD_HEAD.unpack_from(data, pos)
        record_end = pos + RECORD_HEAD.size + length
        if record_end > stop:
            raise ValueError(f'a {record_name(opcode)} record at offset {pos} runs past the end '
                             f'of its chunk')
        yield opcode, pos, record_end
        pos = record_end


def inflate(compression: str, payload: bytes | memoryview, declared: int) -> bytes:
    """Decompress a chunk's records, refusing to produce more than it declares or the maximum."""
    if declared > MAX_CHUNK_BYTES:
        raise ValueError(f'it declares {declared} bytes uncompressed, more than the '
                         f'{MAX_CHUNK_BYTES} bytes allowed')
    if compression == '':
        out = bytes(payload)
    elif compression == 'zstd':
        reader = zstandard.ZstdDecompressor().stream_reader(
            BytesIO(payload), read_across_frames=True)
        pieces, total = [], 0
        while total <= declared:
            piece = reader.read(declared + 1 - total)
            if not piece:
                break
            pieces.append(piece)
            total += len(piece)
        out = b''.join(pieces)
    elif compression == 'lz4':
        out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(payload),
                                                          max_length=declared + 1)
    else:
        raise ValueError(f'unknown compression {compression!r}')
    if len(out) > declared:
        raise ValueError(f'it inflates to more than the {declared} bytes it declares')
    if len(out) < declared:
        raise ValueError(f'it inflates to {len(out)} bytes, not the {declared} it declares')
    return out


def _stream(body: bytes | memoryview) -> ReadDataStream:
    return ReadDataStream(BytesIO(body))


class Walker:
    """Walk an MCAP file once, in file order: definitions here, message records in blocks.

    Schemas, channels, metadata and statistics are collected as they come; :meth:`blocks`
    yields the message records. A consumer that finds a block's records malformed calls
    :meth:`corrupted`, which raises or (``corrupt='skip'``) notes the problem.
    """

    def __init__(self, path: str | Path, corrupt: Corrupt = 'raise') -> None:
        self.path = Path(path)
        self.corrupt = corrupt
        self.size = 0
        self.profile = ''
        self.library = ''
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        self.statistics: Statistics | None = None
        self.complete = False
        self.problems: list[str] = []

    def corrupted(self, opcode: int, offset: int, exc: BaseException | str) -> None:
        """Raise (or note, skipping the record) that a record cannot be read."""
        problem = (f'{self.path} is corrupted: the {record_name(opcode)} record at byte '
                   f'{offset} cannot be read ({exc})')
        if self.corrupt == 'raise':
            raise RecorderError(problem) from (exc if isinstance(exc, BaseException) else None)
        self.problems.append(problem)

    def define(self, opcode: int, body: bytes | memoryview) -> None:
        """Register a schema or channel record's body (the first definition of an id wins)."""
        if opcode == Opcode.SCHEMA:
            schema = Schema.read(_stream(body))
            self.schemas.setdefault(schema.id, schema)
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(_stream(body))
            self.channels.setdefault(channel.id, channel)

    def blocks(self) -> Iterator[Block]:
        """Yield the blocks of message records in file order; collect everything else."""
        try:
            stream = open(self.path, 'rb')   # closed below, also on errors
        except OSError as exc:
            raise RecorderError(f'cannot read {self.path}: {exc.strerror or exc}') from exc
        with stream:
            try:
                yield from self._walk(stream)
            except OSError as exc:
                raise RecorderError(f'cannot read {self.path}: {exc.strerror or exc}') from exc

    def _walk(self, stream: BinaryIO) -> Iterator[Block]:
        self.size = os.fstat(stream.fileno()).st_size
        if stream.read(len(MAGIC)) != MAGIC:
            raise RecorderError(f'{self.path} is not an MCAP file (it does not start with the '
                                f'MCAP magic bytes)')
        pos = len(MAGIC)
        in_summary = False
        chunk: tuple[int, bytes] | None = None
        index: dict[int, NDArray[np.uint64]] | None = None
        while True:
            if pos + RECORD_HEAD.size > self.size:
                self.problems.append(f'{self.path} is truncated: it ends at byte {self.size} '
                                     f'without a footer (the recording was not closed)')
                break
            opcode, length = RECORD_HEAD.unpack(stream.read(RECORD_HEAD.size))
            end = pos + RECORD_HEAD.size + length
            if end > self.size:
                self.problems.append(
                    f'{self.path} is truncated: it ends inside a {record_name(opcode)} record '
                    f'at byte {pos} (the recording was not closed)')
                break
            if chunk is not None and opcode == Opcode.MESSAGE_INDEX:
                body = stream.read(length)
                entries = _message_index(body)
                if entries is None or index is None:
                    index = None   # a malformed index: the records are walked instead
                else:
                    index[entries[0]] = entries[1]
                pos = end
                continue
            if chunk is not None:
                block = self._chunk(*chunk, index)
                if block is not None:
                    yield block
                chunk = index = None
            if pos == len(MAGIC) and opcode != Opcode.HEADER:
                raise RecorderError(f'{self.path} is corrupted: the first record is not a '
                                    f'header but a {record_name(opcode)} record')
            if opcode == Opcode.CHUNK and in_summary:
                stream.seek(end)
            elif opcode == Opcode.CHUNK:
                chunk, index = (pos, stream.read(length)), {}
            elif opcode == Opcode.MESSAGE:
                yield Block(offset=pos, opcode=opcode, index=None, data=RECORD_HEAD.pack(
                    opcode, length) + stream.read(length))
            else:
                body = stream.read(length)
                try:
                    self._other(opcode, body, stream)
                except RecorderError:
                    raise
                except Exception as exc:
                    self.corrupted(opcode, pos, exc)
                if opcode == Opcode.DATA_END:
                    in_summary = True
                if self.complete:
                    break
            pos = end
        if chunk is not None:   # the file ends (truncated) after a chunk and its indexes
            block = self._chunk(*chunk, None)
            if block is not None:
                yield block

    def _other(self, opcode: int, body: bytes, stream: BinaryIO) -> None:
        if opcode == Opcode.HEADER:
            header = Header.read(_stream(body))
            self.profile, self.library = header.profile, header.library
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            self.define(opcode, body)
        elif opcode == Opcode.METADATA:
            metadata = Metadata.read(_stream(body))
            self.metadata[metadata.name] = dict(metadata.metadata)
        elif opcode == Opcode.STATISTICS:
            self.statistics = Statistics.read(_stream(body))
        elif opcode == Opcode.FOOTER:
            if stream.read(len(MAGIC)) != MAGIC:
                raise ValueError('the footer is not followed by the MCAP magic bytes')
            self.complete = True

    def _chunk(self, pos: int, body: bytes,
               index: dict[int, NDArray[np.uint64]] | None) -> Block | None:
        try:
            _, _, declared, crc, name_length = _CHUNK_HEAD.unpack_from(body, 0)
            at = _CHUNK_HEAD.size
            compression = body[at:at + name_length].decode()
            at += name_length
            (payload_length,) = struct.unpack_from('<Q', body, at)
            at += 8
            if at + payload_length > len(body):
                raise ValueError('its records run past its end')
            data = inflate(compression, memoryview(body)[at:at + payload_length], declared)
            if crc != 0 and zlib.crc32(data) != crc:
                raise ValueError(f'CRC mismatch: the records have CRC {zlib.crc32(data)}, the '
                                 f'chunk says {crc}')
        except Exception as exc:
            self.corrupted(Opcode.CHUNK, pos, exc)
            return None
        return Block(offset=pos, opcode=Opcode.CHUNK, data=data, index=index)


def _message_index(body: bytes) -> tuple[int, NDArray[np.uint64]] | None:
    if len(body) < 6:
        return None
    channel_id, records_length = struct.unpack_from('<HI', body, 0)
    if records_length % 16 or 6 + records_length > len(body):
        return None
    pairs = np.frombuffer(body, dtype='<u8', count=records_length // 8, offset=6)
    return channel_id, pairs[1::2]


@dataclass
class Scan:
    """Everything read from an MCAP file, in file order."""

    path: Path
    size: int
    profile: str = ''
    library: str = ''
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[RawMessage] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    statistics: Statistics | None = None
    complete: bool = False
    problems: list[str] = field(default_factory=list)

    def sorted_messages(self) -> list[RawMessage]:
        """Return the messages in log-time order (file order among equal times)."""
        return sorted(self.messages, key=lambda m: m.log_time)


def messages_in(walker: Walker, block: Block) -> list[RawMessage] | None:
    """Return a block's messages in file order (defining its schemas and channels on the way).

    A malformed block goes to :meth:`Walker.corrupted`; then None is returned.
    """
    data = block.data
    out: list[RawMessage] = []
    try:
        for opcode, start, end in records_in(data):
            if opcode == Opcode.MESSAGE:
                if end - start < MESSAGE_HEAD.size:
                    raise ValueError(f'a message record at offset {start} is too short')
                _, _, channel_id, sequence, log_time, publish_time = MESSAGE_HEAD.unpack_from(
                    data, start)
                out.append(RawMessage(channel_id=channel_id, sequence=sequence,
                                      log_time=log_time, publish_time=publish_time,
                                      data=data[start + MESSAGE_HEAD.size:end],
                                      offset=block.offset))
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                walker.define(opcode, memoryview(data)[start + RECORD_HEAD.size:end])
    except Exception as exc:
        walker.corrupted(block.opcode, block.offset, exc)
        return None
    return out


def scan(path: str | Path, *, corrupt: Corrupt = 'raise') -> Scan:
    """Read an MCAP file record by record; see the module docstring for damaged files."""
    walker = Walker(path, corrupt)
    messages: list[RawMessage] = []
    for block in walker.blocks():
        found = messages_in(walker, block)
        if found is not None:
            messages += found
    return Scan(path=walker.path, size=walker.size, profile=walker.profile,
                library=walker.library, schemas=walker.schemas, channels=walker.channels,
                messages=messages, metadata=walker.metadata, statistics=walker.statistics,
                complete=walker.complete, problems=walker.problems)
