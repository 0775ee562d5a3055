"""Read every record of an MCAP file in file order, tolerating a truncated end.

A recording cut short (the process was killed, the disk filled up) has no summary and no footer
and may end inside a record; everything before that record is still good and is returned, with
``complete`` False and a note in ``problems``. A file that is not MCAP, or a record that cannot
be parsed (a chunk whose CRC or compression is broken, for example) raises
:class:`RecorderError`, or with ``corrupt='skip'`` is noted and skipped.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Literal

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Message,
    Metadata,
    Schema,
    Statistics,
)
from mcap.stream_reader import breakup_chunk

from pendulum_sim.recording.errors import RecorderError

MAGIC = bytes((137, 77, 67, 65, 80, 48, 13, 10))
_RECORD_HEAD = struct.Struct('<BQ')


@dataclass(frozen=True)
class RawMessage:
    """One message record: its channel, times and CDR payload, where it sits in the file."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes
    offset: int


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


def _name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.lower().replace('_', ' ')
    except ValueError:
        return f'unknown (opcode {opcode:#04x})'


def scan(path: str | Path, *, corrupt: Literal['raise', 'skip'] = 'raise') -> Scan:
    """Read an MCAP file record by record; see the module docstring for damaged files."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecorderError(f'cannot read {path}: {exc.strerror}') from exc
    result = Scan(path=path, size=len(data))
    if data[:len(MAGIC)] != MAGIC:
        raise RecorderError(f'{path} is not an MCAP file (it does not start with the MCAP '
                            f'magic bytes)')
    pos = len(MAGIC)
    in_summary = False
    while True:
        if pos + _RECORD_HEAD.size > len(data):
            result.problems.append(
                f'{path} is truncated: it ends at byte {len(data)} without a footer (the '
                f'recording was not closed); read {len(result.messages)} messages')
            break
        opcode, length = _RECORD_HEAD.unpack_from(data, pos)
        end = pos + _RECORD_HEAD.size + length
        if end > len(data):
            result.problems.append(
                f'{path} is truncated: it ends inside a {_name(opcode)} record at byte {pos} '
                f'(the recording was not closed); read {len(result.messages)} messages')
            break
        stream = ReadDataStream(BytesIO(data[pos + _RECORD_HEAD.size:end]))
        try:
            if pos == len(MAGIC) and opcode != Opcode.HEADER:
                raise ValueError('the first record is not a header')
            if opcode == Opcode.HEADER:
                header = Header.read(stream)
                result.profile, result.library = header.profile, header.library
            elif opcode == Opcode.SCHEMA:
                schema = Schema.read(stream)
                result.schemas.setdefault(schema.id, schema)
            elif opcode == Opcode.CHANNEL:
                channel = Channel.read(stream)
                result.channels.setdefault(channel.id, channel)
            elif opcode == Opcode.MESSAGE:
                _add_message(result, Message.read(stream, length), pos)
            elif opcode == Opcode.CHUNK and not in_summary:
                for record in breakup_chunk(Chunk.read(stream), validate_crc=True):
                    if isinstance(record, Schema):
                        result.schemas.setdefault(record.id, record)
                    elif isinstance(record, Channel):
                        result.channels.setdefault(record.id, record)
                    elif isinstance(record, Message):
                        _add_message(result, record, pos)
            elif opcode == Opcode.METADATA:
                metadata = Metadata.read(stream)
                result.metadata[metadata.name] = dict(metadata.metadata)
            elif opcode == Opcode.STATISTICS:
                result.statistics = Statistics.read(stream)
            elif opcode == Opcode.DATA_END:
                DataEnd.read(stream)
                in_summary = True
            elif opcode == Opcode.FOOTER:
                Footer.read(stream)
                if data[end:end + len(MAGIC)] != MAGIC:
                    raise ValueError('the footer is not followed by the MCAP magic bytes')
                result.complete = True
                break
        except Exception as exc:
            problem = (f'{path} is corrupted: the {_name(opcode)} record at byte {pos} cannot '
                       f'be read ({exc})')
            if corrupt == 'raise':
                raise RecorderError(problem) from exc
            result.problems.append(problem)
        pos = end
    return result


def _add_message(result: Scan, message: Message, offset: int) -> None:
    result.messages.append(RawMessage(
        channel_id=message.channel_id, sequence=message.sequence, log_time=message.log_time,
        publish_time=message.publish_time, data=message.data, offset=offset))
