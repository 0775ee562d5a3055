"""Load a recording into numpy arrays per topic, for notebooks and reports.

Example
-------
>>> rec = load('run.mcap')                                      # doctest: +SKIP
>>> rec.joint_states.t, rec.joint_states.position, rec.energy.value  # doctest: +SKIP

Times ``t`` are the messages' log times in seconds (the simulated stamps the node recorded);
``stamp_ns`` holds the same times as exact integers. Payloads are decoded with rclpy's
``deserialize_message`` into the generated message classes named by the schemas.
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message

from pendulum_sim.recording.errors import RecorderError
from pendulum_sim.recording.reader import RawMessage, scan
from pendulum_sim.recording.schemas import message_class

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class TruncatedRecordingWarning(UserWarning):
    """A recording was not closed (killed, disk full): only its readable part was loaded."""


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

    ``effort`` is NaN where a message carried no effort.
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
class Recording:
    """A loaded recording: numpy arrays per topic, metadata and what was wrong with the file."""

    path: Path
    profile: str
    metadata: dict[str, dict[str, str]]
    topics: dict[str, TopicInfo]
    joint_states: JointStates | None
    energy: Series | None
    effort_command: Series | None
    diagnostics: Diagnostics | None
    parameter_events: tuple[tuple[int, Any], ...]
    complete: bool
    problems: tuple[str, ...]
    _raw: dict[str, list[RawMessage]] = field(repr=False, default_factory=dict)

    @property
    def scene(self) -> dict[str, str]:
        """Return the scene parameters the recording was made with."""
        return self.metadata.get('scene', {})

    def messages(self, topic: str) -> list[tuple[int, Any]]:
        """Return ``(log_time_ns, decoded message)`` for every message of a topic."""
        if topic not in self.topics:
            raise RecorderError(f'{self.path} has no topic {topic}; it has '
                                f'{", ".join(sorted(self.topics)) or "none"}')
        cls = message_class(self.topics[topic].type)
        return [(m.log_time, deserialize_message(m.data, cls)) for m in self._raw[topic]]


def _times(raw: Sequence[RawMessage]) -> tuple[FloatArray, IntArray]:
    stamp_ns = np.array([m.log_time for m in raw], dtype=np.int64)
    return (stamp_ns * 1e-9).astype(np.float64), stamp_ns


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float('nan')


def _joint_states(topic: str, msgs: list[tuple[int, Any]],
                  raw: list[RawMessage]) -> JointStates:
    t, stamp_ns = _times(raw)
    names = tuple(msgs[0][1].name) if msgs else ()
    count = len(names)
    position = np.full((len(msgs), count), np.nan)
    velocity = np.full((len(msgs), count), np.nan)
    effort = np.full((len(msgs), count), np.nan)
    for row, (_, msg) in enumerate(msgs):
        if tuple(msg.name) != names:
            raise RecorderError(f'{topic}: message {row} names joints {list(msg.name)}, the '
                                f'first named {list(names)}')
        for array, values in ((position, msg.position), (velocity, msg.velocity),
                              (effort, msg.effort)):
            if len(values):
                array[row] = values
    header = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs],
                      dtype=np.int64)
    if count == 1:
        position, velocity, effort = position[:, 0], velocity[:, 0], effort[:, 0]
    return JointStates(t=t, stamp_ns=stamp_ns, header_stamp_ns=header, name=names,
                       position=position, velocity=velocity, effort=effort)


def _series(msgs: list[tuple[int, Any]], raw: list[RawMessage]) -> Series:
    t, stamp_ns = _times(raw)
    return Series(t=t, stamp_ns=stamp_ns,
                  value=np.array([m.data for _, m in msgs], dtype=np.float64))


def _diagnostics(msgs: list[tuple[int, Any]], raw: list[RawMessage]) -> Diagnostics:
    t, stamp_ns = _times(raw)
    values: dict[str, FloatArray] = {}
    for row, (_, msg) in enumerate(msgs):
        for status in msg.status:
            for pair in status.values:
                key = f'{status.name}/{pair.key}'
                if key not in values:
                    values[key] = np.full(len(msgs), np.nan)
                values[key][row] = _float_or_nan(pair.value)
    return Diagnostics(t=t, stamp_ns=stamp_ns, values=values,
                       messages=tuple(m for _, m in msgs))


def load(path: str | Path) -> Recording:
    """Load a recording made by :class:`McapRecorder` (or any ROS 2 MCAP file) into numpy.

    A truncated file is loaded as far as it is readable, with a
    :class:`TruncatedRecordingWarning`, ``complete`` False and the reason in ``problems``.
    A file that is not MCAP, from another profile, or corrupted raises :class:`RecorderError`.
    """
    result = scan(path, corrupt='raise')
    if result.profile != 'ros2':
        raise RecorderError(f"{result.path} has MCAP profile '{result.profile}', expected "
                            f"'ros2'")
    for problem in result.problems:
        warnings.warn(problem, TruncatedRecordingWarning, stacklevel=2)
    by_channel: dict[int, list[RawMessage]] = {cid: [] for cid in result.channels}
    for message in result.sorted_messages():
        if message.channel_id not in by_channel:
            raise RecorderError(f'{result.path} is corrupted: a message at byte '
                                f'{message.offset} refers to channel {message.channel_id}, '
                                f'which is not defined')
        by_channel[message.channel_id].append(message)
    topics: dict[str, TopicInfo] = {}
    raw: dict[str, list[RawMessage]] = {}
    for cid, channel in result.channels.items():
        schema = result.schemas.get(channel.schema_id)
        if schema is None or channel.message_encoding != 'cdr':
            raise RecorderError(f'{result.path}: topic {channel.topic} has no ROS 2 schema or '
                                f"is not CDR (encoding '{channel.message_encoding}')")
        topics[channel.topic] = TopicInfo(name=channel.topic, type=schema.name,
                                          message_count=len(by_channel[cid]),
                                          metadata=dict(channel.metadata))
        raw[channel.topic] = by_channel[cid]

    def decoded(topic: str) -> list[tuple[int, Any]]:
        cls = message_class(topics[topic].type)
        out = []
        for m in raw[topic]:
            try:
                out.append((m.log_time, deserialize_message(m.data, cls)))
            except Exception as exc:
                raise RecorderError(f'{result.path} is corrupted: the {topics[topic].type} '
                                    f'message at log time {m.log_time} ns on {topic} cannot '
                                    f'be decoded ({exc})') from exc
        return out

    def find(basename: str, type_name: str) -> str | None:
        for topic, info in topics.items():
            if topic.rsplit('/', 1)[-1] == basename and info.type == type_name:
                return topic
        return None

    joint_topic = find('joint_states', 'sensor_msgs/msg/JointState')
    energy_topic = find('energy', 'std_msgs/msg/Float64')
    effort_topic = find('effort_command', 'std_msgs/msg/Float64')
    diagnostics_topic = find('diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')
    events_topic = find('parameter_events', 'rcl_interfaces/msg/ParameterEvent')
    return Recording(
        path=result.path,
        profile=result.profile,
        metadata=result.metadata,
        topics=topics,
        joint_states=(None if joint_topic is None else
                      _joint_states(joint_topic, decoded(joint_topic), raw[joint_topic])),
        energy=(None if energy_topic is None else
                _series(decoded(energy_topic), raw[energy_topic])),
        effort_command=(None if effort_topic is None else
                        _series(decoded(effort_topic), raw[effort_topic])),
        diagnostics=(None if diagnostics_topic is None else
                     _diagnostics(decoded(diagnostics_topic), raw[diagnostics_topic])),
        parameter_events=(() if events_topic is None else tuple(decoded(events_topic))),
        complete=result.complete,
        problems=tuple(result.problems),
        _raw=raw,
    )
