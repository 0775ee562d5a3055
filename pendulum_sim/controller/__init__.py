"""The example controller ``pendulum_pd_controller``: PD with gravity compensation.

``pd_law`` is the control law and the settle detectors, without ROS (unit-tested without rclpy);
``pd_controller`` is the rclpy node and its command line.
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
