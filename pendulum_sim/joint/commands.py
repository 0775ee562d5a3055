"""Command decoding and the count of dropped commands, without ROS.

Each command input carries one value for the joint: ``effort_command`` (std_msgs/Float64, no
stamp), ``commands`` (std_msgs/Float64MultiArray of length 1, forward_command_controller, no
stamp) and ``joint_commands`` (sensor_msgs/JointState matched by joint name, the field of the
command interface, stamped; topic_based_ros2_control). The functions here read only the
fields, so they run on ROS messages and on plain values alike.

A command that cannot be used is dropped and counted under a reason from a fixed set (the
topic and a short reason that names no received value), so ``/diagnostics`` holds a bounded
number of keys whatever arrives; the received values appear only in a rate-limited log line,
cut to :data:`DETAIL_CHARS`.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

DETAIL_CHARS = 200
# Log a reason's first drop, then every LOG_EVERY-th.
LOG_EVERY = 1000


class Decoded(NamedTuple):
    """A decoded command: its value and stamp (ns, None without one), or why it is dropped."""

    value: float
    stamp_ns: int | None
    reason: str = ''
    detail: str = ''


def _short(text: str) -> str:
    return text if len(text) <= DETAIL_CHARS else text[:DETAIL_CHARS] + '...'


def from_array(data: Sequence[float]) -> Decoded:
    """Decode forward_command_controller's Float64MultiArray: exactly one value."""
    if len(data) != 1:
        return Decoded(0.0, None, 'expected 1 value (one joint)', f'got {len(data)}')
    return Decoded(float(data[0]), None)


def from_joint_state(joint: str, field: str, names: Sequence[str], values: Sequence[float],
                     sec: int, nanosec: int) -> Decoded:
    """Decode a JointState command: the ``field`` value of ``joint``, stamped (0 is a stamp)."""
    try:
        i = list(names).index(joint)
    except ValueError:
        return Decoded(0.0, None, f'no joint named {joint!r}',
                       _short(f'names {list(names)}'))
    if len(values) <= i:
        return Decoded(0.0, None, f'no {field} for joint {joint!r}',
                       f'{len(values)} {field} values for {len(names)} names')
    return Decoded(float(values[i]), sec * 1_000_000_000 + nanosec)


class Drops:
    """Count dropped commands per (topic, reason): a bounded set of keys."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    @property
    def total(self) -> int:
        """Return the commands dropped so far."""
        return sum(self.counts.values())

    def drop(self, topic: str, reason: str, detail: str = '') -> str | None:
        """Count a drop; return the log line when one is due (the first, then every 1000th)."""
        key = f'{topic}: {reason}'
        count = self.counts.get(key, 0) + 1
        self.counts[key] = count
        if count == 1 or count % LOG_EVERY == 0:
            more = f', {_short(detail)}' if detail else ''
            return f'dropped a command on {topic}: {reason}{more} ({count} so far)'
        return None


def incompatible_line(topic: str, policy: str, synchronous: bool, count: int) -> str | None:
    """Return the log line for a publisher on ``topic`` whose QoS cannot connect (the first,
    then every 100th), naming the policy and what to publish instead."""
    if count != 1 and count % 100 != 0:
        return None
    need = 'reliable (synchronous mode loses no command)' if synchronous else 'a compatible QoS'
    return (f'a publisher on {topic} cannot connect: its QoS is incompatible '
            f"({policy.removeprefix('RMW_QOS_POLICY_')}); publish {need} ({count} so far)")
