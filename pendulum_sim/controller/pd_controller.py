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
import sys
from typing import Any, NoReturn

from sensor_msgs.msg import JointState

from pendulum_sim.dds import exit_with

from .errors import ControllerError
from .node_base import BIG, ControllerNode, FloatTable, controller_parser, serve
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

# name, default, description, (low, high)
_FLOATS: FloatTable = (
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


def _law(values: dict[str, Any]) -> tuple[PDGains, SettleLimits]:
    """Return the law and the settle limits for ``values``; ControllerError if they are bad."""
    gains = PDGains(kp=values['kp'], kd=values['kd'], target=values['target'],
                    mgl=values['mgl'], max_effort=values['max_effort'])
    limits = SettleLimits(position=values['settle_position_tolerance'],
                          velocity=values['settle_velocity_tolerance'],
                          hold=values['settle_hold'])
    return gains, limits


class PDControllerNode(ControllerNode[tuple[PDGains, SettleLimits]]):
    """Answer each joint state with one PD + gravity-compensation effort command.

    Parameters
    ----------
    count : int
        Stop (``done`` becomes True) after this many answers; 0 runs until shut down.
    """

    def __init__(self, *, count: int = 0) -> None:
        super().__init__(NODE_NAME, _FLOATS, _law, count=count)
        gains, limits = self._law
        self._settle = SettleDetector(limits)
        self._step = StepSettling()
        self.get_logger().info(
            f'PD + gravity compensation on joint {self.joint!r}: kp = {gains.kp:g}, '
            f'kd = {gains.kd:g}, target = {gains.target:g} rad, mgl = {gains.mgl:g} N m, '
            f'max_effort = {gains.max_effort:g} N m; one effort_command per joint_states '
            'message')

    def _law_changed(self, old: tuple[PDGains, SettleLimits]) -> None:
        gains, limits = self._law
        if gains.target != old[0].target:
            self._step.restart()   # a new target: a new step, from the next state
        if limits != self._settle.limits:
            self._settle = SettleDetector(limits)

    def _torque(self, msg: JointState, phi: float, dphi: float) -> float | None:
        gains = self._law[0]
        try:
            tau = pd_torque(gains, phi, dphi)
        except ControllerError as exc:
            self._error_once('nonfinite', f'{exc}: not answered (reported once)')
            return None
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        error = wrap_angle(phi - gains.target)
        self._step.update(stamp_ns, phi, gains.target)
        event = self._settle.update(stamp_ns, error, dphi)
        if event is SettleEvent.SETTLED:
            since = self._settle.inside_since_ns or stamp_ns
            lim = self._settle.limits
            self.get_logger().info(
                f"settled at t = {stamp_ns / 1e9:.3f} s (state stamp) by the controller's "
                f'rule: |angle - target| < {lim.position:g} rad and |velocity| < '
                f'{lim.velocity:g} rad/s since t = {since / 1e9:.3f} s (settle_hold '
                f'{lim.hold:g} s); angle {phi:.6f} rad, target {gains.target:g} rad; '
                f'{self._step.text()}')
        elif event is SettleEvent.LEFT:
            self.get_logger().info(
                f'left the target at t = {stamp_ns / 1e9:.3f} s (state stamp): angle '
                f'{phi:.6f} rad, velocity {dphi:.6f} rad/s; settle detection starts over')
        elif event is SettleEvent.RESTARTED:
            self.get_logger().info(
                f'simulated time went back to t = {stamp_ns / 1e9:.3f} s (a reset): '
                'settle detection starts over')
        return tau


def _parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_pd_controller``."""
    return controller_parser(
        NODE_NAME, 'Example controller for pendulum_node: PD with gravity compensation, one '
        'effort_command per joint_states message.', '-p target:=0.5 -p kp:=4.0')


def main(args: list[str] | None = None) -> int:
    """Run the controller until Ctrl-C, SIGTERM or ``--count`` answers; return the exit code."""
    return serve(list(sys.argv if args is None else args), _parser(),
                 lambda count: PDControllerNode(count=count))


def entry() -> NoReturn:
    """The console script ``pendulum_pd_controller``: :func:`main`, ended by ``dds.exit_with``."""
    exit_with(main)


if __name__ == '__main__':
    entry()
