"""Exceptions of the ROS node (the joint's own are in :mod:`pendulum_sim.joint.errors`)."""
from __future__ import annotations

from pendulum_sim.core import PendulumError
from pendulum_sim.joint.errors import JointError, LiveError, ParameterError, SceneError


class NodeError(PendulumError):
    """The node cannot start or run as configured."""


__all__ = ['JointError', 'LiveError', 'NodeError', 'ParameterError', 'SceneError']
