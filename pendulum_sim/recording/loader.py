"""Load a recording into numpy arrays per topic, for notebooks and reports.

Example
-------
>>> rec = load('run.mcap')                                      # doctest: +SKIP
>>> rec.joint_states.t, rec.joint_states.position, rec.energy.value  # doctest: +SKIP
>>> for segment in rec.segments:                                 # doctest: +SKIP
...     segment.joint_states.t                                   # between two resets

Messages are taken in write (file) order, not sorted by log time. Times ``t`` are the messages'
log times in seconds (the simulated stamps the node recorded); ``stamp_ns`` holds the same times
as exact integers. A reset event (:data:`~pendulum_sim.recording.events.RESET_TOPIC`, written by
:meth:`McapRecorder.write_reset`) splits the run: ``segments`` holds the same per-topic arrays for
each stretch between resets (views into the whole-run arrays), ``resets`` the reset stamps.

Decoding. The messages the node writes have a fixed CDR layout (the OMG XCDR1 little-endian
encoding ROS 2 uses: the 4-byte encapsulation header, then each field aligned to its size from
there): a ``std_msgs/msg/Float64`` is always 12 bytes, and a one-joint
``sensor_msgs/msg/JointState`` keeps its layout as long as the frame id, the joint name and
which arrays are empty stay the same. The fast path parses the first message of a chunk (and
checks the result against rclpy's ``deserialize_message``), then takes every message of the
chunk whose bytes match that template outside the stamps, values and padding, with numpy, many
at once. Any other message (several joints, a different name, another encoding) goes through
the per-message decoder, rclpy's ``deserialize_message``; ``load(path, fast=False)`` uses only
that, which is how the two are proven equal.

Type names are read from an untrusted file: a channel whose type is not an allowed, installed
message type (:func:`~pendulum_sim.recording.schemas.check_message_type`) is skipped with a
:class:`SkippedChannelWarning`; nothing it names is imported.
"""
from __future__ import annotations

import itertools
import struct
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from mcap.opcode import Opcode
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message

from pendulum_sim.recording.errors import RecorderError
from pendulum_sim.recording.events import RESET_TOPIC, RESET_TYPE, STOPPED_TOPIC, STOPPED_TYPE
from pendulum_sim.recording.reader import (
    MESSAGE_HEAD,
    RECORD_HEAD,
    Block,
    Walker,
    messages_in,
    record_name,
    records_in,
)
from pendulum_sim.recording.schemas import check_message_type, message_class

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_U8 = NDArray[np.uint8]

_JOINT_STATE: Final = 'sensor_msgs/msg/JointState'
_FLOAT64: Final = 'std_msgs/msg/Float64'
_KINDS: Final = {
    'joint_states': _JOINT_STATE,
    'energy': _FLOAT64,
    'effort_command': _FLOAT64,
    'diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
    'parameter_events': 'rcl_interfaces/msg/ParameterEvent',
}
_CDR_LE: Final = b'\x00\x01\x00\x00'     # encapsulation: plain CDR, little endian, no options
_DATA: Final = MESSAGE_HEAD.size          # where the CDR payload starts in a message record
_LOG_TIME: Final = 15                     # where the log time is in a message record
_BATCH_BYTES: Final = 4 << 20             # decode this much of consecutive chunks at once
_TEMPLATES: Final = 8                     # layouts tried per chunk before decoding one by one


class TruncatedRecordingWarning(UserWarning):
    """A recording does not hold the whole run: not closed (killed, disk full), or stopped."""


class SkippedChannelWarning(UserWarning):
    """A channel was left out: its type is not an allowed message type, or it is not CDR."""


@dataclass(frozen=True)
class TopicInfo:
    """A topic of the recording: its type, message count and channel metadata."""

    name: str
    type: str
    message_count: int
    metadata: dict[str, str]


@dataclass(frozen=True)
class JointStates:
    """``sensor_msgs/msg/JointState`` samples; arrays are (N,) for one joint, else (N, joints).

    ``effort`` (and ``position``, ``velocity``) is NaN where a message carried none.
    """

    t: FloatArray
    stamp_ns: IntArray
    header_stamp_ns: IntArray
    name: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray
    effort: FloatArray


@dataclass(frozen=True)
class Series:
    """A scalar topic (``std_msgs/msg/Float64``): times and values."""

    t: FloatArray
    stamp_ns: IntArray
    value: FloatArray


@dataclass(frozen=True)
class Diagnostics:
    """``diagnostic_msgs/msg/DiagnosticArray`` samples: times and the decoded messages.

    ``values`` maps ``'<status name>/<key>'`` to an array over the samples, with the value
    parsed as a float (NaN where it is missing or not a number).
    """

    t: FloatArray
    stamp_ns: IntArray
    values: dict[str, FloatArray]
    messages: tuple[Any, ...]


@dataclass(frozen=True)
class Segment:
    """The per-topic arrays of a stretch of the run (a topic the file lacks is None)."""

    joint_states: JointStates | None
    energy: Series | None
    effort_command: Series | None
    diagnostics: Diagnostics | None
    parameter_events: tuple[tuple[int, Any], ...]


@dataclass(frozen=True)
class Recording(Segment):
    """A loaded recording: the whole run's arrays, its segments, metadata and problems.

    ``segments`` splits the run at each reset event (one segment without resets); ``resets``
    holds the reset stamps (ns) and ``reset_messages`` their texts, in write order.
    ``stopped_ns`` is the log time of the stop event of a recording cut short
    (:data:`~pendulum_sim.recording.events.STOPPED_TOPIC`), None for one that ran to its end;
    ``complete`` is False for a file cut short or not closed, and ``problems`` says why.
    """

    path: Path
    profile: str
    metadata: dict[str, dict[str, str]]
    topics: dict[str, TopicInfo]
    segments: tuple[Segment, ...]
    resets: IntArray
    reset_messages: tuple[str, ...]
    complete: bool
    problems: tuple[str, ...]
    stopped_ns: int | None = None

    @property
    def scene(self) -> dict[str, str]:
        """Return the scene parameters the recording was made with."""
        return self.metadata.get('scene', {})

    def messages(self, topic: str) -> list[tuple[int, Any]]:
        """Return ``(log_time_ns, decoded message)`` for every message of a topic (file order).

        The file is read again for this, so that :func:`load` keeps no per-message objects.
        """
        if topic not in self.topics:
            raise RecorderError(f'{self.path} has no topic {topic}; it has '
                                f'{", ".join(sorted(self.topics)) or "none"}')
        cls = message_class(self.topics[topic].type)
        walker = Walker(self.path, 'raise')
        out: list[tuple[int, Any]] = []
        wanted: set[int] = set()
        for block in walker.blocks():
            found = messages_in(walker, block) or []
            wanted = {cid for cid, c in walker.channels.items() if c.topic == topic}
            for m in found:
                if m.channel_id in wanted:
                    out.append((m.log_time, _decode(self.path, topic, cls, m.data,
                                                    m.log_time)))
        return out


# -- decoding -----------------------------------------------------------------------------------


def _decode(path: Path, topic: str, cls: type, data: bytes, log_time: int) -> Any:
    try:
        return deserialize_message(data, cls)
    except Exception as exc:
        raise RecorderError(f'{path} is corrupted: the {_type_of(cls)} message at log time '
                            f'{log_time} ns on {topic} cannot be decoded ({exc})') from exc


def _type_of(cls: type) -> str:
    return f'{cls.__module__.split(".")[0]}/msg/{cls.__name__}'


def _gather(u8: _U8, starts: IntArray, width: int) -> _U8:
    """Return the ``width`` bytes at each start as rows of a (N, width) array (a copy)."""
    return np.lib.stride_tricks.sliding_window_view(u8, width)[starts]


def _column(rows: _U8, at: int, dtype: str) -> NDArray[Any]:
    size = np.dtype(dtype).itemsize
    return np.ascontiguousarray(rows[:, at:at + size]).view(dtype)[:, 0]


@dataclass(frozen=True)
class _Layout:
    """Where a fixed-layout message's values sit in its record, and what must match."""

    size: int                        # record size (head + payload)
    fixed: NDArray[np.bool_]         # bytes every message of this layout has the same
    fields: dict[str, int]           # field -> offset in the record of its float64
    stamp: int | None                # offset of header.stamp (int32 sec, uint32 nanosec)
    names: tuple[str, ...]


def _align(pos: int, size: int) -> int:
    """Align a payload offset to ``size``; CDR counts alignment after the 4-byte header."""
    return pos + (-(pos - 4)) % size


def _float64_layout(data: bytes) -> tuple[dict[str, int], int | None, tuple[str, ...],
                                          list[tuple[int, int]]] | None:
    if len(data) != 12 or data[:4] != _CDR_LE:
        return None
    return {'value': 4}, None, (), []


def _joint_state_layout(data: bytes) -> tuple[dict[str, int], int | None, tuple[str, ...],
                                              list[tuple[int, int]]] | None:
    """Parse a one-joint JointState payload: value offsets, stamp, name, padding spans."""
    if data[:4] != _CDR_LE or len(data) < 16:
        return None
    padding: list[tuple[int, int]] = []

    def aligned(pos: int, size: int) -> int:
        new = _align(pos, size)
        if new > pos:
            padding.append((pos, new))
        return new

    def uint32(pos: int) -> int:
        if pos + 4 > len(data):
            raise IndexError(pos)
        return int(struct.unpack_from('<I', data, pos)[0])

    try:
        pos = 12 + 4 + uint32(12)                  # stamp, frame_id
        pos = aligned(pos, 4)
        if uint32(pos) != 1:                       # one joint name
            return None
        length = uint32(pos + 4)
        name = data[pos + 8:pos + 8 + length - 1].decode()
        pos = pos + 8 + length
        fields: dict[str, int] = {}
        for array in ('position', 'velocity', 'effort'):
            pos = aligned(pos, 4)
            count = uint32(pos)
            if count > 1:
                return None
            # Fast CDR aligns a sequence of doubles to 8 even when it is empty.
            pos = aligned(pos + 4, 8)
            if count == 1:
                fields[array] = pos
                pos += 8
    except (IndexError, UnicodeDecodeError):
        return None
    if pos != len(data):
        return None
    return fields, 4, (name,), padding


_LAYOUT_PARSERS: Final[dict[str, Callable[[bytes], Any]]] = {
    _JOINT_STATE: _joint_state_layout, _FLOAT64: _float64_layout}


def _layout(type_name: str, cls: type, record: bytes) -> _Layout | None:
    """Return the layout of a message record, checked against rclpy's decoder, or None."""
    data = record[_DATA:]
    parsed = _LAYOUT_PARSERS[type_name](data)
    if parsed is None:
        return None
    fields, stamp, names, padding = parsed
    try:
        msg = deserialize_message(data, cls)
    except Exception:
        return None
    # The parse must say what rclpy says, bit for bit.
    for key, at in fields.items():
        value = msg.data if key == 'value' else getattr(msg, key)[0]
        if struct.pack('<d', value) != data[at:at + 8]:
            return None
    if type_name == _JOINT_STATE:
        if tuple(msg.name) != names or [k for k in ('position', 'velocity', 'effort')
                                        if len(getattr(msg, k))] != list(fields):
            return None
        if (msg.header.stamp.sec, msg.header.stamp.nanosec) != struct.unpack_from(
                '<iI', data, 4):
            return None
    fixed = np.ones(len(record), dtype=bool)
    fixed[11:_DATA] = False                  # sequence, log time, publish time
    for at in fields.values():
        fixed[_DATA + at:_DATA + at + 8] = False
    if stamp is not None:
        fixed[_DATA + stamp:_DATA + stamp + 8] = False
    for start, end in padding:
        fixed[_DATA + start:_DATA + end] = False
    return _Layout(size=len(record), fixed=fixed,
                   fields={k: _DATA + v for k, v in fields.items()},
                   stamp=None if stamp is None else _DATA + stamp, names=names)


# -- per-topic accumulation ---------------------------------------------------------------------


class _Topic:
    """The rows of one decoded topic, gathered block by block in file order."""

    def __init__(self, path: Path, topic: str, kind: str, type_name: str) -> None:
        self.path, self.topic, self.kind, self.type_name = path, topic, kind, type_name
        self.cls = message_class(type_name)
        self.count = 0
        self.parts: dict[str, list[NDArray[Any]]] = {}
        self.names: tuple[str, ...] | None = None
        self.messages: list[tuple[int, Any]] = []

    def add(self, u8: _U8, record: bytes, offsets: IntArray, lengths: IntArray,
            fast: bool) -> None:
        if self.kind in ('diagnostics', 'parameter_events'):
            for at, length in zip(offsets.tolist(), lengths.tolist(), strict=True):
                log_time = int.from_bytes(record[at + _LOG_TIME:at + _LOG_TIME + 8], 'little')
                self.messages.append((log_time, _decode(
                    self.path, self.topic, self.cls, record[at + _DATA:at + 9 + length],
                    log_time)))
        else:
            self._add_arrays(u8, record, offsets, lengths, fast)
        self.count += len(offsets)

    def _add_arrays(self, u8: _U8, record: bytes, offsets: IntArray, lengths: IntArray,
                    fast: bool) -> None:
        n = len(offsets)
        joint = self.kind == 'joint_states'
        out: dict[str, NDArray[Any]] = {'stamp_ns': np.empty(n, dtype=np.int64)}
        if joint:
            out['header_stamp_ns'] = np.empty(n, dtype=np.int64)
        done = np.zeros(n, dtype=bool)
        for _ in range(_TEMPLATES if fast else 0):
            pending = np.flatnonzero(~done)
            if not len(pending):
                break
            first = int(pending[0])
            start = int(offsets[first])
            layout = _layout(self.type_name, self.cls,
                             record[start:start + 9 + int(lengths[first])])
            if layout is None or (joint and self.names not in (None, layout.names)):
                break
            candidates = pending[lengths[pending] == layout.size - 9]
            rows = _gather(u8, offsets[candidates], layout.size)
            same = (rows[:, layout.fixed] == rows[0, layout.fixed]).all(axis=1)
            take, rows = candidates[same], rows[same]
            out['stamp_ns'][take] = _column(rows, _LOG_TIME, '<i8')
            if joint:
                assert layout.stamp is not None
                self.names = layout.names
                out['header_stamp_ns'][take] = (
                    _column(rows, layout.stamp, '<i4').astype(np.int64) * 10**9
                    + _column(rows, layout.stamp + 4, '<u4'))
                for key in ('position', 'velocity', 'effort'):
                    column = out.setdefault(key, np.full((n, 1), np.nan))
                    if key in layout.fields:
                        column[take, 0] = _column(rows, layout.fields[key], '<f8')
            else:
                column = out.setdefault('value', np.empty(n))
                column[take] = _column(rows, layout.fields['value'], '<f8')
            done[take] = True
        for row in np.flatnonzero(~done).tolist():
            self._decode_row(out, row, record, int(offsets[row]), int(lengths[row]))
        for key, array in out.items():
            self.parts.setdefault(key, []).append(array)

    def _decode_row(self, out: dict[str, NDArray[Any]], row: int, record: bytes, at: int,
                    length: int) -> None:
        log_time = int.from_bytes(record[at + _LOG_TIME:at + _LOG_TIME + 8], 'little')
        msg = _decode(self.path, self.topic, self.cls, record[at + _DATA:at + 9 + length],
                      log_time)
        out['stamp_ns'][row] = log_time
        n = len(out['stamp_ns'])
        if self.kind != 'joint_states':
            out.setdefault('value', np.empty(n))[row] = msg.data
            return
        names = tuple(msg.name)
        if self.names is None:
            self.names = names
        if names != self.names:
            raise RecorderError(f'{self.topic}: message {self.count + row} names joints '
                                f'{list(names)}, the first named {list(self.names)}')
        out['header_stamp_ns'][row] = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        for key in ('position', 'velocity', 'effort'):
            column = out.setdefault(key, np.full((n, len(names)), np.nan))
            values = getattr(msg, key)
            if len(values) == len(names):
                column[row] = values
            elif len(values):
                raise RecorderError(f'{self.topic}: message {self.count + row} has '
                                    f'{len(values)} {key} values for {len(names)} joints')

    def arrays(self) -> dict[str, NDArray[Any]]:
        """Join the parts (consuming them): one array per field over the whole run."""
        return {key: np.concatenate(self.parts.pop(key)) for key in list(self.parts)}

    def result(self) -> JointStates | Series | Diagnostics | tuple[tuple[int, Any], ...]:
        if self.kind == 'parameter_events':
            return tuple(self.messages)
        if self.kind == 'diagnostics':
            return _diagnostics(self.messages)
        a = self.arrays()
        stamp_ns = a.get('stamp_ns', np.empty(0, dtype=np.int64))
        t = _seconds(stamp_ns)
        if self.kind != 'joint_states':
            return Series(t=t, stamp_ns=stamp_ns, value=a.get('value', np.empty(0)))
        names = self.names or ()
        columns = []
        for key in ('position', 'velocity', 'effort'):
            column = a.get(key, np.empty((len(stamp_ns), len(names))))
            if column.shape[1] != len(names):   # rows of several joints and no fast rows
                column = column.reshape(len(stamp_ns), len(names))
            columns.append(column[:, 0] if len(names) == 1 else column)
        return JointStates(t=t, stamp_ns=stamp_ns,
                           header_stamp_ns=a.get('header_stamp_ns', np.empty(0, np.int64)),
                           name=names, position=columns[0], velocity=columns[1],
                           effort=columns[2])


def _seconds(stamp_ns: IntArray) -> FloatArray:
    return stamp_ns.astype(np.float64) * 1e-9


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float('nan')


def _diagnostics(msgs: list[tuple[int, Any]]) -> Diagnostics:
    stamp_ns = np.array([ns for ns, _ in msgs], dtype=np.int64)
    values: dict[str, FloatArray] = {}
    for row, (_, msg) in enumerate(msgs):
        for status in msg.status:
            for pair in status.values:
                key = f'{status.name}/{pair.key}'
                if key not in values:
                    values[key] = np.full(len(msgs), np.nan)
                values[key][row] = _float_or_nan(pair.value)
    return Diagnostics(t=_seconds(stamp_ns), stamp_ns=stamp_ns, values=values,
                       messages=tuple(m for _, m in msgs))


# -- walking the file ---------------------------------------------------------------------------


@dataclass
class _Load:
    """State of one load: channels met so far, topics decoded, reset events."""

    walker: Walker
    fast: bool
    counts: dict[int, int] = field(default_factory=dict)
    decoded: dict[int, _Topic] = field(default_factory=dict)
    kinds: dict[str, int] = field(default_factory=dict)
    skipped: dict[int, str] = field(default_factory=dict)
    reset_channels: set[int] = field(default_factory=set)
    resets: list[tuple[int, str, dict[str, int]]] = field(default_factory=list)
    stop_channels: set[int] = field(default_factory=set)
    stops: list[tuple[int, str]] = field(default_factory=list)
    seen: set[int] = field(default_factory=set)

    def channel(self, cid: int) -> None:
        """Classify a channel the first time a message refers to it."""
        self.seen.add(cid)
        self.counts.setdefault(cid, 0)
        channel = self.walker.channels[cid]
        schema = self.walker.schemas.get(channel.schema_id)
        if schema is None or channel.message_encoding != 'cdr':
            self.skipped[cid] = (f"it is not a ROS 2 CDR channel (message encoding "
                                 f"'{channel.message_encoding}', "
                                 f"{'no schema' if schema is None else 'schema ' + schema.name})")
            return
        try:
            check_message_type(schema.name)
        except RecorderError as exc:
            self.skipped[cid] = str(exc)
            return
        if channel.topic == RESET_TOPIC and schema.name == RESET_TYPE:
            self.reset_channels.add(cid)
            return
        if channel.topic == STOPPED_TOPIC and schema.name == STOPPED_TYPE:
            self.stop_channels.add(cid)
            return
        basename = channel.topic.rsplit('/', 1)[-1]
        if _KINDS.get(basename) == schema.name and basename not in self.kinds:
            self.kinds[basename] = cid
            self.decoded[cid] = _Topic(self.walker.path, channel.topic, basename, schema.name)

    def batch(self, blocks: list[Block]) -> None:
        """Decode the messages of consecutive blocks at once (a malformed block: see Walker)."""
        batch = _locate_batch(self.walker, blocks)
        if batch is None:
            return
        data, offsets, lengths, channels, bases = batch
        u8 = np.frombuffer(data, dtype=np.uint8)
        present, counts = np.unique(channels, return_counts=True)
        for cid, count in zip(present.tolist(), counts.tolist(), strict=True):
            if cid not in self.seen:
                if cid not in self.walker.channels:
                    row = int(np.flatnonzero(channels == cid)[0])
                    block = blocks[int(np.searchsorted(bases, offsets[row], 'right')) - 1]
                    raise RecorderError(
                        f'{self.walker.path} is corrupted: a message in the '
                        f'{record_name(block.opcode)} record at byte {block.offset} refers '
                        f'to channel {cid}, which is not defined')
                self.channel(cid)
            self.counts[cid] += count
        selected = {cid: np.flatnonzero(channels == cid) for cid in present.tolist()
                    if cid in self.decoded or cid in self.reset_channels
                    or cid in self.stop_channels}
        for cid in self.stop_channels & selected.keys():
            for row in selected[cid].tolist():
                at, length = int(offsets[row]), int(lengths[row])
                log_time = int.from_bytes(data[at + _LOG_TIME:at + _LOG_TIME + 8], 'little')
                msg = _decode(self.walker.path, STOPPED_TOPIC, message_class(STOPPED_TYPE),
                              data[at + _DATA:at + 9 + length], log_time)
                self.stops.append((log_time, msg.data))
        for cid in self.reset_channels & selected.keys():
            for row in selected[cid].tolist():
                at, length = int(offsets[row]), int(lengths[row])
                log_time = int.from_bytes(data[at + _LOG_TIME:at + _LOG_TIME + 8], 'little')
                msg = _decode(self.walker.path, RESET_TOPIC, message_class(RESET_TYPE),
                              data[at + _DATA:at + 9 + length], log_time)
                before = {topic.kind: topic.count + int(np.searchsorted(
                    selected[tid], row)) if tid in selected else topic.count
                          for tid, topic in self.decoded.items()}
                self.resets.append((log_time, msg.data, before))
        for cid, rows in selected.items():
            if cid in self.decoded:
                self.decoded[cid].add(u8, data, offsets[rows], lengths[rows], self.fast)


_Batch = tuple[bytes, IntArray, IntArray, IntArray, IntArray]


def _locate_batch(walker: Walker, blocks: list[Block]) -> _Batch | None:
    """Return the blocks' records joined, with offsets, lengths, channels and block starts.

    Blocks that all have a message index are checked at once (:func:`_indexed`); otherwise, or
    if that check fails, block by block (:func:`_locate`).
    """
    if not blocks:
        return None
    if all(block.index for block in blocks):
        located = _indexed(walker, blocks)
        if located is not None:
            return located
    datas: list[bytes] = []
    parts: list[tuple[IntArray, IntArray, IntArray]] = []
    bases: list[int] = []
    base = 0
    for block in blocks:
        try:
            offsets, lengths, channels = _locate(walker, block)
        except Exception as exc:
            walker.corrupted(block.opcode, block.offset, exc)
            continue
        datas.append(block.data)
        parts.append((offsets + base, lengths, channels))
        bases.append(base)
        base += len(block.data)
    if not parts:
        return None
    offsets, lengths, channels = (np.concatenate([p[i] for p in parts]) for i in range(3))
    return b''.join(datas), offsets, lengths, channels, np.array(bases, dtype=np.int64)


def _locate(walker: Walker, block: Block) -> tuple[IntArray, IntArray, IntArray]:
    """Return offsets, payload lengths and channels of a block's message records, in order.

    The records are walked one by one (a block without a usable message index).
    """
    data = block.data
    offsets: list[int] = []
    for opcode, start, end in records_in(data):
        if opcode == Opcode.MESSAGE:
            if end - start < _DATA:
                raise ValueError(f'a message record at offset {start} is too short')
            offsets.append(start)
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            walker.define(opcode, memoryview(data)[start + RECORD_HEAD.size:end])
    at = np.array(offsets, dtype=np.int64)
    u8 = np.frombuffer(data, dtype=np.uint8)
    return (at, _column(_gather(u8, at + 1, 8), 0, '<u8').astype(np.int64),
            _column(_gather(u8, at + 9, 2), 0, '<u2').astype(np.int64))


def _indexed(walker: Walker, blocks: list[Block]) -> _Batch | None:
    """Locate the message records of blocks from their message indexes, checking them.

    The indexed records must be message records that, with the schema and channel records in
    between, tile each block exactly, so that no message is missed or read twice.
    """
    sizes = np.array([len(block.data) for block in blocks], dtype=np.int64)
    bases = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    runs = []
    for block, size, base in zip(blocks, sizes.tolist(), bases.tolist(), strict=True):
        assert block.index
        index = np.sort(np.concatenate(list(block.index.values())))
        if not len(index) or int(index[-1]) > size - _DATA:
            return None
        runs.append(index.astype(np.int64) + base)
    counts = np.array([len(run) for run in runs], dtype=np.int64)
    offsets = np.concatenate(runs)
    data = b''.join(block.data for block in blocks)
    u8 = np.frombuffer(data, dtype=np.uint8)
    if (u8[offsets] != Opcode.MESSAGE).any():
        return None
    lengths = _column(_gather(u8, offsets + 1, 8), 0, '<u8')
    if (lengths < _DATA - 9).any() or (lengths > len(data)).any():
        return None
    lengths = lengths.astype(np.int64)
    ends = np.cumsum(counts)
    # Per block: [o1, ..., on, block end] must equal [block start, end of o1, ..., end of on],
    # except where schema or channel records fill the gap.
    starts = np.insert(offsets, ends, bases + sizes)
    previous_ends = np.insert(offsets + 9 + lengths, ends - counts, bases)
    for gap in np.flatnonzero(starts != previous_ends).tolist():
        begin, end = int(previous_ends[gap]), int(starts[gap])
        if begin > end:
            return None    # overlapping records
        try:
            for opcode, start, stop in records_in(data, begin, end):
                if opcode == Opcode.MESSAGE:
                    return None   # a message the index leaves out
                if opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                    walker.define(opcode, memoryview(data)[start + RECORD_HEAD.size:stop])
        except Exception:
            return None   # block by block, a malformed record is reported with its offset
    channels = _column(_gather(u8, offsets + 9, 2), 0, '<u2').astype(np.int64)
    return data, offsets, lengths, channels, bases


def _segments(whole: Segment, counts: dict[str, int],
              resets: Iterable[dict[str, int]]) -> tuple[Segment, ...]:
    bounds = [{kind: 0 for kind in counts}, *resets, counts]
    out = []
    for before, after in itertools.pairwise(bounds):
        def part(kind: str, value: Any, before: dict[str, int] = before,
                 after: dict[str, int] = after) -> Any:
            if value is None:
                return None
            return _slice(value, before.get(kind, 0), after.get(kind, 0))
        out.append(Segment(
            joint_states=part('joint_states', whole.joint_states),
            energy=part('energy', whole.energy),
            effort_command=part('effort_command', whole.effort_command),
            diagnostics=part('diagnostics', whole.diagnostics),
            parameter_events=part('parameter_events', whole.parameter_events) or ()))
    return tuple(out)


def _slice(value: Any, a: int, b: int) -> Any:
    if isinstance(value, tuple):
        return value[a:b]
    if isinstance(value, Diagnostics):
        return Diagnostics(t=value.t[a:b], stamp_ns=value.stamp_ns[a:b],
                           values={k: v[a:b] for k, v in value.values.items()},
                           messages=value.messages[a:b])
    if isinstance(value, Series):
        return Series(t=value.t[a:b], stamp_ns=value.stamp_ns[a:b], value=value.value[a:b])
    assert isinstance(value, JointStates)
    return JointStates(t=value.t[a:b], stamp_ns=value.stamp_ns[a:b],
                       header_stamp_ns=value.header_stamp_ns[a:b], name=value.name,
                       position=value.position[a:b], velocity=value.velocity[a:b],
                       effort=value.effort[a:b])


def load(path: str | Path, *, fast: bool = True) -> Recording:
    """Load a recording made by :class:`McapRecorder` (or any ROS 2 MCAP file) into numpy.

    A truncated file is loaded as far as it is readable, with a
    :class:`TruncatedRecordingWarning`, ``complete`` False and the reason in ``problems``; so is
    a recording cut short (its stop event), with ``stopped_ns`` where it stopped.
    A file that is not MCAP, from another profile, or corrupted raises :class:`RecorderError`.
    ``fast=False`` decodes every message with rclpy (see the module docstring); the result is
    the same.
    """
    walker = Walker(path, 'raise')
    state = _Load(walker, fast)
    pending: list[Block] = []
    size = 0
    for block in walker.blocks():
        if walker.profile != 'ros2':
            break
        pending.append(block)
        size += len(block.data)
        if size >= _BATCH_BYTES:
            state.batch(pending)
            pending, size = [], 0
    state.batch(pending)
    if walker.profile != 'ros2':
        raise RecorderError(f"{walker.path} has MCAP profile '{walker.profile}', expected "
                            f"'ros2'")
    problems = list(walker.problems)
    for stamp_ns, reason in state.stops:
        problems.append(f'{walker.path} was cut short at {stamp_ns} ns '
                        f'(t = {stamp_ns / 1e9:.9g} s): {reason}')
    for problem in problems:
        warnings.warn(problem, TruncatedRecordingWarning, stacklevel=2)
    for cid in walker.channels:
        if cid not in state.seen:
            state.seen.add(cid)
            state.channel(cid)
    for cid, reason in state.skipped.items():
        warnings.warn(f'{walker.path}: skipping topic {walker.channels[cid].topic}: {reason}',
                      SkippedChannelWarning, stacklevel=2)
    topics = {}
    for cid, channel in walker.channels.items():
        if cid in state.skipped:
            continue
        schema = walker.schemas[channel.schema_id]
        topics[channel.topic] = TopicInfo(name=channel.topic, type=schema.name,
                                          message_count=state.counts.get(cid, 0),
                                          metadata=dict(channel.metadata))
    results: dict[str, Any] = {kind: state.decoded[cid].result()
                               for kind, cid in state.kinds.items()}
    whole = Segment(joint_states=results.get('joint_states'), energy=results.get('energy'),
                    effort_command=results.get('effort_command'),
                    diagnostics=results.get('diagnostics'),
                    parameter_events=results.get('parameter_events', ()))
    counts = {topic.kind: topic.count for topic in state.decoded.values()}
    segments = _segments(whole, counts, (before for _, _, before in state.resets))
    return Recording(
        joint_states=whole.joint_states, energy=whole.energy,
        effort_command=whole.effort_command, diagnostics=whole.diagnostics,
        parameter_events=whole.parameter_events,
        path=walker.path, profile=walker.profile, metadata=walker.metadata, topics=topics,
        segments=segments, resets=np.array([ns for ns, _, _ in state.resets], dtype=np.int64),
        reset_messages=tuple(text for _, text, _ in state.resets),
        complete=walker.complete and not state.stops, problems=tuple(problems),
        stopped_ns=state.stops[0][0] if state.stops else None)
