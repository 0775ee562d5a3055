"""Replay an MCAP recording onto ROS 2 topics with its recorded timing, as ``ros2 bag play``.

Usage: ``pendulum_replay FILE.mcap [--rate R] [--loop] [--topics T ...] [--start S] [--end S]
[--clock [HZ]] [--wait-for-subscribers S]``. The raw CDR payloads are published unchanged, on
publishers made from each channel's schema name and recorded QoS offer. Damaged files are
replayed as far as that is safe: a truncated end is dropped, corrupted chunks are skipped and
channels of unknown types or encodings are left out, each with a warning on stderr.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TextIO

import rclpy
import yaml
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from pendulum_sim.dds import shut_down, use_loopback_profile
from pendulum_sim.recording.errors import RecorderError
from pendulum_sim.recording.reader import RawMessage, Scan, scan
from pendulum_sim.recording.schemas import message_class

PROG = 'pendulum_replay'
_PROGRESS_PERIOD = 0.1   # s between progress-line updates
_MAX_SLEEP = 0.05        # s; sleep in slices to publish /clock and update the progress line


MAX_SECONDS: Final = 9.2e9      # s; a time offset in int64 nanoseconds stays below 2**63
MAX_RATE: Final = 1e6
MAX_CLOCK_HZ: Final = 1e4
MAX_WAIT: Final = 86400.0       # s


def _number(low: float, high: float, low_allowed: bool) -> Callable[[str], float]:
    """Return an argparse type: a finite number in ``[low, high]`` (``(low, high]``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'must be a number, got {text!r}') from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f'must be a finite number, got {text}')
        if not (value >= low if low_allowed else value > low):
            raise argparse.ArgumentTypeError(f'must be {">=" if low_allowed else ">"} '
                                             f'{low:g}, got {text}')
        if value > high:
            raise argparse.ArgumentTypeError(f'must be <= {high:g}, got {text}')
        return value
    return parse


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser of ``pendulum_replay``."""
    parser = argparse.ArgumentParser(
        prog=PROG, description='Republish an MCAP recording with its recorded timing.')
    parser.add_argument('file', type=Path, help='the .mcap recording')
    parser.add_argument('--rate', type=_number(0, MAX_RATE, False), default=1.0,
                        help='playback speed factor (default 1.0)')
    parser.add_argument('--loop', action='store_true', help='replay again and again')
    parser.add_argument('--topics', nargs='+', metavar='T', default=None,
                        help='replay only these topics')
    parser.add_argument('--start', type=_number(0, MAX_SECONDS, True), default=0.0, metavar='S',
                        help='start S seconds after the first message')
    parser.add_argument('--end', type=_number(0, MAX_SECONDS, False), default=None, metavar='S',
                        help='stop S seconds after the first message')
    parser.add_argument('--clock', type=_number(0, MAX_CLOCK_HZ, False), nargs='?', const=100.0,
                        default=None,
                        metavar='HZ', help='publish /clock with the recorded time at HZ '
                        '(default 100 Hz when given without a value)')
    parser.add_argument('--wait-for-subscribers', type=_number(0, MAX_WAIT, True), default=0.0,
                        metavar='S', help='wait up to S seconds until every replayed topic '
                        'has a subscriber')
    return parser


@dataclass(frozen=True)
class _Plan:
    messages: list[RawMessage]
    topics: dict[int, tuple[str, str, QoSProfile]]   # channel id -> (topic, type, qos)
    first_ns: int
    start_ns: int
    end_ns: int


def _recorded_qos(channel_metadata: dict[str, str]) -> QoSProfile:
    """Return the profile to offer: the recorded reliability and durability, keep-last 1000."""
    profile = QoSProfile(depth=1000)
    try:
        offers = yaml.safe_load(channel_metadata.get('offered_qos_profiles', '')) or []
        offer = offers[0] if offers else {}
        if offer.get('reliability') == 'best_effort':
            profile.reliability = QoSReliabilityPolicy.BEST_EFFORT
        if offer.get('durability') == 'transient_local':
            profile.durability = QoSDurabilityPolicy.TRANSIENT_LOCAL
    except (yaml.YAMLError, AttributeError, TypeError, KeyError):
        pass
    return profile


def plan(result: Scan, topics: Sequence[str] | None, start: float, end: float | None,
         warn: TextIO) -> _Plan:
    """Choose the channels and messages to replay; warn about what is left out and why."""
    if result.profile != 'ros2':
        print(f"{PROG}: warning: {result.path} has MCAP profile '{result.profile}', not "
              f"'ros2'; replaying only its CDR channels with ROS 2 schemas", file=warn)
    chosen: dict[int, tuple[str, str, QoSProfile]] = {}
    for cid, channel in sorted(result.channels.items()):
        if topics is not None and channel.topic not in topics:
            continue
        schema = result.schemas.get(channel.schema_id)
        if (schema is None or channel.message_encoding != 'cdr'
                or schema.encoding not in ('ros2msg', 'ros2idl')):
            print(f'{PROG}: warning: skipping {channel.topic}: not a ROS 2 CDR channel '
                  f"(message encoding '{channel.message_encoding}', schema encoding "
                  f"'{'' if schema is None else schema.encoding}')", file=warn)
            continue
        try:
            message_class(schema.name)
        except RecorderError as exc:
            print(f'{PROG}: warning: skipping {channel.topic}: {exc}', file=warn)
            continue
        chosen[cid] = (channel.topic, schema.name, _recorded_qos(dict(channel.metadata)))
    if not chosen:
        raise RecorderError(f'{result.path} has nothing to replay')
    everything = result.sorted_messages()
    first_ns = everything[0].log_time if everything else 0
    start_ns = first_ns + round(start * 1e9)
    end_ns = 2**63 if end is None else first_ns + round(end * 1e9)
    messages = [m for m in everything
                if m.channel_id in chosen and start_ns <= m.log_time <= end_ns]
    if not messages:
        raise RecorderError(f'{result.path} has no messages to replay between {start} s and '
                            f'{end} s')
    return _Plan(messages=messages, topics=chosen, first_ns=first_ns, start_ns=start_ns,
                 end_ns=min(end_ns, messages[-1].log_time))


class _Progress:
    """Keep one status line on stderr up to date."""

    def __init__(self, stream: TextIO, total_s: float, count: int) -> None:
        self._stream, self._total_s, self._count = stream, total_s, count
        self._last = 0.0

    def show(self, at_s: float, done: int, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last >= _PROGRESS_PERIOD:
            self._last = now
            self._stream.write(f'\r[{PROG}] {at_s:8.3f} / {self._total_s:.3f} s  '
                               f'{done}/{self._count} messages')
            self._stream.flush()


def replay(node: Any, the_plan: _Plan, rate: float, loop: bool, clock_hz: float | None,
           wait_for_subscribers: float, stream: TextIO) -> int:
    """Publish the planned messages with their recorded timing; return how many were sent."""
    publishers = {cid: node.create_publisher(message_class(type_name), topic, qos)
                  for cid, (topic, type_name, qos) in the_plan.topics.items()}
    clock_pub = None
    if clock_hz is not None:
        from rosgraph_msgs.msg import Clock
        clock_pub = node.create_publisher(Clock, '/clock', 10)
    deadline = time.monotonic() + wait_for_subscribers
    while (time.monotonic() < deadline
           and any(p.get_subscription_count() == 0 for p in publishers.values())):
        time.sleep(0.01)

    def publish_clock(stamp_ns: int) -> None:
        if clock_pub is not None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(stamp_ns, 10**9)
            clock_pub.publish(msg)

    span_s = (the_plan.end_ns - the_plan.start_ns) * 1e-9
    progress = _Progress(stream, span_s, len(the_plan.messages))
    sent = 0
    clock_period = None if clock_hz is None else 1.0 / clock_hz
    while True:
        wall_start = time.monotonic()
        next_clock = wall_start
        for done, message in enumerate(the_plan.messages):
            target = wall_start + (message.log_time - the_plan.start_ns) * 1e-9 / rate
            while True:
                now = time.monotonic()
                if clock_period is not None and now >= next_clock:
                    # Never ahead of the message about to go out, so /clock never runs back.
                    publish_clock(min(message.log_time, the_plan.start_ns
                                      + round((now - wall_start) * rate * 1e9)))
                    next_clock += clock_period
                progress.show((now - wall_start) * rate, done)
                if now >= target:
                    break
                pause = target - now
                if clock_period is not None:
                    pause = min(pause, max(0.0, next_clock - now))
                time.sleep(min(pause, _MAX_SLEEP))
            publishers[message.channel_id].publish(message.data)
            sent += 1
        publish_clock(the_plan.end_ns)
        progress.show(span_s, len(the_plan.messages), force=True)
        if not loop:
            break
    for publisher in publishers.values():
        publisher.wait_for_all_acked(Duration(seconds=2))
    return sent


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pendulum_replay``; return the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.end is not None and args.end <= args.start:
        parser.error(f'argument --end: must be after --start ({args.start} s), got {args.end}')
    try:
        result = scan(args.file, corrupt='skip')
    except RecorderError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    if args.topics is not None:
        recorded = {c.topic for c in result.channels.values()}
        missing = [t for t in args.topics if t not in recorded]
        if missing:
            parser.error(f"argument --topics: {', '.join(missing)} not in {args.file} (it has "
                         f"{', '.join(sorted(recorded)) or 'no topics'})")
    for problem in result.problems:
        print(f'{PROG}: warning: {problem}', file=sys.stderr)
    try:
        the_plan = plan(result, args.topics, args.start, args.end, sys.stderr)
    except RecorderError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    # DDS on 127.0.0.1 unless the user chose a profile or a wider discovery range.
    use_loopback_profile(os.environ)
    # Ctrl-C and SIGTERM end the replay between two messages (Python raises KeyboardInterrupt
    # between bytecodes); rclpy's own handlers would shut the context down at once, in the
    # middle of a publish, which then fails (as pendulum_node, which also declines them).
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.default_int_handler)
    node = None
    try:
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node('pendulum_replay')
        replay(node, the_plan, args.rate, args.loop, args.clock, args.wait_for_subscribers,
               sys.stderr)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        sys.stderr.write('\n')
        shut_down(node, 0)
    return 0


if __name__ == '__main__':
    sys.exit(main())
