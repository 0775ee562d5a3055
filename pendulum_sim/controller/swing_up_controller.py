"""``pendulum_swing_up_controller``: the reference swing-up as an rclpy node answering every state.

Each ``joint_states`` message (sensor_msgs/JointState) that holds the joint is answered with
exactly one ``effort_command`` (std_msgs/Float64, N·m, reliable), computed only from that
message by :func:`pendulum_sim.controller.swing_up_law.swing_up_torque`: energy shaping away
from upright, the LQR balance inside its region-of-attraction ellipse (the gain from the
parameters' body, linearised at upright, by python-control's ``lqr``). Like
``pendulum_pd_controller`` it has no timer and reads no clock, so against the joint's
synchronous mode a run is reproducible bit for bit, and it answers as the in-process law
``pendulum_sim.testing.examples:energy_lqr`` does for the same parameters.

Run it as::

    pendulum_node --scene swing_up &
    pendulum_swing_up_controller --ros-args -p k_energy:=5.0
    pendulum_benchmark pendulum_swing_up_controller --out bench --roa-grid 4 --episodes 4
"""
from __future__ import annotations

import argparse
import sys
from typing import Any, NoReturn

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.dds import exit_with

from .errors import ControllerError
from .pd_controller import BIG, RELIABLE_QOS, serve
from .pd_controller import _parser as controller_parser
from .swing_up_law import SwingUpGains, balance, swing_up_torque

NODE_NAME = 'pendulum_swing_up_controller'
_G = SwingUpGains()
# name, default, description, (low, high)
_FLOATS: tuple[tuple[str, float, str, tuple[float, float]], ...] = (
    ('m', _G.m, 'Mass the law assumes, kg (> 0).', (0.0, BIG)),
    ('l', _G.l, 'Pivot to centre of mass the law assumes, m (> 0).', (0.0, BIG)),
    ('inertia', _G.inertia, 'Inertia about the pivot the law assumes, kg m^2 (>= m l^2).',
     (0.0, BIG)),
    ('g', _G.g, 'Gravity the law assumes, m/s^2 (>= 0).', (0.0, BIG)),
    ('gamma', _G.gamma, 'Viscous damping the law assumes, 1/s (>= 0).', (0.0, BIG)),
    ('max_effort', _G.max_effort, 'The torque limit, N m (> 0): commands are clipped to it.',
     (0.0, BIG)),
    ('q_angle', _G.q[0], 'LQR weight on the angle from upright, 1/rad^2 (>= 0).', (0.0, BIG)),
    ('q_rate', _G.q[1], 'LQR weight on the rate, s^2/rad^2 (>= 0).', (0.0, BIG)),
    ('r', _G.r, 'LQR weight on the torque, 1/(N m)^2 (> 0).', (0.0, BIG)),
    ('k_energy', _G.k_energy, 'Energy-shaping gain, N m per J (> 0).', (0.0, BIG)),
)
_DEFAULT_JOINT = 'pendulum_joint'


def gains_of(values: dict[str, Any]) -> SwingUpGains:
    """Return the law's gains for the parameter ``values``; ControllerError if they are bad."""
    return SwingUpGains(m=values['m'], l=values['l'], inertia=values['inertia'], g=values['g'],
                        gamma=values['gamma'], max_effort=values['max_effort'],
                        q=(values['q_angle'], values['q_rate']), r=values['r'],
                        k_energy=values['k_energy'])


class SwingUpControllerNode(Node):
    """Answer each joint state with one energy-shaping / LQR effort command.

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
        self._gains = gains_of(self._values)   # values given at start-up checked here
        self._balance = balance(self._gains)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.count = count
        self.answers = 0
        self.skipped = 0
        self.done = False
        self._warned = False
        # The states' subscription first: a synchronous joint steps once it sees a publisher
        # of commands, and the first state must find the subscription there.
        self._sub = self.create_subscription(JointState, 'joint_states', self._on_state,
                                             RELIABLE_QOS)
        self._pub = self.create_publisher(
            Float64, 'effort_command', RELIABLE_QOS,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        k = self._balance.gain
        self.get_logger().info(
            f'energy shaping + LQR on joint {self._values["joint_name"]!r}: max_effort = '
            f'{self._gains.max_effort:g} N m, k_energy = {self._gains.k_energy:g}, LQR gain '
            f'K = [{k[0]:.6g}, {k[1]:.6g}]; one effort_command per joint_states message')

    def _on_matched(self, info: QoSPublisherMatchedInfo) -> None:
        """Log each change in the subscribers the answers reach: the loop's connection."""
        self.get_logger().info(f'effort_command reaches {info.current_count} subscriber(s)')

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        proposed = dict(self._values)
        proposed.update({p.name: p.value for p in params if p.name in proposed})
        try:
            gains_of(proposed)
        except ControllerError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        self._values.update({p.name: p.value for p in params if p.name in self._values})
        self._gains = gains_of(self._values)
        self._balance = balance(self._gains)

    def _on_state(self, msg: JointState) -> None:
        joint = str(self._values['joint_name'])
        try:
            i = list(msg.name).index(joint)
            phi, dphi = float(msg.position[i]), float(msg.velocity[i])
        except (ValueError, IndexError):
            self.skipped += 1
            if not self._warned:
                self._warned = True
                self.get_logger().error(
                    f'joint_states has no position and velocity for joint {joint!r} (names '
                    f'{list(msg.name)}): not answered; set the parameter joint_name')
            return
        tau = float(swing_up_torque(self._gains, self._balance, phi, dphi))
        self._pub.publish(Float64(data=tau))
        self.answers += 1
        if self.count and self.answers >= self.count:
            self.done = True

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every answer is acknowledged by the subscribers (up to ``timeout``)."""
        return bool(self._pub.wait_for_all_acked(Duration(seconds=timeout)))


def _parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_swing_up_controller``."""
    return controller_parser(
        NODE_NAME, 'The reference swing-up controller for pendulum_node: energy shaping, LQR '
        'balance near upright; one effort_command per joint_states message.',
        '-p k_energy:=5.0 -p max_effort:=0.98')


def main(args: list[str] | None = None) -> int:
    """Run the controller until Ctrl-C, SIGTERM or ``--count`` answers; return the exit code.

    The LQR's solver (python-control, a second or more to import) is loaded first: a node
    that takes long between its start and its endpoints can miss the first state of a
    synchronous joint that already counts it as connected.
    """
    balance(_G)
    return serve(list(sys.argv if args is None else args), _parser(),
                 lambda count: SwingUpControllerNode(count=count))


def entry() -> NoReturn:
    """The console script ``pendulum_swing_up_controller``: :func:`main`, ended by
    ``dds.exit_with``."""
    exit_with(main)


if __name__ == '__main__':
    entry()
