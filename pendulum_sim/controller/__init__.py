"""The controller nodes: the example ``pendulum_pd_controller`` (PD with gravity compensation)
and the reference swing-up ``pendulum_swing_up_controller``.

``pd_law`` and ``swing_up_law`` are the control laws (and the PD's settle detectors), without
ROS (unit-tested without rclpy); ``node_base`` is what both rclpy nodes share (the node that
answers each state, its parameters, command line and main); ``pd_controller`` and
``swing_up_controller`` are the nodes, each its law, parameters and log lines.
"""
from __future__ import annotations

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

__all__ = ['ControllerError', 'PDGains', 'SettleDetector', 'SettleEvent', 'SettleLimits',
           'StepSettling', 'pd_torque', 'wrap_angle']
