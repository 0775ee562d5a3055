"""``pendulum_pd_controller``: the example controller, an rclpy node answering every state.

Each ``joint_states`` message (sensor_msgs/JointState) that holds the joint is answered with
exactly one ``effort_command`` (std_msgs/Float64, N·m, reliable), computed only from that
message by :func:`pendulum_sim.controller.pd_law.pd_torque`. The node has no timer and reads no
clock: its output is a function of the states it receives, so in the joint's synchronous mode,
where the joint waits for the answer to each state, a run is reproducible bit for bit. Time, for
the settle report, is the states' ``header.stamp`` (simulated time in lockstep), so the
controller behaves the same with or without ``use_sim_time`` and at any real-time factor.

The settle report names its rule and gives, beside it, the step-response settling time that
the test bench reports for the same run (python-control's ``step_info``, 2 % of the step):
``settled at t = 2.670 s (state stamp) by the controller's rule: ...; step-response settling
time t = 1.300 s so far ...`` for the README's run, two measures of one response.

Run it as::

    pendulum_pd_controller --ros-args -p target:=0.5 -p kp:=4.0
    ros2 run pendulum_sim pendulum_pd_controller --count 1000
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable
from typing import Any, NoReturn, Protocol

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
    exit_with,
    make_executor,
    release,
    shut_down,
    use_loopback_profile,
)

from .errors import ControllerError
from .pd_law import (
    PDGains,
    SettleDetector,
    SettleEvent,
    SettleLimits,
    StepSettling,
    pd_torque,
    wrap_angle,
)

NODE_NAME = 'pendulum_pd_controller'
# Reliable and in order both ways: in synchronous mode the joint waits for the answer to every
# state, so neither a state nor an answer may be lost.
RELIABLE_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
BIG = 1e9  # upper end of the ranges: a FloatingPointRange needs a finite bound

# name, default, description, (low, high)
_FLOATS: tuple[tuple[str, float, str, tuple[float, float]], ...] = (
    ('kp', PDGains.kp, 'Proportional gain Kp in N m/rad (>= 0).', (0.0, BIG)),
    ('kd', PDGains.kd, 'Derivative gain Kd in N m s/rad (>= 0).', (0.0, BIG)),
    ('target', PDGains.target, 'Reference angle in rad (0 hangs straight down; the error is '
     'wrapped to [-pi, pi], so the joint turns the short way).', (-BIG, BIG)),
    ('mgl', PDGains.mgl, 'Gravity compensation m g l in N m (>= 0; 0 switches it off). The '
     "default 0.2 * 9.8 * 1.0 is the default scene's body.", (0.0, BIG)),
    ('max_effort', PDGains.max_effort, 'The command is clipped to [-max_effort, max_effort] '
     'N m (> 0).', (0.0, BIG)),
    ('settle_position_tolerance', SettleLimits.position, 'Settled when |angle - target| stays '
     'below this (rad, > 0) ...', (0.0, BIG)),
    ('settle_velocity_tolerance', SettleLimits.velocity, '... and |velocity| below this '
     '(rad/s, > 0) ...', (0.0, BIG)),
    ('settle_hold', SettleLimits.hold, '... for this long in simulated time (s, >= 0, read from '
     "the states' stamps).", (0.0, BIG)),
)
_DEFAULT_JOINT = 'pendulum_joint'


def _law(values: dict[str, Any]) -> tuple[PDGains, SettleLimits]:
    """Return the law and the settle limits for ``values``; ControllerError if they are bad."""
    gains = PDGains(kp=values['kp'], kd=values['kd'], target=values['target'],
                    mgl=values['mgl'], max_effort=values['max_effort'])
    limits = SettleLimits(position=values['settle_position_tolerance'],
                          velocity=values['settle_velocity_tolerance'],
                          hold=values['settle_hold'])
    return gains, limits


class PDControllerNode(Node):
    """Answer each joint state with one PD + gravity-compensation effort command.

    Parameters
    ----------
    count : int
        Stop (``done`` becomes True) after this many answers; 0 runs until shut down.
    """

    def __init__(self, *, count: int = 0) -> None:
        super().__init__(NODE_NAME)
        for name, default, text, (low, high) in _FLOATS:
            self.declare_parameter(name, default, ParameterDescriptor(
                description=text, floating_point_range=[
                    FloatingPointRange(from_value=low, to_value=high, step=0.0)]))
        self.declare_parameter('joint_name', _DEFAULT_JOINT, ParameterDescriptor(
            description='The joint to control: its index in JointState.name is used.'))
        self._values: dict[str, Any] = {
            name: self.get_parameter(name).value for name, *_ in _FLOATS}
        self._values['joint_name'] = self.get_parameter('joint_name').value
        # Values given at start-up are checked here (rclpy has already checked the ranges).
        self._gains, limits = _law(self._values)
        self._settle = SettleDetector(limits)
        self._step = StepSettling()
        self._joint = str(self._values['joint_name'])
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)

        self.count = count
        self.answers = 0
        self.skipped = 0
        self.done = False
        self._warned: set[str] = set()
        self._pub = self.create_publisher(
            Float64, 'effort_command', RELIABLE_QOS,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        self._sub = self.create_subscription(JointState, 'joint_states', self._on_state,
                                             RELIABLE_QOS)
        g = self._gains
        self.get_logger().info(
            f'PD + gravity compensation on joint {self._joint!r}: kp = {g.kp:g}, '
            f'kd = {g.kd:g}, target = {g.target:g} rad, mgl = {g.mgl:g} N m, '
            f'max_effort = {g.max_effort:g} N m; one effort_command per joint_states message')

    def _on_matched(self, info: QoSPublisherMatchedInfo) -> None:
        """Log each change in the subscribers the answers reach: the loop's connection."""
        self.get_logger().info(f'effort_command reaches {info.current_count} subscriber(s)')

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        proposed = dict(self._values)
        for p in params:
            if p.name in proposed:
                proposed[p.name] = p.value
        try:
            _law(proposed)
        except ControllerError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        for p in params:
            if p.name in self._values:
                self._values[p.name] = p.value
        target = self._gains.target
        self._gains, limits = _law(self._values)
        if self._gains.target != target:
            self._step.restart()   # a new target: a new step, from the next state
        if limits != self._settle.limits:
            self._settle = SettleDetector(limits)
        self._joint = str(self._values['joint_name'])

    # ------------------------------------------------------------------ the loop
    def _error_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().error(text)

    def _on_state(self, msg: JointState) -> None:
        try:
            i = list(msg.name).index(self._joint)
            phi, dphi = float(msg.position[i]), float(msg.velocity[i])
        except (ValueError, IndexError):
            self.skipped += 1
            self._error_once(f'joint {self._joint} in {list(msg.name)}',
                            f'joint_states has no position and velocity for joint '
                            f'{self._joint!r} (names {list(msg.name)}, {len(msg.position)} '
                            f'positions, {len(msg.velocity)} velocities): not answered; set '
                            f'the parameter joint_name')
            return
        try:
            tau = pd_torque(self._gains, phi, dphi)
        except ControllerError as exc:
            self.skipped += 1
            self._error_once('nonfinite', f'{exc}: not answered (reported once)')
            return
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        error = wrap_angle(phi - self._gains.target)
        self._step.update(stamp_ns, phi, self._gains.target)
        event = self._settle.update(stamp_ns, error, dphi)
        if event is SettleEvent.SETTLED:
            since = self._settle.inside_since_ns or stamp_ns
            lim = self._settle.limits
            self.get_logger().info(
                f"settled at t = {stamp_ns / 1e9:.3f} s (state stamp) by the controller's "
                f'rule: |angle - target| < {lim.position:g} rad and |velocity| < '
                f'{lim.velocity:g} rad/s since t = {since / 1e9:.3f} s (settle_hold '
                f'{lim.hold:g} s); angle {phi:.6f} rad, target {self._gains.target:g} rad; '
                f'{self._step.text()}')
        elif event is SettleEvent.LEFT:
            self.get_logger().info(
                f'left the target at t = {stamp_ns / 1e9:.3f} s (state stamp): angle '
                f'{phi:.6f} rad, velocity {dphi:.6f} rad/s; settle detection starts over')
        elif event is SettleEvent.RESTARTED:
            self.get_logger().info(
                f'simulated time went back to t = {stamp_ns / 1e9:.3f} s (a reset): '
                'settle detection starts over')
        self._pub.publish(Float64(data=tau))
        self.answers += 1
        if self.count and self.answers >= self.count:
            self.done = True

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every answer is acknowledged by the subscribers (up to ``timeout``)."""
        return bool(self._pub.wait_for_all_acked(Duration(seconds=timeout)))


def _parser(prog: str = NODE_NAME, description: str = (
        'Example controller for pendulum_node: PD with gravity compensation, one '
        'effort_command per joint_states message.'),
        example: str = '-p target:=0.5 -p kp:=4.0') -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog, description=description,
        epilog=f'ROS arguments follow --ros-args, e.g. --ros-args {example} '
               '-p use_sim_time:=true -r __ns:=/my_ns')
    parser.add_argument('--count', type=int, default=0, metavar='N',
                        help='exit (code 0) after answering N states; 0 (default) runs until '
                        'Ctrl-C / SIGTERM')
    add_executor_option(parser)
    return parser


class AnsweringNode(Protocol):
    """What :func:`serve` runs: a node that answers states and counts its answers."""

    answers: int
    skipped: int
    done: bool

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every answer is acknowledged."""


def serve(argv: list[str], parser: argparse.ArgumentParser,
          make_node: Callable[[int], Any]) -> int:
    """Run a controller node until Ctrl-C, SIGTERM or ``--count`` answers; return the code.

    The one ``main`` of the package's controller nodes: ``make_node(count)`` builds the node
    (an :class:`AnsweringNode`); bad parameters end it with code 2 and one line.
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
    node: Any = None
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


def main(args: list[str] | None = None) -> int:
    """Run the controller until Ctrl-C, SIGTERM or ``--count`` answers; return the exit code."""
    return serve(list(sys.argv if args is None else args), _parser(),
                 lambda count: PDControllerNode(count=count))


def entry() -> NoReturn:
    """The console script ``pendulum_pd_controller``: :func:`main`, ended by ``dds.exit_with``."""
    exit_with(main)


if __name__ == '__main__':
    entry()
