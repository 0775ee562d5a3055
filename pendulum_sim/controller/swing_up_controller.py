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
from typing import Any, NamedTuple, NoReturn

from sensor_msgs.msg import JointState

from pendulum_sim.dds import exit_with

from .node_base import BIG, ControllerNode, FloatTable, controller_parser, serve
from .swing_up_law import Balance, SwingUpGains, balance, swing_up_torque

NODE_NAME = 'pendulum_swing_up_controller'
_G = SwingUpGains()
# name, default, description, (low, high)
_FLOATS: FloatTable = (
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


def gains_of(values: dict[str, Any]) -> SwingUpGains:
    """Return the law's gains for the parameter ``values``; ControllerError if they are bad."""
    return SwingUpGains(m=values['m'], l=values['l'], inertia=values['inertia'], g=values['g'],
                        gamma=values['gamma'], max_effort=values['max_effort'],
                        q=(values['q_angle'], values['q_rate']), r=values['r'],
                        k_energy=values['k_energy'])


class SwingUpLaw(NamedTuple):
    """The law a :class:`SwingUpControllerNode` answers with: its gains and their LQR."""

    gains: SwingUpGains
    balance: Balance


def law_of(values: dict[str, Any]) -> SwingUpLaw:
    """Return the law for the parameter ``values``; ControllerError if they are bad."""
    gains = gains_of(values)
    return SwingUpLaw(gains, balance(gains))


class SwingUpControllerNode(ControllerNode[SwingUpLaw]):
    """Answer each joint state with one energy-shaping / LQR effort command.

    Parameters
    ----------
    count : int
        Stop (``done`` becomes True) after this many answers; 0 runs until shut down.
    """

    def __init__(self, *, count: int = 0) -> None:
        super().__init__(NODE_NAME, _FLOATS, law_of, count=count)
        gains, k = self._law.gains, self._law.balance.gain
        self.get_logger().info(
            f'energy shaping + LQR on joint {self.joint!r}: max_effort = '
            f'{gains.max_effort:g} N m, k_energy = {gains.k_energy:g}, LQR gain '
            f'K = [{k[0]:.6g}, {k[1]:.6g}]; one effort_command per joint_states message')

    def _torque(self, msg: JointState, phi: float, dphi: float) -> float | None:
        return float(swing_up_torque(self._law.gains, self._law.balance, phi, dphi))


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
