"""Publish fixed-layout messages as CDR bytes with a few fields patched in place.

rclpy converts a Python message to C and serializes it on every ``publish``; for the messages the
node publishes thousands of times a second (joint_states, energy, /clock) that conversion costs
more than the physics. Their layout never changes (one joint, no frame id), so each is serialized
once with sentinel values, the sentinels' byte offsets are found, and every publication patches
the new values into a copy and publishes the bytes (``Publisher.publish`` takes serialized
messages). A round-trip test checks the bytes deserialize to the intended message.
"""
from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any

from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

# Values no real message field takes, so their bytes occur once in the template.
_SEC, _NANOSEC = 0x5EC0FFEE, 0x3B9AC9F0
_DOUBLES = (1.2345678901234567e-301, 2.3456789012345678e-302, 3.4567890123456789e-303)


class PatchedMessage:
    """Serialize ``msg`` once; return its bytes with the sentinel fields replaced.

    Parameters
    ----------
    msg
        A message holding the sentinel values at the fields to patch.
    slots
        ``(struct format, sentinel values)`` per patched field group, in the order ``pack``
        takes their new values; each group's bytes must occur exactly once in the template.
    """

    def __init__(self, msg: Any, slots: Sequence[tuple[str, tuple[float | int, ...]]]) -> None:
        data = serialize_message(msg)
        # The CDR encapsulation header: 0x0001 little endian, 0x0000 big endian.
        order = '<' if data[1] == 1 else '>'
        found: list[tuple[int, int, str]] = []  # (offset, slot index, format)
        for index, (fmt, values) in enumerate(slots):
            raw = struct.pack(order + fmt, *values)
            at = data.find(raw)
            if at < 0 or data.find(raw, at + 1) >= 0:
                raise ValueError(f'sentinel {values!r} is not unique in the serialized '
                                 f'{type(msg).__name__}')
            found.append((at, index, fmt))
        found.sort()
        # One struct for the whole message: the fixed bytes between the slots as 's' fields.
        fmt_parts: list[str] = [order]
        self._fixed: list[bytes] = []
        pos = 0
        for at, _, fmt in found:
            if at < pos:
                raise ValueError('overlapping sentinels')
            fmt_parts.append(f'{at - pos}s{fmt}')
            self._fixed.append(data[pos:at])
            pos = at + struct.calcsize(order + fmt)
        fmt_parts.append(f'{len(data) - pos}s')
        self._fixed.append(data[pos:])
        self._struct = struct.Struct(''.join(fmt_parts))
        self._order = [index for _, index, _ in found]
        assert self._struct.size == len(data)

    @property
    def struct(self) -> struct.Struct:
        """Return the struct packing fixed parts and slots in byte order."""
        return self._struct

    @property
    def fixed(self) -> tuple[bytes, ...]:
        """Return the fixed byte strings around the slots (one more than the slots)."""
        return tuple(self._fixed)

    @property
    def slot_order(self) -> list[int]:
        """Return the slot indices in byte order."""
        return list(self._order)

    def pack(self, *groups: tuple[float | int, ...]) -> bytes:
        """Return the serialized message with each slot set to its group of values."""
        args: list[Any] = []
        for fixed, index in zip(self._fixed, self._order, strict=False):
            args.append(fixed)
            args.extend(groups[index])
        args.append(self._fixed[-1])
        return self._struct.pack(*args)


class JointStateBytes:
    """joint_states for one joint: stamp, position, velocity, effort patched per message."""

    def __init__(self, joint_name: str) -> None:
        msg = JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = _SEC, _NANOSEC
        msg.name = [joint_name]
        msg.position, msg.velocity, msg.effort = [_DOUBLES[0]], [_DOUBLES[1]], [_DOUBLES[2]]
        patched = PatchedMessage(msg, [('iI', (_SEC, _NANOSEC)), ('d', (_DOUBLES[0],)),
                                       ('d', (_DOUBLES[1],)), ('d', (_DOUBLES[2],))])
        # The fields lie in declaration order, so one struct call packs them all.
        assert patched.slot_order == [0, 1, 2, 3]
        self._pack = patched.struct.pack
        self._f = patched.fixed

    def pack(self, sec: int, nanosec: int, position: float, velocity: float,
             effort: float) -> bytes:
        """Return the serialized JointState."""
        f = self._f
        return self._pack(f[0], sec, nanosec, f[1], position, f[2], velocity, f[3], effort, f[4])


class ClockBytes:
    """rosgraph_msgs/Clock with the time patched."""

    def __init__(self) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = _SEC, _NANOSEC
        patched = PatchedMessage(msg, [('iI', (_SEC, _NANOSEC))])
        self._pack = patched.struct.pack
        self._f = patched.fixed

    def pack(self, sec: int, nanosec: int) -> bytes:
        """Return the serialized Clock."""
        f = self._f
        return self._pack(f[0], sec, nanosec, f[1])


class Float64Bytes:
    """std_msgs/Float64 with the value patched."""

    def __init__(self) -> None:
        patched = PatchedMessage(Float64(data=_DOUBLES[0]), [('d', (_DOUBLES[0],))])
        self._pack = patched.struct.pack
        self._f = patched.fixed

    def pack(self, value: float) -> bytes:
        """Return the serialized Float64."""
        f = self._f
        return self._pack(f[0], value, f[1])
