"""Shared helpers of the recording and replay tests (no tests here)."""
from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.recording import McapRecorder, RecorderError, load
from pendulum_sim.recording.loader import TruncatedRecordingWarning

TOPICS = {
    '/joint_states': (JointState, QoSProfile(depth=10)),
    '/energy': (Float64, QoSProfile(depth=10)),
    '/effort_command': (Float64, QoSProfile(
        depth=5, reliability=QoSReliabilityPolicy.BEST_EFFORT)),
    '/diagnostics': (DiagnosticArray, QoSProfile(depth=10)),
    '/parameter_events': (ParameterEvent, QoSProfile(
        depth=1000, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)),
}
SCENE = {'gamma': '1.0', 'n': '1.5', 'rate_hz': '1000.0', 'recording.path': 'x.mcap'}
METADATA = {'scene': SCENE, 'pendulum_sim': {'version': '0.1.0'}}


def stamp_of(ns: int) -> tuple[int, int]:
    """Split nanoseconds into ``(sec, nanosec)``."""
    return divmod(ns, 10**9)


def joint_state(k: int, ns: int) -> JointState:
    """Return a JointState with values that differ in every field from message to message."""
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(ns)
    msg.header.frame_id = f'frame{k % 3}'
    msg.name = ['pendulum_joint']
    msg.position = [0.5 * k - 1.0 / (k + 1)]
    msg.velocity = [-0.25 * k + 1e-9 * k * k]
    msg.effort = [] if k % 7 == 3 else [1e-3 * k]
    return msg


def diagnostic_array(k: int, ns: int) -> DiagnosticArray:
    """Return a DiagnosticArray with two statuses and key-value pairs."""
    msg = DiagnosticArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(ns)
    msg.status = [
        DiagnosticStatus(level=DiagnosticStatus.OK, name='pendulum: loop', message='ok',
                         hardware_id='sim',
                         values=[KeyValue(key='wake_latency_p99_ms', value=f'{0.01 * k:.6f}'),
                                 KeyValue(key='overruns', value=str(k))]),
        DiagnosticStatus(level=DiagnosticStatus.WARN, name='pendulum: guard',
                         message=f'warn {k}', hardware_id='', values=[]),
    ]
    return msg


def parameter_event(k: int, ns: int) -> ParameterEvent:
    """Return a ParameterEvent that changes a double and adds an array parameter."""
    msg = ParameterEvent()
    msg.stamp.sec, msg.stamp.nanosec = stamp_of(ns)
    msg.node = '/pendulum'
    msg.changed_parameters = [Parameter(name='gamma', value=ParameterValue(
        type=ParameterType.PARAMETER_DOUBLE, double_value=0.1 * k))]
    msg.new_parameters = [Parameter(name=f'extra{k}', value=ParameterValue(
        type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[1.0, 2.0 * k]))]
    return msg


def scripted_messages(count: int, period_ns: int = 1_000_000,
                      t0_ns: int = 0) -> list[tuple[str, Any, int]]:
    """Return ``(topic, message, stamp_ns)`` like a node running ``count`` loop ticks."""
    out: list[tuple[str, Any, int]] = []
    for k in range(count):
        ns = t0_ns + k * period_ns
        out.append(('/joint_states', joint_state(k, ns), ns))
        out.append(('/energy', Float64(data=1.0 / (k + 1)), ns))
        if k % 5 == 0:
            out.append(('/effort_command', Float64(data=0.01 * k - 0.3), ns))
        if k % 100 == 50:
            out.append(('/diagnostics', diagnostic_array(k, ns), ns))
        if k % 250 == 100:
            out.append(('/parameter_events', parameter_event(k, ns), ns))
    return out


def record(path: Path, messages: list[tuple[str, Any, int]], **kwargs: Any) -> McapRecorder:
    """Record messages on every topic of TOPICS and close the file."""
    with McapRecorder(path, metadata=METADATA, **kwargs) as rec:
        for topic, (msg_type, qos) in TOPICS.items():
            rec.add_channel(topic, msg_type, qos)
        for topic, msg, ns in messages:
            rec.write(topic, msg, ns)
    return rec


def read_independently(path: Path) -> tuple[Any, list[tuple[Any, Any, Any, Any]]]:
    """Read a file with mcap and mcap-ros2-support; return its summary and decoded messages."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        decoded = list(reader.iter_decoded_messages(log_time_order=False))
    return summary, decoded


def assert_same(a: Any, b: Any, where: str = 'rec') -> None:
    """Assert two loaded values are identical: arrays bit for bit (NaN payloads too)."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where
    elif hasattr(a, '__dataclass_fields__'):
        assert type(a) is type(b), where
        for name in a.__dataclass_fields__:
            assert_same(getattr(a, name), getattr(b, name), f'{where}.{name}')
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            assert_same(a[key], b[key], f'{where}[{key!r}]')
    elif isinstance(a, tuple) and a and hasattr(a[0], 'joint_states'):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f'{where}[{i}]')
    else:
        assert a == b, where


@contextlib.contextmanager
def ros_node(name: str) -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    """Give a node and an executor in a context of their own, shut down afterwards."""
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def spin_until(executor: SingleThreadedExecutor, done: Callable[[], bool],
               timeout: float) -> bool:
    """Spin until ``done()`` or the timeout; return ``done()``."""
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return done()


def joint_states_on_disk(path: Path) -> int:
    """Return how many joint_states the file holds now (a recording being written is truncated)."""
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', TruncatedRecordingWarning)
        try:
            rec = load(path)
        except RecorderError:  # no complete record yet
            return 0
    return 0 if rec.joint_states is None else len(rec.joint_states.t)
