"""Test fixtures for pendulum_node: the node in its own process, a probe node in the test's.

Nothing is mocked: the node under test is the installed ``pendulum_node`` executable started with
``subprocess``, and the probe talks to it over real DDS (the environment from conftest.py keeps
DDS on this machine). Every wait polls with a timeout.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue, SetParametersResult
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile

from pendulum_sim.node.diagnostics import values_of

REPO = Path(__file__).resolve().parents[2]
NODE_NAME = 'pendulum_node'


def node_command() -> list[str]:
    """Return the command that starts the node: the venv's entry point script if installed."""
    script = Path(sys.executable).parent / 'pendulum_node'
    if script.is_file():
        return [str(script)]
    return [sys.executable, '-m', 'pendulum_sim.node.cli']


def unique_namespace() -> str:
    """Return a namespace no other test (or test run in the same domain) uses."""
    return f'/t{uuid.uuid4().hex[:10]}'


def ros_value(value: Any) -> str:
    """Return ``value`` in the YAML form that ``-p name:=value`` expects."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return f"'{value}'"
    return str(value)


class NodeProcess:
    """Run pendulum_node in its own process; stop it with a real signal.

    Parameters
    ----------
    scene : str or None
        Passed as ``--scene``; None starts without one.
    params : dict
        ``-p name:=value`` overrides, applied after the scene.
    namespace : str
        The node's namespace (unique per test).
    remap : dict
        Extra remapping rules, ``from:=to``.
    params_file : Path
        A parameter file given the ROS way, ``--ros-args --params-file``.
    """

    def __init__(self, scene: str | None = 'default', params: dict[str, Any] | None = None,
                 namespace: str | None = None, remap: dict[str, str] | None = None,
                 extra_args: Iterable[str] = (), params_file: Path | None = None) -> None:
        self.namespace = namespace or unique_namespace()
        self.fqn = f'{self.namespace}/{NODE_NAME}'
        cmd = node_command()
        if scene is not None:
            cmd += ['--scene', scene]
        cmd += list(extra_args)
        cmd += ['--ros-args', '-r', f'__ns:={self.namespace}']
        if params_file is not None:
            cmd += ['--params-file', str(params_file)]
        for src, dst in (remap or {}).items():
            cmd += ['-r', f'{src}:={dst}']
        for name, value in (params or {}).items():
            cmd += ['-p', f'{name}:={ros_value(value)}']
        self.cmd = cmd
        self._log = tempfile.TemporaryFile(mode='w+')
        self.proc: subprocess.Popen[str] | None = None
        self.returncode: int | None = None

    def start(self) -> NodeProcess:
        """Start the process."""
        self.proc = subprocess.Popen(self.cmd, stdout=self._log, stderr=subprocess.STDOUT,
                                     text=True, env=dict(os.environ))
        return self

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.stop()
        self._log.close()

    def alive(self) -> bool:
        """Return True while the process runs."""
        return self.proc is not None and self.proc.poll() is None

    def output(self) -> str:
        """Return what the process wrote to stdout and stderr so far."""
        self._log.flush()
        self._log.seek(0)
        return self._log.read()

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        """Send ``sig``, wait for the exit and return the exit code (kill after ``timeout``)."""
        assert self.proc is not None
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                raise AssertionError(
                    f'pendulum_node ignored signal {sig}:\n{self.output()}') from None
        self.returncode = self.proc.returncode
        return self.returncode

    def wait(self, timeout: float = 20.0) -> int:
        """Wait for the process to exit; return its exit code (fail with its output if not)."""
        assert self.proc is not None
        try:
            self.returncode = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f'{self.cmd[0]} still running after {timeout} s:\n'
                                 f'{self.output()}') from None
        return self.returncode


def ready_to_answer(node: Any, executor: Any, server_fqn: str, timeout: float = 30.0) -> None:
    """Return once the node ``server_fqn`` can answer every client ``node`` has made so far.

    ``service_is_ready()`` says that this side matched the server; the server may not have
    matched this client yet, and then it drops the request or the answer (rmw_fastrtps waits
    100 ms for the client's reader, then logs 'client will not receive response'): a call
    right after start-up waits forever. This asks the server's ``get_parameters`` for nothing,
    which changes nothing, again each second until it answers, from a client made after the
    others: discovery announces a participant's endpoints in the order they were made, over
    one reliable channel for writers and one for readers, so once this answer is back the
    server has matched the earlier clients' request writers and answer readers too.
    """
    client = node.create_client(GetParameters, f'{server_fqn}/get_parameters')
    try:
        end = time.monotonic() + timeout
        while True:
            while not client.service_is_ready():
                if time.monotonic() > end:
                    raise AssertionError(f'{server_fqn}/get_parameters did not appear within '
                                         f'{timeout} s')
                executor.spin_once(timeout_sec=0.02)
            future = client.call_async(GetParameters.Request())
            ask_again = min(end, time.monotonic() + 1.0)
            while not future.done() and time.monotonic() < ask_again:
                executor.spin_once(timeout_sec=0.02)
            if future.done():
                return
            if time.monotonic() >= end:
                raise AssertionError(f'{server_fqn} did not answer within {timeout} s')
    finally:
        node.destroy_client(client)


class Received:
    """Messages of one subscription with their receive times (monotonic and wall clock, ns)."""

    def __init__(self) -> None:
        self.msgs: list[Any] = []
        self.times: list[int] = []
        self.wall_times: list[int] = []

    def __call__(self, msg: Any) -> None:
        self.times.append(time.monotonic_ns())
        self.wall_times.append(time.time_ns())
        self.msgs.append(msg)

    def __len__(self) -> int:
        return len(self.msgs)

    def clear(self) -> None:
        """Forget everything received so far."""
        self.msgs.clear()
        self.times.clear()
        self.wall_times.clear()


class Probe:
    """A node in the test process, in a context of its own, with blocking helpers."""

    def __init__(self, name: str = 'probe', *, use_sim_time: bool = False,
                 remap: dict[str, str] | None = None, executor: str = 'single') -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        args = None
        if remap:
            args = ['--ros-args'] + [x for src, dst in remap.items()
                                     for x in ('-r', f'{src}:={dst}')]
        self.node = rclpy.create_node(
            f'{name}_{uuid.uuid4().hex[:6]}', context=self.context, cli_args=args,
            parameter_overrides=[rclpy.parameter.Parameter(
                'use_sim_time', rclpy.parameter.Parameter.Type.BOOL, use_sim_time)])
        if executor == 'events':  # less CPU per message: for the benchmark's subscriber
            from rclpy.experimental import EventsExecutor
            self.executor: Any = EventsExecutor(context=self.context)
        else:
            self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self) -> None:
        """Destroy the node and shut the context down."""
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> Probe:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def subscribe(self, msg_type: type, topic: str, qos: QoSProfile | int = 10,
                  callback: Callable[[Any], None] | None = None) -> Received:
        """Subscribe to ``topic`` and return the growing list of what arrives."""
        received = Received()

        def on_msg(msg: Any) -> None:
            received(msg)
            if callback is not None:
                callback(msg)

        self.node.create_subscription(msg_type, topic, on_msg, qos)
        return received

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.01, max(0.0, end - time.monotonic())))

    def spin_until(self, predicate: Callable[[], bool], timeout: float, what: str = '') -> None:
        """Process callbacks until ``predicate()`` holds; fail after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                raise AssertionError(f'timed out after {timeout} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.01)

    def call(self, srv_type: type, name: str, request: Any, timeout: float = 10.0) -> Any:
        """Call a service and return its response (waits until the server can answer first)."""
        client = self.node.create_client(srv_type, name)
        try:
            end = time.monotonic() + timeout
            while not client.service_is_ready():
                if time.monotonic() > end:
                    raise AssertionError(f'service {name} did not appear within {timeout} s')
                self.executor.spin_once(timeout_sec=0.02)
            ready_to_answer(self.node, self.executor, name.rsplit('/', 1)[0], timeout)
            future = client.call_async(request)
            self.spin_until(future.done, timeout, f'a response from {name}')
            return future.result()
        finally:
            self.node.destroy_client(client)

    def set_parameters(self, node_fqn: str, values: dict[str, Any],
                       timeout: float = 10.0) -> list[SetParametersResult]:
        """Set parameters of ``node_fqn`` through its SetParameters service; return results."""
        request = SetParameters.Request()
        request.parameters = [ParameterMsg(name=k, value=parameter_value(v))
                              for k, v in values.items()]
        return list(self.call(SetParameters, f'{node_fqn}/set_parameters', request,
                              timeout).results)

    def get_parameters(self, node_fqn: str, names: list[str]) -> dict[str, Any]:
        """Return parameter values of ``node_fqn`` through its GetParameters service."""
        response = self.call(GetParameters, f'{node_fqn}/get_parameters',
                             GetParameters.Request(names=names))
        return {n: python_value(v) for n, v in zip(names, response.values, strict=True)}


def parameter_value(value: Any) -> ParameterValue:
    """Return a ParameterValue message holding ``value`` with the type Python gives it."""
    if isinstance(value, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    if isinstance(value, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    if isinstance(value, str):
        return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    raise TypeError(f'unsupported parameter value {value!r}')


def python_value(value: ParameterValue) -> Any:
    """Return the Python value held by a ParameterValue message."""
    return {
        ParameterType.PARAMETER_BOOL: lambda: value.bool_value,
        ParameterType.PARAMETER_INTEGER: lambda: value.integer_value,
        ParameterType.PARAMETER_DOUBLE: lambda: value.double_value,
        ParameterType.PARAMETER_STRING: lambda: value.string_value,
        ParameterType.PARAMETER_NOT_SET: lambda: None,
    }[value.type]()


def stamp_ns(msg: Any) -> int:
    """Return a message's header stamp in ns."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def all_finite(values: Iterable[float]) -> bool:
    """Return True when every value is finite."""
    return all(math.isfinite(x) for x in values)


def diagnostics_of(received: list[DiagnosticArray], fqn: str) -> list[dict[str, str]]:
    """Return the key/values of the diagnostics published by node ``fqn``."""
    return [values_of(a) for a in received if a.status and a.status[0].name.startswith(fqn)]
