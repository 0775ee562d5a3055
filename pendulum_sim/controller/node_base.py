"""What the package's controller nodes share: :class:`ControllerNode`, its command line and main.

A controller node answers each ``joint_states`` message (sensor_msgs/JointState) that holds
its joint with exactly one ``effort_command`` (std_msgs/Float64, N·m, reliable), computed only
from that message; it has no timer and reads no clock. :class:`ControllerNode` is that loop:
the float parameters of a law (a :data:`FloatTable`, each with its range) and ``joint_name``,
all live and checked by the law before they are taken; the joint's position and velocity
looked up in each state (a state without them is skipped and logged once); the answer
published, counted and acknowledged (:meth:`ControllerNode.flush`). A subclass names its law
(``law_of``) and turns a state into a torque (:meth:`ControllerNode._torque`).
:func:`controller_parser` and :func:`serve` are the command line and ``main`` of every
controller node.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable
from typing import Any, Generic, TypeVar

import rclpy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.dds import (
    add_executor_option,
    make_executor,
    release,
    shut_down,
    use_loopback_profile,
)

from .errors import ControllerError

# Reliable and in order both ways: in synchronous mode the joint waits for the answer to every
# state, so neither a state nor an answer may be lost.
RELIABLE_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
BIG = 1e9  # upper end of the ranges: a FloatingPointRange needs a finite bound
DEFAULT_JOINT = 'pendulum_joint'
JOINT_NAME_TEXT = 'The joint to control: its index in JointState.name is used.'

FloatTable = tuple[tuple[str, float, str, tuple[float, float]], ...]
"""A law's float parameters: name, default, description, (low, high) each."""

LawT = TypeVar('LawT')
"""The law a controller node answers with: its gains, and what it derives from them."""


class ControllerNode(Node, Generic[LawT]):
    """Answer each joint state that holds the joint with one effort command.

    Parameters
    ----------
    name : str
        The node's name.
    floats : FloatTable
        The law's float parameters, declared with their ranges; ``joint_name`` besides.
    law_of : callable
        ``law_of(values)``, the parameter values by name, returns the law the node answers
        with (``self._law``) or raises :class:`ControllerError`: the values given at start-up
        end the start, a change that makes no law is rejected with its reason.
    count : int
        Stop (``done`` becomes True) after this many answers; 0 runs until shut down.
    """

    def __init__(self, name: str, floats: FloatTable,
                 law_of: Callable[[dict[str, Any]], LawT], *, count: int = 0) -> None:
        super().__init__(name)
        for key, default, text, (low, high) in floats:
            self.declare_parameter(key, default, ParameterDescriptor(
                description=text, floating_point_range=[
                    FloatingPointRange(from_value=low, to_value=high, step=0.0)]))
        self.declare_parameter('joint_name', DEFAULT_JOINT,
                               ParameterDescriptor(description=JOINT_NAME_TEXT))
        self._values: dict[str, Any] = {
            key: self.get_parameter(key).value for key, *_ in floats}
        self._values['joint_name'] = self.get_parameter('joint_name').value
        self._law_of = law_of
        # Values given at start-up are checked here (rclpy has already checked the ranges),
        # before the node has endpoints.
        self._law: LawT = law_of(self._values)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)

        self.count = count
        self.answers = 0
        self.skipped = 0
        self.done = False
        self._warned: set[str] = set()
        self._held: float | None = None
        # The states' subscription first: a synchronous joint steps once it sees a publisher
        # of commands, and the first state must find the subscription there. DDS matches the
        # two sides of each topic on its own, in no set order: the joint can see this
        # publisher, and send a state, before the publisher reaches the joint's subscription;
        # an answer published then would reach no one (volatile), so it is held until the
        # publisher reaches a subscriber (:meth:`_on_matched`).
        self._sub = self.create_subscription(JointState, 'joint_states', self._on_state,
                                             RELIABLE_QOS)
        self._pub = self.create_publisher(
            Float64, 'effort_command', RELIABLE_QOS,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))

    @property
    def joint(self) -> str:
        """Return the joint the node controls (the parameter ``joint_name``)."""
        return str(self._values['joint_name'])

    def _on_matched(self, info: QoSPublisherMatchedInfo) -> None:
        """Log each change in the subscribers the answers reach: the loop's connection; send
        an answer held for want of one."""
        self.get_logger().info(f'effort_command reaches {info.current_count} subscriber(s)')
        if info.current_count > 0 and self._held is not None:
            tau, self._held = self._held, None
            self._answer(tau)

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        proposed = dict(self._values)
        proposed.update({p.name: p.value for p in params if p.name in proposed})
        try:
            self._law_of(proposed)
        except ControllerError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        self._values.update({p.name: p.value for p in params if p.name in self._values})
        old = self._law
        self._law = self._law_of(self._values)
        self._law_changed(old)

    def _law_changed(self, old: LawT) -> None:
        """Take the new ``self._law`` (``old`` the one before a change of parameters)."""

    # ------------------------------------------------------------------ the loop
    def _error_once(self, key: str, text: str) -> None:
        """Log ``text`` as an error the first time ``key`` comes up."""
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().error(text)

    def _torque(self, msg: JointState, phi: float, dphi: float) -> float | None:
        """Return the answer to ``msg``, whose joint is at ``phi`` (rad), ``dphi`` (rad/s).

        None leaves the state unanswered (counted in ``skipped``).
        """
        raise NotImplementedError

    def _on_state(self, msg: JointState) -> None:
        joint = self.joint
        try:
            i = list(msg.name).index(joint)
            phi, dphi = float(msg.position[i]), float(msg.velocity[i])
        except (ValueError, IndexError):
            self.skipped += 1
            self._error_once(f'joint {joint} in {list(msg.name)}',
                             f'joint_states has no position and velocity for joint '
                             f'{joint!r} (names {list(msg.name)}, {len(msg.position)} '
                             f'positions, {len(msg.velocity)} velocities): not answered; set '
                             f'the parameter joint_name')
            return
        tau = self._torque(msg, phi, dphi)
        if tau is None:
            self.skipped += 1
        elif self._pub.get_subscription_count() == 0:
            self._held = tau   # the latest state's answer, sent once the publisher connects
        else:
            self._answer(tau)

    def _answer(self, tau: float) -> None:
        self._pub.publish(Float64(data=tau))
        self.answers += 1
        if self.count and self.answers >= self.count:
            self.done = True

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every answer is acknowledged by the subscribers (up to ``timeout``)."""
        return bool(self._pub.wait_for_all_acked(Duration(seconds=timeout)))


def controller_parser(prog: str, description: str, example: str) -> argparse.ArgumentParser:
    """Return the argument parser of the controller node ``prog``.

    ``example`` is a ``-p name:=value`` sample of its parameters, for the epilog.
    """
    parser = argparse.ArgumentParser(
        prog=prog, description=description,
        epilog=f'ROS arguments follow --ros-args, e.g. --ros-args {example} '
               '-p use_sim_time:=true -r __ns:=/my_ns')
    parser.add_argument('--count', type=int, default=0, metavar='N',
                        help='exit (code 0) after answering N states; 0 (default) runs until '
                        'Ctrl-C / SIGTERM')
    add_executor_option(parser)
    return parser


def serve(argv: list[str], parser: argparse.ArgumentParser,
          make_node: Callable[[int], ControllerNode[Any]]) -> int:
    """Run a controller node until Ctrl-C, SIGTERM or ``--count`` answers; return the code.

    The one ``main`` of the package's controller nodes: ``make_node(count)`` builds the node;
    bad parameters end it with code 2 and one line.
    """
    prog = parser.prog
    opts = parser.parse_args(remove_ros_args(argv)[1:])
    if opts.count < 0:
        print(f'{prog}: --count must be >= 0, got {opts.count}', file=sys.stderr)
        return 2
    # Ctrl-C and SIGTERM only ask the loop to stop. rclpy's own handlers would shut the context
    # down at once, in the middle of a callback that is still publishing (a FATAL log and a
    # traceback); a flag stops the loop between callbacks, and the finally clause shuts down.
    use_loopback_profile(os.environ)   # DDS on 127.0.0.1, as pendulum_node
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []

    def request_stop(signum: int, frame: object) -> None:
        stop.append(signum)

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)
    node: ControllerNode[Any] | None = None
    executor: Executor | None = None
    code = 0
    try:
        executor = make_executor(opts.executor)
        node = make_node(opts.count)
        executor.add_node(node)
        # spin_once in a loop: the EventsExecutor's spin() would not return to Python, and the
        # stop flag and --count are checked between callbacks.
        while rclpy.ok() and not stop and not node.done:
            executor.spin_once(timeout_sec=0.1)
        if node.done:
            node.flush()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ControllerError, InvalidParameterValueException,
            InvalidParameterTypeException) as exc:
        hint = ' (write doubles with a decimal point, e.g. 4.0)' if isinstance(
            exc, InvalidParameterTypeException) else ''
        print(f'{prog}: {exc}{hint}', file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            print(f'{prog}: answered {node.answers} states, skipped {node.skipped}',
                  file=sys.stderr, flush=True)
        release(executor, node)
        shut_down(node, code)
    return code
